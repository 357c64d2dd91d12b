//! `kinema.ode`: integrators driven by Python callables, and the stability analysis.

use super::args::Int;
use super::array::{compute, rows};
use crate::error::{filled, too_large, Error};
use crate::ode::{
    max_stable_dt, max_stable_dt_oscillator, solve_adaptive, stability_function, Adaptive, Event,
    Method, OdeSystem, Stepper,
};
use nalgebra::{Complex, DMatrix};
use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

type Array<'py> = Bound<'py, PyArrayDyn<f64>>;

/// An [`OdeSystem`] whose `f(t, y)` (and optional `jac(t, y)`) are Python callables. The GIL
/// is held throughout (every evaluation calls Python); a Python exception is kept and re-raised.
struct PySystem<'py> {
    py: Python<'py>,
    f: Bound<'py, PyAny>,
    jac: Option<Bound<'py, PyAny>>,
    /// Event functions `g(t, y) -> float`.
    events: Vec<Bound<'py, PyAny>>,
    n: usize,
    error: Option<PyErr>,
    /// The Jacobian as `jac` returned it, row-major (kept between calls).
    jac_rows: Vec<f64>,
    /// `f` also takes `y` of shape `(n, k)` (k states as columns) and returns `(n, k)`.
    vectorized: bool,
}

impl PySystem<'_> {
    /// Call `func(t, y)` and write its result, raveled, into `out`. A C-contiguous float64
    /// array (what a numpy right-hand side returns) is copied straight from its buffer; anything
    /// else goes through `numpy.asarray(r, "float64").ravel()` first.
    fn call(
        &mut self,
        func: &Bound<'_, PyAny>,
        t: f64,
        y: &[f64],
        out: &mut [f64],
        what: &str,
    ) -> crate::Result<()> {
        let py = self.py;
        let arr = PyArray1::from_slice(py, y);
        let result = func.call1((t, arr)).and_then(|r| {
            let r = match r.cast_into::<PyArrayDyn<f64>>() {
                Ok(a) if a.is_c_contiguous() => a,
                Ok(a) => as_float_array(py, a.into_any())?,
                Err(e) => as_float_array(py, e.into_inner())?,
            };
            let values = r.try_readonly()?;
            Ok(values.as_slice().map(|v| {
                if v.len() == out.len() {
                    out.copy_from_slice(v);
                }
                v.len()
            }))
        });
        match result {
            Ok(Ok(len)) if len == out.len() => Ok(()),
            Ok(Ok(len)) => {
                Err(Error::invalid(what, format!("returned {len} values, expected {}", out.len())))
            }
            Ok(Err(_)) => {
                Err(Error::invalid(what, "returned an array numpy cannot make contiguous"))
            }
            Err(e) => {
                self.error = Some(e);
                Err(Error::invalid(what, "raised an exception"))
            }
        }
    }
}

/// `numpy.ascontiguousarray(r, "float64").ravel()`.
fn as_float_array<'py>(
    py: Python<'py>,
    r: Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let np = py.import("numpy")?;
    let a = np.call_method1("ascontiguousarray", (r, "float64"))?;
    Ok(a.call_method0("ravel")?.cast_into::<PyArrayDyn<f64>>()?)
}

/// `numpy.asarray(r, "float64")`, read-only, whatever its dimensions.
fn as_float_array2<'py>(
    py: Python<'py>,
    r: Bound<'py, PyAny>,
) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    let np = py.import("numpy")?;
    let a = np.call_method1("asarray", (r, "float64"))?;
    Ok(a.cast_into::<PyArrayDyn<f64>>()?.try_readonly()?)
}

