//! The cloth's state: what changes in time and what a later step reads — positions,
//! velocities, time, the BDF2 history (Choi & Ko 2002), the PCG warm start, the contact
//! states of the last step (Baraff & Witkin 1998, §5.3, §6) — and the inputs of the next
//! steps: vertex constraints (pins and their targets, §5.3) and the kinematic colliders with
//! their current poses. Several states of one [`Model`] can be stepped by one
//! [`super::Solver`]; a state snapshot records the model's fingerprint.

use super::{Collider, ContactState, MeshCollider, Model, VertexConstraint};
use crate::error::{Error, Result};
use crate::snapshot::{check, finite, Stamped};
use glam::DVec3;

/// The state of a cloth of `N` vertices (see the module documentation). Copy it with
/// `clone_from` to reuse its buffers (no allocation once they are large enough).
#[derive(serde::Serialize, serde::Deserialize, Debug, PartialEq)]
pub struct State {
    /// Positions (m), `(N, 3)`; only ever overwritten in place (Python views them).
    pub(super) x: Vec<DVec3>,
    /// Velocities (m/s), `(N, 3)`; only ever overwritten in place.
    pub(super) v: Vec<DVec3>,
    /// Simulated time (s).
    pub(super) time: f64,
    /// Positions and velocities before the last step, and its length (s): the BDF2 history,
    /// valid when `previous_dt` is set.
    pub(super) previous_x: Vec<DVec3>,
    pub(super) previous_v: Vec<DVec3>,
    pub(super) previous_dt: Option<f64>,
    /// The last implicit step's `Δv` (m/s), the PCG's warm start.
    pub(super) dv: Vec<DVec3>,
    /// What each vertex's contact did in the last step.
    pub(super) contact: Vec<ContactState>,
    /// The user constraint of each vertex.
    pub(super) constraints: Vec<Option<VertexConstraint>>,
    /// The colliders, at the current time.
    pub(super) colliders: Vec<Collider>,
    /// The triangle-mesh colliders, at the current time (absent from snapshots written before
    /// they existed).
    #[serde(default)]
    pub(super) meshes: Vec<MeshCollider>,
}

impl Clone for State {
    fn clone(&self) -> State {
        let mut out = State::empty();
        out.clone_from(self);
        out
    }

    /// Field by field, reusing this state's buffers (the derived `clone_from` would
    /// allocate a whole new state).
    fn clone_from(&mut self, other: &State) {
        // Destructured so that a new field cannot be forgotten here.
        let State {
            x,
            v,
            time,
            previous_x,
            previous_v,
            previous_dt,
            dv,
            contact,
            constraints,
            colliders,
            meshes,
        } = other;
        self.x.clone_from(x);
        self.v.clone_from(v);
        self.time = *time;
        self.previous_x.clone_from(previous_x);
        self.previous_v.clone_from(previous_v);
        self.previous_dt = *previous_dt;
        self.dv.clone_from(dv);
        self.contact.clone_from(contact);
        self.constraints.clone_from(constraints);
        self.colliders.clone_from(colliders);
        self.meshes.truncate(meshes.len());
        let kept = self.meshes.len();
        for (mine, theirs) in self.meshes.iter_mut().zip(meshes) {
            mine.clone_from(theirs);
        }
        self.meshes.extend(meshes[kept..].iter().cloned());
    }
}

impl Stamped for State {
    const TAG: &'static str = "ClothState";
    type Model = Model;

