//! The one error type of kinema.
//!
//! Every fallible function in the core returns [`Result<T>`]. The Python bindings map
//! [`Error::InvalidInput`] and [`Error::Shape`] to `ValueError`, [`Error::Parse`] to
//! `kinema.ParseError` (a `ValueError`) and [`Error::Diverged`] / [`Error::SolverFailed`] to
//! `kinema.SimulationError`, so no Rust panic ever reaches Python for bad input.

use std::fmt;

/// `Result` with kinema's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What went wrong, with enough context to fix it.
#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// An argument holds a value the method cannot use (zero quaternion, NaN, negative mass...).
    InvalidInput {
        /// Name of the argument, as the user-facing API spells it.
        arg: String,
        /// Index of the offending item in a batch, if the argument is a batch.
        index: Option<usize>,
        /// What is wrong with it.
        reason: String,
    },
    /// An array argument has the wrong shape.
    Shape {
        /// Name of the argument.
        arg: String,
        /// The shape that was expected, e.g. `"(N, 4)"`.
        expected: String,
        /// The shape that was received.
        got: Vec<usize>,
    },
    /// A file or text could not be parsed.
    Parse {
        /// File name (or `"<string>"`).
        file: String,
        /// 1-based line number.
        line: usize,
        /// What the parser expected to find.
        expected: String,
    },
    /// A simulation produced a non-finite or exploding state; the state was left at the last
    /// good step.
    Diverged {
        /// Index of the step (counted from the start of the call) that failed.
        step: usize,
        /// Index of the first element (particle, body, vertex) found bad.
        index: usize,
        /// What was detected.
        reason: String,
    },
    /// A linear or nonlinear solver failed (not positive definite, no convergence...).
    SolverFailed {
        /// What failed and why.
        reason: String,
    },
}

impl Error {
    /// An [`Error::InvalidInput`] for argument `arg` without a batch index.
    pub fn invalid(arg: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::InvalidInput { arg: arg.into(), index: None, reason: reason.into() }
    }

    /// The same error, attributed to item `index` of a batch.
    pub fn at(self, index: usize) -> Self {
        match self {
            Error::InvalidInput { arg, reason, .. } => {
                Error::InvalidInput { arg, index: Some(index), reason }
            }
            other => other,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::InvalidInput { arg, index: Some(i), reason } => {
                write!(f, "{arg}[{i}]: {reason}")
            }
            Error::InvalidInput { arg, index: None, reason } => write!(f, "{arg}: {reason}"),
            Error::Shape { arg, expected, got } => {
                write!(f, "{arg}: expected shape {expected}, got {got:?}")
            }
            Error::Parse { file, line, expected } => {
                write!(f, "{file}:{line}: expected {expected}")
            }
            Error::Diverged { step, index, reason } => {
                write!(f, "diverged at step {step}, element {index}: {reason}")
            }
            Error::SolverFailed { reason } => write!(f, "solver failed: {reason}"),
        }
    }
}

impl std::error::Error for Error {}

/// Check that every value is finite, naming `arg` and the item index on failure.
pub fn ensure_finite<const N: usize>(arg: &str, item: &[f64; N]) -> Result<()> {
    if item.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(Error::invalid(arg, "contains NaN or infinity"))
    }
}

/// `n` copies of `value` in a new vector, or an [`Error::InvalidInput`] naming `arg` (the
/// argument that sized it) when `n` items do not fit in memory: the allocator's refusal
/// (`Vec::try_reserve_exact`) becomes an error instead of aborting the process.
pub fn filled<T: Clone>(arg: &str, n: usize, value: T) -> Result<Vec<T>> {
    let mut v = Vec::new();
    reserve(arg, &mut v, n)?;
    v.resize(n, value);
    Ok(v)
}

/// Room for `additional` more items in `v` (`Vec::try_reserve`), or an
/// [`Error::InvalidInput`] naming `arg` with the size asked for, instead of aborting the
/// process when the allocator refuses.
///
/// Linux grants far more memory than it has (overcommit) and kills the process when the pages
/// are touched, so a buffer that must grow beyond [`CHECKED_BYTES`] is also refused when it
/// would not fit in the memory available now ([`available_memory`]).
pub fn reserve<T>(arg: &str, v: &mut Vec<T>, additional: usize) -> Result<()> {
    let bytes = v.len().saturating_add(additional).saturating_mul(size_of::<T>());
    if v.len() + additional > v.capacity()
        && bytes > CHECKED_BYTES
        && available_memory().is_some_and(|free| bytes > free)
    {
        return Err(too_large(arg, additional, size_of::<T>()));
    }
    v.try_reserve(additional).map_err(|_| too_large(arg, additional, size_of::<T>()))
}

/// Buffers larger than this (bytes) are checked against the available memory before they
/// are allocated.
pub const CHECKED_BYTES: usize = 64 << 20;

/// The memory (bytes) the process can use now, where the system says: Linux's
/// `MemAvailable` plus free swap (`/proc/meminfo`), and the room left under the cgroup v2
/// limit (`/sys/fs/cgroup/memory.max` minus `memory.current`) when there is one. `None`
/// elsewhere.
pub fn available_memory() -> Option<usize> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let field = |name: &str| {
        meminfo.lines().find_map(|l| {
            let kib = l.strip_prefix(name)?.trim().strip_suffix("kB")?.trim();
            kib.parse::<usize>().ok().map(|k| k.saturating_mul(1024))
        })
    };
    let mut free = field("MemAvailable:")?.saturating_add(field("SwapFree:").unwrap_or(0));
    let cgroup = |name: &str| {
        std::fs::read_to_string(format!("/sys/fs/cgroup/{name}")).ok()?.trim().parse::<usize>().ok()
    };
    if let (Some(limit), Some(used)) = (cgroup("memory.max"), cgroup("memory.current")) {
        free = free.min(limit.saturating_sub(used));
    }
    Some(free)
}

/// The error for `count` items of `bytes` bytes each that cannot be allocated.
pub fn too_large(arg: &str, count: impl fmt::Display, bytes: usize) -> Error {
    Error::invalid(
        arg,
        format!("needs {count} items of {bytes} bytes, more memory than can be allocated"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_buffer_beyond_the_available_memory_is_refused_before_it_is_allocated() {
        // Linux's allocator grants this (overcommit); touching it would get the process killed.
        let Some(free) = available_memory() else { return };
        let mut v: Vec<u8> = Vec::new();
        let err = reserve("count", &mut v, free + CHECKED_BYTES).unwrap_err();
        assert!(err.to_string().starts_with("count: needs"), "{err}");
        assert_eq!(v.capacity(), 0);
        // Small buffers are not checked and are granted.
        reserve("count", &mut v, 1024).unwrap();
        assert!(v.capacity() >= 1024);
    }
}
