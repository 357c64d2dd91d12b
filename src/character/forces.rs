//! The forces of a step other than servos: applied joint torques, viscous joint damping,
//! joint limits as stiff one-sided spring-dampers, pushes, and ground contact as penalty
//! spring-dampers with regularised Coulomb friction.
//!
//! - **Limits** (one-sided springs, not constraints): a degree of freedom past its range by
//!   `e` gets `τ = −(k e + c ė)`, kept from pulling towards the violation, with `k = m ω²`,
//!   `c = 2 ζ m ω` (`m = 1 / (M⁻¹)_jj` the effective inertia of the degree of freedom at the
//!   current pose, the rest of the tree free, [`super::Settings::limit_frequency`],
//!   [`super::Settings::limit_damping`]): a mode of frequency ω, whatever the limb. Ball joints limit the
//!   components of the rotation vector `log(q)` about the limit axes, with rates `ω`.
//! - **Contact** with the plane `y = 0`: every capsule end is a sphere; one of depth
//!   `d = r − y > 0` gets at its lowest point the normal force `f_n = max(0, k d − c ẏ)`,
//!   `k = m ω²`, `c = 2 ζ m ω` (`m` the body's mass, ω
//!   [`super::Settings::contact_frequency`]): a body resting on one point sinks `g / ω²`.
//!   Friction `f_t = −μ f_n v_t / max(|v_t|, v_s)` (Coulomb above the slip speed `v_s`,
//!   viscous below). In an explicit step both viscous coefficients are capped at
//!   `m / (4 dt)`, above which the step would overshoot (a capsule end's effective mass can
//!   be `m / 4`). When the step solves stable PD ([`implicit`]) they are not capped: each
//!   contact is recorded ([`Contact`]) and its damping is taken at the next step's velocity
//!   in the same linear solve as the servos ([`super::servo::stable`]), as stable PD does
//!   for the servos' `k_d`. Against a moving collider the damping and friction act on the
//!   velocity relative to the collider's surface (taken as known in the solve, as the
//!   surface's motion is prescribed).
//! - **Self-collision** (with [`super::Settings::self_collision`]), between the capsules of
//!   each pair of [`Model::collision_pairs`]: at depth `d = r_i + r_j − |p_j − p_i| > 0`
//!   (`p_i`, `p_j` the closest points of the axes) the force `f_n = max(0, k d − c v_n)`
//!   along `n = (p_j − p_i)/|p_j − p_i|`, with `k = M ω²` on the heavier body's mass `M`
//!   (the lighter carries the heavier's weight at depth `g/ω²`, as on the ground),
//!   `c = 2 ζ ω √(M m)` (the critical damping of that spring on the reduced mass
//!   `m = m_i m_j / (m_i + m_j)`), always capped at `m / (4 dt)` (explicit: a self-contact
//!   is not part of stable PD's solve), `v_n` the normal relative velocity at
//!   the midpoint of the overlap, and the ground's regularised friction on the tangential
//!   relative velocity; equal and opposite on the two bodies, so it conserves momentum.

use super::dynamics::Tree;
use super::joints::quat;
use super::model::{Joint, Model, ServoMode};
use super::servo::{ltl, ltl_solve};
use super::spatial::spatial;
use super::state::Push;
use crate::geometry::segment::closest_points_of_segments;
use crate::rotation::quat_to_rotvec;
use glam::DVec3;

/// A contact (ground or collider) of the last [`passive`] of an implicit step: the body, the
/// contact point (m, world), its unit normal (world, out of the touched surface) and the
/// viscous coefficients (N s/m) of its force, `c_n` on the normal velocity (zero when the
/// normal force is clamped at zero) and `c_t` on the tangential velocity (friction's
/// `μ f_n / max(|v_t|, v_s)`).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Contact {
    pub body: usize,
    pub point: DVec3,
    pub direction: DVec3,
    pub normal: f64,
    pub tangent: f64,
}

/// Whether a step of `model` solves stable PD, and so takes the contacts' damping at the
/// next step's velocity (uncapped) in the same solve.
pub(super) fn implicit(model: &Model) -> bool {
    model.settings.servo_mode == ServoMode::Stable && super::servo::any(model)
}