    /// Check the state against `model`: one entry per vertex, finite values, unit
    /// constraint directions, valid colliders.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] naming the first inconsistent field.
    fn validate(&self, model: &Model) -> Result<()> {
        let n = model.len();
        let vec3 = |v: &[DVec3]| finite(v.iter().flat_map(|p| p.to_array()));
        let per_vertex = [&self.x, &self.v, &self.previous_x, &self.previous_v, &self.dv];
        check(
            per_vertex.iter().all(|v| v.len() == n)
                && self.contact.len() == n
                && self.constraints.len() == n,
            "state",
            || format!("not of {n} vertices"),
        )?;
        check(vec3(&self.x) && vec3(&self.v), "x", || "non-finite positions or velocities".into())?;
        check(
            vec3(&self.previous_x) && vec3(&self.previous_v) && vec3(&self.dv),
            "history",
            || "non-finite values".into(),
        )?;
        check(self.previous_dt.is_none_or(|h| h.is_finite() && h > 0.0), "history", || {
            "previous step not finite and > 0".into()
        })?;
        check(self.time.is_finite(), "time", || "non-finite".into())?;
        let constraint_ok = |c: &VertexConstraint| match *c {
            VertexConstraint::Pinned(p) | VertexConstraint::Velocity(p) => p.is_finite(),
            VertexConstraint::Plane(d) | VertexConstraint::Line(d) => {
                d.is_finite() && (d.length() - 1.0).abs() < 1e-6
            }
        };
        check(self.constraints.iter().flatten().all(constraint_ok), "constraints", || {
            "non-finite or non-unit constraint vectors".into()
        })?;
        check(
            self.contact.iter().all(|c| match c {
                ContactState::Touching(j) => j.is_finite(),
                _ => true,
            }),
            "contact",
            || "non-finite contact impulses".into(),
        )?;
        for c in &self.colliders {
            c.checked()?;
        }
        for m in &self.meshes {
            m.validate()?;
        }
        Ok(())
    }
}

impl State {
    /// The initial state of `model`: its mesh's positions, at rest, at time 0, no history,
    /// every vertex free, no colliders.
    pub fn new(model: &Model) -> State {
        let n = model.len();
        let zero = vec![DVec3::ZERO; n];
        State {
            x: model.initial.clone(),
            v: zero.clone(),
            time: 0.0,
            previous_x: zero.clone(),
            previous_v: zero.clone(),
            previous_dt: None,
            dv: zero,
            contact: vec![ContactState::Free; n],
            constraints: vec![None; n],
            colliders: Vec::new(),
            meshes: Vec::new(),
        }
    }

    /// A state of no vertices, to be filled by `clone_from`.
    fn empty() -> State {
        State {
            x: Vec::new(),
            v: Vec::new(),
            time: 0.0,
            previous_x: Vec::new(),
            previous_v: Vec::new(),
            previous_dt: None,
            dv: Vec::new(),
            contact: Vec::new(),
            constraints: Vec::new(),
            colliders: Vec::new(),
            meshes: Vec::new(),
        }
    }

    /// Number of vertices `N`.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Whether the state has no vertices.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Vertex positions (m), `(N, 3)`.
    pub fn positions(&self) -> &[DVec3] {
        &self.x
    }

