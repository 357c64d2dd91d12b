//! The sparse Newton iteration matrix `I - γ h J` of the implicit methods, factorised by faer's
//! sparse LU with partial pivoting.

use crate::error::{Error, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::lu::{factorize_symbolic_lu, LuRef, NumericLu, SymbolicLu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par};

/// A sparse Jacobian `∂f/∂y` (dim x dim) in compressed sparse columns, written by
/// [`super::OdeSystem::sparse_jacobian`].
///
/// Column `c` holds the rows `row_idx[col_ptr[c]..col_ptr[c + 1]]`, strictly increasing, with
/// the values at the same positions of `values`. A system may write the same pattern at every
/// call and only new values (the usual case), or a new pattern when its coupling changes; the
/// stepper compares the pattern with the one it analysed and redoes the symbolic factorisation
/// only when it differs. Entries of the pattern may hold zeros.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, Default, PartialEq)]
pub struct SparseJacobian {
    /// Column pointers, `dim + 1` values starting at 0.
    pub col_ptr: Vec<usize>,
    /// Row index of each stored entry.
    pub row_idx: Vec<usize>,
    /// Value of each stored entry.
    pub values: Vec<f64>,
}

impl SparseJacobian {
    /// Check that this is a valid `n x n` pattern with rows strictly increasing per column.
    fn validate(&self, n: usize) -> Result<()> {
        let cp = &self.col_ptr;
        let nnz = self.row_idx.len();
        let ok = cp.len() == n + 1
            && cp[0] == 0
            && cp[n] == nnz
            && self.values.len() == nnz
            && cp.windows(2).all(|w| w[0] <= w[1])
            && (0..n).all(|c| {
                let rows = &self.row_idx[cp[c]..cp[c + 1]];
                rows.windows(2).all(|w| w[0] < w[1]) && rows.last().is_none_or(|&r| r < n)
            });
        if ok {
            Ok(())
        } else {
            Err(Error::invalid(
                "jacobian",
                format!(
                    "the sparse Jacobian is not a {n} x {n} compressed-column pattern with \
                     strictly increasing rows per column and one value per entry"
                ),
            ))
        }
    }
}

/// `M = I - γ h J` in the pattern of `J` plus the diagonal, with its sparse LU factorisation.
///
/// The pattern of `M`, the map from `J`'s entries to `M`'s and the symbolic factorisation
/// (COLAMD column ordering) are built when the pattern of `J` first appears or changes; each
/// Jacobian update only refills the values and redoes the numeric factorisation, on one thread
/// so that results do not depend on the thread count, unless the values of `M` are bitwise
/// those already factorised (a linear force's constant Jacobian at a constant step): then the
/// factors are kept, which gives the same bits as factorising again (the factorisation is a
/// function of the pattern and the values alone). faer sizes the numeric factors on the
/// first factorisations (partial pivoting may change the fill) and reuses the memory after.
#[derive(Default)]
pub(super) struct SparseNewton {
    /// The Jacobian the system writes.
    pub jac: SparseJacobian,
    /// The [`super::OdeSystem::constant_jacobian`] key and the bits of `γ h` whose `M` the
    /// factors hold (`None` when they belong to no key).
    pub key: Option<(u64, u64)>,
    /// The pattern of `J` that `M` was built for.
    j_col_ptr: Vec<usize>,
    j_row_idx: Vec<usize>,
    m_col_ptr: Vec<usize>,
    m_row_idx: Vec<usize>,
    m_values: Vec<f64>,
    /// The values of `M` that `numeric` holds the factors of (empty when it holds none).
    factored: Vec<f64>,
    /// Position in `M` of each entry of `J`, and of each diagonal entry.
    j_to_m: Vec<usize>,
    diag: Vec<usize>,
    symbolic: Option<SymbolicLu<usize>>,
    numeric: NumericLu<usize, f64>,
    buffer: Option<MemBuffer>,
}

impl std::fmt::Debug for SparseNewton {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "SparseNewton(nnz J = {}, nnz M = {})",
            self.j_row_idx.len(),
            self.m_row_idx.len()
        )
    }
}

/// Scratch of a factorisation: cloning gives an empty one, rebuilt at the next Jacobian update.
impl Clone for SparseNewton {
    fn clone(&self) -> Self {
        SparseNewton::default()
    }
}

impl SparseNewton {
    /// Whether a Jacobian pattern has been analysed (the system offers a sparse Jacobian).
    pub fn is_active(&self) -> bool {
        self.symbolic.is_some()
    }

    /// Forget the analysed pattern (the system stopped offering a sparse Jacobian).
    pub fn clear(&mut self) {
        *self = SparseNewton::default();
    }

