//! The joint formulations as functions over the world's arrays: penalty forces, sequential
//! impulses with a position pass, and the XPBD projection (the Lagrange multiplier system is
//! in [`lagrange`](super::lagrange)). The equations are in the module docs of
//! [`joint`](super::joint) and in `docs/rigid.md`.

use super::joint::{Joint, Kinematics, Row, RowKind};
use glam::{DQuat, DVec3};

/// Inverse masses and inverse principal moments per body (zero for fixed bodies).
#[derive(Clone, Copy)]
pub(crate) struct Mass<'a> {
    pub inv_mass: &'a [f64],
    pub inv_moments: &'a [DVec3],
}

impl Mass<'_> {
    /// `I⁻¹ w` in the world frame for body `i` whose principal frame is `q`.
    pub fn inv_inertia(&self, i: usize, q: DQuat, w: DVec3) -> DVec3 {
        q * ((q.conjugate() * w) * self.inv_moments[i])
    }

    /// `J M⁻¹ Jᵀ` of one row of a joint.
    pub fn row_compliance(&self, j: &Joint, r: &Row, q: &[DQuat]) -> f64 {
        let mut k = self.inv_mass[j.a] * r.la.length_squared()
            + r.aa.dot(self.inv_inertia(j.a, q[j.a], r.aa));
        if let Some(b) = j.b {
            k += self.inv_mass[b] * r.lb.length_squared()
                + r.ab.dot(self.inv_inertia(b, q[b], r.ab));
        }
        k
    }
}

/// `1/k`, or 0 for a row that moves nothing (both bodies fixed, or a zero Jacobian).
fn effective_mass(k: f64) -> f64 {
    if k > 1e-300 {
        1.0 / k
    } else {
        0.0
    }
}

/// `Ċ = J q̇` of a row.
pub(crate) fn rate(j: &Joint, r: &Row, v: &[DVec3], w: &[DVec3]) -> f64 {
    let mut c = r.la.dot(v[j.a]) + r.aa.dot(w[j.a]);
    if let Some(b) = j.b {
        c += r.lb.dot(v[b]) + r.ab.dot(w[b]);
    }
    c
}

/// `v += M⁻¹ Jᵀ λ` for an impulse `λ` (N s or N m s) along a row.
pub(crate) fn apply(
    m: &Mass<'_>,
    j: &Joint,
    r: &Row,
    lambda: f64,
    q: &[DQuat],
    v: &mut [DVec3],
    w: &mut [DVec3],
) {
    v[j.a] += r.la * (lambda * m.inv_mass[j.a]);
    w[j.a] += m.inv_inertia(j.a, q[j.a], r.aa * lambda);
    if let Some(b) = j.b {
        v[b] += r.lb * (lambda * m.inv_mass[b]);
        w[b] += m.inv_inertia(b, q[b], r.ab * lambda);
    }
}

/// Add the generalised force `Jᵀ λ` of a row to the bodies' forces and torques (N, N m).
pub(crate) fn add_force(
    j: &Joint,
    r: &Row,
    lambda: f64,
    force: &mut [DVec3],
    torque: &mut [DVec3],
) {
    force[j.a] += r.la * lambda;
    torque[j.a] += r.aa * lambda;
    if let Some(b) = j.b {
        force[b] += r.lb * lambda;
        torque[b] += r.ab * lambda;
    }
}

/// Penalty forces of one joint's evaluated `rows` (Bender et al. 2014, §4.2), added to
/// `force` and `torque`: per row `λ = −μ (k C + d Ċ)`, with the joint's `k` (1/s²) and `d`
/// (1/s) per unit of the row's natural mass `μ`: the reduced mass `1/(1/m_a + 1/m_b)` of a
/// linear row, the effective inertia `1/(J M⁻¹ Jᵀ)` of an angular one. The damper is capped
/// at `m_eff/h` (`m_eff = 1/(J M⁻¹ Jᵀ)` of the row), the value that removes the row's
/// velocity in one step, so it cannot make the explicit step unstable; the spring is explicit
/// (stable while `√(k μ/m_eff) h < 2`). Limit rows act only while violated and only push; a
/// motor row is a velocity servo `λ = m_eff (speed − Ċ)/h` clamped to its torque bound (with
/// the row's own `m_eff`, a lower bound of the true effective inertia, so it never
/// overshoots).
pub(crate) fn penalty(
    j: &Joint,
    rows: &[Row],
    m: &Mass<'_>,
    s: &Kinematics<'_>,
    h: f64,
    force: &mut [DVec3],
    torque: &mut [DVec3],
) {
    for r in rows {
        let me = effective_mass(m.row_compliance(j, r, s.q));
        if me == 0.0 {
            continue;
        }
        let mu = if r.la == DVec3::ZERO {
            me
        } else {
            effective_mass(m.inv_mass[j.a] + j.b.map_or(0.0, |b| m.inv_mass[b]))
        };
        let cdot = rate(j, r, s.v, s.w);
        let spring = -mu * j.stiffness * r.c;
        let damper = -(mu * j.damping).min(me / h) * cdot;
        let lambda = match r.kind {
            RowKind::Inactive => continue,
            RowKind::Equality => spring + damper,
            RowKind::Limit if r.c < 0.0 => (spring + damper).max(0.0),
            RowKind::Limit => continue,
            RowKind::Motor { speed, max } => (me * (speed - cdot) / h).clamp(-max, max),
        };
        add_force(j, r, lambda, force, torque);
    }
}

