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
//! - **Friction between strands** (Coulomb, lagged as against the shapes): with the normal
//!   force at the start of the step `λ = k max(0, −g₀)` and the other strand's velocity `v_q`
//!   at `q` then, the relative tangential motion of the closest points over the step
//!   `u = (I − n nᵀ)((1 − s)(x_a − x_a⁰) + s (x_{a+1} − x_{a+1}⁰) − h v_q)` stores
//!   `μ λ f₀(|u|)` (`μ` [`super::Repulsion::friction`]): a force `μ λ` opposing relative
//!   sliding faster than `ε_v`, a stiff spring below it.

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
        let (e, g, h) = sliding(c.limit, c.normal, x[c.vertex] - x0[c.vertex], eps);
        energy += e;
        for a in 0..3 {
            grad[4 * c.vertex + a] += g[a];
        }
        if let Some(band) = band.as_deref_mut() {
            add_block(band, 4 * c.vertex, &h);
        }
    }
    energy
}

/// IPC's lagged friction potential `μλ f₀(|u|)` of the motion `m` over the step projected
/// on the plane of `normal`, `u = (I − n nᵀ) m`, with the limit `μλ` (N) and `ε` (m): its
/// energy (J), its gradient with respect to `m` and its Hessian (positive semi-definite,
/// IPC sec. 5.2).
fn sliding(limit: f64, normal: DVec3, motion: DVec3, eps: f64) -> (f64, DVec3, DMat3) {
    let n = normal;
    let projector = DMat3::IDENTITY - DMat3::from_cols(n * n.x, n * n.y, n * n.z);
    let u = projector * motion;
    let y = u.length();
    // f0, f1(y)/y (IPC eq. 16) and y d(f1/y)/dy, the Hessian's weight along u/|u|.
    let (f0, f1_over_y, along) = if y < eps {
        let e2 = eps * eps;
        (-y * y * y / (3.0 * e2) + y * y / eps + eps / 3.0, 2.0 / eps - y / e2, -y / e2)
    } else {
        (y, 1.0 / y, -1.0 / y)
    };
    let w = if y > 0.0 { u / y } else { DVec3::ZERO };
    let ww = DMat3::from_cols(w * w.x, w * w.y, w * w.z);
    (limit * f0, limit * f1_over_y * u, limit * (f1_over_y * projector + along * ww))
}

/// The rod–rod repulsion of a [`super::Hair`] (see the module docs).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Repulsion {
    /// Penalty stiffness `k` (N/m); 0 turns the repulsion off.
    pub stiffness: f64,
    /// The distance `d` the centrelines keep (m), typically twice the strand radius.
    pub thickness: f64,
    /// Coulomb's friction coefficient `μ` between strands (≥ 0; 0, the default, for none).
    pub friction: f64,
}

impl Repulsion {
    /// The repulsion, checked: all finite and ≥ 0.
    ///
    /// # Errors
    /// A bad value (`repulsion_stiffness`, `thickness`, `strand_friction`).
    pub fn checked(self) -> Result<Self> {
        if !(self.stiffness.is_finite() && self.stiffness >= 0.0) {
            return Err(Error::invalid("repulsion_stiffness", "must be finite and >= 0"));
        }
        if !(self.thickness.is_finite() && self.thickness >= 0.0) {
            return Err(Error::invalid("thickness", "must be finite and >= 0"));
        }
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            return Err(Error::invalid("strand_friction", "must be finite and >= 0"));
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
    /// The velocity of the other strand at `q` (m/s), interpolated between its vertices.
    pub velocity: DVec3,
    /// The gap `|p₀ − q| − d` at the start of the step (m): the lagged normal force is
    /// `k max(0, −gap)`.
    pub gap: f64,
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
            add_edge_point(band, a, w, &(k * DMat3::from_cols(n * n.x, n * n.y, n * n.z)));
        }
    }
    energy
}

/// Add the lagged friction between strands (see the module docs) of `obstacles` on the
/// vertices `x` (from `x0`, over a step of `h` s, with `ε = ε_v h`, m) to `grad` and, with
/// `band`, its Hessian (`w wᵀ ⊗` the Hessian of [`sliding`], `w = (1 − s, s)`); returns its
/// energy (J). Nothing when `μ` is 0.
#[allow(clippy::too_many_arguments)]
pub(super) fn rub(
    obstacles: &[Obstacle],
    repulsion: Repulsion,
    x: &[DVec3],
    x0: &[DVec3],
    h: f64,
    eps: f64,
    grad: &mut [f64],
    band: Option<&mut Band>,
) -> f64 {
    if repulsion.friction == 0.0 {
        return 0.0;
    }
    let mut energy = 0.0;
    let mut band = band;
    for o in obstacles.iter().filter(|o| o.gap < 0.0) {
        let (a, w) = (o.edge, [1.0 - o.s, o.s]);
        let limit = repulsion.friction * repulsion.stiffness * -o.gap;
        let motion = w[0] * (x[a] - x0[a]) + w[1] * (x[a + 1] - x0[a + 1]) - h * o.velocity;
        let (e, g, hess) = sliding(limit, o.normal, motion, eps);
        energy += e;
        for (v, wv) in w.iter().enumerate() {
            for r in 0..3 {
                grad[4 * (a + v) + r] += wv * g[r];
            }
        }
        if let Some(band) = band.as_deref_mut() {
            add_edge_point(band, a, w, &hess);
        }
    }
    energy
}

