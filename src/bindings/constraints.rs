//! `kinema.constraints`: constraints on the particles of a compiled particle system, and the
//! reduced-coordinate bead and pendulum.

use super::anim::KeyTrack;
use super::args::{counts, Int};
use super::error::detached;
use super::particles::Particles;
use super::pickle::{recipe, Reduced};
use crate::constraints::{
    ConstrainedSystem, Constraint, ConstraintFunction, ConstraintSolver, Curve, ReducedBead,
    ReducedPendulum, State,
};
use crate::error::Error;
use crate::ode::Method;
use crate::snapshot::Snapshot;
use glam::DVec3;
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use std::sync::{Arc, Mutex};

fn v3(p: &[f64], k: usize) -> DVec3 {
    DVec3::new(p[k], p[k + 1], p[k + 2])
}

fn need(p: &[f64], k: usize, what: &str) -> PyResult<()> {
    if p.len() == k {
        Ok(())
    } else {
        Err(Error::invalid(what, format!("expected {k} parameters, got {}", p.len())).into())
    }
}

/// A curve by kind: `line` (point 3, direction 3), `circle` (center 3, normal 3, radius),
/// `helix` (center 3, axis 3, radius, pitch) or `track` (a 3-channel `KeyTrack`).
fn curve(kind: &str, p: &[f64], track: Option<&Bound<'_, KeyTrack>>) -> PyResult<Curve> {
    Ok(match kind {
        "line" => {
            need(p, 6, "line")?;
            Curve::Line { point: v3(p, 0), direction: v3(p, 3) }
        }
        "circle" => {
            need(p, 7, "circle")?;
            Curve::Circle { center: v3(p, 0), normal: v3(p, 3), radius: p[6] }
        }
        "helix" => {
            need(p, 8, "helix")?;
            Curve::Helix { center: v3(p, 0), axis: v3(p, 3), radius: p[6], pitch: p[7] }
        }
        "track" => match track {
            Some(t) => Curve::Track(t.get().track.clone()),
            None => return Err(Error::invalid("curve", "a track curve needs its track").into()),
        },
        other => return Err(Error::invalid("curve", format!("unknown curve {other:?}")).into()),
    })
}

/// A [`ConstraintFunction`] whose value and gradient are Python callables of the positions
/// `(k, 3)`. A Python exception is kept in `error` (shared with the owning `Constrained`) and
/// re-raised when the call returns.
#[derive(Debug)]
struct PyConstraint {
    value: Py<PyAny>,
    gradient: Py<PyAny>,
    particles: usize,
    rows: usize,
    error: Arc<Mutex<Option<PyErr>>>,
}

impl PyConstraint {
    fn call(&self, f: &Py<PyAny>, x: &[f64], out: &mut [f64], what: &str) -> crate::Result<()> {
        Python::attach(|py| {
            let result = PyArray1::from_slice(py, x)
                .reshape([self.particles, 3])
                .and_then(|arr| f.call1(py, (arr,)))
                .and_then(|r| {
                    let np = py.import("numpy")?;
                    np.call_method1("ravel", (np.call_method1("asarray", (r, "float64"))?,))?
                        .extract::<Vec<f64>>()
                });
            match result {
                Ok(v) if v.len() == out.len() => {
                    out.copy_from_slice(&v);
                    Ok(())
                }
                Ok(v) => Err(Error::invalid(
                    what,
                    format!(
                        "returned {} values, expected {} ({} rows x {} coordinates)",
                        v.len(),
                        out.len(),
                        self.rows,
                        out.len() / self.rows
                    ),
                )),
                Err(e) => {
                    *self.error.lock().unwrap_or_else(|p| p.into_inner()) = Some(e);
                    Err(Error::invalid(what, "raised an exception"))
                }
            }
        })
    }
}

impl ConstraintFunction for PyConstraint {
    fn rows(&self) -> usize {
        self.rows
    }
    fn value(&self, x: &[f64], value: &mut [f64]) -> crate::Result<()> {
        self.call(&self.value, x, value, "value")
    }
    fn gradient(&self, x: &[f64], gradient: &mut [f64]) -> crate::Result<()> {
        self.call(&self.gradient, x, gradient, "gradient")
    }
}

