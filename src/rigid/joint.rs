//! Joints between two bodies, or between a body and the world: their kinds, their geometry
//! (the constraint rows `C`, `J`, `J̇ q̇` every formulation reads) and the violation report.
//!
//! A joint holds two frames, one fixed in each body (or in the world), that coincide when the
//! joint is made: an anchor point `p` and a joint frame whose x axis is the joint's axis.
//! With `pa`, `pb` the anchors and `Fa`, `Fb` the frames in world coordinates,
//!
//! | kind | rows (`= 0`) | free motion |
//! |---|---|---|
//! | ball | `eₖ · (pb − pa)`, k = x, y, z | 3 rotations |
//! | hinge | ball rows, `(Fa x) · (Fb y)`, `(Fa x) · (Fb z)` | rotation about the axis |
//! | slider | `(Fb y) · (pb − pa)`, `(Fb z) · (pb − pa)`, `(Fa x)·(Fb y)`, `(Fa y)·(Fb z)`, `(Fa z)·(Fb x)` | translation along the axis |
//! | fixed | ball rows and the three angular rows of the slider | none |
//!
//! (the three angular rows vanish, to first order, only for `Fa = Fb`: a small relative
//! rotation `δ` changes them by `−δ_z, −δ_x, −δ_y`). A hinge may add a lower and an upper limit
//! on its angle `θ = atan2((Fa y × Fb y) · Fa x, Fa y · Fb y)` (rows `θ − lo ≥ 0`,
//! `hi − θ ≥ 0`) and a motor (a velocity row `θ̇ = speed` whose torque is bounded by
//! `max_torque`). Each row `r` is `C_r` with its Jacobian written per body as
//! `Ċ_r = la · va + aa · ωa + lb · vb + ab · ωb` (centre-of-mass velocities, world angular
//! velocities) and `J̇ q̇`, the part of `C̈_r` that does not depend on the accelerations
//! (needed by the multiplier formulation). Rows follow Bender, Erleben & Trinkle 2014,
//! "Interactive simulation of rigid body dynamics in computer graphics" (CGF 33(1)), §4.
//!
//! The position-based formulation uses the directional constraints of Müller et al. 2020,
//! "Detailed rigid body simulation with extended position based dynamics" (SCA), §3.3:
//! one positional row along the anchors' offset `pb − pa` (its part normal to the axis for a
//! slider) and one angular row about the rotation vector that aligns the frames (`Fa x × Fb x`
//! for a hinge, `2 Im(Fb Fa*)` for a fixed joint or a slider).

use crate::error::{Error, Result};
use glam::{DQuat, DVec3};

/// Torque bound and target speed of a hinge motor.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Motor {
    /// Target angular velocity of `b` relative to `a` about the hinge axis (rad/s).
    pub speed: f64,
    /// Largest torque the motor exerts (N m, `≥ 0`; infinite makes a velocity constraint).
    pub max_torque: f64,
}

/// What a joint lets the two bodies do relative to each other.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub enum JointKind {
    /// The anchors coincide; any relative rotation (3 rows).
    Ball,
    /// The anchors coincide and the bodies turn only about the axis (5 rows), with optional
    /// limits `(lo, hi)` on the angle (rad, `lo ≤ hi`, zero at creation, positive turning
    /// `b` about `+axis` relative to `a`) and an optional motor.
    Hinge {
        /// Lower and upper angle (rad), or none.
        limits: Option<(f64, f64)>,
        /// Velocity motor, or none.
        motor: Option<Motor>,
    },
    /// No relative rotation; `b` moves relative to `a` only along the axis (5 rows).
    Slider,
    /// No relative motion at all (6 rows).
    Fixed,
}

