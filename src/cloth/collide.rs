//! The cloth against kinematic colliders (Baraff & Witkin 1998, §5.3 and §6): a collider is a
//! [`Shape`] of [`crate::geometry`] moving at a constant velocity with Coulomb friction. Each
//! step, vertices that would reach a collider within the step become constrained (the filter
//! `S = I − n nᵀ` with the collider's normal velocity prescribed, released when the contact
//! pulls), vertices that still penetrate after the solve are projected out, and the colliders
//! are moved on by `velocity · h`.

use super::*;

impl Cloth {
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

    /// The colliders, at the cloth's current time.
    pub fn colliders(&self) -> &[Collider] {
        &self.colliders
    }

    /// Filter, prescribed velocity change and position correction of every vertex for a step
    /// to `t + h`, given the step's effective `h_eff` and BDF2 history displacement `cx`.
    pub(super) fn build_constraints(&mut self, h: f64, h_eff: f64) {
        let Scratch { filter, z, y, constrained, contact_normal, hx, .. } = &mut self.scratch;
        constrained.clear();
        contact_normal.clear();
        for i in 0..self.x.len() {
            let (x, v) = (self.x[i], self.v[i]);
            let cx = hx[i];
            let (mut s, mut zi, mut yi) = (DMat3::IDENTITY, DVec3::ZERO, DVec3::ZERO);
            match self.constraints[i] {
                Some(VertexConstraint::Pinned(p)) => {
                    s = DMat3::ZERO;
                    zi = (p - x - cx) / h_eff - v;
                }
                Some(VertexConstraint::Plane(n)) => {
                    s = DMat3::IDENTITY - outer(n, n);
                    zi = -n * n.dot(v);
                }
                Some(VertexConstraint::Line(d)) => {
                    s = outer(d, d);
                    zi = -(v - d * d.dot(v));
                }
                Some(VertexConstraint::Velocity(target)) => {
                    s = DMat3::ZERO;
                    zi = target - v;
                }
                None => {
                    // The deepest contact wins.
                    let mut best: Option<(f64, DVec3, DVec3, f64)> = None;
                    for col in &self.colliders {
                        let shape = col.shape.translated(col.velocity * h);
                        let (predicted, _) = shape.distance(x + h * v);
                        // Contacts live in a band of two thicknesses so that a vertex resting
                        // at `thickness` stays in contact; released vertices leave freely
                        // unless they would penetrate.
                        if predicted >= 2.0 * self.thickness
                            || (self.contact[i] == ContactState::Released && predicted >= 0.0)
                        {
                            continue;
                        }
                        let (now, n) = shape.distance(x);
                        if best.is_none_or(|b| now < b.0) {
                            best = Some((now, n, col.velocity, col.friction));
                        }
                    }
                    if let Some((now, n, vc, mu)) = best {
                        // End the step at `thickness` from the surface: a vertex still above
                        // it approaches at the speed that lands it there; one below moves
                        // with the surface and the position correction `y` lifts it out.
                        let gap = self.thickness - now - n.dot(cx) - h_eff * n.dot(vc);
                        let approach = if gap < 0.0 { gap / h_eff } else { 0.0 };
                        yi = n * gap.max(0.0);
                        s = DMat3::IDENTITY - outer(n, n);
                        zi = n * (n.dot(vc) + approach - n.dot(v));
                        // The normal impulse of the last step, or on a new contact the one
                        // that stops the approach (forces are added once assembled).
                        let jn = match self.contact[i] {
                            ContactState::Touching(jn) => jn,
                            _ => self.mass[i] * (-n.dot(v - vc)).max(0.0),
                        };
                        contact_normal.push((i, n, vc, mu, jn));
                    }
                }
            }
            if s != DMat3::IDENTITY {
                constrained.push(i);
            }
            filter[i] = s;
            z[i] = zi;
            y[i] = yi;
        }
    }

    /// The fallback for vertices that were not in contact at the start of the step but end it
    /// inside a collider (dragged in by their neighbours): put them back at `thickness` and
    /// remove their approaching normal velocity.
    pub(super) fn project_penetrating(&self, scratch: &mut Scratch, h: f64) {
        for col in &self.colliders {
            let shape = col.shape.translated(col.velocity * h);
            for i in 0..self.x.len() {
                if self.constraints[i].is_some() || scratch.filter[i] != DMat3::IDENTITY {
                    continue;
                }
                let (d, normal) = shape.distance(scratch.x_new[i]);
                if d < 0.0 {
                    scratch.x_new[i] += normal * (self.thickness - d);
                    let vn = (scratch.v_new[i] - col.velocity).dot(normal);
                    if vn < 0.0 {
                        scratch.v_new[i] -= normal * vn;
                    }
                }
            }
        }
    }

    pub(super) fn advance_colliders(&mut self, h: f64) {
        for c in &mut self.colliders {
            c.shape = c.shape.translated(c.velocity * h);
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