impl OdeSystem for PySystem<'_> {
    fn dim(&self) -> usize {
        self.n
    }
    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) -> crate::Result<()> {
        let f = self.f.clone();
        self.call(&f, t, y, dydt, "f")
    }
    fn rhs_many(&mut self, t: f64, ys: &[f64], dydt: &mut [f64]) -> crate::Result<()> {
        let n = self.n.max(1);
        if !self.vectorized {
            for (y, d) in ys.chunks_exact(n).zip(dydt.chunks_exact_mut(n)) {
                self.rhs(t, y, d)?;
            }
            return Ok(());
        }
        let (py, k) = (self.py, ys.len() / n);
        // The states one after another are the (n, k) matrix of columns in Fortran order.
        let result = PyArray1::from_slice(py, ys)
            .reshape([k, n])
            .and_then(|a| a.getattr("T"))
            .and_then(|a| self.f.call1((t, a)))
            .and_then(|r| as_float_array2(py, r));
        let values = match result {
            Ok(values) => values,
            Err(e) => {
                self.error = Some(e);
                return Err(Error::invalid("f", "raised an exception"));
            }
        };
        let view = values.as_array();
        if view.shape() != [n, k] {
            return Err(Error::invalid(
                "f",
                format!(
                    "vectorized: called with y of shape ({n}, {k}), returned shape {:?}",
                    view.shape()
                ),
            ));
        }
        for (j, d) in dydt.chunks_exact_mut(n).enumerate() {
            for (i, v) in d.iter_mut().enumerate() {
                *v = view[[i, j]];
            }
        }
        Ok(())
    }
    fn jacobian(&mut self, t: f64, y: &[f64], jac: &mut DMatrix<f64>) -> crate::Result<bool> {
        let Some(j) = self.jac.clone() else { return Ok(false) };
        let mut rows = std::mem::take(&mut self.jac_rows);
        rows.resize(self.n * self.n, 0.0);
        let result = self.call(&j, t, y, &mut rows, "jac");
        for r in 0..self.n {
            for c in 0..self.n {
                jac[(r, c)] = rows[r * self.n + c];
            }
        }
        self.jac_rows = rows;
        result.map(|()| true)
    }
    fn events(&mut self, t: f64, y: &[f64], g: &mut [f64]) -> crate::Result<()> {
        let arr = PyArray1::from_slice(self.py, y);
        for (e, out) in self.events.iter().zip(g.iter_mut()) {
            match e.call1((t, arr.clone())).and_then(|r| r.extract::<f64>()) {
                Ok(v) if v.is_finite() => *out = v,
                Ok(v) => return Err(Error::invalid("events", format!("returned {v} at t = {t}"))),
                Err(err) => {
                    self.error = Some(err);
                    return Err(Error::invalid("events", "raised an exception"));
                }
            }
        }
        Ok(())
    }
}

fn finish<T>(system: &mut PySystem<'_>, result: crate::Result<T>) -> PyResult<T> {
    match (system.error.take(), result) {
        (Some(e), Err(_)) => Err(e),
        (_, r) => r.map_err(PyErr::from),
    }
}

/// Fixed-step solve of y' = f(t, y) from t0 with `steps` steps of (t1 - t0)/steps; returns the
/// states (steps + 1, n) and the counts (nfev, njev).
#[pyfunction]
#[pyo3(signature = (f, y0, t0, t1, steps, method, jac=None, vectorized=false))]
#[allow(clippy::too_many_arguments)]
fn ode_solve_fixed<'py>(
    py: Python<'py>,
    f: Bound<'py, PyAny>,
    y0: PyReadonlyArrayDyn<'py, f64>,
    t0: f64,
    t1: f64,
    steps: Int,
    method: &str,
    jac: Option<Bound<'py, PyAny>>,
    vectorized: bool,
) -> PyResult<(Array<'py>, usize, usize)> {
    let steps = steps.count("steps")?;
    let method = Method::parse(method)?;
    let y0 = y0
        .as_slice()
        .map_err(|_| PyErr::from(Error::invalid("y0", "must be contiguous")))?
        .to_vec();
    let n = y0.len();
    if !(t0.is_finite() && t1.is_finite() && t1 > t0) || steps == 0 {
        return Err(Error::invalid(
            "t_span",
            format!("needs finite t1 > t0 and at least one step, got ({t0}, {t1}), {steps} steps"),
        )
        .into());
    }
    let mut system = PySystem {
        py,
        f,
        jac,
        events: Vec::new(),
        n,
        error: None,
        jac_rows: Vec::new(),
        vectorized,
    };
    let mut stepper = Stepper::new(method, n)?;
    let h = (t1 - t0) / steps as f64;
    let len = steps.checked_add(1).and_then(|m| m.checked_mul(n));
    let mut out = filled("steps", len.ok_or_else(|| too_large("steps", steps, 8 * n))?, 0.0)?;
    out[..n].copy_from_slice(&y0);
    let mut y = y0;
    for s in 0..steps {
        let r = stepper.step(&mut system, t0 + s as f64 * h, &mut y, h).map_err(|e| match e {
            Error::Diverged { index, reason, .. } => Error::Diverged { step: s, index, reason },
            other => other,
        });
        finish(&mut system, r)?;
        out[(s + 1) * n..(s + 2) * n].copy_from_slice(&y);
    }
    let states = numpy::PyArray1::from_vec(py, out).reshape([steps + 1, n])?.to_dyn().clone();
    Ok((states, stepper.history.nfev, stepper.history.njev))
}