/// Add the body forces (contacts, pushes) to `tree.f_ext` and the joint forces (applied
/// torques, damping, limits) to `tau`, at the state of the last [`Tree::kinematics`] and
/// `time` (s: where the moving colliders are).
/// Pushes act with weight `min(remaining, dt) / dt` (the impulse of a push ending inside
/// the step). With `implicit`, the contacts' viscous coefficients are not capped and the
/// contacts are recorded in `tree.contacts` for the solve.
#[allow(clippy::too_many_arguments)]
pub(super) fn passive(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    torques: &[f64],
    pushes: &[Push],
    time: f64,
    dt: f64,
    implicit: bool,
    tree: &mut Tree,
    tau: &mut [f64],
) {
    tau.copy_from_slice(torques);
    tree.contacts.clear();
    for p in pushes {
        let w = p.remaining.min(dt) / dt;
        let com = model.bodies()[p.body].com;
        apply(tree, p.body, com, w * p.force);
    }
    if model.settings.ground {
        for i in 0..model.bodies().len() {
            for (contact, point, force) in
                contacts(model, tree, i, dt, implicit).into_iter().flatten()
            {
                apply(tree, i, point, force);
                if implicit {
                    tree.contacts.push(contact);
                }
            }
        }
    }
    if !model.colliders().is_empty() {
        for i in 0..model.bodies().len() {
            collider_contacts(model, tree, i, time, dt, implicit);
        }
    }
    if model.settings.self_collision {
        self_contacts(model, tree, dt);
    }
    for (i, b) in model.bodies().iter().enumerate() {
        let (_, iv) = model.starts(i);
        if matches!(b.joint, Joint::Revolute { .. } | Joint::Ball) {
            for k in 0..b.joint.nv() {
                tau[iv + k] -= b.damping * qd[iv + k];
            }
        }
    }
    limits(model, q, qd, tree, tau);
}

/// Add the world force `force` (N) acting at `point` (m, body frame) of body `i`.
fn apply(tree: &mut Tree, i: usize, point: DVec3, force: DVec3) {
    let f = tree.rot[i].conjugate() * force;
    tree.f_ext[i] += spatial(point.cross(f), f);
}

/// The world velocity (m/s) of the point `point` (m, body frame) of body `i`.
fn point_velocity(tree: &Tree, i: usize, point: DVec3) -> DVec3 {
    let v = &tree.v[i];
    tree.rot[i] * (DVec3::new(v[3], v[4], v[5]) + DVec3::new(v[0], v[1], v[2]).cross(point))
}

/// Add the self-collision forces of the module documentation to `tree.f_ext`.
fn self_contacts(model: &Model, tree: &mut Tree, dt: f64) {
    let s = &model.settings;
    let bodies = model.bodies();
    for &(i, j) in model.collision_pairs() {
        let (Some(ci), Some(cj)) = (bodies[i].shape, bodies[j].shape) else { continue };
        let world = |k: usize, p: DVec3| tree.pos[k] + tree.rot[k] * p;
        let (pi, pj) = closest_points_of_segments(
            world(i, ci.a),
            world(i, ci.b),
            world(j, cj.a),
            world(j, cj.b),
        );
        let (gap, depth) = (pj - pi, ci.radius + cj.radius - pi.distance(pj));
        if depth <= 0.0 || gap.length_squared() == 0.0 {
            continue;
        }
        let n = gap.normalize();
        let at = 0.5 * (pi + ci.radius * n + pj - cj.radius * n);
        let local = |k: usize| tree.rot[k].conjugate() * (at - tree.pos[k]);
        let (li, lj) = (local(i), local(j));
        let rel = point_velocity(tree, j, lj) - point_velocity(tree, i, li);
        let (mi, mj) = (bodies[i].mass, bodies[j].mass);
        let (heavier, reduced) = (mi.max(mj), mi * mj / (mi + mj));
        let cap = reduced / (4.0 * dt);
        let k = heavier * s.contact_frequency.powi(2);
        let c =
            (2.0 * s.contact_damping * (heavier * reduced).sqrt() * s.contact_frequency).min(cap);
        let normal = (k * depth - c * rel.dot(n)).max(0.0);
        let slip = rel - rel.dot(n) * n;
        let tangent = (s.friction * normal / slip.length().max(s.slip_speed)).min(cap);
        let force = normal * n - tangent * slip;
        apply(tree, j, lj, force);
        apply(tree, i, li, -force);
    }
}

/// The total ground force (N, world) on `bodies` at the state of the last
/// [`Tree::kinematics`], for a step `dt` (zero without a ground), at the current velocities
/// (an implicit step's damping adds its part at the next step's).
pub(super) fn ground_force(
    model: &Model,
    tree: &Tree,
    bodies: impl IntoIterator<Item = usize>,
    dt: f64,
) -> DVec3 {
    let mut total = DVec3::ZERO;
    if model.settings.ground {
        let implicit = implicit(model);
        for i in bodies {
            for (_, _, force) in contacts(model, tree, i, dt, implicit).into_iter().flatten() {
                total += force;
            }
        }
    }
    total
}

