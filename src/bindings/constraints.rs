//! `kinema.constraints`: constraints on the particles of a compiled particle system.

use super::particles::Particles;
use crate::constraints::{ConstrainedSystem, Constraint, ConstraintSolver};
use crate::error::Error;
use crate::ode::Method;
use glam::DVec3;
use numpy::PyArray2;
use pyo3::prelude::*;

/// Constraints acting on a `Particles` object; see `kinema.constraints.ConstrainedSystem`.
#[pyclass(module = "kinema._kinema", unsendable)]
pub struct Constrained {
    particles: Py<Particles>,
    system: ConstrainedSystem,
}

#[pymethods]
impl Constrained {
    /// Constraints on `particles` with feedback gains `ks` (1/s²), `kd` (1/s) and a solver
    /// (`"cholesky"` or `"cg"`).
    #[new]
    fn new(particles: Py<Particles>, ks: f64, kd: f64, solver: &str) -> PyResult<Self> {
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
        Ok(Constrained { particles, system: ConstrainedSystem::new(ks, kd, solver)? })
    }

    /// Add a constraint: `distance` (i, j, [length]), `on_sphere` (i, -, [center 3, radius]),
    /// `on_plane` (i, -, [point 3, normal 3]) or `fixed` (i, -, [point 3]).
    fn add(&mut self, py: Python<'_>, kind: &str, i: usize, j: usize, p: Vec<f64>) -> PyResult<()> {
        let need = |k: usize| -> PyResult<()> {
            if p.len() == k {
                Ok(())
            } else {
                Err(Error::invalid(kind, format!("expected {k} parameters, got {}", p.len()))
                    .into())
            }
        };
        let v = |k: usize| DVec3::new(p[k], p[k + 1], p[k + 2]);
        let c = match kind {
            "distance" => {
                need(1)?;
                Constraint::Distance { i, j, length: p[0] }
            }
            "on_sphere" => {
                need(4)?;
                Constraint::OnSphere { i, center: v(0), radius: p[3] }
            }
            "on_plane" => {
                need(6)?;
                Constraint::OnPlane { i, point: v(0), normal: v(3) }
            }
            "fixed" => {
                need(3)?;
                Constraint::Fixed { i, point: v(0) }
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

    /// Advance `steps` steps of `dt` with an ODE method, or `"projection"` for the
    /// velocity-level formulation with position post-stabilisation.
    fn step(&mut self, py: Python<'_>, dt: f64, steps: usize, method: &str) -> PyResult<()> {
        let mut particles = self.particles.bind(py).borrow_mut();
        if method == "projection" {
            Ok(self.system.step_projection(&mut particles.system, dt, steps)?)
        } else {
            let method = Method::parse(method)?;
            Ok(self.system.step(&mut particles.system, dt, steps, method)?)
        }
    }

    /// (max |C|, max |Ċ|) over all constraint rows.
    fn violation(&mut self, py: Python<'_>) -> (f64, f64) {
        let particles = self.particles.bind(py).borrow();
        self.system.violation(&particles.system)
    }

    /// Constraint forces Jᵀλ (capacity, 3) in N at the current state.
    fn constraint_forces<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let mut particles = self.particles.bind(py).borrow_mut();
        let f = self.system.constraint_forces(&mut particles.system)?;
        let rows: Vec<Vec<f64>> = f.iter().map(|v| v.to_array().to_vec()).collect();
        Ok(PyArray2::from_vec2(py, &rows).map_err(|e| Error::invalid("forces", e.to_string()))?)
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

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Constrained>()
}
