//! The cloth against kinematic colliders (Baraff & Witkin 1998, §5.3 and §6): a collider is a
//! [`Shape`] of [`crate::geometry`] moving at a constant velocity with Coulomb friction. Each
//! step, vertices that would reach a collider within the step become constrained (the filter
//! `S = I − n nᵀ` with the collider's normal velocity prescribed, released when the contact
//! pulls), vertices that still penetrate after the solve are projected out, and the colliders
//! are moved on by `velocity · h`.

use super::{Model, Solver, State, VertexConstraint};
use crate::error::{Error, Result};
use crate::geometry::{material, Shape};
use crate::math::outer;
use glam::{DMat3, DVec3};

impl Solver {
    /// Filter `S`, prescribed velocity change `z` and position correction `y` of every vertex
    /// for a step to `t + h` (Baraff & Witkin §5.3, §6), given the step's effective `h_eff` and
    /// the BDF2 history displacements in the scratch.
    pub(super) fn build_constraints(&mut self, model: &Model, state: &State, h: f64, h_eff: f64) {
        let s = &mut self.scratch;
        s.constrained.clear();
        s.contact_normal.clear();
        for i in 0..state.len() {
            let (x, v, cx) = (state.x[i], state.v[i], s.hx[i]);
            let (filter, zi, yi) = match state.constraints[i] {
                Some(VertexConstraint::Pinned(p)) => {
                    (DMat3::ZERO, (p - x - cx) / h_eff - v, DVec3::ZERO)
                }
                Some(VertexConstraint::Plane(n)) => {
                    (DMat3::IDENTITY - outer(n, n), -n * n.dot(v), DVec3::ZERO)
                }
                Some(VertexConstraint::Line(d)) => (outer(d, d), -(v - d * d.dot(v)), DVec3::ZERO),
                Some(VertexConstraint::Velocity(target)) => (DMat3::ZERO, target - v, DVec3::ZERO),
                None => match deepest_contact(model, state, i, h) {
                    Some((now, n, vc, mu)) => {
                        // End the step at `thickness` from the surface: a vertex still above
                        // it approaches at the speed that lands it there; one below moves
                        // with the surface and the position correction `y` lifts it out.
                        let gap = model.thickness - now - n.dot(cx) - h_eff * n.dot(vc);
                        let approach = if gap < 0.0 { gap / h_eff } else { 0.0 };
                        // The normal impulse of the last step, or on a new contact the one
                        // that stops the approach (forces are added once assembled).
                        let jn = match state.contact[i] {
                            ContactState::Touching(jn) => jn,
                            _ => model.mass[i] * (-n.dot(v - vc)).max(0.0),
                        };
                        s.contact_normal.push((i, n, vc, mu, jn));
                        let z = n * (n.dot(vc) + approach - n.dot(v));
                        (DMat3::IDENTITY - outer(n, n), z, n * gap.max(0.0))
                    }
                    None => (DMat3::IDENTITY, DVec3::ZERO, DVec3::ZERO),
                },
            };
            if filter != DMat3::IDENTITY {
                s.constrained.push(i);
            }
            s.filter[i] = filter;
            s.z[i] = zi;
            s.y[i] = yi;
        }
    }

    /// The fallback for vertices that were not in contact at the start of the step but end it
    /// inside a collider (dragged in by their neighbours): put them back at `thickness` and
    /// remove their approaching normal velocity.
    pub(super) fn project_penetrating(&mut self, model: &Model, state: &State, h: f64) {
        let s = &mut self.scratch;
        for col in &state.colliders {
            let shape = col.shape.translated(col.velocity * h);
            for i in 0..state.len() {
                if state.constraints[i].is_some() || s.filter[i] != DMat3::IDENTITY {
                    continue;
                }
                let (d, normal) = shape.distance(s.x_new[i]);
                if d < 0.0 {
                    s.x_new[i] += normal * (model.thickness - d);
                    let vn = (s.v_new[i] - col.velocity).dot(normal);
                    if vn < 0.0 {
                        s.v_new[i] -= normal * vn;
                    }
                }
            }
        }
    }
}

/// The contact of free vertex `i` for a step of `h`, the deepest of the colliders it would come
/// within `2 thickness` of: `(distance now, normal, collider velocity, friction)`.
fn deepest_contact(
    model: &Model,
    state: &State,
    i: usize,
    h: f64,
) -> Option<(f64, DVec3, DVec3, f64)> {
    let (x, v) = (state.x[i], state.v[i]);
    let mut best: Option<(f64, DVec3, DVec3, f64)> = None;
    for col in &state.colliders {
        let shape = col.shape.translated(col.velocity * h);
        let (predicted, _) = shape.distance(x + h * v);
        // Contacts live in a band of two thicknesses so that a vertex resting at `thickness`
        // stays in contact; released vertices leave freely unless they would penetrate.
        if predicted >= 2.0 * model.thickness
            || (state.contact[i] == ContactState::Released && predicted >= 0.0)
        {
            continue;
        }
        let (now, n) = shape.distance(x);
        if best.is_none_or(|b| now < b.0) {
            best = Some((now, n, col.velocity, col.friction));
        }
    }
    best
}

impl State {
    /// Move the colliders and the mesh colliders' vertices on by `velocity · h` and the time
    /// by `h`.
    pub(super) fn advance_colliders(&mut self, h: f64) {
        for c in &mut self.colliders {
            c.shape = c.shape.translated(c.velocity * h);
        }
        for m in &mut self.meshes {
            m.advance(h);
        }
        self.time += h;
    }
}

/// A kinematic collider: a shape moving at a constant velocity, with Coulomb friction.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Collider {
    /// The shape at the cloth's current time.
    pub shape: Shape,
    /// Velocity (m/s); the shape is translated by `velocity · dt` each step.
    pub velocity: DVec3,
    /// Coulomb friction coefficient >= 0.
    pub friction: f64,
}

impl Collider {
    /// The collider, checked ([`Shape::checked`]), with a plane's normal made unit.
    pub(super) fn checked(self) -> Result<Collider> {
        let shape = self.shape.checked()?;
        if !self.velocity.is_finite() {
            return Err(Error::invalid("velocity", "must be finite"));
        }
        Ok(Collider { shape, friction: material::friction(self.friction)?, ..self })
    }
}

/// What a vertex's contact did in the last step.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub(super) enum ContactState {
    /// Not in contact.
    Free,
    /// The contact impulse pulled: the vertex may leave unless it would penetrate.
    Released,
    /// In contact, with the normal impulse (N s) of the last step.
    Touching(f64),
}