/// How a joint's constraint is enforced; see `docs/rigid.md` for the equations and the
/// measured trade.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointMethod {
    /// Stiff springs and dampers on `C` and `Ċ` (Bender et al. 2014, §4.2): per row the force
    /// `−μ (k C + d Ċ) ∇C`, `k` and `d` per unit of the row's mass `μ` (see
    /// [`JointDesc::stiffness`]). Drift of order `g/k`; explicit, so the step must stay below
    /// about `2/√k` (less when a body turns easily about the anchor).
    Penalty,
    /// Lagrange multipliers at the acceleration level (Bender et al. 2014, §4.3; Witkin's
    /// constrained dynamics): `J M⁻¹ Jᵀ λ = −½ J̇ q̇ − J M⁻¹ f − k_d Ċ − k_s C` solved by a
    /// sparse Cholesky factorisation (faer), with Baumgarte feedback `k_d = 1/h`, `k_s = β/h²`
    /// (the ½ makes the semi-implicit step second-order consistent), then one post-stabilising
    /// Newton projection of the positions with the same factorisation pattern (Cline & Pai
    /// 2003), so long chains stay connected at large steps. With contacts in the world, a few
    /// velocity projections onto the joints alternate with contact sweeps.
    Lagrange,
    /// Sequential impulses at the velocity level (Catto 2005; Bender et al. 2014, §4.4), warm
    /// started, then a nonlinear Gauss–Seidel pass on the positions that removes the drift
    /// without adding kinetic energy (as the contacts do).
    Impulse,
    /// Extended position-based dynamics (Müller et al. 2020), rigid (zero compliance):
    /// substeps, each predicting the positions, projecting them onto the joints once, and
    /// taking the velocities from the positions; hinges with limits or a motor then get a
    /// velocity pass over their rows.
    Xpbd,
}

impl JointMethod {
    /// Parse `"penalty" | "lagrange" | "impulse" | "xpbd"`.
    ///
    /// # Errors
    /// Any other name.
    pub fn parse(name: &str) -> Result<Self> {
        Ok(match name {
            "penalty" => Self::Penalty,
            "lagrange" => Self::Lagrange,
            "impulse" => Self::Impulse,
            "xpbd" => Self::Xpbd,
            _ => {
                return Err(Error::invalid(
                    "method",
                    format!("{name:?} is not one of penalty, lagrange, impulse, xpbd"),
                ))
            }
        })
    }
}

/// Everything needed to add one joint to a [`World`](super::World).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug)]
pub struct JointDesc {
    /// The joint's kind, with its limits and motor.
    pub kind: JointKind,
    /// The formulation that enforces it.
    pub method: JointMethod,
    /// First body.
    pub a: usize,
    /// Second body, or `None` for the world.
    pub b: Option<usize>,
    /// World anchor at creation (m); used by ball and hinge joints (sliders and fixed joints
    /// anchor at the centre of mass of `a`).
    pub anchor: DVec3,
    /// World axis at creation (any length > 0); used by hinges and sliders.
    pub axis: DVec3,
    /// Penalty only: stiffness per unit mass, `k` (1/s²): a linear row's spring is `k μ` (N/m)
    /// with `μ` the reduced mass of the two bodies, an angular row's `k I_eff` (N m/rad), so
    /// `√k` is the frequency at which a joint alone would ring. Default [`PENALTY_STIFFNESS`].
    pub stiffness: f64,
    /// Penalty only: damping per unit mass, `d` (1/s), capped per row so that it never more
    /// than stops the row's velocity in one step. Default [`PENALTY_DAMPING`].
    pub damping: f64,
}

/// Default penalty stiffness per unit mass (1/s²): a 100 rad/s spring.
pub const PENALTY_STIFFNESS: f64 = 1e4;
/// Default penalty damping per unit mass (1/s): critical for [`PENALTY_STIFFNESS`].
pub const PENALTY_DAMPING: f64 = 200.0;
/// Row slots per joint (a hinge's 5 rows, two limits and a motor).
pub(crate) const SLOTS: usize = 8;

/// What a row asks for.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub(crate) enum RowKind {
    /// Not used by this joint (zero Jacobian).
    Inactive,
    /// `C = 0`.
    Equality,
    /// `C ≥ 0`.
    Limit,
    /// `Ċ = speed` with the force bounded by `max` (N m).
    Motor { speed: f64, max: f64 },
}

/// One evaluated constraint row (see the module docs for the notation).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug)]
pub(crate) struct Row {
    pub la: DVec3,
    pub aa: DVec3,
    pub lb: DVec3,
    pub ab: DVec3,
    /// `C` (m or rad).
    pub c: f64,
    /// `J̇ q̇` (m/s² or rad/s²).
    pub jdv: f64,
    pub kind: RowKind,
}

