//! Sparse symmetric positive definite solves shared by the systems: a Cholesky factorisation
//! (faer) whose pattern and symbolic analysis are computed once and whose numeric
//! factorisation is redone in preallocated memory, and a Jacobi-preconditioned conjugate
//! gradient for systems given as an operator.

use crate::error::{Error, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::ldlt::factor::LdltRegularization;
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LdltRef, LltRef, SymbolicCholesky,
    SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

/// Most right-hand sides [`SparseCholesky::solve_in_place`] solves at once (the three
/// coordinates of a system of 3-vectors whose matrix is a scalar one times the identity).
pub const MAX_COLUMNS: usize = 3;

/// [`SparseCholesky::simplicial_factor`]: the permutation (if any), then `L`'s column
/// pointers, row indices and values.
pub type SimplicialFactor<'a> = (Option<&'a [usize]>, &'a [usize], &'a [usize], &'a [f64]);

/// `L Lᵀ` factorisation of a sparse SPD matrix, or `L D Lᵀ` of a sparse symmetric
/// quasi-definite one (`[A Bᵀ; B -C]` with `A`, `C` positive definite, e.g. a regularised KKT
/// matrix, which has such a factorisation for every ordering: Vanderbei 1995, "Symmetric
/// quasidefinite matrices", SIAM J. Optim. 5(1)), with a fixed pattern (faer, AMD ordering).
///
/// The pattern is the lower triangle in compressed sparse columns (`col_ptr`, `row_idx`, rows
/// sorted within each column, diagonal included). [`SparseCholesky::factorize`] refills the
/// numbers; nothing is allocated after construction. Runs on one thread so results do not
/// depend on the thread count.
pub struct SparseCholesky {
    n: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    symbolic: SymbolicCholesky<usize>,
    factor: Vec<f64>,
    buffer: MemBuffer,
    /// The sign of each pivot of a quasi-definite matrix (`L D Lᵀ`); empty for `L Lᵀ`.
    signs: Vec<i8>,
}

impl std::fmt::Debug for SparseCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SparseCholesky(n = {}, nnz = {})", self.n, self.row_idx.len())
    }
}

impl SparseCholesky {
    /// Analyse the pattern (lower triangle, CSC) of an `n x n` matrix.
    ///
    /// # Errors
    /// An invalid pattern (faer's checks) or out of memory.
    pub fn new(n: usize, col_ptr: Vec<usize>, row_idx: Vec<usize>) -> Result<Self> {
        Self::analyse(n, col_ptr, row_idx, SupernodalThreshold::AUTO)
    }

    /// [`Self::new`] with faer's simplicial (column by column) factorisation forced, so that
    /// the factor is one compressed-column matrix ([`Self::simplicial_factor`]).
    ///
    /// # Errors
    /// As [`Self::new`].
    pub fn simplicial(n: usize, col_ptr: Vec<usize>, row_idx: Vec<usize>) -> Result<Self> {
        Self::analyse(n, col_ptr, row_idx, SupernodalThreshold::FORCE_SIMPLICIAL)
    }

