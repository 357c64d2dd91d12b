//! Constrained particle dynamics with Lagrange multipliers (Witkin, "Constrained dynamics",
//! in Witkin & Baraff, *Physically Based Modeling*, SIGGRAPH course notes).
//!
//! Each constraint `C(x) = 0` supplies its value, its Jacobian `J = ∂C/∂x` and the product
//! `J̇ q̇`. Requiring the constraint acceleration to vanish, with Baumgarte-style feedback on the
//! drift, gives the multipliers from
//!
//! `J W Jᵀ λ = -J̇ q̇ - J W Q - k_s C - k_d Ċ`,
//!
//! (`W` the inverse masses, `Q` the applied forces) and the constraint force `Q̂ = Jᵀ λ`, which
//! does no work on any legal velocity (`J q̇ = 0`). The matrix `J W Jᵀ` is sparse (rows couple
//! only when their constraints share a particle); it is solved by a faer sparse Cholesky whose
//! pattern and symbolic analysis are computed once, or by Jacobi-preconditioned conjugate
//! gradient. A relative regularisation `ε = 1e-10 · max(diag, 1)` on the diagonal makes
//! redundant or conflicting constraints solvable (the least-norm compromise) instead of a
//! failure.
//!
//! The constrained equations are integrated by any method of [`crate::ode`]; colliders and
//! emitters of the particle system are not applied in a constrained step.

use crate::error::{Error, Result};
use crate::linalg::{conjugate_gradient, SparseCholesky};
use crate::ode::{Method, OdeSystem, Stepper};
use crate::particles::ParticleSystem;
use glam::DVec3;

/// Position projections per [`ConstrainedSystem::step_projection`] step, at most.
pub const PROJECTION_ITERATIONS: usize = 30;
/// Largest `|C|` (m) at which the position projection stops early.
pub const PROJECTION_TOL: f64 = 1e-10;

/// A holonomic constraint on particles.
#[derive(Clone, Debug, PartialEq)]
pub enum Constraint {
    /// `|x_i - x_j| - length = 0` (a rod).
    Distance {
        /// First particle.
        i: usize,
        /// Second particle.
        j: usize,
        /// Rod length (m) > 0.
        length: f64,
    },
    /// `|x_i - center| - radius = 0` (a bead on a sphere, or on a circle in a plane).
    OnSphere {
        /// Particle.
        i: usize,
        /// Centre (m).
        center: DVec3,
        /// Radius (m) > 0.
        radius: f64,
    },
    /// `n · (x_i - point) = 0`.
    OnPlane {
        /// Particle.
        i: usize,
        /// A point of the plane (m).
        point: DVec3,
        /// Normal (normalised here).
        normal: DVec3,
    },
    /// `x_i - point = 0` (three rows).
    Fixed {
        /// Particle.
        i: usize,
        /// Position (m).
        point: DVec3,
    },
}

impl Constraint {
    fn rows(&self) -> usize {
        if matches!(self, Constraint::Fixed { .. }) {
            3
        } else {
            1
        }
    }

    fn particles(&self) -> [Option<usize>; 2] {
        match *self {
            Constraint::Distance { i, j, .. } => [Some(i), Some(j)],
            Constraint::OnSphere { i, .. }
            | Constraint::OnPlane { i, .. }
            | Constraint::Fixed { i, .. } => [Some(i), None],
        }
    }
}

/// One row of `J`: up to two particle blocks, with `C`, `Ċ` and `J̇ q̇`.
#[derive(Clone, Copy, Debug, Default)]
struct Row {
    blocks: [(usize, DVec3); 2],
    count: usize,
    c: f64,
    cdot: f64,
    jdot_qdot: f64,
}

/// Which linear solver computes the multipliers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConstraintSolver {
    /// faer sparse Cholesky (pattern analysed once).
    Cholesky,
    /// Jacobi-preconditioned conjugate gradient to relative residual 1e-12.
    ConjugateGradient,
}