impl Row {
    pub const INACTIVE: Row = Row {
        la: DVec3::ZERO,
        aa: DVec3::ZERO,
        lb: DVec3::ZERO,
        ab: DVec3::ZERO,
        c: 0.0,
        jdv: 0.0,
        kind: RowKind::Inactive,
    };
}

/// A joint as the world stores it: local anchors and frames in each body's principal frame
/// (about its centre of mass), or in the world for `b = None`.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug)]
pub(crate) struct Joint {
    pub kind: JointKind,
    pub method: JointMethod,
    pub a: usize,
    pub b: Option<usize>,
    ra: DVec3,
    rb: DVec3,
    fa: DQuat,
    fb: DQuat,
    pub stiffness: f64,
    pub damping: f64,
}

/// Pose and velocity of one side of a joint, world frame.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy)]
struct Side {
    /// World anchor and its lever arm from the centre of mass.
    p: DVec3,
    r: DVec3,
    /// Joint frame in the world.
    f: DQuat,
    v: DVec3,
    w: DVec3,
}

/// Body state the rows read: centres of mass, principal frames (→ world), velocities and
/// world angular velocities (may be empty for position-only evaluations).
pub(crate) struct Kinematics<'a> {
    pub x: &'a [DVec3],
    pub q: &'a [DQuat],
    pub v: &'a [DVec3],
    pub w: &'a [DVec3],
}

impl Kinematics<'_> {
    fn vel(&self, i: usize) -> (DVec3, DVec3) {
        if self.v.is_empty() {
            (DVec3::ZERO, DVec3::ZERO)
        } else {
            (self.v[i], self.w[i])
        }
    }
}

fn check_vec(arg: &str, v: DVec3) -> Result<()> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(Error::invalid(arg, "contains NaN or infinity"))
    }
}

/// The row `C = n · (p_b − p_a)` of two sides, `n` fixed in the world or (`turning`) turning
/// with side `b`.
fn linear_row(a: &Side, b: &Side, n: DVec3, turning: bool) -> Row {
    let d = b.p - a.p;
    let dd = (b.v + b.w.cross(b.r)) - (a.v + a.w.cross(a.r));
    let mut ab = b.r.cross(n);
    let mut jdv = n.dot(b.w.cross(b.w.cross(b.r)) - a.w.cross(a.w.cross(a.r)));
    if turning {
        ab += n.cross(d);
        let nd = b.w.cross(n);
        jdv += b.w.cross(nd).dot(d) + 2.0 * nd.dot(dd);
    }
    Row { la: -n, aa: -a.r.cross(n), lb: n, ab, c: n.dot(d), jdv, kind: RowKind::Equality }
}

/// The row `C = u · w` of two sides, `u` turning with side `a`, `w` with side `b`.
fn angular_row(a: &Side, b: &Side, u: DVec3, w: DVec3) -> Row {
    let (du, dw) = (a.w.cross(u), b.w.cross(w));
    let jdv = a.w.cross(du).dot(w) + 2.0 * du.dot(dw) + u.dot(b.w.cross(dw));
    let uw = u.cross(w);
    Row {
        la: DVec3::ZERO,
        aa: uw,
        lb: DVec3::ZERO,
        ab: -uw,
        c: u.dot(w),
        jdv,
        kind: RowKind::Equality,
    }
}

