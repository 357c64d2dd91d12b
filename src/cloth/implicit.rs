//! The implicit step of the cloth (Baraff & Witkin 1998, §4–§5): implicit Euler or the
//! variable-step BDF2 of Choi & Ko (2002) share one assembly of `(M − γh ∂f/∂v − (γh)² ∂f/∂x)`
//! with history terms, solved by the modified PCG with the constraint filter (§5.3) or by
//! sparse Cholesky; a step that strains the cloth too much is redone as two half steps.

use super::*;

impl Cloth {
    /// An implicit step of `h`, redone as two half steps (recursively, at most five times)
    /// when it changes a stretch ratio by more than `options.max_strain_change`. BDF2 keeps its
    /// history through the halving: halving and the steps after it change the step by a ratio
    /// of 1/2 or 2, which the variable-step coefficients take.
    pub(super) fn step_adaptive(
        &mut self,
        h: f64,
        bdf2: bool,
        options: SolveOptions,
        depth: u32,
    ) -> Result<()> {
        const MAX_HALVINGS: u32 = 5;
        if self.step_implicit(h, bdf2, options, depth < MAX_HALVINGS)? {
            return Ok(());
        }
        self.step_adaptive(0.5 * h, bdf2, options, depth + 1)?;
        self.step_adaptive(0.5 * h, bdf2, options, depth + 1)
    }

    /// The largest change of a stretch ratio between the current positions and `x_new`.
    pub(super) fn strain_change(&self, x_new: &[DVec3]) -> f64 {
        let mut worst: f64 = 0.0;
        if self.model == Model::BaraffWitkin {
            for t in &self.elements {
                let (u0, v0) = t.warp(&self.x);
                let (u1, v1) = t.warp(x_new);
                worst = worst
                    .max((u1.length() - u0.length()).abs())
                    .max((v1.length() - v0.length()).abs());
            }
        }
        for sp in &self.springs {
            let [a, b] = sp.verts;
            let change =
                ((x_new[b] - x_new[a]).length() - (self.x[b] - self.x[a]).length()) / sp.rest;
            worst = worst.max(change.abs());
        }
        worst
    }

    /// One linearised implicit step; returns `false` (and changes nothing) when `check` is set
    /// and the step changes a stretch ratio by more than allowed.
    pub(super) fn step_implicit(
        &mut self,
        h: f64,
        bdf2: bool,
        options: SolveOptions,
        check: bool,
    ) -> Result<bool> {
        let n = self.x.len();
        let t0 = Instant::now();
        let history = if bdf2 { self.history.take() } else { None };
        // Variable-step BDF2 (Choi & Ko 2002, eq. 12, at a constant step): with (c, γ) of
        // `bdf2_weights`, x₊ = x + c (x - x₋) + γh v₊, v₊ = v + c (v - v₋) + γh M⁻¹ f₊.
        let h_eff = self.history_terms(h, history.as_ref());
        self.build_constraints(h, h_eff);
        let collide_time = t0.elapsed().as_secs_f64();

        let t1 = Instant::now();
        let mut scratch = std::mem::take(&mut self.scratch);
        self.assemble(&mut scratch, h_eff);
        let assemble_time = t1.elapsed().as_secs_f64();
        // A step so large that `h² ∂f/∂x` or `h f` overflows has no meaningful solve (at
        // dt = 1e100 the PCG would stop at once and the step would silently do nothing).
        if !(scratch.b.iter().all(|b| b.is_finite())
            && self.matrix.blocks.iter().all(|b| b.is_finite()))
        {
            self.scratch = scratch;
            self.history = history;
            return Err(Error::invalid(
                "dt",
                format!("{h} s is too large for this cloth: the implicit system overflows"),
            ));
        }

        let t2 = Instant::now();
        let solved = match options.solver {
            Solver::Pcg => self.solve_pcg(&mut scratch, options),
            Solver::Cholesky => self.solve_cholesky(&mut scratch),
        };
        let solve_time = t2.elapsed().as_secs_f64();
        let (iterations, residual, converged) = match solved {
            Ok(r) => r,
            Err(e) => {
                self.scratch = scratch;
                self.history = history;
                return Err(e);
            }
        };
        self.stats.iterations += iterations;
        self.stats.assemble_seconds += assemble_time;
        self.stats.solve_seconds += solve_time;

        // New velocities and positions.
        let t3 = Instant::now();
        for i in 0..n {
            scratch.v_new[i] = self.v[i] + scratch.dv[i];
        }
        self.contact_states(&mut scratch);
        for i in 0..n {
            scratch.x_new[i] = match self.constraints[i] {
                Some(VertexConstraint::Pinned(p)) => p,
                _ => self.x[i] + scratch.hx[i] + h_eff * scratch.v_new[i] + scratch.y[i],
            };
        }
        self.project_penetrating(&mut scratch, h);
        if check
            && options.max_strain_change.is_finite()
            && self.strain_change(&scratch.x_new) > options.max_strain_change
        {
            self.scratch = scratch;
            self.history = history;
            self.stats.collide_seconds += collide_time + t3.elapsed().as_secs_f64();
            return Ok(false);
        }
        if let Some(i) =
            (0..n).find(|&i| !(scratch.x_new[i].is_finite() && scratch.v_new[i].is_finite()))
        {
            self.scratch = scratch;
            self.history = history;
            return Err(Error::Diverged {
                step: 0,
                index: i,
                reason: "non-finite cloth state".into(),
            });
        }
        self.commit(&mut scratch, history, h);
        self.stats.residual = residual;
        self.stats.converged &= converged;
        self.stats.contacts = scratch.contact_normal.len();
        self.stats.substeps += 1;
        self.stats.collide_seconds += collide_time + t3.elapsed().as_secs_f64();
        self.scratch = scratch;
        Ok(true)
    }