/// Constraints on the particles of a [`ParticleSystem`], stepped with the system's forces.
pub struct ConstrainedSystem {
    constraints: Vec<Constraint>,
    /// Feedback stiffness `k_s` on the drift `C` (1/s²).
    pub ks: f64,
    /// Feedback damping `k_d` on `Ċ` (1/s).
    pub kd: f64,
    solver: ConstraintSolver,
    work: Work,
    stepper: Option<Stepper>,
}

/// Workspaces of the multiplier solve, sized when the constraints change.
#[derive(Default)]
struct Work {
    rows: Vec<Row>,
    b: Vec<f64>,
    lambda: Vec<f64>,
    diag: Vec<f64>,
    scratch: Vec<f64>,
    cg: [Vec<f64>; 4],
    chol: Option<SparseCholesky>,
    values: Vec<f64>,
    /// (value index, row r, row s, particle) per contribution w_p J_rp · J_sp.
    contributions: Vec<(usize, usize, usize, usize)>,
    diagonal_index: Vec<usize>,
    iterations: usize,
}

impl std::fmt::Debug for ConstrainedSystem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "ConstrainedSystem({} constraints, ks = {}, kd = {})",
            self.constraints.len(),
            self.ks,
            self.kd
        )
    }
}

impl ConstrainedSystem {
    /// No constraints yet; feedback gains `ks`, `kd` (0 turns feedback off).
    ///
    /// # Errors
    /// Negative or non-finite gains.
    pub fn new(ks: f64, kd: f64, solver: ConstraintSolver) -> Result<Self> {
        if !(ks.is_finite() && kd.is_finite() && ks >= 0.0 && kd >= 0.0) {
            return Err(Error::invalid("ks", "feedback gains must be finite and >= 0"));
        }
        Ok(ConstrainedSystem {
            constraints: Vec::new(),
            ks,
            kd,
            solver,
            work: Work::default(),
            stepper: None,
        })
    }

    /// The constraints, in the order added.
    pub fn constraints(&self) -> &[Constraint] {
        &self.constraints
    }

    /// Conjugate-gradient iterations of the last multiplier solve (0 with Cholesky).
    pub fn iterations(&self) -> usize {
        self.work.iterations
    }

    /// Add a constraint on `particles`.
    ///
    /// # Errors
    /// Indices out of range, a distance constraint between a particle and itself or between
    /// particles that currently coincide (no direction), non-positive lengths or radii, zero
    /// normals, non-finite values.
    pub fn add(&mut self, particles: &ParticleSystem, constraint: Constraint) -> Result<()> {
        let n = particles.capacity();
        let pos = |i: usize| DVec3::from_slice(&particles.positions()[3 * i..]);
        for p in constraint.particles().into_iter().flatten() {
            if p >= n {
                return Err(Error::invalid(
                    "i",
                    format!("particle {p} out of range ({n} particles)"),
                ));
            }
        }
        let constraint = match constraint {
            Constraint::Distance { i, j, length } => {
                if i == j {
                    return Err(Error::invalid(
                        "j",
                        "a distance constraint needs two different particles",
                    ));
                }
                if !(length.is_finite() && length > 0.0) {
                    return Err(Error::invalid(
                        "length",
                        format!("must be positive and finite, got {length}"),
                    ));
                }
                if pos(i) == pos(j) {
                    return Err(Error::invalid(
                        "j",
                        format!("particles {i} and {j} coincide; the rod has no direction"),
                    ));
                }
                constraint
            }
            Constraint::OnSphere { center, radius, .. } => {
                if !(center.is_finite() && radius.is_finite() && radius > 0.0) {
                    return Err(Error::invalid(
                        "radius",
                        format!("must be positive with a finite centre, got {radius}"),
                    ));
                }
                constraint
            }
            Constraint::OnPlane { i, point, normal } => {
                if !(point.is_finite() && normal.is_finite() && normal.length() > 0.0) {
                    return Err(Error::invalid("normal", "must be a finite non-zero vector"));
                }
                Constraint::OnPlane { i, point, normal: normal.normalize() }
            }
            Constraint::Fixed { point, .. } => {
                if !point.is_finite() {
                    return Err(Error::invalid("point", "contains NaN or infinity"));
                }
                constraint
            }
        };
        self.constraints.push(constraint);
        self.work.chol = None; // the pattern changed
        self.stepper = None;
        Ok(())
    }