impl JointDesc {
    /// `Ok` when the description fits a world of `n` bodies: indices, anchor and axis,
    /// limits, motor and penalty parameters in their domains.
    fn check(&self, n: usize) -> Result<()> {
        if self.a >= n {
            return Err(Error::invalid(
                "a",
                format!("body index {} out of range ({n} bodies)", self.a),
            ));
        }
        if let Some(b) = self.b {
            if b >= n {
                return Err(Error::invalid(
                    "b",
                    format!("body index {b} out of range ({n} bodies)"),
                ));
            }
            if b == self.a {
                return Err(Error::invalid(
                    "b",
                    format!("a joint needs two different bodies, got a = b = {b}"),
                ));
            }
        }
        check_vec("anchor", self.anchor)?;
        check_vec("axis", self.axis)?;
        let uses_axis = matches!(self.kind, JointKind::Hinge { .. } | JointKind::Slider);
        if uses_axis && self.axis.length() <= 1e-12 {
            return Err(Error::invalid("axis", "must be a non-zero vector"));
        }
        if let JointKind::Hinge { limits, motor } = self.kind {
            if let Some((lo, hi)) = limits {
                if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                    return Err(Error::invalid(
                        "limits",
                        format!("must be finite with lo <= hi, got ({lo}, {hi})"),
                    ));
                }
                if !(lo <= 0.0 && hi >= 0.0) {
                    return Err(Error::invalid(
                        "limits",
                        format!("must hold the angle at creation, 0, got ({lo}, {hi})"),
                    ));
                }
            }
            if let Some(m) = motor {
                if !m.speed.is_finite() {
                    return Err(Error::invalid(
                        "motor_speed",
                        format!("must be finite, got {}", m.speed),
                    ));
                }
                if m.max_torque.is_nan() || m.max_torque < 0.0 {
                    return Err(Error::invalid(
                        "max_torque",
                        format!("must be >= 0, got {}", m.max_torque),
                    ));
                }
            }
        }
        if self.method == JointMethod::Penalty {
            if !(self.stiffness.is_finite() && self.stiffness > 0.0) {
                return Err(Error::invalid(
                    "stiffness",
                    format!("must be positive and finite, got {}", self.stiffness),
                ));
            }
            if !(self.damping.is_finite() && self.damping >= 0.0) {
                return Err(Error::invalid(
                    "damping",
                    format!("must be non-negative and finite, got {}", self.damping),
                ));
            }
        }
        Ok(())
    }
}

impl Joint {
    /// Check `desc` against a world of `n` bodies at state `s` and make the joint.
    pub fn new(desc: &JointDesc, n: usize, s: &Kinematics<'_>) -> Result<Joint> {
        desc.check(n)?;
        let uses_axis = matches!(desc.kind, JointKind::Hinge { .. } | JointKind::Slider);
        let anchor = match desc.kind {
            JointKind::Ball | JointKind::Hinge { .. } => desc.anchor,
            JointKind::Slider | JointKind::Fixed => s.x[desc.a],
        };
        let frame = if uses_axis {
            DQuat::from_rotation_arc(DVec3::X, desc.axis.normalize())
        } else {
            DQuat::IDENTITY
        };
        let local = |i: Option<usize>| match i {
            Some(i) => {
                (s.q[i].conjugate() * (anchor - s.x[i]), (s.q[i].conjugate() * frame).normalize())
            }
            None => (anchor, frame),
        };
        let (ra, fa) = local(Some(desc.a));
        let (rb, fb) = local(desc.b);
        Ok(Joint {
            kind: desc.kind,
            method: desc.method,
            a: desc.a,
            b: desc.b,
            ra,
            rb,
            fa,
            fb,
            stiffness: desc.stiffness,
            damping: desc.damping,
        })
    }

    /// Rows used by this kind (a prefix of the [`SLOTS`]).
    pub fn slots(&self) -> usize {
        match self.kind {
            JointKind::Ball => 3,
            JointKind::Hinge { .. } => SLOTS,
            JointKind::Slider => 5,
            JointKind::Fixed => 6,
        }
    }

    fn side(&self, s: &Kinematics<'_>, body: Option<usize>, r: DVec3, f: DQuat) -> Side {
        match body {
            Some(i) => {
                let r = s.q[i] * r;
                let (v, w) = s.vel(i);
                Side { p: s.x[i] + r, r, f: s.q[i] * f, v, w }
            }
            None => Side { p: r, r: DVec3::ZERO, f, v: DVec3::ZERO, w: DVec3::ZERO },
        }
    }

    fn sides(&self, s: &Kinematics<'_>) -> (Side, Side) {
        (self.side(s, Some(self.a), self.ra, self.fa), self.side(s, self.b, self.rb, self.fb))
    }

    /// The hinge angle `θ` (rad) and the world axis (`Fa x`).
    fn angle(a: &Side, b: &Side) -> (f64, DVec3) {
        let u = a.f * DVec3::X;
        let (ya, yb) = (a.f * DVec3::Y, b.f * DVec3::Y);
        (ya.cross(yb).dot(u).atan2(ya.dot(yb)), u)
    }

