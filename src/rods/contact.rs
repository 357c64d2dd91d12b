//! Contacts of a rod's vertices with the shared collision shapes ([`crate::geometry::Shape`]),
//! as potentials in the implicit step's incremental potential, so Newton and its line search
//! treat them like the elastic energy:
//!
//! - **Normal penalty**: a vertex whose centreline point is closer than the rod's radius `r`
//!   (the larger semi-axis) to a shape, gap `g = d(x) − r < 0`, stores `½ k g²` (`k` the
//!   model's `contact_stiffness`, N/m): force `−k g n` along the shape's outward normal, so a
//!   resting rod penetrates by its weight over `k`. Hessian `k n nᵀ` (the surface's curvature
//!   term, negative inside a ball, is left out: a Gauss–Newton, positive semi-definite
//!   approximation; the line search uses the exact potential).
//! - **Coulomb friction, lagged** (Li et al. 2020, "Incremental Potential Contact", sec. 5):
//!   the normal force `λ = −k g₀ ≥ 0` and the normal `n₀` are those at the start of the step;
//!   the tangential displacement over the step `u = (I − n₀n₀ᵀ)(x − x₀)` stores
//!   `μ λ f₀(|u|)` with `f₀(y) = −y³/(3ε²) + y²/ε + ε/3` below `ε = ε_v h` and `y` above
//!   (IPC eq. 16): a force of magnitude `μ λ` opposing sliding faster than `ε_v`
//!   (`friction_velocity`, m/s), and a stiff spring below it (static friction, with a creep
//!   slower than `ε_v`). The static solve and symplectic Euler have no friction.
//! - **Rod–rod repulsion** (hair volume; [`super::Hair`]): an [`Obstacle`] is a segment of
//!   another strand near edge `a` of this one, found at the start of the step (closest points
//!   `p₀ = (1 − s) x_a + s x_{a+1}` and `q`, unit normal `n = (p₀ − q)/|p₀ − q|`). During the
//!   step the other strand is held where it was and the contact is linearised about the start
//!   (the plane through `q` of normal `n`, the parameter `s` kept): the gap
//!   `g = n·((1 − s) x_a + s x_{a+1} − q) − d` (`d` the distance the centrelines keep,
//!   [`super::Repulsion::thickness`]) stores `½ k g²` when `g < 0` (`k`
//!   [`super::Repulsion::stiffness`], N/m): a penalty, implicit in this strand and lagged in
//!   the other, as the strands are stepped in parallel. Both strands of a pair feel it.

use super::band::Band;
use super::Model;
use crate::error::{Error, Result};
use crate::geometry::Shape;
use glam::{DMat3, DVec3};

/// A static collision shape with its Coulomb friction coefficient.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Collider {
    /// The shape (world frame, m).
    pub shape: Shape,
    /// Coulomb's friction coefficient `μ` (≥ 0).
    pub friction: f64,
}

impl Collider {
    /// The collider, checked ([`Shape::checked`], friction finite and ≥ 0).
    ///
    /// # Errors
    /// A bad shape (named by [`Shape::checked`]); a bad friction (`friction`).
    pub fn checked(self) -> Result<Self> {
        let shape = self.shape.checked()?;
        let friction = crate::geometry::material::friction(self.friction)?;
        Ok(Collider { shape, friction })
    }
}

/// A contact at the start of a step, read by the friction potential.
#[derive(Clone, Copy, Debug)]
pub(super) struct Lagged {
    /// The vertex.
    vertex: usize,
    /// The shape's outward normal at the start of the step.
    normal: DVec3,
    /// `μ λ`: the friction coefficient times the normal force at the start of the step (N).
    limit: f64,
}

/// The contact radius of the rod (m): its larger semi-axis.
fn radius(model: &Model) -> f64 {
    model.material.radius[0].max(model.material.radius[1])
}

/// Add the normal penalties of the vertices `x` against the model's colliders to `grad`
/// (interleaved degrees of freedom) and, with `band`, `k n nᵀ` to the Hessian; returns the
/// penalty energy (J).
pub(super) fn penalty(
    model: &Model,
    x: &[DVec3],
    grad: &mut [f64],
    band: Option<&mut Band>,
) -> f64 {
    let (k, r) = (model.settings.contact_stiffness, radius(model));
    let mut energy = 0.0;
    let mut band = band;
    for c in &model.colliders {
        for (i, p) in x.iter().enumerate() {
            let (d, n) = c.shape.distance(*p);
            let g = d - r;
            if g >= 0.0 {
                continue;
            }
            energy += 0.5 * k * g * g;
            for a in 0..3 {
                grad[4 * i + a] += k * g * n[a];
            }
            if let Some(band) = band.as_deref_mut() {
                add_block(band, 4 * i, &(k * DMat3::from_cols(n * n.x, n * n.y, n * n.z)));
            }
        }
    }
    energy
}

/// The contacts of `x0` (the start of a step) into `out`.
pub(super) fn lag(model: &Model, x0: &[DVec3], out: &mut Vec<Lagged>) {
    out.clear();
    let (k, r) = (model.settings.contact_stiffness, radius(model));
    for c in model.colliders.iter().filter(|c| c.friction > 0.0) {
        for (i, p) in x0.iter().enumerate() {
            let (d, n) = c.shape.distance(*p);
            if d - r < 0.0 {
                out.push(Lagged { vertex: i, normal: n, limit: c.friction * k * (r - d) });
            }
        }
    }
}

