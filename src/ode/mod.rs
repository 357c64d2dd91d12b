//! Time integration of ordinary differential equations `y' = f(t, y)`.
//!
//! One contract for every system in kinema: an [`OdeSystem`] supplies `f` (and optionally its
//! Jacobian `∂f/∂y`); a [`Workspace`] advances the state by fixed steps with one of the
//! [`Method`]s, reading and updating a [`History`] (what carries from step to step: the method,
//! the previous BDF2 step, the Newton settings), so that a system keeps the history in its
//! state and the workspace in its solver ([`Stepper`] holds the two together);
//! [`solve_adaptive`] runs an adaptive method with error control and dense output
//! ([`Adaptive`]: Dormand–Prince 5(4), DOP853 of order 8, or the implicit Radau IIA of order
//! 5 for stiff problems). Second-order methods (symplectic Euler, velocity Verlet) read the state as
//! `y = [x; v]` with `f = [v; a(t, x, v)]`.
//!
//! Every method states its order and its stability function `R(z)` (the growth factor per step
//! on the test equation `y' = λy` with `z = hλ`), see [`stability_function`] and
//! [`max_stable_dt`]; the tests measure both. Sources: Hairer, Nørsett & Wanner, *Solving ODEs
//! I* (explicit Runge–Kutta, Dormand–Prince 1980); Hairer & Wanner, *Solving ODEs II* (implicit
//! Euler, trapezoidal rule, BDF2); Hairer, Lubich & Wanner, *Geometric Numerical Integration*
//! (symplectic Euler, Störmer–Verlet).

mod adaptive;
mod dop853;
mod dopri5;
mod history;
mod output;
mod radau;
mod sparse;
mod stability;
mod stepper;

pub use adaptive::{solve_adaptive, Adaptive, AdaptiveSolution};
pub use history::History;
pub use output::Event;
pub use sparse::SparseJacobian;
pub use stability::{max_stable_dt, max_stable_dt_oscillator, stability_function};
pub use stepper::{Stepper, Workspace};

use crate::error::{Error, Result};
use nalgebra::DMatrix;

/// A first-order system `y' = f(t, y)` of fixed dimension.
pub trait OdeSystem {
    /// Length of the state vector.
    fn dim(&self) -> usize;
    /// Write `f(t, y)` into `dydt` (both of length [`OdeSystem::dim`]).
    ///
    /// # Errors
    /// Whatever the system reports (e.g. an exception in a Python callback).
    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) -> Result<()>;
    /// Write `f(t, y_j)` for several states at once: `ys` holds them one after another
    /// (state `j` at `ys[j dim..(j + 1) dim]`) and `dydt` receives the derivatives in the same
    /// layout. The finite-difference Jacobians of the implicit methods evaluate all their
    /// columns in one call; the default calls [`OdeSystem::rhs`] for each state, and a system
    /// that evaluates many states at once for less (a vectorised Python function, as scipy's
    /// `vectorized=True`) overrides it.
    ///
    /// # Errors
    /// Whatever the system reports.
    fn rhs_many(&mut self, t: f64, ys: &[f64], dydt: &mut [f64]) -> Result<()> {
        let n = self.dim().max(1);
        for (y, d) in ys.chunks_exact(n).zip(dydt.chunks_exact_mut(n)) {
            self.rhs(t, y, d)?;
        }
        Ok(())
    }
    /// Write the Jacobian `∂f/∂y` (dim x dim) into `jac` and return `true`, or return `false`
    /// when the system has no analytic Jacobian (implicit methods then use finite differences).
    ///
    /// # Errors
    /// Whatever the system reports.
    fn jacobian(&mut self, _t: f64, _y: &[f64], _jac: &mut DMatrix<f64>) -> Result<bool> {
        Ok(false)
    }
    /// Write the Jacobian `∂f/∂y` in compressed sparse columns into `jac` and return `true`,
    /// or return `false` when the system has no sparse Jacobian (the default; implicit methods
    /// then use [`OdeSystem::jacobian`] or dense finite differences). When offered, implicit
    /// methods factorise `I - γ h J` by sparse LU in the pattern written here, so large,
    /// sparsely coupled systems (particles joined by springs) avoid the `dim²` dense matrix
    /// and the `dim` extra evaluations of differencing. See [`SparseJacobian`] for the layout
    /// and for patterns that change between calls.
    ///
    /// # Errors
    /// Whatever the system reports.
    fn sparse_jacobian(&mut self, _t: f64, _y: &[f64], _jac: &mut SparseJacobian) -> Result<bool> {
        Ok(false)
    }
    /// `Some(key)` when `f` is affine in `y` (`f = J y + g(t)`, a Jacobian constant in `t`
    /// and `y`) and the system promises that every call returning the same `key` has bitwise
    /// the same Jacobian; `None` (the default) otherwise. Keys must be unique over the life of
    /// the process (a fresh one, [`fresh_key`], each time the system may have changed).
    /// The implicit methods then evaluate the Jacobian and factorise `I - γ h J` only when the
    /// key or `γ h` changes (for a sparse Jacobian a new key still keeps the factors when the
    /// matrix is bitwise the one factorised), and take the one Newton step that solves an
    /// affine equation exactly, without the step that would confirm it.
    fn constant_jacobian(&self) -> Option<u64> {
        None
    }
    /// Write the values of the event functions `g_i(t, y)` into `g` (one per [`Event`] given
    /// to [`solve_adaptive`], `g.len()` of them); the adaptive methods locate their zeros on
    /// the dense output. Called only when events are given; the default writes nothing.
    ///
    /// # Errors
    /// Whatever the system reports.
    fn events(&mut self, _t: f64, _y: &[f64], _g: &mut [f64]) -> Result<()> {
        Ok(())
    }
}