/// The ground contacts of body `i` (one per capsule end below the ground): the contact
/// (its point in world axes), the point (m, body frame) and the force there (N, world),
/// with the viscous coefficients capped unless `implicit`.
pub(super) fn contacts(
    model: &Model,
    tree: &Tree,
    i: usize,
    dt: f64,
    implicit: bool,
) -> [Option<(Contact, DVec3, DVec3)>; 2] {
    let mut out = [None; 2];
    let b = &model.bodies()[i];
    let Some(shape) = b.shape else { return out };
    let spring = Spring::new(model, i, dt, implicit, model.settings.friction);
    let ends: &[DVec3] = if shape.a == shape.b { &[shape.a][..] } else { &[shape.a, shape.b][..] };
    for (slot, &end) in out.iter_mut().zip(ends) {
        let centre = tree.pos[i] + tree.rot[i] * end;
        let depth = shape.radius - centre.y;
        if depth > 0.0 {
            let point = end + tree.rot[i].conjugate() * (-shape.radius * DVec3::Y);
            *slot = Some(spring.touch(tree, i, point, DVec3::Y, depth, DVec3::ZERO));
        }
    }
    out
}

/// The penalty spring-damper of body `i`'s contacts (the module documentation): stiffness
/// `k = m ω²`, damping `c = 2 ζ m ω` and friction coefficient `mu`, the viscous coefficients
/// capped at `m / (4 dt)` unless `implicit`; `weight` scales the whole force (1 but for
/// the inner contacts of [`collider_contacts`]).
struct Spring {
    k: f64,
    c: f64,
    mu: f64,
    slip_speed: f64,
    cap: f64,
    weight: f64,
}

impl Spring {
    fn new(model: &Model, i: usize, dt: f64, implicit: bool, mu: f64) -> Spring {
        let (s, m) = (&model.settings, model.bodies()[i].mass);
        // Viscous coefficients above m / (4 dt) would overshoot in an explicit step.
        let cap = if implicit { f64::INFINITY } else { m / (4.0 * dt) };
        let k = m * s.contact_frequency.powi(2);
        let c = (2.0 * s.contact_damping * m * s.contact_frequency).min(cap);
        Spring { k, c, mu, slip_speed: s.slip_speed, cap, weight: 1.0 }
    }

    /// The contact of body `i` at `point` (m, body frame, on the capsule's surface) at
    /// `depth` (m, > 0) along the unit normal `n` (world, out of the touched shape) of a
    /// surface moving at `surface` (m/s, world): the contact, the point and the force (N,
    /// world), `w (max(0, k d − c v·n) n − c_t v_t)`, `c_t = μ f_n / max(|v_t|, v_s)`, `v`
    /// the point's velocity relative to the surface.
    fn touch(
        &self,
        tree: &Tree,
        i: usize,
        point: DVec3,
        n: DVec3,
        depth: f64,
        surface: DVec3,
    ) -> (Contact, DVec3, DVec3) {
        let vel = point_velocity(tree, i, point) - surface;
        let (w, vn) = (self.weight, vel.dot(n));
        let normal = w * (self.k * depth - self.c * vn).max(0.0);
        let slip = vel - vn * n;
        let tangent = (self.mu * normal / slip.length().max(self.slip_speed)).min(self.cap);
        let contact = Contact {
            body: i,
            point: tree.pos[i] + tree.rot[i] * point,
            direction: n,
            normal: if normal > 0.0 { w * self.c } else { 0.0 },
            tangent,
        };
        (contact, point, normal * n - tangent * slip)
    }
}