    /// Vertex velocities (m/s), `(N, 3)`.
    pub fn velocities(&self) -> &[DVec3] {
        &self.v
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// The constraint of each vertex, `(N,)`.
    pub fn constraints(&self) -> &[Option<VertexConstraint>] {
        &self.constraints
    }

    /// The colliders, at the current time.
    pub fn colliders(&self) -> &[Collider] {
        &self.colliders
    }

    /// Overwrite positions (m) and velocities (m/s), each `(N, 3)`, in place; clears the BDF2
    /// history.
    ///
    /// # Errors
    /// Wrong lengths or non-finite values; the state is then unchanged.
    pub fn set_motion(&mut self, positions: &[DVec3], velocities: &[DVec3]) -> Result<()> {
        for (name, values) in [("positions", positions), ("velocities", velocities)] {
            if values.len() != self.x.len() {
                return Err(Error::Shape {
                    arg: name.into(),
                    expected: format!("({}, 3)", self.x.len()),
                    got: vec![values.len(), 3],
                });
            }
            if let Some(i) = values.iter().position(|p| !p.is_finite()) {
                return Err(Error::invalid(name, "must be finite").at(i));
            }
        }
        self.x.copy_from_slice(positions);
        self.v.copy_from_slice(velocities);
        self.previous_dt = None;
        Ok(())
    }

    /// Set or clear (`None`) the constraint of vertices `indices` (Baraff & Witkin §5.3);
    /// plane normals and line directions are made unit.
    ///
    /// # Errors
    /// An index out of range, or a zero / non-finite direction or position.
    pub fn constrain(
        &mut self,
        indices: &[usize],
        constraint: Option<VertexConstraint>,
    ) -> Result<()> {
        if let Some(&i) = indices.iter().find(|&&i| i >= self.x.len()) {
            return Err(Error::invalid(
                "indices",
                format!("vertex {i} is out of range for {} vertices", self.x.len()),
            ));
        }
        let constraint = match constraint {
            Some(VertexConstraint::Pinned(p)) if !p.is_finite() => {
                return Err(Error::invalid("positions", "must be finite"))
            }
            Some(VertexConstraint::Velocity(v)) if !v.is_finite() => {
                return Err(Error::invalid("velocities", "must be finite"))
            }
            Some(VertexConstraint::Plane(n)) | Some(VertexConstraint::Line(n))
                if !(n.is_finite() && n.length() > 0.0) =>
            {
                return Err(Error::invalid("direction", "must be finite and non-zero"))
            }
            Some(VertexConstraint::Plane(n)) => Some(VertexConstraint::Plane(n.normalize())),
            Some(VertexConstraint::Line(d)) => Some(VertexConstraint::Line(d.normalize())),
            other => other,
        };
        for &i in indices {
            self.constraints[i] = constraint;
        }
        Ok(())
    }

    /// Pin vertices `indices` at `positions` (m, `(K, 3)`; their current positions when
    /// `None`).
    ///
    /// # Errors
    /// Out-of-range indices, a length mismatch, or non-finite positions.
    pub fn pin(&mut self, indices: &[usize], positions: Option<&[DVec3]>) -> Result<()> {
        if let Some(p) = positions {
            if p.len() != indices.len() {
                return Err(Error::Shape {
                    arg: "positions".into(),
                    expected: format!("({}, 3)", indices.len()),
                    got: vec![p.len(), 3],
                });
            }
        }
        self.constrain(indices, None)?;
        for (k, &i) in indices.iter().enumerate() {
            let target = positions.map_or(self.x[i], |p| p[k]);
            self.constrain(&[i], Some(VertexConstraint::Pinned(target)))?;
        }
        Ok(())
    }

    /// Add a collider; returns its index.
    ///
    /// # Errors
    /// Invalid shape, velocity or friction.
    pub fn add_collider(&mut self, collider: Collider) -> Result<usize> {
        self.colliders.push(collider.checked()?);
        Ok(self.colliders.len() - 1)
    }

    /// Replace collider `index` (to move it along a path of the user's choosing).
    ///
    /// # Errors
    /// A bad index or an invalid collider.
    pub fn set_collider(&mut self, index: usize, collider: Collider) -> Result<()> {
        let count = self.colliders.len();
        let slot = self.colliders.get_mut(index).ok_or_else(|| {
            Error::invalid("index", format!("no collider {index} (have {count})"))
        })?;
        *slot = collider.checked()?;
        Ok(())
    }

    /// Add a triangle-mesh collider; returns its index (for
    /// [`State::set_mesh_collider`]).
    pub fn add_mesh_collider(&mut self, mesh: MeshCollider) -> usize {
        self.meshes.push(mesh);
        self.meshes.len() - 1
    }

    /// Set the vertices (m) of mesh collider `index` at the current time and their velocities
    /// (m/s) over the next steps ([`MeshCollider::set_motion`]).
    ///
    /// # Errors
    /// A bad index, wrong lengths or non-finite values; the collider is then unchanged.
    pub fn set_mesh_collider(
        &mut self,
        index: usize,
        vertices: &[DVec3],
        velocities: &[DVec3],
    ) -> Result<()> {
        let count = self.meshes.len();
        let mesh = self.meshes.get_mut(index).ok_or_else(|| {
            Error::invalid("index", format!("no mesh collider {index} (have {count})"))
        })?;
        mesh.set_motion(vertices, velocities)
    }

    /// The triangle-mesh colliders, at the current time.
    pub fn mesh_colliders(&self) -> &[MeshCollider] {
        &self.meshes
    }

    /// Whether the state has the sizes of a state of `model` (the cheap check of every step).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"state"`) otherwise.
    pub(super) fn fits(&self, model: &Model) -> Result<()> {
        let n = model.len();
        let sizes = [
            self.x.len(),
            self.v.len(),
            self.previous_x.len(),
            self.previous_v.len(),
            self.dv.len(),
            self.contact.len(),
            self.constraints.len(),
        ];
        check(sizes.iter().all(|&s| s == n), "state", || {
            format!("is not a state of this model ({n} vertices)")
        })
    }
}
