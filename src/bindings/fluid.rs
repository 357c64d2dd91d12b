//! `kinema.fluid`: a compiled SPH fluid whose positions and velocities numpy views without a
//! copy.

use super::args::{Int, MAX_ITERATIONS};
use super::array::{compute, zeroed};
use super::error::detached;
use super::pickle::{reduce, Reduced};
use super::view::view;
use crate::error::Error;
use crate::fluid::{
    Collider, Emitter, Fluid as Core, Kernel, Pressure, Settings, State, Stats, Viscosity, Wall,
};
use crate::snapshot::Snapshot;
use glam::DVec3;
use numpy::{PyArray1, PyArray2, PyArrayDyn, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A particle fluid; see `kinema.fluid.Fluid` for the API.
#[pyclass(module = "kinema._kinema")]
pub struct Fluid {
    fluid: Core,
    /// Whether a view of the positions or velocities was handed out: their buffers must then
    /// never be reallocated, so no block, emitter or kill box may be added.
    viewed: bool,
    /// The scene's undo point (`_mark`), with the number of colliders then.
    saved: Option<(State, Stats, usize)>,
}

impl Fluid {
    fn wrap(fluid: Core) -> Self {
        Fluid { fluid, viewed: false, saved: None }
    }

    /// Whether the particle count can change in a step (then positions and velocities are
    /// copies, not views).
    fn varying(&self) -> bool {
        let model = self.fluid.model();
        !model.emitters().is_empty() || model.kill_box().is_some()
    }

    fn refuse_if_viewed(&self, arg: &str, what: &str) -> PyResult<()> {
        if self.viewed {
            let why = format!(
                "add {what} before reading positions or velocities (their views must stay valid)"
            );
            return Err(Error::invalid(arg, why).into());
        }
        Ok(())
    }

    fn rows<'py>(
        slf: &Bound<'py, Self>,
        pick: fn(&State) -> &[DVec3],
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let this = slf.borrow();
        let n = this.fluid.state().len();
        if this.varying() {
            let rows = pick(this.fluid.state());
            return compute::<3>(slf.py(), n, &[3], |out| {
                let out = zeroed(out);
                out.iter_mut().zip(rows).for_each(|(o, p)| *o = p.to_array());
                Ok(())
            });
        }
        drop(this);
        slf.borrow_mut().viewed = true;
        view(slf, &[n, 3], move |f| bytemuck::cast_slice(pick(f.fluid.state())))
    }
}

/// A collider from its kind and parameters: the shape's ([`super::geometry::shape`]), then
/// velocity 3.
fn collider(kind: &str, p: &[f64]) -> PyResult<Collider> {
    let (shape, t) = super::geometry::shape(kind, p, 3)?;
    Ok(Collider { shape, velocity: DVec3::new(t[0], t[1], t[2]) })
}

/// Vertices (V, 3) and triangles (T, 3) of a surface.
type SurfaceMesh<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<u32>>);

fn v3(p: [f64; 3]) -> DVec3 {
    DVec3::from_array(p)
}