/// Add the forces of body `i`'s capsule's contacts with `model`'s colliders, where they are
/// at `time` ([`super::model::Collider::at`]), to `tree.f_ext` (and with `implicit` record
/// them in `tree.contacts`); velocities are relative to the collider's. Per collider, with
/// `a`, `b` the capsule's ends (world), `r` its radius, `φ` the collider's signed distance ([`crate::geometry::Shape::distance`]) and `n`
/// its normal: every end with `φ < r` touches at depth `r − φ` along `n`; and the axis's
/// deepest point `p(t)` ([`crate::geometry::Shape::deepest_on_segment`]), when it lies
/// inside the axis and deeper than both ends (the capsule across a box's edge or a sphere),
/// touches with its force weighted by `min(1, s / r)`, `s` its distance along the axis to
/// the nearer end (near an end, that end's contact already holds it); "deeper" by more
/// than 1e-12 m, so that a capsule lying on a face (a plateau of `φ`) keeps its two end
/// contacts only, whatever point of the plateau the search returns. A capsule whose axis
/// midpoint is farther than `r + |b − a| / 2` from the collider is skipped (the signed
/// distance changes by at most the distance moved).
fn collider_contacts(model: &Model, tree: &mut Tree, i: usize, time: f64, dt: f64, implicit: bool) {
    let each = |tree: &mut Tree, (contact, point, force): (Contact, DVec3, DVec3)| {
        apply(tree, i, point, force);
        if implicit {
            tree.contacts.push(contact);
        }
    };
    let Some(shape) = model.bodies()[i].shape else { return };
    let (pos, rot) = (tree.pos[i], tree.rot[i]);
    let local = |p: DVec3| rot.conjugate() * (p - pos);
    let (a, b) = (pos + rot * shape.a, pos + rot * shape.b);
    let (r, length) = (shape.radius, a.distance(b));
    for collider in model.colliders() {
        let geometry = &collider.at(time);
        let surface = |p: DVec3| collider.surface_velocity(geometry, p);
        if geometry.distance(0.5 * (a + b)).0 >= r + 0.5 * length {
            continue;
        }
        let mu = collider.friction.unwrap_or(model.settings.friction);
        let mut spring = Spring::new(model, i, dt, implicit, mu);
        let ends: &[DVec3] = if length == 0.0 { &[a][..] } else { &[a, b][..] };
        let mut least = f64::INFINITY;
        for &end in ends {
            let (d, n) = geometry.distance(end);
            least = least.min(d);
            if d < r {
                let p = end - r * n;
                let touch = spring.touch(tree, i, local(p), n, r - d, surface(p));
                each(tree, touch);
            }
        }
        let t = geometry.deepest_on_segment(a, b);
        let s = t.min(1.0 - t) * length;
        let p = a.lerp(b, t);
        let (d, n) = geometry.distance(p);
        if s > 0.0 && d < r && d < least - 1e-12 {
            spring.weight = if r > 0.0 { (s / r).min(1.0) } else { 1.0 };
            let q = p - r * n;
            let touch = spring.touch(tree, i, local(q), n, r - d, surface(q));
            each(tree, touch);
        }
    }
}

/// The joint-limit torques into `tau`; the joint-space inertia is computed and factorised
/// (CRBA, LTL, in the workspace) only when a limit is passed.
fn limits(model: &Model, q: &[f64], qd: &[f64], tree: &mut Tree, tau: &mut [f64]) {
    let mut factorised: Option<bool> = None;
    let (w, zeta) = (model.settings.limit_frequency, model.settings.limit_damping);
    for (i, b) in model.bodies().iter().enumerate() {
        let Some(lim) = b.limits else { continue };
        let (iq, iv) = model.starts(i);
        let (axes, angles, rates): ([DVec3; 3], DVec3, DVec3) = match b.joint {
            Joint::Revolute { .. } => (
                [DVec3::X, DVec3::ZERO, DVec3::ZERO],
                DVec3::new(q[iq], 0.0, 0.0),
                DVec3::new(qd[iv], 0.0, 0.0),
            ),
            Joint::Ball => {
                let f = lim.frame;
                let r = f.conjugate() * DVec3::from_array(quat_to_rotvec(quat(&q[iq..])));
                let om = f.conjugate() * DVec3::new(qd[iv], qd[iv + 1], qd[iv + 2]);
                ([f * DVec3::X, f * DVec3::Y, f * DVec3::Z], r, om)
            }
            _ => continue,
        };
        let count = if b.joint == Joint::Ball { 3 } else { 1 };
        for k in 0..count {
            let (lo, hi) = lim.ranges[k];
            let e = if angles[k] > hi {
                angles[k] - hi
            } else if angles[k] < lo {
                angles[k] - lo
            } else {
                continue;
            };
            let ok = *factorised.get_or_insert_with(|| {
                tree.crba(model);
                ltl(&mut tree.mass_matrix, &tree.dof_paths)
            });
            let inverse =
                if ok { axis_inverse_inertia(tree, iv, count, axes[k]) } else { f64::NAN };
            let inertia = 1.0 / inverse;
            let t = -(inertia * w * w * e + 2.0 * zeta * inertia * w * rates[k]);
            let t = if e > 0.0 { t.min(0.0) } else { t.max(0.0) };
            if count == 1 {
                tau[iv] += t;
            } else {
                for (r, a) in axes[k].to_array().iter().enumerate() {
                    tau[iv + r] += t * a;
                }
            }
        }
    }
}

/// `aᵀ (M⁻¹)_jj a`: the inverse effective inertia of a joint's `count` degrees of freedom at
/// `iv` about the unit direction `axis` (a revolute joint: its own), the whole tree free to
/// respond; `tree.mass_matrix` holds the LTL factor of `M`, `tree.column` is scratch.
fn axis_inverse_inertia(tree: &mut Tree, iv: usize, count: usize, axis: DVec3) -> f64 {
    let a = if count == 1 { [1.0, 0.0, 0.0] } else { axis.to_array() };
    tree.column.fill(0.0);
    tree.column[iv..iv + count].copy_from_slice(&a[..count]);
    ltl_solve(&tree.mass_matrix, &tree.dof_paths, &mut tree.column);
    (0..count).map(|r| a[r] * tree.column[iv + r]).sum()
}