/// Fill each row's effective mass `1/(J M⁻¹ Jᵀ)` into `mass` (0 when it moves nothing).
pub(crate) fn effective_masses(
    j: &Joint,
    rows: &[Row],
    m: &Mass<'_>,
    q: &[DQuat],
    mass: &mut [f64],
) {
    for (r, out) in rows.iter().zip(mass.iter_mut()) {
        *out = if r.kind == RowKind::Inactive {
            0.0
        } else {
            effective_mass(m.row_compliance(j, r, q))
        };
    }
}

/// One sweep of sequential impulses over one joint's rows (velocity level): equality rows
/// drive `Ċ` to 0; a limit row's accumulated impulse stays `≥ 0` and lets the joint close at
/// most the gap to the limit within the step (`Ċ ≥ −max(C, 0)/h`); a motor row drives `Ċ` to
/// its speed with `|λ| ≤ max_torque · h`. `impulse` holds the accumulated impulses (warm
/// started by the caller).
#[allow(clippy::too_many_arguments)]
pub(crate) fn sweep(
    j: &Joint,
    rows: &[Row],
    mass: &[f64],
    impulse: &mut [f64],
    m: &Mass<'_>,
    q: &[DQuat],
    h: f64,
    v: &mut [DVec3],
    w: &mut [DVec3],
) {
    for ((r, &me), acc) in rows.iter().zip(mass).zip(impulse.iter_mut()) {
        if me == 0.0 {
            continue;
        }
        let cdot = rate(j, r, v, w);
        let new = match r.kind {
            RowKind::Inactive => continue,
            RowKind::Equality => *acc - me * cdot,
            RowKind::Limit => (*acc + me * (-r.c.max(0.0) / h - cdot)).max(0.0),
            RowKind::Motor { speed, max } => (*acc + me * (speed - cdot)).clamp(-max * h, max * h),
        };
        let d = new - *acc;
        *acc = new;
        apply(m, j, r, d, q, v, w);
    }
}

/// Largest correction of one row per sweep of the impulse position pass (m or rad), as Box2D
/// limits its joints' position corrections: beyond it the linearisation is not trusted.
pub(crate) const MAX_CORRECTION: f64 = 0.2;

/// One sweep of the position pass of the impulse formulation over one joint's rows evaluated
/// at the end of the step: each equality row (and each violated limit) moves the bodies by a
/// pseudo-impulse that zeroes its linearised value `C + J (dx, dθ)` (clamped to
/// ±[`MAX_CORRECTION`]), where `dx`, `dθ` are the
/// corrections so far (translations and small world rotations per body). Velocities are left
/// alone, so the pass adds no kinetic energy.
pub(crate) fn correct_positions(
    j: &Joint,
    rows: &[Row],
    mass: &[f64],
    m: &Mass<'_>,
    q: &[DQuat],
    dx: &mut [DVec3],
    dtheta: &mut [DVec3],
) {
    for (r, &me) in rows.iter().zip(mass) {
        if me == 0.0 || !matches!(r.kind, RowKind::Equality | RowKind::Limit) {
            continue;
        }
        let c = r.c + rate(j, r, dx, dtheta);
        if r.kind == RowKind::Limit && c >= 0.0 {
            continue;
        }
        let c = c.clamp(-MAX_CORRECTION, MAX_CORRECTION);
        apply(m, j, r, -me * c, q, dx, dtheta);
    }
}