/// A key for [`OdeSystem::constant_jacobian`] that no earlier call returned (a process-wide
/// counter).
pub fn fresh_key() -> u64 {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
}

/// Largest step ratio `ω = h / h₋` at which BDF2 keeps its history: the variable-step formula
/// is zero-stable for ratios below `1 + √2` (Grigorieff 1983; Hairer & Wanner, *Solving ODEs
/// II*, §III.5); a step that grows by more restarts with one implicit Euler step.
pub const BDF2_MAX_RATIO: f64 = 2.0;

/// The variable-step BDF2 step from `y₋` (at `t - h₋`) and `y` (at `t`) to `y₊` (at `t + h`),
/// `y₊ - (1+ω)²/(1+2ω) y + ω²/(1+2ω) y₋ = h (1+ω)/(1+2ω) f(t + h, y₊)` with `ω = h / h₋`
/// (Hairer & Wanner, *Solving ODEs II*, §III.5, eq. 5.9; Crouzeix & Lisbona 1984), written as
/// `y₊ = y + c (y - y₋) + γ h f(t + h, y₊)`: returns `(c, γ) = (ω²/(1+2ω), (1+ω)/(1+2ω))`,
/// which are `(1/3, 2/3)` at a constant step. `None` (restart with implicit Euler,
/// `y₊ = y + h f(t + h, y₊)`) without a previous step `prev_h` or when `ω` exceeds
/// [`BDF2_MAX_RATIO`].
pub fn bdf2_weights(h: f64, prev_h: Option<f64>) -> Option<(f64, f64)> {
    let ratio = h / prev_h?;
    (ratio <= BDF2_MAX_RATIO).then(|| {
        let d = 1.0 + 2.0 * ratio;
        (ratio * ratio / d, (1.0 + ratio) / d)
    })
}

/// A fixed-step integration method.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// Forward Euler, order 1, `R(z) = 1 + z`.
    ExplicitEuler,
    /// Explicit midpoint rule (RK2), order 2, `R(z) = 1 + z + z²/2`.
    Midpoint,
    /// Heun's method (explicit trapezoid, RK2), order 2, `R(z) = 1 + z + z²/2`.
    Heun,
    /// The classic Runge–Kutta method, order 4, `R(z) = Σ_{k≤4} z^k/k!`.
    Rk4,
    /// Semi-implicit (symplectic) Euler on `y = [x; v]`: `v₁ = v₀ + h a(x₀, v₀)`,
    /// `x₁ = x₀ + h v₁`. Order 1, symplectic for conservative forces.
    SymplecticEuler,
    /// Velocity Verlet / leapfrog (kick–drift–kick) on `y = [x; v]`. Order 2, symplectic and
    /// time-reversible for conservative forces; for velocity-dependent forces the closing kick
    /// uses the predicted velocity `v₀ + h a₀`, which keeps second order.
    VelocityVerlet,
    /// Backward Euler, order 1, L-stable, `R(z) = 1/(1 - z)`; Newton iterations.
    ImplicitEuler,
    /// Trapezoidal rule (Crank–Nicolson), order 2, A-stable, `R(z) = (1 + z/2)/(1 - z/2)`.
    Trapezoidal,
    /// Two-step backward differentiation formula, order 2, A-stable:
    /// `y₂ - 4/3 y₁ + 1/3 y₀ = 2/3 h f(t₂, y₂)` at a constant step, the variable-step
    /// coefficients of [`bdf2_weights`] after a change of step; started (and restarted after
    /// a step more than [`BDF2_MAX_RATIO`] times the last) with one backward Euler step.
    Bdf2,
}

impl Method {
    /// Every fixed-step method, in the order of the docs.
    pub const ALL: [Method; 9] = [
        Method::ExplicitEuler,
        Method::Midpoint,
        Method::Heun,
        Method::Rk4,
        Method::SymplecticEuler,
        Method::VelocityVerlet,
        Method::ImplicitEuler,
        Method::Trapezoidal,
        Method::Bdf2,
    ];

    /// The method's name as the Python API spells it (`"rk4"`, `"implicit_euler"`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Method::ExplicitEuler => "explicit_euler",
            Method::Midpoint => "midpoint",
            Method::Heun => "heun",
            Method::Rk4 => "rk4",
            Method::SymplecticEuler => "symplectic_euler",
            Method::VelocityVerlet => "velocity_verlet",
            Method::ImplicitEuler => "implicit_euler",
            Method::Trapezoidal => "trapezoidal",
            Method::Bdf2 => "bdf2",
        }
    }

    /// Parse a name of [`Method::name`].
    ///
    /// # Errors
    /// An unknown name, listing the known ones.
    pub fn parse(name: &str) -> Result<Self> {
        Method::ALL.into_iter().find(|m| m.name() == name).ok_or_else(|| {
            let known: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
            Error::invalid("method", format!("{name:?} is not one of {}", known.join(", ")))
        })
    }

    /// Order of convergence.
    pub fn order(self) -> u32 {
        match self {
            Method::ExplicitEuler | Method::SymplecticEuler | Method::ImplicitEuler => 1,
            Method::Rk4 => 4,
            _ => 2,
        }
    }

    /// Whether each step solves a (non)linear system.
    pub fn is_implicit(self) -> bool {
        matches!(self, Method::ImplicitEuler | Method::Trapezoidal | Method::Bdf2)
    }

    /// Whether the method needs the state split as `y = [x; v]`.
    pub fn is_second_order(self) -> bool {
        matches!(self, Method::SymplecticEuler | Method::VelocityVerlet)
    }
}
