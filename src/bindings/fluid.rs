//! `kinema.fluid`: a compiled SPH fluid whose positions and velocities numpy views without a
//! copy.

use super::args::{Int, MAX_ITERATIONS};
use super::array::compute;
use super::error::detached;
use super::pickle::{reduce, Reduced};
use super::view::view;
use crate::error::Error;
use crate::fluid::{Fluid as Core, Kernel, Pressure, Settings, Wall};
use crate::snapshot::Snapshot;
use glam::DVec3;
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A particle fluid; see `kinema.fluid.Fluid` for the API.
#[pyclass(module = "kinema._kinema")]
pub struct Fluid {
    fluid: Core,
    /// Whether a view of the positions or velocities was handed out: their buffers must then
    /// never be reallocated, so no block may be added.
    viewed: bool,
}

fn v3(p: [f64; 3]) -> DVec3 {
    DVec3::from_array(p)
}

fn out1<'py>(py: Python<'py>, values: &[f64]) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    compute::<1>(py, values.len(), &[], |out| {
        out.iter_mut().zip(values).for_each(|(o, v)| o[0] = *v);
        Ok(())
    })
}

#[pymethods]
impl Fluid {
    /// Pickle support: the fluid as a snapshot (model and state).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.fluid, vec![])
    }

    /// The object stored by `__reduce__`.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { fluid: Core::from_snapshot(data)?, viewed: false })
    }

    /// An empty fluid: `spacing` (m), `rest_density` (kg/m³), `kernel` ("cubic" or
    /// "wendland"), XSPH `viscosity`, `solver` ("dfsph" or "wcsph") with its tolerances (%)
    /// and iteration cap, or `sound_speed` (m/s); `cfl`, `max_dt` (s), `max_substeps`,
    /// `gravity` (m/s²).
    #[new]
    #[allow(clippy::too_many_arguments)]
    fn new(
        spacing: f64,
        rest_density: f64,
        kernel: &str,
        viscosity: f64,
        solver: &str,
        density_tolerance: f64,
        divergence_tolerance: f64,
        max_iterations: Int,
        sound_speed: f64,
        cfl: f64,
        max_dt: f64,
        max_substeps: Int,
        gravity: [f64; 3],
    ) -> PyResult<Self> {
        let kernel = match kernel {
            "cubic" => Kernel::CubicSpline,
            "wendland" => Kernel::WendlandC2,
            _ => return Err(Error::invalid("kernel", "expected 'cubic' or 'wendland'").into()),
        };
        let pressure = match solver {
            "dfsph" => Pressure::Dfsph {
                density_tolerance,
                divergence_tolerance,
                max_iterations: max_iterations.range("max_iterations", 1, MAX_ITERATIONS)?,
            },
            "wcsph" => Pressure::Wcsph { sound_speed },
            _ => return Err(Error::invalid("solver", "expected 'dfsph' or 'wcsph'").into()),
        };
        let settings = Settings {
            spacing,
            rest_density,
            kernel,
            viscosity,
            pressure,
            cfl,
            max_dt,
            max_substeps: max_substeps.range("max_substeps", 1, MAX_ITERATIONS)?,
            gravity: v3(gravity),
        };
        Ok(Fluid { fluid: Core::new(settings)?, viewed: false })
    }

    /// Fill the box `[lower, upper]` (m) with fluid moving at `velocity` (m/s); returns the
    /// number of particles added.
    fn add_block(
        &mut self,
        lower: [f64; 3],
        upper: [f64; 3],
        velocity: [f64; 3],
    ) -> PyResult<usize> {
        if self.viewed {
            return Err(Error::invalid(
                "lower",
                "add blocks before reading positions or velocities (their views must stay valid)",
            )
            .into());
        }
        Ok(self.fluid.add_block(v3(lower), v3(upper), v3(velocity))?)
    }

    /// Add a closed tank: the inside of the box `[lower, upper]` (m).
    fn add_boundary_box(&mut self, lower: [f64; 3], upper: [f64; 3]) -> PyResult<()> {
        Ok(self.fluid.add_wall(Wall::Box { lower: v3(lower), upper: v3(upper) })?)
    }

    /// Add the square `|t| ≤ half_extent` (m) about `point` of the plane of unit `normal`.
    fn add_boundary_plane(
        &mut self,
        point: [f64; 3],
        normal: [f64; 3],
        half_extent: f64,
    ) -> PyResult<()> {
        let wall = Wall::Plane { point: v3(point), normal: v3(normal), half_extent };
        Ok(self.fluid.add_wall(wall)?)
    }

    /// Advance `steps` frames of `dt` seconds in CFL substeps (GIL released).
    fn step(&mut self, py: Python<'_>, dt: f64, steps: Int) -> PyResult<()> {
        let steps = steps.count("steps")?;
        let fluid = &mut self.fluid;
        detached(py, || fluid.step(dt, steps))
    }

    /// Number of fluid particles.
    fn __len__(&self) -> usize {
        self.fluid.state().len()
    }

    /// Read-only view (N, 3) of the positions (m), updated in place by `step`.
    #[getter]
    fn positions<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        slf.borrow_mut().viewed = true;
        let n = slf.borrow().fluid.state().len();
        view(slf, &[n, 3], |f| bytemuck::cast_slice(f.fluid.state().positions()))
    }

    /// Read-only view (N, 3) of the velocities (m/s), updated in place by `step`.
    #[getter]
    fn velocities<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        slf.borrow_mut().viewed = true;
        let n = slf.borrow().fluid.state().len();
        view(slf, &[n, 3], |f| bytemuck::cast_slice(f.fluid.state().velocities()))
    }

    /// Densities (N,) in kg/m³ of the particles as they are now (a new array).
    fn densities<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let fluid = &mut self.fluid;
        let rho = detached(py, || Ok(fluid.densities()))?;
        out1(py, &rho)
    }

    /// Pressures (N,) in Pa of the last substep (a new array).
    fn pressures<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        out1(py, &self.fluid.pressures())
    }

    /// The boundary particles (B, 3) in m (a new array).
    fn boundary_particles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let b = self.fluid.model().boundary_particles();
        compute::<3>(py, b.len(), &[3], |out| {
            out.iter_mut().zip(b).for_each(|(o, p)| *o = p.to_array());
            Ok(())
        })
    }

    /// The mass of one particle (kg).
    #[getter]
    fn particle_mass(&self) -> f64 {
        self.fluid.model().particle_mass()
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.fluid.state().time()
    }

    /// What the last `step` call did.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.fluid.stats;
        let d = PyDict::new(py);
        d.set_item("substeps", s.substeps)?;
        d.set_item("density_iterations", s.density_iterations)?;
        d.set_item("divergence_iterations", s.divergence_iterations)?;
        d.set_item("density_error", s.density_error)?;
        d.set_item("max_density_error", s.max_density_error)?;
        d.set_item("divergence_error", s.divergence_error)?;
        Ok(d)
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Fluid>()
}