    /// The BDF2 history terms `c (x - x₋)`, `c (v - v₋)` into the scratch (zero for implicit
    /// Euler or a restart), with `(c, γ)` of [`bdf2_weights`] for this step `h` and the
    /// previous one; returns the effective step `γh` (`h` for implicit Euler).
    fn history_terms(&mut self, h: f64, history: Option<&(Vec<DVec3>, Vec<DVec3>, f64)>) -> f64 {
        let weights = history.and_then(|&(_, _, hp)| bdf2_weights(h, Some(hp)));
        for i in 0..self.x.len() {
            (self.scratch.hx[i], self.scratch.hv[i]) = match (history, weights) {
                (Some((xp, vp, _)), Some((c, _))) => {
                    (c * (self.x[i] - xp[i]), c * (self.v[i] - vp[i]))
                }
                _ => (DVec3::ZERO, DVec3::ZERO),
            };
        }
        weights.map_or(h, |(_, gamma)| gamma * h)
    }

    /// Assemble `A = M - h ∂f/∂v - h² ∂f/∂x` (into the matrix) and `b = M c_v + h (f + ∂f/∂x u)`,
    /// `u = c_x + h v + y`, with `h` the effective step `h_eff` and Coulomb friction at the
    /// contacts as an explicit force.
    fn assemble(&mut self, scratch: &mut Scratch, h_eff: f64) {
        let n = self.x.len();
        for i in 0..n {
            scratch.u[i] = scratch.hx[i] + h_eff * self.v[i] + scratch.y[i];
            scratch.f[i] = (self.gravity - self.material.air_damping * self.v[i]) * self.mass[i];
            scratch.ku[i] = DVec3::ZERO;
        }
        self.matrix.blocks.iter_mut().for_each(|b| *b = DMat3::ZERO);
        let diagonal = 1.0 + h_eff * self.material.air_damping;
        for i in 0..n {
            self.matrix.blocks[i] = DMat3::from_diagonal(DVec3::splat(self.mass[i] * diagonal));
        }
        let mut blocks = std::mem::take(&mut self.matrix.blocks);
        {
            let mut acc = Accumulator {
                v: &self.v,
                f: &mut scratch.f,
                matrix: Some((&mut blocks, h_eff, h_eff * h_eff)),
                ku: Some((&scratch.u, &mut scratch.ku)),
                energy: 0.0,
            };
            self.add_elements(&self.x, &mut acc);
        }
        self.matrix.blocks = blocks;
        // Coulomb friction as an explicit force: the tangential impulse that would bring the
        // vertex to rest on the surface within the step against its momentum and gravity,
        // `p = m (v_rel + h g)` on the tangent plane, limited to `μ jₙ` — static when the limit
        // is not reached. (The stiff elastic forces stay out of it: an explicit force built
        // from them would be an explicit step of them.)
        for &(i, normal, vc, mu, jn) in &scratch.contact_normal {
            let p = self.mass[i] * (self.v[i] - vc + h_eff * self.gravity);
            let jn = jn.max(-normal.dot(p));
            let pt = p - normal * normal.dot(p);
            let len = pt.length();
            if len > 0.0 {
                scratch.f[i] -= pt * ((mu * jn).min(len) / (len * h_eff));
            }
        }
        for i in 0..n {
            scratch.b[i] = self.mass[i] * scratch.hv[i] + h_eff * (scratch.f[i] + scratch.ku[i]);
        }
    }