/// Constraints acting on a `Particles` object; see `kinema.constraints.ConstrainedSystem`.
#[pyclass(module = "kinema._kinema", unsendable)]
pub struct Constrained {
    particles: Py<Particles>,
    system: ConstrainedSystem,
    /// The exception raised by a custom constraint's callable during the current call.
    error: Arc<Mutex<Option<PyErr>>>,
    /// The undo point of [`Constrained::_mark`], a copy of the constraint state (none before
    /// the first).
    saved: Option<State>,
}

impl Constrained {
    /// The callback's exception if one was raised, else the mapped error.
    fn finish<T>(&self, result: crate::Result<T>) -> PyResult<T> {
        let raised = self.error.lock().unwrap_or_else(|p| p.into_inner()).take();
        match (raised, result) {
            (Some(e), Err(_)) => Err(e),
            (_, r) => r.map_err(PyErr::from),
        }
    }
}

#[pymethods]
impl Constrained {
    /// Pickle support: the particles and the constraints as a snapshot (refused, with a
    /// `ValueError`, when a constraint is a Python function).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        let this = slf.borrow();
        let bytes = this.system.to_snapshot()?;
        recipe(slf.as_any(), &bytes, vec![this.particles.bind(slf.py()).clone().into_any()])
    }

    /// The system stored by `__reduce__`, on `particles` (its constraints must refer to
    /// particles of that system).
    #[staticmethod]
    fn _from_snapshot(py: Python<'_>, data: &[u8], particles: Py<Particles>) -> PyResult<Self> {
        let system = ConstrainedSystem::from_snapshot(data)?;
        system.check_particles(particles.borrow(py).system.capacity())?;
        Ok(Constrained { particles, system, error: Arc::default(), saved: None })
    }

    /// Remember the constraint state as it is now (a scene's undo point before a frame; the
    /// particles are marked on their own, the model does not change in a frame), reusing the
    /// last undo point's buffers.
    fn _mark(&mut self) {
        match &mut self.saved {
            Some(saved) => saved.clone_from(self.system.state()),
            None => self.saved = Some(self.system.state().clone()),
        }
    }

    /// Put the constraint state back as it was at the last [`Constrained::_mark`].
    fn _rollback(&mut self) -> PyResult<()> {
        if let Some(saved) = &self.saved {
            self.system.set_state(saved)?;
        }
        Ok(())
    }

    /// Constraints on `particles`: `formulation` `"multipliers"` with feedback gains `ks`
    /// (1/s²), `kd` (1/s), a solver (`"cholesky"` or `"cg"`) and post-stabilisation
    /// `stabilize`, or `"penalty"` with `stiffness` (N/m) and `damping` (N s/m) and
    /// `stabilize` false.
    #[new]
    #[allow(clippy::too_many_arguments)]
    fn new(
        particles: Py<Particles>,
        ks: f64,
        kd: f64,
        solver: &str,
        formulation: &str,
        stiffness: f64,
        damping: f64,
        stabilize: bool,
    ) -> PyResult<Self> {
        let solver = match solver {
            "cholesky" => ConstraintSolver::Cholesky,
            "cg" => ConstraintSolver::ConjugateGradient,
            other => {
                return Err(Error::invalid(
                    "solver",
                    format!("{other:?} is not 'cholesky' or 'cg'"),
                )
                .into())
            }
        };
        let mut system = match formulation {
            "multipliers" => ConstrainedSystem::new(ks, kd, solver)?,
            "penalty" => ConstrainedSystem::penalty(stiffness, damping)?,
            other => {
                return Err(Error::invalid(
                    "formulation",
                    format!("{other:?} is not 'multipliers' or 'penalty'"),
                )
                .into())
            }
        };
        system.set_stabilization(stabilize)?;
        Ok(Constrained { particles, system, error: Arc::default(), saved: None })
    }

    /// Add a constraint: `distance` (i, j, [length]), `on_sphere` (i, -, [center 3, radius]),
    /// `on_plane` (i, -, [point 3, normal 3]) or `fixed` (i, -, [point 3]).
    fn add(&mut self, py: Python<'_>, kind: &str, i: Int, j: Int, p: Vec<f64>) -> PyResult<()> {
        let (i, j) = (i.count("i")?, j.count("j")?);
        let c = match kind {
            "distance" => {
                need(&p, 1, kind)?;
                Constraint::Distance { i, j, length: p[0] }
            }
            "on_sphere" => {
                need(&p, 4, kind)?;
                Constraint::OnSphere { i, center: v3(&p, 0), radius: p[3] }
            }
            "on_plane" => {
                need(&p, 6, kind)?;
                Constraint::OnPlane { i, point: v3(&p, 0), normal: v3(&p, 3) }
            }
            "fixed" => {
                need(&p, 3, kind)?;
                Constraint::Fixed { i, point: v3(&p, 0) }
            }
            other => {
                return Err(
                    Error::invalid("constraint", format!("unknown constraint {other:?}")).into()
                )
            }
        };
        let particles = self.particles.bind(py).borrow();
        Ok(self.system.add(&particles.system, c)?)
    }

    /// Add `OnCurve`: particle `i` on a curve (see `curve` kinds above).
    #[pyo3(signature = (i, kind, p, track=None))]
    fn add_on_curve(
        &mut self,
        py: Python<'_>,
        i: Int,
        kind: &str,
        p: Vec<f64>,
        track: Option<Bound<'_, KeyTrack>>,
    ) -> PyResult<()> {
        let i = i.count("i")?;
        let curve = curve(kind, &p, track.as_ref())?;
        let particles = self.particles.bind(py).borrow();
        Ok(self.system.add(&particles.system, Constraint::OnCurve { i, curve })?)
    }

    /// Add `Custom`: `rows` conditions on `indices` with callables `value(x)` and
    /// `gradient(x)` of the positions `x` (len(indices), 3).
    fn add_custom(
        &mut self,
        py: Python<'_>,
        indices: Vec<Int>,
        value: Py<PyAny>,
        gradient: Py<PyAny>,
        rows: Int,
    ) -> PyResult<()> {
        let (indices, rows) = (counts(&indices, "indices")?, rows.count("rows")?);
        let function = PyConstraint {
            value,
            gradient,
            particles: indices.len(),
            rows,
            error: self.error.clone(),
        };
        let c = Constraint::Custom { particles: indices, function: Arc::new(function) };
        let particles = self.particles.bind(py).borrow();
        let result = self.system.add(&particles.system, c);
        self.finish(result)
    }

    /// Advance `steps` steps of `dt` with an ODE method, or `"projection"` for the
    /// velocity-level formulation with position post-stabilisation. The GIL is released
    /// unless a custom constraint calls Python.
    fn step(&mut self, py: Python<'_>, dt: f64, steps: Int, method: &str) -> PyResult<()> {
        let steps = steps.count("steps")?;
        let projection = method == "projection";
        let method = if projection { Method::Rk4 } else { Method::parse(method)? };
        let custom = self.system.has_custom();
        let mut particles = self.particles.bind(py).borrow_mut();
        let (system, ps) = (&mut self.system, &mut particles.system);
        let mut run = move || {
            if projection {
                system.step_projection(ps, dt, steps)
            } else {
                system.step(ps, dt, steps, method)
            }
        };
        if custom {
            let result = run();
            self.finish(result)
        } else {
            detached(py, run)
        }
    }

    /// (max |C|, max |Ċ|) over all constraint rows.
    fn violation(&mut self, py: Python<'_>) -> PyResult<(f64, f64)> {
        let particles = self.particles.bind(py).borrow();
        let result = self.system.violation(&particles.system);
        self.finish(result)
    }

    /// Constraint forces (capacity, 3) in N at the current state.
    fn constraint_forces<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let mut particles = self.particles.bind(py).borrow_mut();
        let result = self.system.constraint_forces(&mut particles.system);
        let f = self.finish(result)?;
        let rows: Vec<Vec<f64>> = f.iter().map(|v| v.to_array().to_vec()).collect();
        Ok(PyArray2::from_vec2(py, &rows).map_err(|e| Error::invalid("forces", e.to_string()))?)
    }

    /// The tracked curve parameter of constraint `k` (None unless it is an `OnCurve`).
    fn curve_parameter(&self, k: Int) -> PyResult<Option<f64>> {
        Ok(self.system.curve_parameter(k.count("k")?))
    }

    /// Conjugate-gradient iterations of the last solve (0 with Cholesky).
    fn iterations(&self) -> usize {
        self.system.iterations()
    }

    /// Number of constraints.
    fn __len__(&self) -> usize {
        self.system.constraints().len()
    }
}