    fn analyse(
        n: usize,
        col_ptr: Vec<usize>,
        row_idx: Vec<usize>,
        threshold: SupernodalThreshold,
    ) -> Result<Self> {
        if col_ptr.len() != n + 1 || col_ptr[n] != row_idx.len() || row_idx.iter().any(|&r| r >= n)
        {
            return Err(Error::invalid("pattern", "is not a valid compressed-column pattern"));
        }
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Lower,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams {
                supernodal_flop_ratio_threshold: threshold,
                ..Default::default()
            },
        )
        .map_err(|e| Error::SolverFailed { reason: format!("symbolic Cholesky: {e:?}") })?;
        let req = symbolic
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
            .or(symbolic.factorize_numeric_ldlt_scratch::<f64>(Par::Seq, Default::default()))
            .or(symbolic.solve_in_place_scratch::<f64>(MAX_COLUMNS, Par::Seq));
        let factor = vec![0.0; symbolic.len_val()];
        Ok(SparseCholesky {
            n,
            col_ptr,
            row_idx,
            symbolic,
            factor,
            buffer: MemBuffer::new(req),
            signs: Vec::new(),
        })
    }

    /// Analyse the pattern of a quasi-definite matrix whose pivot `k` has the sign `signs[k]`
    /// (`+1` or `-1`); [`Self::factorize`] then computes `L D Lᵀ`, and a pivot of the wrong
    /// sign or below `1e-300` in size is replaced (faer's dynamic regularisation).
    ///
    /// # Errors
    /// As [`Self::new`], or `signs` of the wrong length.
    pub fn quasi_definite(
        n: usize,
        col_ptr: Vec<usize>,
        row_idx: Vec<usize>,
        signs: Vec<i8>,
    ) -> Result<Self> {
        if signs.len() != n {
            return Err(Error::invalid("signs", "needs one sign per row"));
        }
        Ok(SparseCholesky { signs, ..Self::new(n, col_ptr, row_idx)? })
    }

    /// The factor `L` of the last `L Lᵀ` factorisation of `P A Pᵀ` when it is simplicial
    /// (always after [`Self::simplicial`]): `(perm, col_ptr, row_idx, values)`, row `i` of
    /// `P A Pᵀ` being row `perm[i]` of `A` (no `perm`: `P = I`), and `L` lower triangular in
    /// compressed columns with each column's diagonal entry first. `None` for a supernodal or
    /// `L D Lᵀ` factorisation.
    pub fn simplicial_factor(&self) -> Option<SimplicialFactor<'_>> {
        let SymbolicCholeskyRaw::Simplicial(l) = self.symbolic.raw() else {
            return None;
        };
        let perm = self.symbolic.perm().map(|p| p.arrays().0);
        self.signs.is_empty().then_some((perm, l.col_ptr(), l.row_idx(), &self.factor[..]))
    }

    /// Number of stored entries of the pattern (lower triangle).
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// Factorise the matrix with `values` in the pattern's order. A quasi-definite matrix's
    /// pivot of the wrong sign becomes `±1e-10 max|value|`.
    ///
    /// # Errors
    /// [`Error::SolverFailed`] when an SPD matrix is not numerically positive definite.
    pub fn factorize(&mut self, values: &[f64]) -> Result<()> {
        let pattern = SymbolicSparseColMatRef::new_checked(
            self.n,
            self.n,
            &self.col_ptr,
            None,
            &self.row_idx,
        );
        let a = SparseColMatRef::new(pattern, values);
        let stack = MemStack::new(&mut self.buffer);
        if self.signs.is_empty() {
            self.symbolic
                .factorize_numeric_llt::<f64>(
                    &mut self.factor,
                    a,
                    Side::Lower,
                    LltRegularization::default(),
                    Par::Seq,
                    stack,
                    Default::default(),
                )
                .map_err(|e| Error::SolverFailed {
                    reason: format!("Cholesky factorisation: {e:?} (matrix not positive definite)"),
                })?;
        } else {
            let regularization = LdltRegularization {
                dynamic_regularization_signs: Some(&self.signs),
                dynamic_regularization_delta: 1e-10
                    * values.iter().fold(f64::MIN_POSITIVE, |a, v| a.max(v.abs())),
                dynamic_regularization_epsilon: 1e-300,
            };
            self.symbolic
                .factorize_numeric_ldlt::<f64>(
                    &mut self.factor,
                    a,
                    Side::Lower,
                    regularization,
                    Par::Seq,
                    stack,
                    Default::default(),
                )
                .map_err(|e| Error::SolverFailed {
                    reason: format!("L D Lᵀ factorisation: {e:?}"),
                })?;
        }
        Ok(())
    }

    /// Overwrite `rhs` with the solution of `A x = rhs` for the last factorised `A`: one
    /// right-hand side of `n` values, or up to [`MAX_COLUMNS`] of them one after another
    /// (`rhs.len()` a multiple of `n`, column-major), solved together.
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) {
        let columns = rhs.len() / self.n.max(1);
        assert!(
            columns * self.n == rhs.len() && columns <= MAX_COLUMNS,
            "solve_in_place: {} values for n = {}",
            rhs.len(),
            self.n
        );
        let mat = MatMut::from_column_major_slice_mut(rhs, self.n, columns);
        let stack = MemStack::new(&mut self.buffer);
        if self.signs.is_empty() {
            LltRef::new(&self.symbolic, &self.factor).solve_in_place_with_conj(
                Conj::No,
                mat,
                Par::Seq,
                stack,
            );
        } else {
            LdltRef::new(&self.symbolic, &self.factor).solve_in_place_with_conj(
                Conj::No,
                mat,
                Par::Seq,
                stack,
            );
        }
    }
}