/// Add the Hessian `w wᵀ ⊗ h` of a term on the point `w[0] x[a] + w[1] x[a + 1]` of edge `a`
/// whose Hessian in that point is `h`.
fn add_edge_point(band: &mut Band, a: usize, w: [f64; 2], h: &DMat3) {
    add_block(band, 4 * a, &(w[0] * w[0] * *h));
    add_block(band, 4 * (a + 1), &(w[1] * w[1] * *h));
    for r in 0..3 {
        for c in 0..3 {
            band.add(4 * (a + 1) + r, 4 * a + c, w[0] * w[1] * h.col(c)[r]);
        }
    }
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

#[cfg(test)]
mod tests {
    use super::super::{Material, Model, Settings, Solver, State};
    use super::{Obstacle, Repulsion};
    use glam::DVec3;

    const G: f64 = 9.81;
    const H: f64 = 1.0 / 60.0;
    const THICKNESS: f64 = 2e-3;

    /// A 10 cm strand of 2 edges along `z` (`E = 1 GPa`, `r = 1 mm`, `ρ = 1000 kg/m³`) lying
    /// across a fixed strand along `x` (the obstacle, its centreline the `x` axis, moving at
    /// `(speed, 0, 0)`), crossing it at its middle vertex and pressed onto it by gravity;
    /// settled for 30 steps of 1/60 s, then dragged along `x` by `drag` (N, spread over the
    /// vertices by mass) for `steps` steps. Returns the momentum-averaged velocity along `x`
    /// after each step, the largest speed of the crossing vertex along `x`, and the strand's
    /// mass and weight.
    fn drag(mu: f64, drag: f64, speed: f64, steps: usize) -> (Vec<f64>, f64, f64, f64) {
        let material = Material {
            youngs_modulus: 1e7,
            shear_modulus: 3e6,
            density: 1000.0,
            radius: [1e-3; 2],
        };
        let settings = Settings { gravity: DVec3::new(0.0, -G, 0.0), ..Settings::default() };
        let points = [-0.05, 0.0, 0.05].map(|z| DVec3::new(0.0, THICKNESS, z));
        let model = Model::new(&points, material, settings).unwrap();
        let mass: f64 = model.masses().iter().sum();
        let repulsion = Repulsion { stiffness: 1e4, thickness: THICKNESS, friction: mu };
        let (mut state, mut solver) = (State::new(&model), Solver::new(&model));
        let (mut velocities, mut creep) = (Vec::new(), 0.0_f64);
        for k in 0..30 + steps {
            let (f, v) = if k < 30 { (0.0, 0.0) } else { (drag, speed) };
            for i in 0..3 {
                state.set_force(i, DVec3::new(f * model.masses()[i] / mass, 0.0, 0.0)).unwrap();
            }
            let p = state.positions()[1];
            let obstacle = Obstacle {
                edge: 0,
                s: 1.0,
                point: DVec3::new(p.x, 0.0, 0.0),
                normal: DVec3::Y,
                velocity: DVec3::new(v, 0.0, 0.0),
                gap: p.y - THICKNESS,
            };
            solver.step_among(&model, &mut state, H, &[obstacle], repulsion).unwrap();
            let momentum: f64 =
                state.velocities().iter().zip(model.masses()).map(|(v, m)| m * v.x).sum();
            if k >= 30 {
                velocities.push(momentum / mass);
                creep = creep.max(state.velocities()[1].x.abs());
            }
        }
        (velocities, creep, mass, mass * G)
    }

    /// Coulomb's law between strands: dragged by less than `μ N` the strand sticks (its
    /// crossing vertex creeps slower than the friction velocity, and the friction force
    /// equals the drag); dragged by
    /// more it slides with the acceleration `(F − μ N)/m` (the friction force is `μ N`, to
    /// 1e-3); an obstacle strand sliding under it carries it along at `μ g`. Without friction
    /// the drag alone accelerates it.
    #[test]
    fn friction_between_strands_is_coulombs() {
        let mu = 0.5;
        let (_, _, mass, weight) = drag(mu, 0.0, 0.0, 1);
        // Sticking: 0.8 μ N for 1 s.
        let (v, creep, _, _) = drag(mu, 0.8 * mu * weight, 0.0, 60);
        let accel = (v[59] - v[29]) / (30.0 * H);
        let friction = 0.8 * mu * weight - mass * accel;
        println!("stick: creep {creep:e} m/s, friction {friction:e} N, μN {:e} N", mu * weight);
        assert!(creep < 1e-3, "{creep:e}");
        assert!((friction / (0.8 * mu * weight) - 1.0).abs() < 1e-3, "{friction:e}");
        // Sliding: 1.5 μ N.
        let (v, ..) = drag(mu, 1.5 * mu * weight, 0.0, 60);
        let accel = (v[59] - v[29]) / (30.0 * H);
        let friction = 1.5 * mu * weight - mass * accel;
        println!("slide: acceleration {accel:e} m/s², friction {friction:e} N");
        assert!((friction / (mu * weight) - 1.0).abs() < 1e-3, "{friction:e}");
        assert!(v[59] > 1.0, "{}", v[59]);
        // Carried by the other strand moving at 1 m/s: a = μ g until the speeds match.
        let (v, ..) = drag(mu, 0.0, 1.0, 6);
        let accel = (v[5] - v[0]) / (5.0 * H);
        println!("carried: acceleration {accel:e} m/s² (μ g = {:e})", mu * G);
        assert!((accel / (mu * G) - 1.0).abs() < 1e-3, "{accel:e}");
        // Frictionless: the drag alone.
        let (v, ..) = drag(0.0, 0.8 * mu * weight, 0.0, 60);
        let accel = (v[59] - v[29]) / (30.0 * H);
        assert!((accel / (0.8 * mu * weight / mass) - 1.0).abs() < 1e-6, "{accel:e}");
    }
}