/// Add the lagged friction potential of the vertices `x` (from `x0`, with `ε = ε_v h`, m)
/// to `grad` and, with `band`, its Hessian (positive semi-definite, IPC sec. 5.2); returns
/// its energy (J).
pub(super) fn friction(
    lagged: &[Lagged],
    x: &[DVec3],
    x0: &[DVec3],
    eps: f64,
    grad: &mut [f64],
    band: Option<&mut Band>,
) -> f64 {
    let mut energy = 0.0;
    let mut band = band;
    for c in lagged {
        let n = c.normal;
        let projector = DMat3::IDENTITY - DMat3::from_cols(n * n.x, n * n.y, n * n.z);
        let u = projector * (x[c.vertex] - x0[c.vertex]);
        let y = u.length();
        // f0, f1(y)/y (IPC eq. 16) and y d(f1/y)/dy, the Hessian's weight along u/|u|.
        let (f0, f1_over_y, along) = if y < eps {
            let e2 = eps * eps;
            (-y * y * y / (3.0 * e2) + y * y / eps + eps / 3.0, 2.0 / eps - y / e2, -y / e2)
        } else {
            (y, 1.0 / y, -1.0 / y)
        };
        energy += c.limit * f0;
        let g = c.limit * f1_over_y * u;
        for a in 0..3 {
            grad[4 * c.vertex + a] += g[a];
        }
        if let Some(band) = band.as_deref_mut() {
            let w = if y > 0.0 { u / y } else { DVec3::ZERO };
            let ww = DMat3::from_cols(w * w.x, w * w.y, w * w.z);
            add_block(band, 4 * c.vertex, &(c.limit * (f1_over_y * projector + along * ww)));
        }
    }
    energy
}

/// The rod–rod repulsion of a [`super::Hair`] (see the module docs).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Repulsion {
    /// Penalty stiffness `k` (N/m); 0 turns the repulsion off.
    pub stiffness: f64,
    /// The distance `d` the centrelines keep (m), typically twice the strand radius.
    pub thickness: f64,
}

impl Repulsion {
    /// The repulsion, checked: both finite and ≥ 0.
    ///
    /// # Errors
    /// A bad value (`repulsion_stiffness`, `thickness`).
    pub fn checked(self) -> Result<Self> {
        if !(self.stiffness.is_finite() && self.stiffness >= 0.0) {
            return Err(Error::invalid("repulsion_stiffness", "must be finite and >= 0"));
        }
        if !(self.thickness.is_finite() && self.thickness >= 0.0) {
            return Err(Error::invalid("thickness", "must be finite and >= 0"));
        }
        Ok(self)
    }
}

/// A segment of another strand near edge `edge` of this one, at the start of a step (see
/// the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Obstacle {
    /// The edge `a` of this strand.
    pub edge: usize,
    /// The parameter `s` ∈ [0, 1] of its closest point.
    pub s: f64,
    /// The closest point `q` of the other segment (m).
    pub point: DVec3,
    /// The unit normal from `q` towards this edge.
    pub normal: DVec3,
}

/// Add the repulsion penalties of `obstacles` on the vertices `x` to `grad` and, with `band`, their Hessian
/// (`k w wᵀ ⊗ n nᵀ`, `w = (1 − s, s)`); returns their energy (J).
pub(super) fn repel(
    obstacles: &[Obstacle],
    repulsion: Repulsion,
    x: &[DVec3],
    grad: &mut [f64],
    band: Option<&mut Band>,
) -> f64 {
    let (k, thickness) = (repulsion.stiffness, repulsion.thickness);
    let mut energy = 0.0;
    let mut band = band;
    for o in obstacles {
        let (a, n, w) = (o.edge, o.normal, [1.0 - o.s, o.s]);
        let g = n.dot(w[0] * x[a] + w[1] * x[a + 1] - o.point) - thickness;
        if g >= 0.0 {
            continue;
        }
        energy += 0.5 * k * g * g;
        for (v, wv) in w.iter().enumerate() {
            for r in 0..3 {
                grad[4 * (a + v) + r] += k * g * wv * n[r];
            }
        }
        if let Some(band) = band.as_deref_mut() {
            let nn = k * DMat3::from_cols(n * n.x, n * n.y, n * n.z);
            add_block(band, 4 * a, &(w[0] * w[0] * nn));
            add_block(band, 4 * (a + 1), &(w[1] * w[1] * nn));
            for r in 0..3 {
                for c in 0..3 {
                    band.add(4 * (a + 1) + r, 4 * a + c, w[0] * w[1] * nn.col(c)[r]);
                }
            }
        }
    }
    energy
}

/// Add the symmetric 3×3 block `h` at rows and columns `k..k + 3`.
fn add_block(band: &mut Band, k: usize, h: &DMat3) {
    for r in 0..3 {
        for c in 0..=r {
            band.add(k + r, k + c, h.col(c)[r]);
        }
    }
}

/// Check the contact settings: stiffness and friction velocity finite and > 0.
pub(super) fn validate_settings(stiffness: f64, velocity: f64) -> Result<()> {
    if !(stiffness.is_finite() && stiffness > 0.0) {
        return Err(Error::invalid("contact_stiffness", "must be finite and > 0"));
    }
    if !(velocity.is_finite() && velocity > 0.0) {
        return Err(Error::invalid("friction_velocity", "must be finite and > 0"));
    }
    Ok(())
}