/// One XPBD projection of one joint (Müller et al. 2020, Alg. 2 with zero compliance): each
/// of its position-based rows is re-evaluated at the current pose and corrected by
/// `Δλ = −C / (J M⁻¹ Jᵀ)`, moving `x += M⁻¹ lᵀ Δλ` and turning `q ← normalise(q + ½ (φ, 0) q)`
/// with `φ = I⁻¹ aᵀ Δλ`. The corrections are also added to `dx`, `dtheta`, from which the
/// caller updates the velocities (`v += dx/h`, `ω += dθ/h`).
///
/// The angular alignment is corrected as a block, not as one row along the error `θ`: with
/// anisotropic inertia `I⁻¹ θ` is not parallel to `θ`, so the paper's single row zeroes the
/// error along `θ` while turning the bodies out of the plane of rotations the joint forbids
/// (a slender link loses almost nothing per projection: the residual is ~0.96 of the error for
/// an inertia ratio of 50, and a hinged chain's axes tilted by up to 0.17 rad). The block
/// solves `P (I_a⁻¹ + I_b⁻¹) P τ = −θ` over the constrained rotations (the plane normal to a
/// hinge's axis, all three for a slider or a fixed joint), which zeroes the linearised error
/// in one projection.
pub(crate) fn project(
    j: &Joint,
    m: &Mass<'_>,
    x: &mut [DVec3],
    q: &mut [DQuat],
    dx: &mut [DVec3],
    dtheta: &mut [DVec3],
) {
    let mut rows = [Row::INACTIVE; 4];
    for k in 0..4 {
        // Re-evaluate after each correction (Gauss–Seidel on the true pose).
        j.xpbd_rows(&Kinematics { x, q, v: &[], w: &[] }, &mut rows);
        let r = rows[k];
        if r.kind == RowKind::Inactive {
            continue;
        }
        if k == 1 {
            let free = j.free_axis(&Kinematics { x, q, v: &[], w: &[] });
            project_alignment(j, m, free, r.ab * r.c, q, dtheta);
            continue;
        }
        let me = effective_mass(m.row_compliance(j, &r, q));
        if me == 0.0 {
            continue;
        }
        let dl = -r.c * me;
        let mut move_body = |i: usize, l: DVec3, a: DVec3| {
            let p = l * (dl * m.inv_mass[i]);
            let phi = m.inv_inertia(i, q[i], a * dl);
            x[i] += p;
            dx[i] += p;
            dtheta[i] += phi;
            q[i] = (q[i] + DQuat::from_xyzw(phi.x, phi.y, phi.z, 0.0) * q[i] * 0.5).normalize();
        };
        move_body(j.a, r.la, r.aa);
        if let Some(b) = j.b {
            move_body(b, r.lb, r.ab);
        }
    }
}

/// The block angular correction of [`project`]: `θ` is the alignment error (rad, world; the
/// relative rotation the joint forbids), `free` the axis the bodies may turn about (hinge).
fn project_alignment(
    j: &Joint,
    m: &Mass<'_>,
    free: Option<DVec3>,
    theta: DVec3,
    q: &mut [DQuat],
    dtheta: &mut [DVec3],
) {
    // K = I_a⁻¹ + I_b⁻¹ in the world, applied to a vector.
    let k = |u: DVec3| {
        let mut ku = m.inv_inertia(j.a, q[j.a], u);
        if let Some(b) = j.b {
            ku += m.inv_inertia(b, q[b], u);
        }
        ku
    };
    let tau = match free {
        Some(axis) => {
            let (e1, e2) = axis.normalize().any_orthonormal_pair();
            let (k1, k2) = (k(e1), k(e2));
            let (a, b, d) = (e1.dot(k1), e1.dot(k2), e2.dot(k2));
            let det = a * d - b * b;
            if det <= 1e-300 * (a * d).max(f64::MIN_POSITIVE) {
                return;
            }
            let (c1, c2) = (e1.dot(theta), e2.dot(theta));
            let (l1, l2) = ((-d * c1 + b * c2) / det, (b * c1 - a * c2) / det);
            e1 * l1 + e2 * l2
        }
        None => {
            let kmat = glam::DMat3::from_cols(k(DVec3::X), k(DVec3::Y), k(DVec3::Z));
            let det = kmat.determinant();
            if !(det.is_finite() && det > 0.0) {
                return;
            }
            -(kmat.inverse() * theta)
        }
    };
    let mut turn = |i: usize, torque: DVec3| {
        let phi = m.inv_inertia(i, q[i], torque);
        dtheta[i] += phi;
        q[i] = (q[i] + DQuat::from_xyzw(phi.x, phi.y, phi.z, 0.0) * q[i] * 0.5).normalize();
    };
    turn(j.a, -tau);
    if let Some(b) = j.b {
        turn(b, tau);
    }
}