    /// Largest `|C|` and `|Ċ|` over all constraint rows at the particles' current state.
    pub fn violation(&mut self, particles: &ParticleSystem) -> (f64, f64) {
        let n = particles.capacity();
        let mut y = particles.positions().to_vec();
        y.extend_from_slice(particles.velocities());
        evaluate(&self.constraints, &y, n, &mut self.work.rows);
        self.work.rows.iter().fold((0.0, 0.0), |(a, b), r| (a.max(r.c.abs()), b.max(r.cdot.abs())))
    }

    /// The constraint forces `Jᵀ λ` (N, world frame) on every particle at the current state,
    /// as used by the next step.
    ///
    /// # Errors
    /// A solver failure.
    pub fn constraint_forces(&mut self, particles: &mut ParticleSystem) -> Result<Vec<DVec3>> {
        let n = particles.capacity();
        self.prepare(n)?;
        let (mut system, y, time) =
            assemble(&self.constraints, self.ks, self.kd, self.solver, &mut self.work, particles);
        let mut dydt = vec![0.0; 6 * n];
        system.rhs(*time, y, &mut dydt)?;
        let mut forces = vec![DVec3::ZERO; n];
        for (r, row) in self.work.rows.iter().enumerate() {
            for &(p, g) in &row.blocks[..row.count] {
                forces[p] += self.work.lambda[r] * g;
            }
        }
        Ok(forces)
    }

    fn prepare(&mut self, n: usize) -> Result<()> {
        if self.work.chol.is_none() && self.solver == ConstraintSolver::Cholesky {
            self.build_pattern(n)?;
        }
        let m: usize = self.constraints.iter().map(Constraint::rows).sum();
        for v in [&mut self.work.b, &mut self.work.lambda, &mut self.work.diag] {
            v.resize(m, 0.0);
        }
        self.work.scratch.resize(3 * n, 0.0);
        Ok(())
    }