/// A bead on a wire in its curve parameter; see `kinema.constraints.ReducedBead`.
#[pyclass(module = "kinema._kinema", name = "ReducedBead")]
pub struct PyReducedBead {
    bead: ReducedBead,
}

#[pymethods]
impl PyReducedBead {
    /// A bead of `mass` (kg) on a curve (kind, parameters, track) at `u` with rate `u_dot`,
    /// under `gravity` (3 values, m/s²).
    #[new]
    #[pyo3(signature = (kind, p, track, mass, gravity, u, u_dot))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        kind: &str,
        p: Vec<f64>,
        track: Option<Bound<'_, KeyTrack>>,
        mass: f64,
        gravity: Vec<f64>,
        u: f64,
        u_dot: f64,
    ) -> PyResult<Self> {
        need(&gravity, 3, "gravity")?;
        let curve = curve(kind, &p, track.as_ref())?;
        Ok(PyReducedBead { bead: ReducedBead::new(curve, mass, v3(&gravity, 0), u, u_dot)? })
    }

    /// Advance `steps` steps of `dt` with an ODE method (GIL released).
    fn step(&mut self, py: Python<'_>, dt: f64, steps: Int, method: &str) -> PyResult<()> {
        let steps = steps.count("steps")?;
        let method = Method::parse(method)?;
        let bead = &mut self.bead;
        detached(py, || bead.step(dt, steps, method))
    }

    /// (u, u̇).
    fn state(&self) -> (f64, f64) {
        let [u, du] = self.bead.state();
        (u, du)
    }

    /// Position (3,) in m and velocity (3,) in m/s.
    fn position_velocity(&self) -> ([f64; 3], [f64; 3]) {
        (self.bead.position().to_array(), self.bead.velocity().to_array())
    }

    /// Kinetic plus potential energy (J).
    fn energy(&self) -> f64 {
        self.bead.energy()
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.bead.time()
    }
}

