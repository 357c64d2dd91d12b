//! The four joint formulations as functions over the world's arrays: penalty forces, the
//! Lagrange multiplier system (faer sparse Cholesky, pattern built once), sequential impulses
//! with a position pass, and the XPBD projection. The equations are in the module docs of
//! [`joint`](super::joint) and in `docs/rigid.md`.

use super::joint::{Joint, JointKind, JointMethod, Kinematics, Row, RowKind, SLOTS};
use crate::error::{Error, Result};
use crate::linalg::SparseCholesky;
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
fn add_force(j: &Joint, r: &Row, lambda: f64, force: &mut [DVec3], torque: &mut [DVec3]) {
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

/// How a row of the multiplier system takes part in the current solve.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
enum Activity {
    /// Solved for.
    Active,
    /// Left out (`λ = 0`).
    Off,
    /// Held at a bound: a known force (a motor at its torque limit).
    Clamped(f64),
}

/// The multiplier system `J M⁻¹ Jᵀ λ = b` of the joints using [`JointMethod::Lagrange`]: the
/// rows that can take part (the used slots of those joints), the lower-triangle pattern of
/// rows sharing a body, its symbolic factorisation, and every workspace of the solve.
#[derive(Debug, Default)]
pub(crate) struct Multipliers {
    /// The pattern (lower triangle, compressed columns), kept to rebuild the factorisation of
    /// a clone.
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Global row (`joint · SLOTS + slot`) and joint of each matrix row.
    map: Vec<(usize, usize)>,
    /// `(value index, matrix row k, matrix row l, body)`: row k's block on `body` times row
    /// l's, for `l ≥ k`.
    contributions: Vec<(usize, usize, usize, usize)>,
    diagonal: Vec<usize>,
    values: Vec<f64>,
    rhs: Vec<f64>,
    lambda: Vec<f64>,
    activity: Vec<Activity>,
    /// Not cloned: rebuilt by `solve_rhs` (same pattern, same factor).
    chol: Option<SparseCholesky>,
    acc: Vec<DVec3>,
    alpha: Vec<DVec3>,
}

impl Clone for Multipliers {
    fn clone(&self) -> Self {
        Multipliers {
            col_ptr: self.col_ptr.clone(),
            row_idx: self.row_idx.clone(),
            map: self.map.clone(),
            contributions: self.contributions.clone(),
            diagonal: self.diagonal.clone(),
            values: self.values.clone(),
            rhs: self.rhs.clone(),
            lambda: self.lambda.clone(),
            activity: self.activity.clone(),
            chol: None,
            acc: self.acc.clone(),
            alpha: self.alpha.clone(),
        }
    }
}

/// Rounds of the active-set loop at most (limits switching off, motors hitting their bounds).
const ACTIVE_SET_ROUNDS: usize = 4;

fn block(j: &Joint, r: &Row, body: usize) -> (DVec3, DVec3) {
    if body == j.a {
        (r.la, r.aa)
    } else {
        (r.lb, r.ab)
    }
}

fn slot_used(j: &Joint, k: usize) -> bool {
    match j.kind {
        JointKind::Hinge { limits, motor } => {
            k < 5 || (limits.is_some() && (k == 5 || k == 6)) || (motor.is_some() && k == 7)
        }
        _ => k < j.slots(),
    }
}

impl Multipliers {
    /// Build the pattern and symbolic factorisation for the Lagrange joints of `joints` in a
    /// world of `n` bodies.
    pub fn build(&mut self, joints: &[Joint], n: usize) -> Result<()> {
        self.map.clear();
        let mut rows_of_body: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (ji, j) in joints.iter().enumerate() {
            if j.method != JointMethod::Lagrange {
                continue;
            }
            for k in (0..SLOTS).filter(|&k| slot_used(j, k)) {
                let row = self.map.len();
                self.map.push((ji * SLOTS + k, ji));
                rows_of_body[j.a].push(row);
                if let Some(b) = j.b {
                    rows_of_body[b].push(row);
                }
            }
        }
        let m = self.map.len();
        let mut entries = Vec::new();
        for (body, rows) in rows_of_body.iter().enumerate() {
            for &k in rows {
                for &l in rows.iter().filter(|&&l| l >= k) {
                    entries.push((k, l, body));
                }
            }
        }
        let mut pattern: Vec<(usize, usize)> = entries.iter().map(|&(k, l, _)| (k, l)).collect();
        pattern.extend((0..m).map(|k| (k, k)));
        pattern.sort_unstable();
        pattern.dedup();
        let mut col_ptr = vec![0usize; m + 1];
        for &(k, _) in &pattern {
            col_ptr[k + 1] += 1;
        }
        for k in 0..m {
            col_ptr[k + 1] += col_ptr[k];
        }
        let row_idx: Vec<usize> = pattern.iter().map(|&(_, l)| l).collect();
        let index = |k: usize, l: usize| pattern.binary_search(&(k, l)).expect("entry in pattern");
        self.contributions = entries.iter().map(|&(k, l, b)| (index(k, l), k, l, b)).collect();
        self.diagonal = (0..m).map(|k| index(k, k)).collect();
        self.values = vec![0.0; pattern.len()];
        self.rhs = vec![0.0; m];
        self.lambda = vec![0.0; m];
        self.activity = vec![Activity::Active; m];
        self.acc = vec![DVec3::ZERO; n];
        self.alpha = vec![DVec3::ZERO; n];
        self.chol = if m > 0 {
            Some(SparseCholesky::new(m, col_ptr.clone(), row_idx.clone())?)
        } else {
            None
        };
        self.col_ptr = col_ptr;
        self.row_idx = row_idx;
        Ok(())
    }

    /// Factorise the assembled `values` and solve for `lambda` with the right-hand side `rhs`;
    /// `false` when there is no system. The symbolic analysis is redone first if missing (in a
    /// clone, which does not carry faer's structure; rebuilt identically).
    fn solve_rhs(&mut self) -> Result<bool> {
        if self.chol.is_none() && !self.map.is_empty() {
            let m = self.map.len();
            self.chol = Some(SparseCholesky::new(m, self.col_ptr.clone(), self.row_idx.clone())?);
        }
        let Some(chol) = self.chol.as_mut() else { return Ok(false) };
        chol.factorize(&self.values)?;
        self.lambda.copy_from_slice(&self.rhs);
        chol.solve_in_place(&mut self.lambda);
        Ok(true)
    }

    /// Fill the values of `J M⁻¹ Jᵀ` over the active rows (identity rows for the others, and
    /// for rows that move nothing, which are switched off), with the relative regularisation
    /// `1e-10 · max(diag, 1)` on the diagonal.
    fn assemble(&mut self, joints: &[Joint], rows: &[Row], m: &Mass<'_>, q: &[DQuat]) {
        self.values.fill(0.0);
        for &(idx, k, l, body) in &self.contributions {
            if self.activity[k] == Activity::Active && self.activity[l] == Activity::Active {
                let (jk, rk) = (&joints[self.map[k].1], &rows[self.map[k].0]);
                let (jl, rl) = (&joints[self.map[l].1], &rows[self.map[l].0]);
                let (lk, ak) = block(jk, rk, body);
                let (ll, al) = block(jl, rl, body);
                self.values[idx] +=
                    m.inv_mass[body] * lk.dot(ll) + ak.dot(m.inv_inertia(body, q[body], al));
            }
        }
        let eps = 1e-10 * self.diagonal.iter().fold(1.0_f64, |a, &d| a.max(self.values[d]));
        for (k, &d) in self.diagonal.iter().enumerate() {
            if self.activity[k] == Activity::Active && self.values[d] > 1e-300 {
                self.values[d] += eps;
            } else {
                self.values[d] = 1.0;
                if self.activity[k] == Activity::Active {
                    self.activity[k] = Activity::Off; // moves nothing (fixed bodies)
                }
            }
        }
    }

    /// Project the velocities onto the Lagrange joints, `J M⁻¹ Jᵀ μ = −J q̇`,
    /// `q̇ += M⁻¹ Jᵀ μ`, over the equality rows and the active limits of `rows` (evaluated at
    /// the start of the step). Used after the contacts have changed the velocities, so the
    /// contacts and the joints agree within the step.
    ///
    /// # Errors
    /// [`Error::SolverFailed`] when the factorisation fails.
    pub fn project_velocities(
        &mut self,
        joints: &[Joint],
        rows: &[Row],
        m: &Mass<'_>,
        q: &[DQuat],
        v: &mut [DVec3],
        w: &mut [DVec3],
    ) -> Result<()> {
        if self.map.is_empty() {
            return Ok(());
        }
        for (k, &(g, ji)) in self.map.iter().enumerate() {
            let r = &rows[g];
            self.activity[k] = match r.kind {
                RowKind::Equality => Activity::Active,
                RowKind::Limit if r.c <= 0.0 && rate(&joints[ji], r, v, w) < 0.0 => {
                    Activity::Active
                }
                _ => Activity::Off,
            };
        }
        self.assemble(joints, rows, m, q);
        for (k, &(g, ji)) in self.map.iter().enumerate() {
            self.rhs[k] = if self.activity[k] == Activity::Active {
                -rate(&joints[ji], &rows[g], v, w)
            } else {
                0.0
            };
        }
        if !self.solve_rhs()? {
            return Ok(());
        }
        for (k, &(g, ji)) in self.map.iter().enumerate() {
            let mu = self.lambda[k];
            if self.activity[k] == Activity::Active && mu.is_finite() {
                apply(m, &joints[ji], &rows[g], mu, q, v, w);
            }
        }
        Ok(())
    }

    /// Post-stabilisation (Cline & Pai 2003): one Newton step of the positions onto the
    /// Lagrange joints, `Δ = M⁻¹ Jᵀ μ` with `J M⁻¹ Jᵀ μ = −C`, over the equality rows and the
    /// violated limits evaluated at the end of the step (`rows`), added to `dx` (translations)
    /// and `dtheta` (small world rotations). Velocities are left alone.
    ///
    /// # Errors
    /// [`Error::SolverFailed`] when the factorisation fails.
    pub fn project(
        &mut self,
        joints: &[Joint],
        rows: &[Row],
        m: &Mass<'_>,
        q: &[DQuat],
        dx: &mut [DVec3],
        dtheta: &mut [DVec3],
    ) -> Result<()> {
        if self.map.is_empty() {
            return Ok(());
        }
        for (k, &(g, _)) in self.map.iter().enumerate() {
            let r = &rows[g];
            self.activity[k] = match r.kind {
                RowKind::Equality => Activity::Active,
                RowKind::Limit if r.c < 0.0 => Activity::Active,
                _ => Activity::Off,
            };
        }
        self.assemble(joints, rows, m, q);
        for (k, &(g, _)) in self.map.iter().enumerate() {
            self.rhs[k] = if self.activity[k] == Activity::Active { -rows[g].c } else { 0.0 };
        }
        if !self.solve_rhs()? {
            return Ok(());
        }
        for (k, &(g, ji)) in self.map.iter().enumerate() {
            let mu = self.lambda[k];
            if self.activity[k] != Activity::Active || !mu.is_finite() {
                continue;
            }
            apply(m, &joints[ji], &rows[g], mu, q, dx, dtheta);
        }
        Ok(())
    }

    /// Solve for the multipliers of the Lagrange joints and add their forces `Jᵀ λ` to `force`
    /// and `torque`.
    ///
    /// `rows` holds every joint's rows evaluated at the start of the step; `acc_free` and
    /// `alpha_free` are each body's accelerations without the joints (m/s², rad/s², world,
    /// gyroscopic term included). Equality rows ask for `J a = −½ J̇ q̇ − k_d Ċ − k_s C` with
    /// `k_d = 1/h`, `k_s = β/h²`: for the semi-implicit step (`v' = v + h a`, `x' = x + h v'`)
    /// this makes the end-of-step velocity satisfy `J v' = −β C/h − ½ h J̇ q̇`, which cancels
    /// `C(x')` to second order in `h` (the whole `J̇ q̇` overshoots by a factor two and made a
    /// chain at 60 Hz blow up); a limit row that would be crossed within the step asks for
    /// the velocity `−C/h` (or `−β C/h` once past) by the end of it and is dropped when its
    /// multiplier would pull; a motor asks for `Ċ = speed` by the end of the step and is held
    /// at `±max_torque` when it would need more (an active-set loop of a few rounds).
    ///
    /// # Errors
    /// [`Error::SolverFailed`] when the factorisation fails.
    #[allow(clippy::too_many_arguments)]
    pub fn solve(
        &mut self,
        joints: &[Joint],
        rows: &[Row],
        m: &Mass<'_>,
        s: &Kinematics<'_>,
        acc_free: &[DVec3],
        alpha_free: &[DVec3],
        h: f64,
        beta: f64,
        force: &mut [DVec3],
        torque: &mut [DVec3],
    ) -> Result<()> {
        if self.map.is_empty() {
            return Ok(());
        }
        let (ks, kd) = (beta / (h * h), 1.0 / h);
        for (k, &(g, ji)) in self.map.iter().enumerate() {
            let r = &rows[g];
            let j = &joints[ji];
            self.activity[k] = match r.kind {
                RowKind::Inactive => Activity::Off,
                RowKind::Limit if r.c + h * rate(j, r, s.v, s.w) > 0.0 => Activity::Off,
                _ => Activity::Active,
            };
        }
        for _ in 0..ACTIVE_SET_ROUNDS {
            // Accelerations without the solved rows: free ones plus the clamped motors'.
            self.acc.clear();
            self.acc.extend_from_slice(acc_free);
            self.alpha.clear();
            self.alpha.extend_from_slice(alpha_free);
            for (k, &(g, ji)) in self.map.iter().enumerate() {
                if let Activity::Clamped(l) = self.activity[k] {
                    let (j, r) = (&joints[ji], &rows[g]);
                    self.acc[j.a] += r.la * (l * m.inv_mass[j.a]);
                    self.alpha[j.a] += m.inv_inertia(j.a, s.q[j.a], r.aa * l);
                    if let Some(b) = j.b {
                        self.acc[b] += r.lb * (l * m.inv_mass[b]);
                        self.alpha[b] += m.inv_inertia(b, s.q[b], r.ab * l);
                    }
                }
            }
            self.assemble(joints, rows, m, s.q);
            for (k, &(g, ji)) in self.map.iter().enumerate() {
                let (j, r) = (&joints[ji], &rows[g]);
                if self.activity[k] != Activity::Active {
                    self.rhs[k] = 0.0;
                    continue;
                }
                let cdot = rate(j, r, s.v, s.w);
                let target = match r.kind {
                    RowKind::Equality => -0.5 * r.jdv - kd * cdot - ks * r.c,
                    RowKind::Limit => {
                        let v_end = if r.c > 0.0 { -r.c / h } else { -beta * r.c / h };
                        (v_end - cdot) / h
                    }
                    RowKind::Motor { speed, .. } => (speed - cdot) / h,
                    RowKind::Inactive => 0.0,
                };
                let mut ja = r.la.dot(self.acc[j.a]) + r.aa.dot(self.alpha[j.a]);
                if let Some(b) = j.b {
                    ja += r.lb.dot(self.acc[b]) + r.ab.dot(self.alpha[b]);
                }
                self.rhs[k] = target - ja;
            }
            if !self.solve_rhs()? {
                return Ok(());
            }
            if let Some(k) = self.lambda.iter().position(|l| !l.is_finite()) {
                return Err(Error::SolverFailed {
                    reason: format!("joint multiplier {k} is not finite"),
                });
            }
            let mut changed = false;
            for (k, &(g, _)) in self.map.iter().enumerate() {
                if self.activity[k] != Activity::Active {
                    continue;
                }
                let l = self.lambda[k];
                match rows[g].kind {
                    RowKind::Limit if l < 0.0 => {
                        self.activity[k] = Activity::Off;
                        changed = true;
                    }
                    RowKind::Motor { max, .. } if l.abs() > max => {
                        self.activity[k] = Activity::Clamped(max.copysign(l));
                        changed = true;
                    }
                    _ => {}
                }
            }
            if !changed {
                break;
            }
        }
        for (k, &(g, ji)) in self.map.iter().enumerate() {
            let l = match self.activity[k] {
                Activity::Active => self.lambda[k],
                Activity::Clamped(l) => l,
                Activity::Off => continue,
            };
            add_force(&joints[ji], &rows[g], l, force, torque);
        }
        Ok(())
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