    /// Advance the particles `steps` steps of `dt` with constraints enforced at the velocity
    /// level (impulses), the formulation of rigid-body engines: `v* = v + h W Q`, then
    /// `J W Jᵀ λ = -J v*`, `v₁ = v* + W Jᵀ λ`, `x₁ = x + h v₁`, followed by up to
    /// [`PROJECTION_ITERATIONS`] Gauss–Newton projections of the positions onto `C = 0`
    /// (post-stabilisation, Cline & Pai 2003). First order and dissipative, but stable at large
    /// steps where the acceleration-level formulation with an explicit integrator is not (a
    /// rope of short rods at 1/60 s).
    ///
    /// # Errors
    /// A bad `dt`, a solver failure or a non-finite state; the particles are left at the last
    /// good step.
    pub fn step_projection(
        &mut self,
        particles: &mut ParticleSystem,
        dt: f64,
        steps: usize,
    ) -> Result<()> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid("dt", format!("must be positive and finite, got {dt}")));
        }
        let n = particles.capacity();
        self.prepare(n)?;
        let mut next = vec![0.0; 6 * n];
        let (mut system, y, time) =
            assemble(&self.constraints, 0.0, 0.0, self.solver, &mut self.work, particles);
        for s in 0..steps {
            // next = [v; a_free]; v* = v + h a_free.
            system.free.rhs(*time, y, &mut next)?;
            for k in 0..3 * n {
                next[3 * n + k] = y[3 * n + k] + dt * next[3 * n + k];
            }
            evaluate(system.constraints, y, n, &mut system.work.rows);
            let w = &mut *system.work;
            for (r, row) in w.rows.iter().enumerate() {
                let jv: f64 = row.blocks[..row.count]
                    .iter()
                    .map(|&(p, g)| g.dot(DVec3::from_slice(&next[3 * n + 3 * p..])))
                    .sum();
                w.b[r] = -jv;
            }
            system.solve_multipliers()?;
            let w = &mut *system.work;
            for (r, row) in w.rows.iter().enumerate() {
                for &(p, g) in &row.blocks[..row.count] {
                    let dv = system.inv_mass[p] * w.lambda[r] * g;
                    for k in 0..3 {
                        next[3 * n + 3 * p + k] += dv[k];
                    }
                }
            }
            for k in 0..3 * n {
                next[k] = y[k] + dt * next[3 * n + k];
            }
            // Post-stabilisation (Cline & Pai 2003): Gauss–Newton projection of the positions
            // back onto C = 0, mass-weighted: (J W Jᵀ) δ = -C, x += W Jᵀ δ.
            for _ in 0..PROJECTION_ITERATIONS {
                evaluate(system.constraints, &next, n, &mut system.work.rows);
                let w = &mut *system.work;
                let worst = w.rows.iter().fold(0.0_f64, |a, r| a.max(r.c.abs()));
                if worst <= PROJECTION_TOL {
                    break;
                }
                for (r, row) in w.rows.iter().enumerate() {
                    w.b[r] = -row.c;
                }
                system.solve_multipliers()?;
                let w = &mut *system.work;
                for (r, row) in w.rows.iter().enumerate() {
                    for &(p, g) in &row.blocks[..row.count] {
                        let dx = system.inv_mass[p] * w.lambda[r] * g;
                        for k in 0..3 {
                            next[3 * p + k] += dx[k];
                        }
                    }
                }
            }
            if let Some(bad) = next.iter().position(|v| !v.is_finite()) {
                return Err(Error::Diverged {
                    step: s,
                    index: (bad % (3 * n)) / 3,
                    reason: "non-finite state in the constraint projection".into(),
                });
            }
            y.copy_from_slice(&next);
            *time += dt;
        }
        Ok(())
    }

    /// Advance the particles `steps` steps of `dt` with `method`, constrained.
    ///
    /// # Errors
    /// A bad `dt`, a solver failure or a non-finite state; the particles are left at the last
    /// good step.
    pub fn step(
        &mut self,
        particles: &mut ParticleSystem,
        dt: f64,
        steps: usize,
        method: Method,
    ) -> Result<()> {
        let n = particles.capacity();
        if self.stepper.as_ref().is_none_or(|s| s.method() != method) {
            self.stepper = Some(Stepper::new(method, 6 * n)?);
        }
        self.prepare(n)?;
        let stepper = self.stepper.as_mut().expect("created above");
        let (mut system, y, time) =
            assemble(&self.constraints, self.ks, self.kd, self.solver, &mut self.work, particles);
        for s in 0..steps {
            stepper.step(&mut system, *time, y, dt).map_err(|e| match e {
                Error::Diverged { index, reason, .. } => {
                    Error::Diverged { step: s, index: (index % (3 * n)) / 3, reason }
                }
                other => other,
            })?;
            *time += dt;
        }
        Ok(())
    }

    /// The pattern of `J W Jᵀ` (rows sharing a particle), its symbolic factorisation, and the
    /// list of contributions that refill its values.
    fn build_pattern(&mut self, n: usize) -> Result<()> {
        let mut row_of_particle: Vec<Vec<usize>> = vec![Vec::new(); n];
        let mut r = 0;
        for c in &self.constraints {
            for _ in 0..c.rows() {
                for p in c.particles().into_iter().flatten() {
                    row_of_particle[p].push(r);
                }
                r += 1;
            }
        }
        let m = r;
        let mut entries: Vec<(usize, usize, usize)> = Vec::new(); // (col s, row r >= s, particle)
        for (p, rows) in row_of_particle.iter().enumerate() {
            for &a in rows {
                for &b in rows {
                    if a >= b {
                        entries.push((b, a, p));
                    }
                }
            }
        }
        let mut pattern: Vec<(usize, usize)> = entries.iter().map(|&(s, r, _)| (s, r)).collect();
        pattern.extend((0..m).map(|k| (k, k)));
        pattern.sort_unstable();
        pattern.dedup();
        let mut col_ptr = vec![0usize; m + 1];
        for &(s, _) in &pattern {
            col_ptr[s + 1] += 1;
        }
        for k in 0..m {
            col_ptr[k + 1] += col_ptr[k];
        }
        let row_idx: Vec<usize> = pattern.iter().map(|&(_, r)| r).collect();
        let index = |s: usize, r: usize| pattern.binary_search(&(s, r)).expect("entry in pattern");
        self.work.contributions = entries.iter().map(|&(s, r, p)| (index(s, r), r, s, p)).collect();
        self.work.diagonal_index = (0..m).map(|k| index(k, k)).collect();
        self.work.values = vec![0.0; pattern.len()];
        self.work.chol = Some(SparseCholesky::new(m, col_ptr, row_idx)?);
        Ok(())
    }
}

