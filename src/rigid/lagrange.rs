//! The Lagrange multiplier formulation of the joints: the system `J M⁻¹ Jᵀ λ = b` over the
//! rows of the joints using [`JointMethod::Lagrange`], its pattern and symbolic factorisation
//! (faer sparse Cholesky) built once per set of joints, the active-set solve for the joint
//! forces, the velocity projection and the post-stabilisation (Cline & Pai 2003). The
//! equations are in the module docs of [`joint`](super::joint) and in `docs/rigid.md`.

use super::joint::{Joint, JointKind, JointMethod, Kinematics, Row, RowKind, SLOTS};
use super::joint_solver::{add_force, apply, rate, Mass};
use crate::error::{Error, Result};
use crate::linalg::SparseCholesky;
use glam::{DQuat, DVec3};

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
            self.accelerations(joints, rows, m, s.q, (acc_free, alpha_free));
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
            let changed = self.update_activity(rows);
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
    /// The accelerations without the solved rows (m/s², rad/s², world) into `acc` and
    /// `alpha`: the `free` ones (linear, angular) plus those of the motors held at their bound.
    fn accelerations(
        &mut self,
        joints: &[Joint],
        rows: &[Row],
        m: &Mass<'_>,
        q: &[DQuat],
        free: (&[DVec3], &[DVec3]),
    ) {
        self.acc.clear();
        self.acc.extend_from_slice(free.0);
        self.alpha.clear();
        self.alpha.extend_from_slice(free.1);
        for (k, &(g, ji)) in self.map.iter().enumerate() {
            if let Activity::Clamped(l) = self.activity[k] {
                let (j, r) = (&joints[ji], &rows[g]);
                self.acc[j.a] += r.la * (l * m.inv_mass[j.a]);
                self.alpha[j.a] += m.inv_inertia(j.a, q[j.a], r.aa * l);
                if let Some(b) = j.b {
                    self.acc[b] += r.lb * (l * m.inv_mass[b]);
                    self.alpha[b] += m.inv_inertia(b, q[b], r.ab * l);
                }
            }
        }
    }

    /// One round of the active-set loop of [`Multipliers::solve`]: limits whose multiplier
    /// pulls are switched off, motors beyond their torque bound are held at it; whether any
    /// row changed.
    fn update_activity(&mut self, rows: &[Row]) -> bool {
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
        changed
    }
}
