//! Integer arguments checked with messages that name them.
//!
//! PyO3's own conversion to `usize` raises `OverflowError: can't convert negative int to
//! unsigned` for `-1` and `10**30` without naming the argument. Every integer argument of the
//! compiled module is taken as [`Int`] instead, which accepts any Python integer (and anything
//! with `__index__`, such as numpy integers), and converted with [`Int::count`] or
//! [`Int::range`], which raise `ValueError` (out of range) or `TypeError` (not an integer)
//! naming the argument.

use pyo3::exceptions::{PyOverflowError, PyTypeError, PyValueError};
use pyo3::prelude::*;

/// Most iterations or sweeps any solver loop accepts (contact and joint sweeps, XPBD
/// substeps, PCG and IK iterations): far above what any converging solve needs, low enough
/// that a mistyped count returns within seconds instead of hanging.
pub const MAX_ITERATIONS: usize = 1_000_000;

/// Most threads `set_num_threads` starts.
pub const MAX_THREADS: usize = 1024;

/// A Python integer argument as received: its value (saturated to the `i128` range, which
/// keeps it out of every accepted range when it was larger) or the name of the type that was
/// not an integer.
pub struct Int(Result<i128, String>);

impl<'py> FromPyObject<'_, 'py> for Int {
    type Error = PyErr;

    fn extract(ob: Borrowed<'_, 'py, PyAny>) -> PyResult<Self> {
        Ok(Int(match ob.extract::<i128>() {
            Ok(v) => Ok(v),
            Err(e) if e.is_instance_of::<PyOverflowError>(ob.py()) => {
                Ok(if ob.lt(0)? { i128::MIN } else { i128::MAX })
            }
            Err(_) => Err(ob.get_type().name().map_or("?".into(), |n| n.to_string())),
        }))
    }
}

impl Int {
    /// Zero, for default values.
    pub const ZERO: Int = Int(Ok(0));

    /// The value as a count in `lo..=hi`, or a `ValueError` / `TypeError` naming `arg`.
    pub fn range(&self, arg: &str, lo: usize, hi: usize) -> PyResult<usize> {
        let v = match &self.0 {
            Ok(v) => *v,
            Err(ty) => {
                return Err(PyTypeError::new_err(format!("{arg}: expected an integer, got {ty}")))
            }
        };
        match usize::try_from(v) {
            Ok(n) if (lo..=hi).contains(&n) => Ok(n),
            _ => {
                let shown = match v {
                    i128::MAX => "a larger integer".to_string(),
                    i128::MIN => "a smaller integer".to_string(),
                    v => v.to_string(),
                };
                Err(PyValueError::new_err(if hi == usize::MAX {
                    format!("{arg}: expected an integer >= {lo}, got {shown}")
                } else {
                    format!("{arg}: expected an integer in [{lo}, {hi}], got {shown}")
                }))
            }
        }
    }

    /// The value as a non-negative count (an index, a number of steps).
    pub fn count(&self, arg: &str) -> PyResult<usize> {
        self.range(arg, 0, usize::MAX)
    }

    /// The value as a random seed in `[0, 2^64)`.
    pub fn seed(&self, arg: &str) -> PyResult<u64> {
        Ok(self.range(arg, 0, u64::MAX as usize)? as u64)
    }
}

/// Every item of `values` as a non-negative count, or an error naming `arg[k]`.
pub fn counts(values: &[Int], arg: &str) -> PyResult<Vec<usize>> {
    values.iter().enumerate().map(|(k, v)| v.count(&format!("{arg}[{k}]"))).collect()
}