/// The constrained equations of motion over `particles`, with the particle state and clock.
fn assemble<'a>(
    constraints: &'a [Constraint],
    ks: f64,
    kd: f64,
    solver: ConstraintSolver,
    work: &'a mut Work,
    particles: &'a mut ParticleSystem,
) -> (Constrained<'a>, &'a mut [f64], &'a mut f64) {
    let (free, y, inv_mass, time) = particles.parts();
    (Constrained { free, constraints, inv_mass, ks, kd, solver, work }, y, time)
}

/// Evaluate every constraint row at `y = [x; v]`.
fn evaluate(constraints: &[Constraint], y: &[f64], n: usize, rows: &mut Vec<Row>) {
    rows.clear();
    let x = |i: usize| DVec3::from_slice(&y[3 * i..]);
    let v = |i: usize| DVec3::from_slice(&y[3 * n + 3 * i..]);
    for c in constraints {
        match *c {
            Constraint::Distance { i, j, length } => {
                let d = x(i) - x(j);
                let len = d.length();
                let dir = if len > 0.0 { d / len } else { DVec3::X };
                let vij = v(i) - v(j);
                let along = dir.dot(vij);
                let jdot =
                    if len > 0.0 { (vij.length_squared() - along * along) / len } else { 0.0 };
                rows.push(Row {
                    blocks: [(i, dir), (j, -dir)],
                    count: 2,
                    c: len - length,
                    cdot: along,
                    jdot_qdot: jdot,
                });
            }
            Constraint::OnSphere { i, center, radius } => {
                let d = x(i) - center;
                let len = d.length();
                let dir = if len > 0.0 { d / len } else { DVec3::X };
                let along = dir.dot(v(i));
                let jdot =
                    if len > 0.0 { (v(i).length_squared() - along * along) / len } else { 0.0 };
                rows.push(Row {
                    blocks: [(i, dir), (0, DVec3::ZERO)],
                    count: 1,
                    c: len - radius,
                    cdot: along,
                    jdot_qdot: jdot,
                });
            }
            Constraint::OnPlane { i, point, normal } => {
                rows.push(Row {
                    blocks: [(i, normal), (0, DVec3::ZERO)],
                    count: 1,
                    c: normal.dot(x(i) - point),
                    cdot: normal.dot(v(i)),
                    jdot_qdot: 0.0,
                });
            }
            Constraint::Fixed { i, point } => {
                for k in 0..3 {
                    let e = DVec3::AXES[k];
                    rows.push(Row {
                        blocks: [(i, e), (0, DVec3::ZERO)],
                        count: 1,
                        c: x(i)[k] - point[k],
                        cdot: v(i)[k],
                        jdot_qdot: 0.0,
                    });
                }
            }
        }
    }
}