/// A one- or two-link pendulum in its angles; see `kinema.constraints.ReducedPendulum`.
#[pyclass(module = "kinema._kinema", name = "ReducedPendulum")]
pub struct PyReducedPendulum {
    pendulum: ReducedPendulum,
}

#[pymethods]
impl PyReducedPendulum {
    /// `pivot` (3 values, m), per link `lengths` (m), `masses` (kg), `angles` (rad), `rates`
    /// (rad/s), gravity `g` (m/s², along -Y).
    #[new]
    fn new(
        pivot: Vec<f64>,
        lengths: Vec<f64>,
        masses: Vec<f64>,
        angles: Vec<f64>,
        rates: Vec<f64>,
        g: f64,
    ) -> PyResult<Self> {
        need(&pivot, 3, "pivot")?;
        Ok(PyReducedPendulum {
            pendulum: ReducedPendulum::new(v3(&pivot, 0), &lengths, &masses, &angles, &rates, g)?,
        })
    }

    /// Advance `steps` steps of `dt` with an ODE method (GIL released).
    fn step(&mut self, py: Python<'_>, dt: f64, steps: Int, method: &str) -> PyResult<()> {
        let steps = steps.count("steps")?;
        let method = Method::parse(method)?;
        let pendulum = &mut self.pendulum;
        detached(py, || pendulum.step(dt, steps, method))
    }

    /// (angles, rates) in rad and rad/s.
    fn state(&self) -> (Vec<f64>, Vec<f64>) {
        (self.pendulum.angles().to_vec(), self.pendulum.rates().to_vec())
    }

    /// Positions (m) and velocities (m/s) of the link ends, one (x, v) pair per link.
    fn positions_velocities(&self) -> Vec<([f64; 3], [f64; 3])> {
        let pv = self.pendulum.positions_velocities();
        pv.iter().map(|(x, v)| (x.to_array(), v.to_array())).collect()
    }

    /// Kinetic plus potential energy (J).
    fn energy(&self) -> f64 {
        self.pendulum.energy()
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.pendulum.time()
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Constrained>()?;
    m.add_class::<PyReducedBead>()?;
    m.add_class::<PyReducedPendulum>()
}
