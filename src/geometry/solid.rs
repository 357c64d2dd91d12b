//! Shapes and their mass properties: mass, centre of mass and the inertia tensor about the
//! centre of mass in the body frame.
//!
//! Primitives use the closed forms (see e.g. Eberly, *Game Physics*, 2nd ed., §2.5); every
//! primitive is centred at the body origin with its axis (capsule, cylinder) along the body's
//! +Y (the up axis). Closed triangle meshes use the exact polyhedral integrals of Blow &
//! Binstock (2004), "How to find the inertia tensor of a 3D solid body represented by a
//! triangle mesh": each outward triangle `(a, b, c)` spans a signed tetrahedron with the origin
//! whose covariance is `det[a b c] · A C₀ Aᵀ` with `C₀ = (1 + δᵢⱼ)/120`; summing gives the
//! second moment `C` of the solid, and `I = tr(C) 1 − C`, shifted to the centre of mass by the
//! parallel-axis theorem.

use crate::error::{Error, Result};
use glam::{DMat3, DVec3};
use std::collections::HashMap;
use std::f64::consts::PI;

/// A solid shape in its body frame (metres).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub enum Solid {
    /// Ball of the given radius centred at the origin.
    Sphere {
        /// Radius (m).
        radius: f64,
    },
    /// Box centred at the origin with the given half extents along x, y, z (m).
    Box {
        /// Half extents (m).
        half_extents: DVec3,
    },
    /// Cylinder of length `height` along +Y with hemispherical caps of `radius` at its ends.
    Capsule {
        /// Radius of the cylinder and the caps (m).
        radius: f64,
        /// Length of the cylindrical part between the cap centres (m).
        height: f64,
    },
    /// Solid cylinder of the given radius and total height along +Y, centred at the origin.
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Total height (m).
        height: f64,
    },
    /// Closed, consistently oriented (outward normals, counter-clockwise) triangle mesh.
    Mesh {
        /// Vertex positions (m).
        vertices: Vec<DVec3>,
        /// Vertex indices of each triangle.
        triangles: Vec<[usize; 3]>,
    },
}

/// Mass, centre of mass and inertia tensor of a rigid body.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct MassProperties {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the body frame (m).
    pub center_of_mass: DVec3,
    /// Inertia tensor about the centre of mass, in body-frame axes (kg m²).
    pub inertia: DMat3,
}

fn positive(arg: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(Error::invalid(arg, format!("must be positive and finite, got {value}")))
    }
}

impl Solid {
    /// Volume (m³), checking the shape's dimensions.
    ///
    /// # Errors
    /// Non-positive or non-finite dimensions; for meshes, see [`Solid::mass_properties`].
    pub fn volume(&self) -> Result<f64> {
        Ok(self.mass_properties(1.0)?.mass)
    }

    /// Radius of the smallest sphere about `center` (body frame) that holds the shape (m).
    pub fn bounding_radius(&self, center: DVec3) -> f64 {
        let c = center.length();
        match self {
            Solid::Sphere { radius } => radius + c,
            Solid::Box { half_extents } => half_extents.length() + c,
            Solid::Capsule { radius, height } => radius + 0.5 * height + c,
            Solid::Cylinder { radius, height } => radius.hypot(0.5 * height) + c,
            Solid::Mesh { vertices, .. } => {
                vertices.iter().map(|v| (*v - center).length()).fold(0.0, f64::max)
            }
        }
    }

