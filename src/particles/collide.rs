//! Particles against colliders: a collider is a [`Shape`] of [`crate::geometry`] with a
//! [`Material`] and a velocity. After the integrator's step a penetrating particle is projected
//! onto the surface, its tangential displacement relative to the collider limited by
//! `μ × penetration` (position-based friction, Macklin et al. 2014), and its velocity relative
//! to the collider gets a normal impulse with restitution and a Coulomb friction impulse
//! (static when the tangential speed can be cancelled). Contacts slower than twice the speed
//! gravity adds in one step are resting (no bounce), so resting particles stay exactly on the
//! surface without jitter.

use super::solver::Step;
use super::CHUNK;
use crate::error::{Error, Result};
use crate::geometry::{Material, Shape};
use glam::DVec3;
use rayon::prelude::*;

/// A surface particles collide with.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct Collider {
    /// The solid (m).
    pub shape: Shape,
    /// Restitution and Coulomb friction of the surface.
    pub material: Material,
    /// Velocity of the collider (m/s): restitution and friction act on the particle's
    /// velocity relative to it (a moving collider pushes and drags particles along). The
    /// shape itself is moved by the caller ([`ParticleSystem::set_collider`]).
    pub velocity: DVec3,
    /// Keep particles inside the solid instead of outside.
    pub inside: bool,
}

impl Collider {
    /// The collider, checked ([`Shape::checked`], [`Material::checked`]), with a plane's
    /// normal made unit.
    ///
    /// # Errors
    /// The shape's, the velocity's (`velocity`, non-finite) and the material's.
    pub fn checked(self) -> Result<Collider> {
        let shape = self.shape.checked()?;
        if !self.velocity.is_finite() {
            return Err(Error::invalid("velocity", "must be finite"));
        }
        Ok(Collider { shape, material: self.material.checked()?, ..self })
    }
}

impl Step<'_> {
    /// Resolve the contacts of every live, movable particle with the colliders, in parallel
    /// chunks (each particle independently, so the result does not depend on the threads).
    pub(super) fn collide(&mut self, dt: f64, gravity: DVec3) {
        if self.model.colliders.is_empty() {
            return;
        }
        let n = self.model.n;
        let (colliders, alive, inv_mass, backup) =
            (&self.model.colliders, &self.state.alive, &self.state.inv_mass, &self.solver.backup);
        let (xs, vs) = self.state.y.split_at_mut(3 * n);
        self.solver.stats.contacts += xs
            .par_chunks_mut(3 * CHUNK)
            .zip(vs.par_chunks_mut(3 * CHUNK))
            .enumerate()
            .map(|(c, (xc, vc))| {
                let mut contacts = 0;
                for k in 0..xc.len() / 3 {
                    let i = c * CHUNK + k;
                    if !alive[i] || inv_mass[i] == 0.0 {
                        continue;
                    }
                    let prev = DVec3::from_slice(&backup[3 * i..3 * i + 3]);
                    let (x, v) = (DVec3::from_slice(&xc[3 * k..]), DVec3::from_slice(&vc[3 * k..]));
                    let (x, v, hits) = collide_one(colliders, x, v, prev, dt, gravity);
                    if hits > 0 {
                        xc[3 * k..3 * k + 3].copy_from_slice(&x.to_array());
                        vc[3 * k..3 * k + 3].copy_from_slice(&v.to_array());
                        contacts += hits;
                    }
                }
                contacts
            })
            .sum::<usize>();
    }
}

/// Resolve the contacts of one particle at `x` with velocity `v` that was at `prev` before the
/// step; returns the new position, velocity and the number of contacts.
pub(super) fn collide_one(
    colliders: &[Collider],
    mut x: DVec3,
    mut v: DVec3,
    prev: DVec3,
    dt: f64,
    gravity: DVec3,
) -> (DVec3, DVec3, usize) {
    let mut contacts = 0;
    for collider in colliders {
        let contact = surface(collider, x);
        if contact.distance >= 0.0 {
            continue;
        }
        contacts += 1;
        (x, v) = respond(&contact, x, v, prev, dt, gravity);
    }
    (x, v, contacts)
}

/// Where a point stands against a collider: the distance to the surface (negative inside the
/// solid), the outward normal, the material and the collider's velocity.
pub(super) struct Contact {
    pub(super) distance: f64,
    pub(super) normal: DVec3,
    pub(super) restitution: f64,
    pub(super) friction: f64,
    pub(super) velocity: DVec3,
}

/// The contact of the point `x` with `collider`.
pub(super) fn surface(collider: &Collider, x: DVec3) -> Contact {
    let (distance, normal) = collider.shape.distance(x);
    let (distance, normal) =
        if collider.inside { (-distance, -normal) } else { (distance, normal) };
    let Material { restitution, friction } = collider.material;
    Contact { distance, normal, restitution, friction, velocity: collider.velocity }
}

/// The response to a penetrating `contact` (distance < 0) of a particle at `x` with velocity
/// `v` that was at `prev` before the step: the new position and velocity.
pub(super) fn respond(
    contact: &Contact,
    mut x: DVec3,
    v: DVec3,
    prev: DVec3,
    dt: f64,
    gravity: DVec3,
) -> (DVec3, DVec3) {
    let Contact { distance: d, normal, restitution: e, friction: mu, velocity: vc } = *contact;
    // Project onto the surface, and apply Coulomb friction to the tangential displacement of
    // this step relative to the collider too (at most μ times the penetration), so that a
    // particle held by static friction does not creep.
    x -= d * normal;
    let moved = x - prev - vc * dt;
    let moved_t = moved - moved.dot(normal) * normal;
    let slip = moved_t.length();
    if slip > 0.0 {
        x -= moved_t * (mu * -d / slip).min(1.0);
    }
    let u = v - vc; // velocity relative to the collider
    let vn = u.dot(normal);
    if vn >= 0.0 {
        return (x, v);
    }
    let resting = -vn <= 2.0 * gravity.dot(normal).abs() * dt;
    let jn = -vn * (1.0 + if resting { 0.0 } else { e });
    let vt = u - vn * normal;
    let speed_t = vt.length();
    let vt = if speed_t <= mu * jn { DVec3::ZERO } else { vt * (1.0 - mu * jn / speed_t) };
    (x, vc + (vn + jn) * normal + vt)
}