/// Solve `A x = b` for symmetric positive (semi)definite `A` given as the operator
/// `apply(x, out) = A x`, by conjugate gradient with the Jacobi preconditioner `diag`
/// (Shewchuk 1994, "An introduction to the conjugate gradient method without the agonizing
/// pain", B3). Starts from the `x` given; stops when `|r| <= tol |b|`. `work` holds 3 vectors
/// of scratch. Returns the iterations used.
///
/// # Errors
/// [`Error::SolverFailed`] when `max_iters` is reached.
pub fn conjugate_gradient(
    apply: &mut dyn FnMut(&[f64], &mut [f64]),
    b: &[f64],
    diag: &[f64],
    x: &mut [f64],
    tol: f64,
    max_iters: usize,
    work: &mut [Vec<f64>; 4],
) -> Result<usize> {
    let n = b.len();
    let [r, z, p, q] = work;
    for w in [&mut *r, &mut *z, &mut *p, &mut *q] {
        w.resize(n, 0.0);
    }
    apply(x, q);
    for i in 0..n {
        r[i] = b[i] - q[i];
    }
    let b_norm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
    if b_norm == 0.0 {
        x.fill(0.0);
        return Ok(0);
    }
    let precondition = |r: &[f64], z: &mut [f64]| {
        for i in 0..n {
            z[i] = if diag[i] > 0.0 { r[i] / diag[i] } else { r[i] };
        }
    };
    precondition(r, z);
    p.copy_from_slice(z);
    let mut rz: f64 = r.iter().zip(z.iter()).map(|(a, b)| a * b).sum();
    for it in 0..max_iters {
        let r_norm = r.iter().map(|v| v * v).sum::<f64>().sqrt();
        if r_norm <= tol * b_norm {
            return Ok(it);
        }
        apply(p, q);
        let pq: f64 = p.iter().zip(q.iter()).map(|(a, b)| a * b).sum();
        if pq <= 0.0 {
            return Ok(it); // the remaining residual lies in the null space (redundant rows)
        }
        let alpha = rz / pq;
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * q[i];
        }
        precondition(r, z);
        let rz_new: f64 = r.iter().zip(z.iter()).map(|(a, b)| a * b).sum();
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
    }
    Err(Error::SolverFailed {
        reason: format!("conjugate gradient did not converge in {max_iters} iterations"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 1-D Laplacian (tridiagonal 2, -1) plus a small shift, lower triangle.
    fn laplacian(n: usize) -> (Vec<usize>, Vec<usize>, Vec<f64>) {
        let (mut col_ptr, mut row_idx, mut val) = (vec![0], vec![], vec![]);
        for c in 0..n {
            row_idx.push(c);
            val.push(2.01);
            if c + 1 < n {
                row_idx.push(c + 1);
                val.push(-1.0);
            }
            col_ptr.push(row_idx.len());
        }
        (col_ptr, row_idx, val)
    }

    #[test]
    fn cholesky_and_cg_solve_the_laplacian() {
        let n = 200;
        let (col_ptr, row_idx, val) = laplacian(n);
        let x_true: Vec<f64> = (0..n).map(|i| (i as f64 * 0.1).sin()).collect();
        let apply = |x: &[f64], out: &mut [f64]| {
            for i in 0..n {
                out[i] = 2.01 * x[i]
                    - if i > 0 { x[i - 1] } else { 0.0 }
                    - if i + 1 < n { x[i + 1] } else { 0.0 };
            }
        };
        let mut b = vec![0.0; n];
        apply(&x_true, &mut b);
        let mut chol = SparseCholesky::new(n, col_ptr, row_idx).unwrap();
        chol.factorize(&val).unwrap();
        let mut x = b.clone();
        chol.solve_in_place(&mut x);
        assert!(x.iter().zip(&x_true).all(|(a, b)| (a - b).abs() < 1e-12));
        let mut x = vec![0.0; n];
        let mut work = Default::default();
        let iters = conjugate_gradient(
            &mut |x, o| apply(x, o),
            &b,
            &vec![2.01; n],
            &mut x,
            1e-13,
            1000,
            &mut work,
        )
        .unwrap();
        assert!(iters > 0 && x.iter().zip(&x_true).all(|(a, b)| (a - b).abs() < 1e-10));
        // An indefinite matrix is reported, not a panic.
        let mut neg = val.clone();
        neg[0] = -1.0;
        assert!(chol.factorize(&neg).is_err());
    }
}
