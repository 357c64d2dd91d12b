//! The linear solves of the implicit step (Baraff & Witkin 1998, §5.3): the prefiltered PCG
//! with the smoothed aggregation multigrid preconditioner ([`super::multigrid`]), the modified
//! PCG's setup with block SSOR (warm start, filtered right-hand sides; the iterations are in
//! [`super::pcg`]) and the sparse Cholesky path on the equivalent SPD system.

use super::multigrid::Hierarchy;
use super::{bsr, pcg, Model, SolveOptions, Solver, State};
use crate::error::{Error, Result};
use crate::linalg::SparseCholesky;
use glam::{DMat3, DVec3};

impl Solver {
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
        &mut self,
        state: &mut State,
        options: SolveOptions,
    ) -> Result<pcg::Outcome> {
        let n = state.len();
        let (a, s) = (&self.matrix, &mut self.scratch);
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
            state.dv[i] = s.z[i] + s.filter[i] * state.dv[i];
        }
        a.mul(&state.dv, &mut s.q);
        for i in 0..n {
            w.dv[i] = pcg::Lane::new(state.dv[i]);
            w.r[i] = pcg::Lane::new(s.filter[i] * (s.b[i] - s.q[i]));
            w.t[i] = pcg::Lane::new(s.filter[i] * s.b[i]);
        }
        // Stop at ε² δ₀, or at the rounding floor of the unfiltered right-hand side when the
        // filter cancels nearly all of it (e.g. a cloth held by friction).
        let floor = (1e3 * f64::EPSILON).powi(2) * delta_b;
        let outcome = pcg::solve(a, w, options.tol, options.max_iterations, floor, omega - 1.0)?;
        for i in 0..n {
            state.dv[i] = w.dv[i].vec3();
        }
        Ok(outcome)
    }

    /// The prefiltered PCG of Tamstorf, Jones & McCormick (2015, §4.2, Algorithm 2) with the
    /// multigrid preconditioner `M` of `Â = S A S + I - S`: it solves `Â y = S (b - A Δv₀)` on
    /// `range(S)` from the warm start `Δv₀ = z + S Δv_last`, preconditioned by `S M⁻¹ S`
    /// (symmetric positive definite on `range(S)`, so every iterate stays in `z + range(S)`, as
    /// in Baraff & Witkin's modified PCG), and stops when `δ = rᵀ S M⁻¹ S r < ε² δ₀` with
    /// `δ₀ = (S b)ᵀ S M⁻¹ S (S b)` (Baraff & Witkin's rule). With `M⁻¹ ≈ Â⁻¹` this bounds the
    /// error of `Δv` in the energy norm: `‖Δv - Δv*‖_Â ≈ √δ ≤ ε ‖S b‖_{Â⁻¹}`.
    pub(super) fn solve_multigrid(
        &mut self,
        model: &Model,
        state: &mut State,
        options: SolveOptions,
    ) -> Result<pcg::Outcome> {
        let n = state.len();
        let (a, s) = (&self.matrix, &mut self.scratch);
        let mg =
            self.multigrid.get_or_insert_with(|| Box::new(Multigrid::new(a, &model.triangles)));
        mg.hierarchy.update(a, &s.filter, &state.x)?;
        let Multigrid { hierarchy: h, r, d, z, q } = &mut **mg;
        // Warm start Δv₀ = z + S Δv_last; r = S (b - A Δv₀); the floor as for block SSOR.
        for i in 0..n {
            state.dv[i] = s.z[i] + s.filter[i] * state.dv[i];
        }
        a.mul(&state.dv, &mut s.q);
        let mut floor = 0.0;
        for i in 0..n {
            r[i] = s.filter[i] * (s.b[i] - s.q[i]);
            q[i] = s.filter[i] * s.b[i];
            floor += s.b[i].dot(a.blocks[i].inverse() * s.b[i]);
        }
        let floor = (1e3 * f64::EPSILON).powi(2) * floor;
        h.apply(&s.filter, q, z);
        let delta0 = dot(q, z);
        h.apply(&s.filter, r, z);
        d.copy_from_slice(z);
        let mut delta = dot(r, z);
        if !(delta0.is_finite() && delta.is_finite()) {
            return Err(Error::SolverFailed {
                reason: "PCG: the residual overflows (the step is too large); reduce dt".into(),
            });
        }
        let target = (options.tol * options.tol * delta0).max(floor);
        let mut iterations = 0;
        while delta > target && iterations < options.max_iterations {
            h.mul(d, q);
            let dq = dot(d, q);
            if dq <= 0.0 || !dq.is_finite() {
                return Err(Error::SolverFailed {
                    reason: format!(
                        "PCG: the system matrix is not positive definite (pᵀAp = {dq})"
                    ),
                });
            }
            let alpha = delta / dq;
            for i in 0..n {
                state.dv[i] += alpha * d[i];
                r[i] -= alpha * q[i];
            }
            h.apply(&s.filter, r, z);
            let next = dot(r, z);
            let beta = next / delta;
            for i in 0..n {
                d[i] = z[i] + beta * d[i];
            }
            delta = next;
            iterations += 1;
            if delta <= 0.0 {
                break;
            }
        }
        let residual = if delta0 > 0.0 { (delta.max(0.0) / delta0).sqrt() } else { 0.0 };
        Ok((iterations, residual, delta <= target))
    }

    /// Sparse Cholesky of `S A S + (I - S)` with right-hand side `S (b - A z)`.
    pub(super) fn solve_cholesky(&mut self, state: &mut State) -> Result<pcg::Outcome> {
        let n = state.len();
        let s = &mut self.scratch;
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
            state.dv[i] = s.z[i] + DVec3::from_slice(&st.rhs[3 * i..3 * i + 3]);
        }
        // Relative residual of the filtered system.
        a.mul(&state.dv, &mut s.q);
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..n {
            num += (s.filter[i] * (s.q[i] - s.b[i])).length_squared();
            den += (s.filter[i] * s.b[i]).length_squared();
        }
        let residual = if den > 0.0 { (num / den).sqrt() } else { 0.0 };
        Ok((0, residual, true))
    }
}

/// `Σ xᵢ · yᵢ`.
fn dot(x: &[DVec3], y: &[DVec3]) -> f64 {
    x.iter().zip(y).map(|(a, b)| a.dot(*b)).sum()
}

/// The multigrid path's hierarchy and the PCG's vectors: residual, direction, preconditioned
/// residual and `Â d`.
pub(super) struct Multigrid {
    hierarchy: Hierarchy,
    r: Vec<DVec3>,
    d: Vec<DVec3>,
    z: Vec<DVec3>,
    q: Vec<DVec3>,
}

impl Multigrid {
    /// The hierarchy's symbolic setup on `a`'s pattern and the vectors.
    fn new(a: &bsr::BlockMatrix, triangles: &[[usize; 3]]) -> Multigrid {
        let zero = vec![DVec3::ZERO; a.n()];
        Multigrid {
            hierarchy: Hierarchy::new(a, triangles),
            r: zero.clone(),
            d: zero.clone(),
            z: zero.clone(),
            q: zero,
        }
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