/// Adaptive solve with `method` ("dopri5", "dop853", "radau"; `jac(t, y) -> (n, n)` used by
/// radau when given); `events` are (g(t, y) -> float, terminal, direction). Returns (times
/// (M,), states (M, n), (steps, nfev, rejected, njev, nlu), event times [(k_i,)], event
/// states [(k_i, n)], terminated), the times being the accepted steps or `t_eval`.
#[pyfunction]
#[pyo3(signature = (f, method, y0, t0, t1, rtol, atol, max_steps, jac=None, t_eval=None, events=Vec::new(), vectorized=false))]
#[allow(clippy::too_many_arguments)]
fn ode_solve_adaptive<'py>(
    py: Python<'py>,
    f: Bound<'py, PyAny>,
    method: &str,
    y0: PyReadonlyArrayDyn<'py, f64>,
    t0: f64,
    t1: f64,
    rtol: f64,
    atol: f64,
    max_steps: Int,
    jac: Option<Bound<'py, PyAny>>,
    t_eval: Option<PyReadonlyArrayDyn<'py, f64>>,
    events: Vec<(Bound<'py, PyAny>, bool, f64)>,
    vectorized: bool,
) -> PyResult<Solution<'py>> {
    let max_steps = max_steps.count("max_steps")?;
    let method = Adaptive::parse(method)?;
    let contiguous = |a: &PyReadonlyArrayDyn<'py, f64>, name: &str| {
        a.as_slice()
            .map(<[f64]>::to_vec)
            .map_err(|_| PyErr::from(Error::invalid(name, "must be contiguous")))
    };
    let y0 = contiguous(&y0, "y0")?;
    let t_eval = t_eval.as_ref().map(|a| contiguous(a, "t_eval")).transpose()?;
    let n = y0.len();
    let specs: Vec<Event> =
        events.iter().map(|&(_, terminal, direction)| Event { terminal, direction }).collect();
    let events = events.into_iter().map(|(g, _, _)| g).collect();
    let mut system =
        PySystem { py, f, jac, events, n, error: None, jac_rows: Vec::new(), vectorized };
    let r = solve_adaptive(
        &mut system,
        method,
        &y0,
        t0,
        t1,
        rtol,
        atol,
        max_steps,
        t_eval.as_deref(),
        &specs,
    );
    let sol = finish(&mut system, r)?;
    let m = sol.t.len();
    let t = numpy::PyArray1::from_vec(py, sol.t).to_dyn().clone();
    let y = numpy::PyArray1::from_vec(py, sol.y).reshape([m, n])?.to_dyn().clone();
    let t_events = sol
        .t_events
        .into_iter()
        .map(|v| numpy::PyArray1::from_vec(py, v).to_dyn().clone())
        .collect();
    let mut y_events = Vec::new();
    for v in sol.y_events {
        let k = v.len() / n.max(1);
        y_events.push(numpy::PyArray1::from_vec(py, v).reshape([k, n])?.to_dyn().clone());
    }
    let counts = (sol.steps, sol.nfev, sol.rejected, sol.njev, sol.nlu);
    Ok((t, y, counts, t_events, y_events, sol.terminated))
}

/// What `ode_solve_adaptive` returns.
type Solution<'py> = (
    Array<'py>,
    Array<'py>,
    (usize, usize, usize, usize, usize),
    Vec<Array<'py>>,
    Vec<Array<'py>>,
    bool,
);

/// R(z) of `method` at points z given as (N, 2) rows (re, im); returns (N, 2).
#[pyfunction]
fn ode_stability_function<'py>(
    py: Python<'py>,
    method: &str,
    z: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let method = Method::parse(method)?;
    let zs = rows::<2>(&z, "z", &[2])?;
    compute(py, zs.len(), &[2], |out| {
        crate::batch::map(zs, out, |p| {
            let r = stability_function(method, Complex::new(p[0], p[1]));
            Ok([r.re, r.im])
        })
    })
}

/// The largest stable step of `method` for eigenvalues given as (N, 2) rows (re, im).
#[pyfunction]
fn ode_max_stable_dt(method: &str, eigenvalues: PyReadonlyArrayDyn<'_, f64>) -> PyResult<f64> {
    let method = Method::parse(method)?;
    let eig: Vec<Complex<f64>> = rows::<2>(&eigenvalues, "eigenvalues", &[2])?
        .iter()
        .map(|p| Complex::new(p[0], p[1]))
        .collect();
    Ok(max_stable_dt(method, &eig)?)
}

/// The largest stable step of `method` on `x'' + damping x' + omega² x = 0`.
#[pyfunction]
fn ode_max_stable_dt_oscillator(method: &str, omega: f64, damping: f64) -> PyResult<f64> {
    Ok(max_stable_dt_oscillator(Method::parse(method)?, omega, damping)?)
}

/// (name, order, implicit, second_order) of every fixed-step method.
#[pyfunction]
fn ode_methods() -> Vec<(&'static str, u32, bool, bool)> {
    Method::ALL
        .iter()
        .map(|m| (m.name(), m.order(), m.is_implicit(), m.is_second_order()))
        .collect()
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(ode_solve_fixed, m)?)?;
    m.add_function(wrap_pyfunction!(ode_solve_adaptive, m)?)?;
    m.add_function(wrap_pyfunction!(ode_stability_function, m)?)?;
    m.add_function(wrap_pyfunction!(ode_max_stable_dt, m)?)?;
    m.add_function(wrap_pyfunction!(ode_max_stable_dt_oscillator, m)?)?;
    m.add_function(wrap_pyfunction!(ode_methods, m)?)?;
    Ok(())
}