fn out1<'py>(py: Python<'py>, values: &[f64]) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    compute::<1>(py, values.len(), &[], |out| {
        let out = zeroed(out);
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
        Ok(Self::wrap(Core::from_snapshot(data)?))
    }

    /// Remember the state, stats and number of colliders as they are now (a scene's undo
    /// point before a frame; no allocation after the first time).
    fn _mark(&mut self) {
        let fluid = &self.fluid;
        let count = fluid.model().colliders();
        let saved = self.saved.get_or_insert_with(|| (fluid.state().clone(), fluid.stats, count));
        saved.0.clone_from(fluid.state());
        (saved.1, saved.2) = (fluid.stats, count);
    }

    /// Put the state and stats back as they were at the last `_mark`, in place (views of the
    /// state stay valid: their particle count cannot change), and remove the colliders the
    /// frame added.
    fn _rollback(&mut self) {
        if let Some((state, stats, count)) = &self.saved {
            self.fluid.truncate_colliders(*count);
            self.fluid.state_mut().clone_from(state);
            self.fluid.stats = *stats;
        }
    }

    /// An empty fluid: `spacing` (m), `rest_density` (kg/m³), `kernel` ("cubic" or
    /// "wendland"), `viscosity` of `viscosity_model` ("xsph": dimensionless; "implicit":
    /// kinematic, m²/s), Akinci's `surface_tension` γ, `solver` ("dfsph", "pbf" or "wcsph") with its
    /// tolerances (%) and iteration cap, PBF's `tensile` `k`, or `sound_speed` (m/s); `cfl`,
    /// `max_dt` (s), `max_substeps`, `gravity` (m/s²).
    #[new]
    #[allow(clippy::too_many_arguments)]
    fn new(
        spacing: f64,
        rest_density: f64,
        kernel: &str,
        viscosity: f64,
        viscosity_model: &str,
        surface_tension: f64,
        solver: &str,
        density_tolerance: f64,
        divergence_tolerance: f64,
        max_iterations: Int,
        sound_speed: f64,
        tensile: f64,
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
        let viscosity = match viscosity_model {
            "xsph" => Viscosity::Xsph(viscosity),
            "implicit" => Viscosity::Implicit(viscosity),
            _ => {
                return Err(
                    Error::invalid("viscosity_model", "expected 'xsph' or 'implicit'").into()
                )
            }
        };
        let pressure = match solver {
            "dfsph" => Pressure::Dfsph {
                density_tolerance,
                divergence_tolerance,
                max_iterations: max_iterations.range("max_iterations", 1, MAX_ITERATIONS)?,
            },
            "pbf" => Pressure::Pbf {
                density_tolerance,
                max_iterations: max_iterations.range("max_iterations", 1, MAX_ITERATIONS)?,
                tensile,
            },
            "wcsph" => Pressure::Wcsph { sound_speed },
            _ => return Err(Error::invalid("solver", "expected 'dfsph', 'pbf' or 'wcsph'").into()),
        };
        let settings = Settings {
            spacing,
            rest_density,
            kernel,
            viscosity,
            surface_tension,
            pressure,
            cfl,
            max_dt,
            max_substeps: max_substeps.range("max_substeps", 1, MAX_ITERATIONS)?,
            gravity: v3(gravity),
        };
        Ok(Self::wrap(Core::new(settings)?))
    }

    /// Fill the box `[lower, upper]` (m) with fluid moving at `velocity` (m/s); returns the
    /// number of particles added.
    fn add_block(
        &mut self,
        lower: [f64; 3],
        upper: [f64; 3],
        velocity: [f64; 3],
    ) -> PyResult<usize> {
        self.refuse_if_viewed("lower", "blocks")?;
        Ok(self.fluid.add_block(v3(lower), v3(upper), v3(velocity))?)
    }

    /// Add a nozzle: a disc of `radius` (m) about `position` (m) facing the unit `direction`,
    /// emitting fluid at `speed` (m/s).
    fn add_emitter(
        &mut self,
        position: [f64; 3],
        direction: [f64; 3],
        speed: f64,
        radius: f64,
    ) -> PyResult<()> {
        self.refuse_if_viewed("position", "emitters")?;
        let emitter = Emitter { position: v3(position), direction: v3(direction), speed, radius };
        Ok(self.fluid.add_emitter(emitter)?)
    }

    /// Remove every particle that leaves the box `[lower, upper]` (m).
    fn kill_box(&mut self, lower: [f64; 3], upper: [f64; 3]) -> PyResult<()> {
        self.refuse_if_viewed("lower", "a kill box")?;
        Ok(self.fluid.kill_box(v3(lower), v3(upper))?)
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

    /// Add a collider of `kind` with the shape's parameters (see [`super::geometry::shape`])
    /// then its velocity (m/s); returns its index.
    fn add_collider(&mut self, kind: &str, p: Vec<f64>) -> PyResult<usize> {
        Ok(self.fluid.add_collider(collider(kind, &p)?)?)
    }

    /// Move collider `index` to the pose and velocity of `kind` with parameters `p`.
    fn set_collider(&mut self, index: Int, kind: &str, p: Vec<f64>) -> PyResult<()> {
        Ok(self.fluid.set_collider(index.count("index")?, collider(kind, &p)?)?)
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

    /// Read-only view (N, 3) of the positions (m), updated in place by `step`; a copy if
    /// emitters or a kill box change the particle count.
    #[getter]
    fn positions<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        Self::rows(slf, State::positions)
    }

    /// Read-only view (N, 3) of the velocities (m/s), updated in place by `step`; a copy if
    /// emitters or a kill box change the particle count.
    #[getter]
    fn velocities<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        Self::rows(slf, State::velocities)
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

    /// Vertices (V, 3) in m and outward triangles (T, 3) of the fluid's surface sampled every
    /// `resolution` m.
    fn surface_mesh<'py>(&self, py: Python<'py>, resolution: f64) -> PyResult<SurfaceMesh<'py>> {
        let fluid = &self.fluid;
        let (v, t) = detached(py, || fluid.surface_mesh(resolution))?;
        let (nv, nt) = (v.len(), t.len());
        let v = PyArray1::from_vec(py, v.into_flattened()).reshape([nv, 3])?;
        let t = PyArray1::from_vec(py, t.into_flattened()).reshape([nt, 3])?;
        Ok((v, t))
    }

    /// The boundary particles (B, 3) in m, the walls' then the colliders' where they are now
    /// (a new array).
    fn boundary_particles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let b = self.fluid.boundary_particles();
        compute::<3>(py, b.len(), &[3], |out| {
            let out = zeroed(out);
            out.iter_mut().zip(&b).for_each(|(o, p)| *o = p.to_array());
            Ok(())
        })
    }

    /// The particle spacing at rest (m).
    #[getter]
    fn spacing(&self) -> f64 {
        self.fluid.model().settings().spacing
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
        d.set_item("viscosity_iterations", s.viscosity_iterations)?;
        d.set_item("viscosity_error", s.viscosity_error)?;
        Ok(d)
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Fluid>()
}
