//! # Geometry: the shapes every system collides with, and their queries
//!
//! One definition of each collision shape, shared by particles, cloth and rigid bodies (and
//! every system to come), so a sphere means the same thing, is checked with the same messages
//! and answers the same distance query everywhere:
//!
//! - [`shape`]: the world-placed shapes ([`Plane`], [`Sphere`], [`Capsule`], [`Cuboid`], and
//!   [`Shape`], one of them) with their validation, one message per mistake;
//! - [`query`]: signed distance with the outward normal, and the closest surface point;
//! - [`segment`]: closest points of a segment to a point and of two segments;
//! - [`material`]: the surface's [`Material`] (restitution, Coulomb friction), kept apart from
//!   the shape so one shape can carry any material;
//! - [`triangle`]: the closest point of a triangle, an exact triangle–triangle intersection
//!   test on the exact predicates of [`exact`], an exact ray crossing for inside tests, and the search for intersecting triangles of
//!   a mesh;
//! - [`tree`]: a bounding volume hierarchy of a triangle mesh that tells whether a segment
//!   meets the surface;
//! - [`ccd`]: continuous collision detection of a moving vertex and triangle, or two edges
//!   (the coplanarity cubic of Provot 1997);
//! - [`isosurface`]: the zero level set of a sampled function as a closed triangle mesh
//!   (marching tetrahedra);
//! - [`solid`]: the body-frame [`Solid`]s of rigid bodies (sphere, box, capsule, cylinder,
//!   closed mesh) with their mass properties.
//!
//! This module imports no system of kinema (only [`crate::error`]); systems import it.

pub mod ccd;
pub mod exact;
pub(crate) mod grid;
pub mod isosurface;
pub mod material;
pub mod query;
pub mod segment;
pub mod shape;
pub mod solid;
pub mod tree;
pub mod triangle;

pub use material::Material;
pub use shape::{Capsule, Cuboid, Plane, Shape, Sphere};
pub use solid::{MassProperties, Solid};
