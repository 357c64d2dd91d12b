//! A kinematic triangle mesh the cloth collides with (a character's body): its vertices at the
//! cloth's current time, a velocity per vertex, its triangles and a Coulomb friction
//! coefficient. Over a step of `h` every vertex moves linearly by `velocity · h`, so a user
//! who animates the mesh sets, before each step, the vertices of the current pose and the
//! velocities `(next pose − pose) / dt` ([`super::State::set_mesh_collider`]). The cloth meets
//! it in the collision filter of Bridson, Fedkiw & Anderson (2002) that self-collision uses
//! ([`super::self_collide`]): the mesh's vertices take part there as vertices of infinite mass.

use crate::error::{Error, Result};
use crate::geometry::material;
use glam::DVec3;

/// A kinematic triangle mesh (see the module documentation).
#[derive(serde::Serialize, serde::Deserialize, Debug, PartialEq)]
pub struct MeshCollider {
    /// Vertex positions (m) at the cloth's current time, `(V, 3)`.
    pub(super) vertices: Vec<DVec3>,
    /// Vertex velocities (m/s), `(V, 3)`, constant over a step.
    pub(super) velocities: Vec<DVec3>,
    /// Triangles, `(T, 3)` vertex indices.
    pub(super) triangles: Vec<[usize; 3]>,
    /// Coulomb friction coefficient (>= 0) between the cloth and the mesh.
    pub(super) friction: f64,
}

impl Clone for MeshCollider {
    fn clone(&self) -> MeshCollider {
        MeshCollider {
            vertices: self.vertices.clone(),
            velocities: self.velocities.clone(),
            triangles: self.triangles.clone(),
            friction: self.friction,
        }
    }

    /// Field by field, reusing this collider's buffers (a failed step's undo copies the
    /// state every step, and must not allocate).
    fn clone_from(&mut self, other: &MeshCollider) {
        self.vertices.clone_from(&other.vertices);
        self.velocities.clone_from(&other.velocities);
        self.triangles.clone_from(&other.triangles);
        self.friction = other.friction;
    }
}

impl MeshCollider {
    /// A mesh collider of `vertices` (m, `(V, 3)`), `triangles` (`(T, 3)` indices into the
    /// vertices, at least one), `velocities` (m/s, `(V, 3)`; at rest when `None`) and Coulomb
    /// `friction` (>= 0).
    ///
    /// # Errors
    /// Each mistake named by its argument: no triangles, an index out of range or a triangle
    /// repeating a vertex (`triangles`), non-finite `vertices` or `velocities`, `velocities`
    /// of another length than `vertices`, a negative or non-finite `friction`.
    pub fn new(
        vertices: Vec<DVec3>,
        triangles: Vec<[usize; 3]>,
        velocities: Option<Vec<DVec3>>,
        friction: f64,
    ) -> Result<MeshCollider> {
        if triangles.is_empty() {
            return Err(Error::invalid("triangles", "a mesh collider needs at least one triangle"));
        }
        let count = vertices.len();
        for (k, t) in triangles.iter().enumerate() {
            if let Some(i) = t.iter().find(|&&i| i >= count) {
                return Err(Error::invalid(
                    "triangles",
                    format!("vertex {i} is out of range for {count} vertices"),
                )
                .at(k));
            }
            if t[0] == t[1] || t[1] == t[2] || t[2] == t[0] {
                return Err(Error::invalid("triangles", "a triangle repeats a vertex").at(k));
            }
        }
        let velocities = velocities.unwrap_or_else(|| vec![DVec3::ZERO; count]);
        let mut mesh = MeshCollider {
            vertices: Vec::new(),
            velocities: Vec::new(),
            triangles,
            friction: material::friction(friction)?,
        };
        mesh.set_motion(&vertices, &velocities)?;
        Ok(mesh)
    }

    /// Set the vertices (m) at the cloth's current time and their velocities (m/s) over the
    /// next steps, `(V, 3)` each (as many as the mesh has).
    ///
    /// # Errors
    /// Wrong lengths or non-finite values (named `vertices` or `velocities`); the collider is
    /// then unchanged.
    pub fn set_motion(&mut self, vertices: &[DVec3], velocities: &[DVec3]) -> Result<()> {
        let count = if self.vertices.is_empty() { vertices.len() } else { self.vertices.len() };
        for (name, values) in [("vertices", vertices), ("velocities", velocities)] {
            if values.len() != count {
                return Err(Error::Shape {
                    arg: name.into(),
                    expected: format!("({count}, 3)"),
                    got: vec![values.len(), 3],
                });
            }
            if let Some(i) = values.iter().position(|p| !p.is_finite()) {
                return Err(Error::invalid(name, "must be finite").at(i));
            }
        }
        self.vertices.clear();
        self.vertices.extend_from_slice(vertices);
        self.velocities.clear();
        self.velocities.extend_from_slice(velocities);
        Ok(())
    }

    /// The checks of [`MeshCollider::new`] on a decoded collider.
    ///
    /// # Errors
    /// As [`MeshCollider::new`].
    pub(super) fn validate(&self) -> Result<()> {
        MeshCollider::new(
            self.vertices.clone(),
            self.triangles.clone(),
            Some(self.velocities.clone()),
            self.friction,
        )
        .map(|_| ())
    }

    /// Vertex positions (m) at the cloth's current time, `(V, 3)`.
    pub fn vertices(&self) -> &[DVec3] {
        &self.vertices
    }

    /// Vertex velocities (m/s), `(V, 3)`.
    pub fn velocities(&self) -> &[DVec3] {
        &self.velocities
    }

    /// Triangles, `(T, 3)` vertex indices.
    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    /// Coulomb friction coefficient.
    pub fn friction(&self) -> f64 {
        self.friction
    }

    /// Move the vertices on by `velocity · h` (s).
    pub(super) fn advance(&mut self, h: f64) {
        for (x, v) in self.vertices.iter_mut().zip(&self.velocities) {
            *x += *v * h;
        }
    }
}