    /// Mass properties of the shape filled with uniform `density` (kg/m³).
    ///
    /// # Errors
    /// A non-positive density or dimension; a mesh that is empty, has an index out of range,
    /// is not closed (an edge not shared by exactly two triangles in opposite directions),
    /// or encloses no positive volume (inverted or flat).
    pub fn mass_properties(&self, density: f64) -> Result<MassProperties> {
        let rho = positive("density", density)?;
        let diag = |x: f64, y: f64, z: f64| DMat3::from_diagonal(DVec3::new(x, y, z));
        let (mass, inertia) = match *self {
            Solid::Sphere { radius } => {
                let r = positive("radius", radius)?;
                let m = rho * 4.0 / 3.0 * PI * r.powi(3);
                let i = 0.4 * m * r * r;
                (m, diag(i, i, i))
            }
            Solid::Box { half_extents: h } => {
                let (x, y, z) = (
                    positive("half_extents", h.x)?,
                    positive("half_extents", h.y)?,
                    positive("half_extents", h.z)?,
                );
                let m = rho * 8.0 * x * y * z;
                (
                    m,
                    diag(
                        m / 3.0 * (y * y + z * z),
                        m / 3.0 * (x * x + z * z),
                        m / 3.0 * (x * x + y * y),
                    ),
                )
            }
            Solid::Cylinder { radius, height } => {
                let (r, h) = (positive("radius", radius)?, positive("height", height)?);
                let m = rho * PI * r * r * h;
                let side = m / 12.0 * (3.0 * r * r + h * h);
                (m, diag(side, 0.5 * m * r * r, side))
            }
            Solid::Capsule { radius, height } => {
                let r = positive("radius", radius)?;
                if !(height.is_finite() && height >= 0.0) {
                    return Err(Error::invalid(
                        "height",
                        format!("must be >= 0 and finite, got {height}"),
                    ));
                }
                let h = height;
                let m_cyl = rho * PI * r * r * h;
                let m_cap = rho * 2.0 / 3.0 * PI * r.powi(3); // one hemisphere
                let axial = 0.5 * m_cyl * r * r + 2.0 * 0.4 * m_cap * r * r;
                // Each cap about its own centre of mass (3r/8 from its flat face), shifted to the
                // capsule centre: m (2/5 r² + h²/4 + 3hr/8).
                let side = m_cyl * (h * h / 12.0 + r * r / 4.0)
                    + 2.0 * m_cap * (0.4 * r * r + h * h / 4.0 + 3.0 * h * r / 8.0);
                (m_cyl + 2.0 * m_cap, diag(side, axial, side))
            }
            Solid::Mesh { ref vertices, ref triangles } => {
                return mesh_mass_properties(vertices, triangles, rho)
            }
        };
        Ok(MassProperties { mass, center_of_mass: DVec3::ZERO, inertia })
    }
}

fn mesh_mass_properties(
    vertices: &[DVec3],
    triangles: &[[usize; 3]],
    rho: f64,
) -> Result<MassProperties> {
    if triangles.is_empty() {
        return Err(Error::invalid("triangles", "the mesh has no triangles"));
    }
    if let Some(i) = vertices.iter().position(|v| !v.is_finite()) {
        return Err(Error::InvalidInput {
            arg: "vertices".into(),
            index: Some(i),
            reason: "contains NaN or infinity".into(),
        });
    }
    // Closed and consistently oriented: every directed edge appears once, its reverse once.
    let mut edges: HashMap<(usize, usize), usize> = HashMap::with_capacity(3 * triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        if let Some(&bad) = tri.iter().find(|&&i| i >= vertices.len()) {
            return Err(Error::InvalidInput {
                arg: "triangles".into(),
                index: Some(t),
                reason: format!(
                    "vertex index {bad} is out of range (mesh has {} vertices)",
                    vertices.len()
                ),
            });
        }
        for k in 0..3 {
            *edges.entry((tri[k], tri[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    for (&(a, b), &count) in &edges {
        if count != 1 || edges.get(&(b, a)) != Some(&1) {
            return Err(Error::invalid(
                "triangles",
                format!("the mesh is not closed and consistently oriented (edge {a}-{b})"),
            ));
        }
    }
    // Signed tetrahedra (origin, a, b, c); shift by a vertex to limit cancellation.
    let o = vertices[triangles[0][0]];
    let (mut volume, mut first, mut second) = (0.0, DVec3::ZERO, DMat3::ZERO);
    for tri in triangles {
        let (a, b, c) = (vertices[tri[0]] - o, vertices[tri[1]] - o, vertices[tri[2]] - o);
        let det = a.dot(b.cross(c));
        volume += det / 6.0;
        first += det / 24.0 * (a + b + c);
        // ∫ x xᵀ over the tetrahedron = det/120 (Σ vᵢvᵢᵀ + (Σ vᵢ)(Σ vᵢ)ᵀ).
        let s = a + b + c;
        let outer = |u: DVec3| DMat3::from_cols(u * u.x, u * u.y, u * u.z);
        second += (outer(a) + outer(b) + outer(c) + outer(s)) * (det / 120.0);
    }
    if volume.is_nan() || volume <= 0.0 {
        return Err(Error::invalid(
            "triangles",
            format!(
                "the mesh encloses volume {volume:e} m³; it must be positive (outward normals)"
            ),
        ));
    }
    let mass = rho * volume;
    let com = first / volume;
    // Second moment about the centre of mass, then I = tr(C) 1 - C.
    let c = (second - DMat3::from_cols(com * com.x, com * com.y, com * com.z) * volume) * rho;
    let trace = c.x_axis.x + c.y_axis.y + c.z_axis.z;
    let inertia = DMat3::from_diagonal(DVec3::splat(trace)) - c;
    Ok(MassProperties { mass, center_of_mass: com + o, inertia })
}