    /// Contact states for the next step from the constraint impulse `A Δv - b` (Baraff &
    /// Witkin §5.3): a pulling impulse releases the contact.
    fn contact_states(&self, scratch: &mut Scratch) {
        scratch.states.iter_mut().for_each(|c| *c = ContactState::Free);
        if !scratch.contact_normal.is_empty() {
            self.matrix.mul(&scratch.dv, &mut scratch.q);
        }
        for &(i, normal, ..) in &scratch.contact_normal {
            let jn = (scratch.q[i] - scratch.b[i]).dot(normal);
            scratch.states[i] =
                if jn < 0.0 { ContactState::Released } else { ContactState::Touching(jn) };
        }
    }

    /// Take the step: the state before it becomes the history (its buffers reused), the new
    /// state is copied in (never swapped: Python views of the state buffers stay valid), the
    /// contact states are kept and the colliders moved on by `h`.
    fn commit(&mut self, scratch: &mut Scratch, history: History, h: f64) {
        let n = self.x.len();
        let (mut xp, mut vp, _) = history
            .or_else(|| self.history.take())
            .unwrap_or_else(|| (vec![DVec3::ZERO; n], vec![DVec3::ZERO; n], h));
        xp.copy_from_slice(&self.x);
        vp.copy_from_slice(&self.v);
        self.history = Some((xp, vp, h));
        self.x.copy_from_slice(&scratch.x_new);
        self.v.copy_from_slice(&scratch.v_new);
        std::mem::swap(&mut self.contact, &mut scratch.states);
        self.advance_colliders(h);
    }

    /// The modified PCG of Baraff & Witkin (1998, §5.3) on the filtered system: it solves
    /// `Â y = S (b - A Δv₀)` with `Â = S A S + I - S` and `Δv₀ = z + S Δv_last` (warm start), so
    /// every iterate stays in `z + range(S)`, and stops when `δ = rᵀ P⁻¹ r < ε² δ₀` with
    /// `δ₀ = (S b)ᵀ P⁻¹ S b` (the paper's rule).
    ///
    /// `P = (D/ω + L) (D/ω)⁻¹ (D/ω + U)` is the block SSOR preconditioner of `Â = L + D + U`
    /// (up to the constant factor `2 - ω`, which PCG does not see), with `ω` from
    /// [`ssor_omega`]; symmetric block Gauss–Seidel (`ω = 1`) needs about a third of the
    /// iterations of the paper's block-Jacobi `P = D` on cloth, and over-relaxation a further
    /// 2% (32²), 18% (64²), 40% (128²) and 53% (256²) fewer on the benchmark cloth.
    /// Eisenstat's trick (Eisenstat 1981, "Efficient implementation of a class of
    /// preconditioned conjugate gradient methods"; Saad, "Iterative Methods for Sparse Linear
    /// Systems", §9.2.2) makes an iteration cost one backward and one forward substitution,
    /// together one product with the matrix: with
    /// `p̂ = (D/ω + U) p` and `Â = (D/ω + L) + (D/ω + U) - (2/ω - 1) D`,
    /// `(D/ω + L)⁻¹ Â p = p + (D/ω + L)⁻¹ (U p + (1 - 1/ω) D p)`, and the iteration runs on
    /// `r̃ = (D/ω + L)⁻¹ r` (so `δ = r̃ᵀ (D/ω) r̃`) and `p̂`.
    ///
    /// The filter enters only through the diagonal: with `D̂ᵢ⁻¹ = Sᵢ (Sᵢ Aᵢᵢ Sᵢ + I - Sᵢ)⁻¹ Sᵢ`
    /// the substitutions on `A`'s blocks give those of `Â` for vectors in `range(S)` (`Â`'s
    /// off-diagonal blocks are `Sᵢ Aᵢⱼ Sⱼ`).
    ///
    /// The setup (diagonal inverses, warm start, right-hand sides) is here; the iterations run
    /// in [`pcg::solve`] on 3-vectors in four lanes (AVX2 where the CPU has it).
    pub(super) fn solve_pcg(
        &self,
        s: &mut Scratch,
        options: SolveOptions,
    ) -> Result<(usize, f64, bool)> {
        let n = self.x.len();
        let a = &self.matrix;
        let omega = ssor_omega(n);
        let w = &mut s.pcg;
        w.resize(n);
        let (filter, b) = (&s.filter, &s.b);
        // Rounding floor: bᵀ D⁻¹ b of the unfiltered right-hand side.
        let mut delta_b = 0.0;
        w.precond.update(a, |i| {
            let (d, f) = (a.blocks[i], filter[i]);
            let inverse = d.inverse();
            delta_b += b[i].dot(inverse * b[i]);
            if f == DMat3::IDENTITY {
                (inverse * omega, d * (1.0 / omega))
            } else {
                (f * (f * d * f + DMat3::IDENTITY - f).inverse() * f * omega, f * d * (1.0 / omega))
            }
        });
        // Warm start Δv₀ = z + S Δv_last; the solve starts from r = S (b - A Δv₀) and, for
        // δ₀, from S b.
        for i in 0..n {
            s.dv[i] = s.z[i] + s.filter[i] * s.dv[i];
        }
        a.mul(&s.dv, &mut s.q);
        for i in 0..n {
            w.dv[i] = pcg::Lane::new(s.dv[i]);
            w.r[i] = pcg::Lane::new(s.filter[i] * (s.b[i] - s.q[i]));
            w.t[i] = pcg::Lane::new(s.filter[i] * s.b[i]);
        }
        // Stop at ε² δ₀, or at the rounding floor of the unfiltered right-hand side when the
        // filter cancels nearly all of it (e.g. a cloth held by friction).
        let floor = (1e3 * f64::EPSILON).powi(2) * delta_b;
        let outcome = pcg::solve(a, w, options.tol, options.max_iterations, floor, omega - 1.0)?;
        for i in 0..n {
            s.dv[i] = w.dv[i].vec3();
        }
        Ok(outcome)
    }