impl Constrained<'_> {
    /// Solve `(J W Jᵀ + εI) λ = b` for the rows and right-hand side in the workspace.
    fn solve_multipliers(&mut self) -> Result<()> {
        let inv_mass = self.inv_mass;
        let w = &mut *self.work;
        for (r, row) in w.rows.iter().enumerate() {
            w.diag[r] = row.blocks[..row.count]
                .iter()
                .map(|&(p, g)| inv_mass[p] * g.length_squared())
                .sum();
        }
        let eps = 1e-10 * w.diag.iter().fold(1.0_f64, |a, &b| a.max(b));
        match self.solver {
            ConstraintSolver::Cholesky => {
                w.values.fill(0.0);
                for &(idx, r, s, p) in &w.contributions {
                    let gr = w.rows[r].blocks[..w.rows[r].count]
                        .iter()
                        .find(|b| b.0 == p)
                        .map_or(DVec3::ZERO, |b| b.1);
                    let gs = w.rows[s].blocks[..w.rows[s].count]
                        .iter()
                        .find(|b| b.0 == p)
                        .map_or(DVec3::ZERO, |b| b.1);
                    w.values[idx] += inv_mass[p] * gr.dot(gs);
                }
                for &k in &w.diagonal_index {
                    w.values[k] += eps;
                }
                let chol = w.chol.as_mut().expect("pattern built before stepping");
                chol.factorize(&w.values)?;
                w.lambda.copy_from_slice(&w.b);
                chol.solve_in_place(&mut w.lambda);
                w.iterations = 0;
            }
            ConstraintSolver::ConjugateGradient => {
                let (rows, scratch) = (&w.rows, &mut w.scratch);
                let mut apply = |x: &[f64], out: &mut [f64]| {
                    // out = (J W Jᵀ + εI) x, matrix-free.
                    scratch.fill(0.0);
                    for (r, row) in rows.iter().enumerate() {
                        for &(p, g) in &row.blocks[..row.count] {
                            for k in 0..3 {
                                scratch[3 * p + k] += g[k] * x[r];
                            }
                        }
                    }
                    for (r, row) in rows.iter().enumerate() {
                        out[r] = eps * x[r]
                            + row.blocks[..row.count]
                                .iter()
                                .map(|&(p, g)| {
                                    inv_mass[p] * g.dot(DVec3::from_slice(&scratch[3 * p..]))
                                })
                                .sum::<f64>();
                    }
                };
                let mut pre = std::mem::take(&mut w.cg);
                let mut lambda = std::mem::take(&mut w.lambda);
                let result = conjugate_gradient(
                    &mut apply,
                    &w.b,
                    &w.diag,
                    &mut lambda,
                    1e-12,
                    10 * w.b.len() + 100,
                    &mut pre,
                );
                w.cg = pre;
                w.lambda = lambda;
                w.iterations = result?;
            }
        }
        Ok(())
    }
}

/// The constrained equations of motion as an [`OdeSystem`].
struct Constrained<'a> {
    free: crate::particles::Dynamics<'a>,
    constraints: &'a [Constraint],
    inv_mass: &'a [f64],
    ks: f64,
    kd: f64,
    solver: ConstraintSolver,
    work: &'a mut Work,
}

impl OdeSystem for Constrained<'_> {
    fn dim(&self) -> usize {
        self.free.dim()
    }

    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) -> Result<()> {
        self.free.rhs(t, y, dydt)?;
        let n = y.len() / 6;
        let w = &mut *self.work;
        evaluate(self.constraints, y, n, &mut w.rows);
        let (acc, inv_mass) = (&mut dydt[3 * n..], self.inv_mass);
        // b = -J̇q̇ - J a_free - ks C - kd Ċ.
        for (r, row) in w.rows.iter().enumerate() {
            let ja: f64 = row.blocks[..row.count]
                .iter()
                .map(|&(p, g)| g.dot(DVec3::from_slice(&acc[3 * p..])))
                .sum();
            w.b[r] = -row.jdot_qdot - ja - self.ks * row.c - self.kd * row.cdot;
        }
        self.solve_multipliers()?;
        let w = &mut *self.work;
        // a += W Jᵀ λ.
        for (r, row) in w.rows.iter().enumerate() {
            for &(p, g) in &row.blocks[..row.count] {
                let f = inv_mass[p] * w.lambda[r] * g;
                for k in 0..3 {
                    acc[3 * p + k] += f[k];
                }
            }
        }
        Ok(())
    }
}