    /// Build `M = I - gh J` from the Jacobian just written into `self.jac` and factorise it;
    /// returns `false` when the factors of this `M` (bitwise) were already at hand and kept.
    ///
    /// # Errors
    /// An invalid pattern ([`Error::InvalidInput`] naming `jacobian`), or a structurally
    /// singular matrix ([`Error::SolverFailed`]).
    pub fn factorize(&mut self, n: usize, gh: f64) -> Result<bool> {
        if self.symbolic.is_none()
            || self.jac.col_ptr != self.j_col_ptr
            || self.jac.row_idx != self.j_row_idx
        {
            self.analyse(n)?;
        }
        if self.jac.values.len() != self.j_to_m.len() {
            return Err(Error::invalid("jacobian", "one value per entry of the pattern"));
        }
        self.m_values.fill(0.0);
        for (&m, &v) in self.j_to_m.iter().zip(&self.jac.values) {
            self.m_values[m] = -gh * v;
        }
        for &d in &self.diag {
            self.m_values[d] += 1.0;
        }
        let same = |a: &[f64], b: &[f64]| {
            a.len() == b.len() && a.iter().zip(b).all(|(a, b)| a.to_bits() == b.to_bits())
        };
        if same(&self.m_values, &self.factored) {
            return Ok(false);
        }
        // Until the factorisation succeeds the numeric factors are of no known `M`.
        self.factored.clear();
        let (Some(symbolic), Some(buffer)) = (&self.symbolic, &mut self.buffer) else {
            unreachable!("analyse sets the symbolic factorisation")
        };
        let pattern =
            SymbolicSparseColMatRef::new_checked(n, n, &self.m_col_ptr, None, &self.m_row_idx);
        let a = SparseColMatRef::new(pattern, &self.m_values);
        symbolic
            .factorize_numeric_lu(
                &mut self.numeric,
                a,
                Par::Seq,
                MemStack::new(buffer),
                Default::default(),
            )
            .map_err(|e| Error::SolverFailed {
                reason: format!("the Newton iteration matrix is singular ({e:?})"),
            })?;
        self.factored.extend_from_slice(&self.m_values);
        Ok(true)
    }

    /// Overwrite `rhs` with `M⁻¹ rhs` for the last factorised `M`.
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) {
        let (Some(symbolic), Some(buffer)) = (&self.symbolic, &mut self.buffer) else {
            unreachable!("solve follows factorize")
        };
        let n = rhs.len();
        let lu = LuRef::new_unchecked(symbolic, &self.numeric);
        let mat = MatMut::from_column_major_slice_mut(rhs, n, 1);
        lu.solve_in_place_with_conj(Conj::No, mat, Par::Seq, MemStack::new(buffer));
    }

    /// Build the pattern of `M` (the pattern of `J` with the diagonal added), the entry maps
    /// and the symbolic factorisation for the pattern now in `self.jac`.
    fn analyse(&mut self, n: usize) -> Result<()> {
        self.jac.validate(n)?;
        // Until the analysis succeeds no pattern is analysed (a failure leaves none half-built).
        self.symbolic = None;
        self.factored.clear();
        let (cp, ri) = (&self.jac.col_ptr, &self.jac.row_idx);
        self.m_col_ptr.clear();
        self.m_row_idx.clear();
        self.j_to_m.clear();
        self.diag.clear();
        self.m_col_ptr.push(0);
        for c in 0..n {
            let rows = &ri[cp[c]..cp[c + 1]];
            let before = rows.partition_point(|&r| r < c);
            for &r in &rows[..before] {
                self.j_to_m.push(self.m_row_idx.len());
                self.m_row_idx.push(r);
            }
            self.diag.push(self.m_row_idx.len());
            self.m_row_idx.push(c);
            for &r in &rows[before..] {
                if r != c {
                    self.m_row_idx.push(r);
                }
                self.j_to_m.push(self.m_row_idx.len() - 1);
            }
            self.m_col_ptr.push(self.m_row_idx.len());
        }
        self.m_values.clear();
        self.m_values.resize(self.m_row_idx.len(), 0.0);
        let pattern =
            SymbolicSparseColMatRef::new_checked(n, n, &self.m_col_ptr, None, &self.m_row_idx);
        let symbolic = factorize_symbolic_lu(pattern, Default::default())
            .map_err(|e| Error::SolverFailed { reason: format!("symbolic LU: {e:?}") })?;
        let req = symbolic
            .factorize_numeric_lu_scratch::<f64>(Par::Seq, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        self.buffer = Some(MemBuffer::new(req));
        self.symbolic = Some(symbolic);
        self.j_col_ptr.clone_from(cp);
        self.j_row_idx.clone_from(ri);
        Ok(())
    }
}