    /// Sparse Cholesky of `S A S + (I - S)` with right-hand side `S (b - A z)`.
    pub(super) fn solve_cholesky(&mut self, s: &mut Scratch) -> Result<(usize, f64, bool)> {
        let n = self.x.len();
        if self.cholesky.is_none() {
            let (col_ptr, row_idx, source) = self.matrix.lower_scalar_pattern();
            let nnz = row_idx.len();
            let factor = SparseCholesky::new(3 * n, col_ptr, row_idx)?;
            self.cholesky = Some(CholeskyState {
                factor,
                source,
                values: vec![0.0; nnz],
                blocks: self.matrix.blocks.clone(),
                rhs: vec![0.0; 3 * n],
            });
        }
        let st = self.cholesky.as_mut().expect("created above");
        let a = &self.matrix;
        st.blocks.copy_from_slice(&a.blocks);
        if !s.constrained.is_empty() {
            for i in 0..n {
                for slot in std::iter::once(i).chain(a.row_ptr[i]..a.row_ptr[i + 1]) {
                    let j = a.cols[slot] as usize;
                    if s.filter[i] != DMat3::IDENTITY || s.filter[j] != DMat3::IDENTITY {
                        st.blocks[slot] = s.filter[i] * st.blocks[slot] * s.filter[j];
                    }
                }
            }
            for &i in &s.constrained {
                st.blocks[i] += DMat3::IDENTITY - s.filter[i];
            }
        }
        for (value, &(slot, k)) in st.values.iter_mut().zip(&st.source) {
            *value = bsr::entry(&st.blocks[slot], k);
        }
        st.factor.factorize(&st.values)?;
        a.mul(&s.z, &mut s.q);
        for i in 0..n {
            let rhs = s.filter[i] * (s.b[i] - s.q[i]);
            st.rhs[3 * i..3 * i + 3].copy_from_slice(&rhs.to_array());
        }
        st.factor.solve_in_place(&mut st.rhs);
        for i in 0..n {
            s.dv[i] = s.z[i] + DVec3::from_slice(&st.rhs[3 * i..3 * i + 3]);
        }
        // Relative residual of the filtered system.
        a.mul(&s.dv, &mut s.q);
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..n {
            num += (s.filter[i] * (s.q[i] - s.b[i])).length_squared();
            den += (s.filter[i] * s.b[i]).length_squared();
        }
        let residual = if den > 0.0 { (num / den).sqrt() } else { 0.0 };
        Ok((0, residual, true))
    }
}

/// Relaxation factor `ω` of the SSOR preconditioner of PCG for `n` vertices. On model
/// problems the best `ω` of an SSOR preconditioner approaches 2 as `2 / (1 + c h)` with the mesh
/// spacing `h ∝ 1/√n` (Axelsson 1994, "Iterative Solution Methods"; cf. Young's
/// `2 / (1 + sin πh)` for SOR); here `2 / (1 + 25/√n)`, at least 1 (symmetric Gauss–Seidel).
/// The constant is fitted on the benchmark cloth, where the best `ω` measured was 1.0–1.2 at
/// 32², 1.4 at 64², 1.7 at 128² and 1.8 at 256² (the formula: 1.12, 1.44, 1.67, 1.82).
pub(super) fn ssor_omega(n: usize) -> f64 {
    (2.0 / (1.0 + 25.0 / (n as f64).sqrt())).max(1.0)
}

/// Faer Cholesky state: the factorisation, where each scalar entry comes from, its values and
/// the filtered blocks.
pub(super) struct CholeskyState {
    factor: SparseCholesky,
    source: Vec<(usize, usize)>,
    values: Vec<f64>,
    blocks: Vec<DMat3>,
    rhs: Vec<f64>,
}