    /// Evaluate the rows at state `s` into `out` (all [`SLOTS`] written; unused ones inactive).
    pub fn rows(&self, s: &Kinematics<'_>, out: &mut [Row]) {
        let (a, b) = self.sides(s);
        out[..SLOTS].fill(Row::INACTIVE);
        let linear = |n: DVec3, turning: bool| linear_row(&a, &b, n, turning);
        let angular = |u: DVec3, w: DVec3| angular_row(&a, &b, u, w);
        let axes = |f: DQuat| (f * DVec3::X, f * DVec3::Y, f * DVec3::Z);
        let (xa, ya, za) = axes(a.f);
        let (xb, yb, zb) = axes(b.f);
        match self.kind {
            JointKind::Ball => {
                for (o, n) in out.iter_mut().zip(DVec3::AXES) {
                    *o = linear(n, false);
                }
            }
            JointKind::Hinge { limits, motor } => {
                for (o, n) in out.iter_mut().zip(DVec3::AXES) {
                    *o = linear(n, false);
                }
                out[3] = angular(xa, yb);
                out[4] = angular(xa, zb);
                let (theta, u) = Self::angle(&a, &b);
                let rel = b.w - a.w;
                let jdv = rel.dot(a.w.cross(u));
                let turn = |sign: f64, c: f64, kind| Row {
                    la: DVec3::ZERO,
                    aa: -sign * u,
                    lb: DVec3::ZERO,
                    ab: sign * u,
                    c,
                    jdv: sign * jdv,
                    kind,
                };
                if let Some((lo, hi)) = limits {
                    out[5] = turn(1.0, theta - lo, RowKind::Limit);
                    out[6] = turn(-1.0, hi - theta, RowKind::Limit);
                }
                if let Some(m) = motor {
                    out[7] = turn(1.0, 0.0, RowKind::Motor { speed: m.speed, max: m.max_torque });
                }
            }
            JointKind::Slider => {
                out[0] = linear(yb, true);
                out[1] = linear(zb, true);
                out[2] = angular(xa, yb);
                out[3] = angular(ya, zb);
                out[4] = angular(za, xb);
            }
            JointKind::Fixed => {
                for (o, n) in out.iter_mut().zip(DVec3::AXES) {
                    *o = linear(n, false);
                }
                out[3] = angular(xa, yb);
                out[4] = angular(ya, zb);
                out[5] = angular(za, xb);
            }
        }
    }

    /// The rows of the position-based formulation (Müller et al. 2020) at state `s`, in fixed
    /// slots (inactive when not needed): a positional row `C = |e|` along the anchors' offset
    /// `e`, an angular row `C = |θ|` about the aligning rotation vector `θ`, and the hinge's
    /// lower and upper limit rows while violated.
    pub fn xpbd_rows(&self, s: &Kinematics<'_>, out: &mut [Row; 4]) {
        let (a, b) = self.sides(s);
        out.fill(Row::INACTIVE);
        let mut e = b.p - a.p;
        if self.kind == JointKind::Slider {
            let u = b.f * DVec3::X;
            e -= e.dot(u) * u;
        }
        let len = e.length();
        if len > 1e-15 {
            let d = e / len;
            out[0] = Row {
                la: -d,
                aa: -a.r.cross(d),
                lb: d,
                ab: b.r.cross(d),
                c: len,
                jdv: 0.0,
                kind: RowKind::Equality,
            };
        }
        let theta = match self.kind {
            JointKind::Ball => DVec3::ZERO,
            JointKind::Hinge { .. } => (a.f * DVec3::X).cross(b.f * DVec3::X),
            JointKind::Slider | JointKind::Fixed => rotation_vector(b.f * a.f.conjugate()),
        };
        let angle = theta.length();
        if angle > 1e-15 {
            let d = theta / angle;
            out[1] = Row {
                la: DVec3::ZERO,
                aa: -d,
                lb: DVec3::ZERO,
                ab: d,
                c: angle,
                jdv: 0.0,
                kind: RowKind::Equality,
            };
        }
        if let JointKind::Hinge { limits: Some((lo, hi)), .. } = self.kind {
            let (t, u) = Self::angle(&a, &b);
            for (k, sign, c) in [(2, 1.0, t - lo), (3, -1.0, hi - t)] {
                if c < 0.0 {
                    out[k] = Row {
                        la: DVec3::ZERO,
                        aa: -sign * u,
                        lb: DVec3::ZERO,
                        ab: sign * u,
                        c,
                        jdv: 0.0,
                        kind: RowKind::Limit,
                    };
                }
            }
        }
    }

    /// The world axis about which the joint leaves the bodies free to turn at state `s` (the
    /// hinge axis of `a`), or `None` when every relative rotation is constrained (slider,
    /// fixed) or none is (ball).
    pub fn free_axis(&self, s: &Kinematics<'_>) -> Option<DVec3> {
        match self.kind {
            JointKind::Hinge { .. } => Some(self.sides(s).0.f * DVec3::X),
            _ => None,
        }
    }

    /// Position error of the joint at state `s`: the distance between the anchors (m; for a
    /// slider, from the anchor of `a` to the line through `b`'s anchor along the axis) and the
    /// angle of the relative rotation the joint forbids (rad; between the axes for a hinge,
    /// the whole relative rotation for a slider or a fixed joint, 0 for a ball).
    pub fn violation(&self, s: &Kinematics<'_>) -> (f64, f64) {
        let (a, b) = self.sides(s);
        let mut e = b.p - a.p;
        let ua = a.f * DVec3::X;
        if self.kind == JointKind::Slider {
            let ub = b.f * DVec3::X;
            e -= e.dot(ub) * ub;
        }
        let angle = match self.kind {
            JointKind::Ball => 0.0,
            JointKind::Hinge { .. } => {
                let ub = b.f * DVec3::X;
                ua.cross(ub).length().atan2(ua.dot(ub))
            }
            JointKind::Slider | JointKind::Fixed => rotation_vector(b.f * a.f.conjugate()).length(),
        };
        (e.length(), angle)
    }

    /// The joint's coordinate and its rate: the hinge angle (rad) and angular velocity of `b`
    /// relative to `a` about the axis (rad/s), the slider's displacement of `b` relative to `a`
    /// along the axis from creation (m) and its rate (m/s); zeros for ball and fixed joints.
    pub fn coordinate(&self, s: &Kinematics<'_>) -> (f64, f64) {
        let (a, b) = self.sides(s);
        match self.kind {
            JointKind::Hinge { .. } => {
                let (t, u) = Self::angle(&a, &b);
                (t, (b.w - a.w).dot(u))
            }
            JointKind::Slider => {
                // s = u · (pb − pa) with u turning with b.
                let u = b.f * DVec3::X;
                let d = b.p - a.p;
                let dd = (b.v + b.w.cross(b.r)) - (a.v + a.w.cross(a.r));
                (u.dot(d), b.w.cross(u).dot(d) + u.dot(dd))
            }
            JointKind::Ball | JointKind::Fixed => (0.0, 0.0),
        }
    }
}

/// Rotation vector (axis × angle, rad) of a unit quaternion, taking the shorter arc.
pub(crate) fn rotation_vector(q: DQuat) -> DVec3 {
    let q = if q.w < 0.0 { -q } else { q };
    let v = DVec3::new(q.x, q.y, q.z);
    let s = v.length();
    if s < 1e-300 {
        return 2.0 * v;
    }
    v * (2.0 * s.atan2(q.w) / s)
}

impl Joint {
    /// Check a joint decoded from a snapshot against a world of `n` bodies: the bodies exist
    /// and differ, anchors are finite, frames are unit quaternions, limits, motor, stiffness
    /// and damping are in the ranges [`Joint::new`] accepts.
    pub fn validate(&self, n: usize) -> Result<()> {
        let unit = |q: DQuat| q.is_finite() && (q.length() - 1.0).abs() < 1e-6;
        let mut ok = self.a < n
            && self.b.is_none_or(|b| b < n && b != self.a)
            && self.ra.is_finite()
            && self.rb.is_finite()
            && unit(self.fa)
            && unit(self.fb)
            && self.stiffness.is_finite()
            && self.stiffness >= 0.0
            && self.damping.is_finite()
            && self.damping >= 0.0;
        if let JointKind::Hinge { limits, motor } = self.kind {
            ok &= limits
                .is_none_or(|(lo, hi)| lo.is_finite() && hi.is_finite() && lo <= 0.0 && hi >= 0.0);
            ok &= motor.is_none_or(|m| m.speed.is_finite() && m.max_torque >= 0.0);
        }
        if ok {
            Ok(())
        } else {
            Err(Error::invalid("joints", "a joint with bodies out of range or invalid parameters"))
        }
    }
}
