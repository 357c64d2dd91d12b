//! `kinema.rods`: a compiled discrete elastic rod whose positions, velocities and twists
//! numpy views without a copy.

use super::args::{Int, MAX_ITERATIONS};
use super::array::{compute, rows, zeroed};
use super::error::detached;
use super::pickle::{reduce, Reduced};
use super::view::view;
use crate::error::Error;
use crate::geometry::Sphere;
use crate::rods::{
    Collider, End, Hair as HairCore, Integrator, Material, Model, Motion, Repulsion, Rod as Core,
    Settings, State, Stats,
};
use crate::snapshot::Snapshot;
use glam::{DQuat, DVec3};
use numpy::{PyArrayDyn, PyReadonlyArrayDyn};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A discrete elastic rod; see `kinema.rods.Rod` for the API.
#[pyclass(module = "kinema._kinema")]
pub struct Rod {
    rod: Core,
    /// The scene's undo point (`_mark`).
    saved: Option<(State, Stats)>,
}

#[pymethods]
impl Rod {
    /// Pickle support: the rod as a snapshot (model and state).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.rod, vec![])
    }

    /// The object stored by `__reduce__`.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { rod: Core::from_snapshot(data)?, saved: None })
    }

    /// A rod at rest in the shape of `points` (N, 3) in m: semi-axes `radius` (m, along
    /// `m1` and `m2`), `youngs_modulus` and `shear_modulus` (Pa), `density` (kg/m³), twist
    /// angles `twist` (N - 1, rad) or none, `gravity` (m/s²), `integrator` ("implicit" or
    /// "symplectic"), Newton `tolerance` and `max_iterations`, the contact penalty's
    /// `contact_stiffness` (N/m) and friction's `friction_velocity` (m/s), `inextensible`
    /// (edge lengths held by projection) and `quasistatic_twist` (twists without inertia);
    /// `closed` for a ring (the last point joined to the first).
    #[new]
    #[allow(clippy::too_many_arguments)]
    fn new(
        points: PyReadonlyArrayDyn<'_, f64>,
        radius: [f64; 2],
        youngs_modulus: f64,
        shear_modulus: f64,
        density: f64,
        twist: Option<Vec<f64>>,
        gravity: [f64; 3],
        integrator: &str,
        tolerance: f64,
        max_iterations: Int,
        contact_stiffness: f64,
        friction_velocity: f64,
        inextensible: bool,
        quasistatic_twist: bool,
        closed: bool,
    ) -> PyResult<Self> {
        let points: Vec<DVec3> =
            rows::<3>(&points, "points", &[3])?.iter().map(|p| DVec3::from_array(*p)).collect();
        let material = Material { youngs_modulus, shear_modulus, density, radius };
        let settings = settings(
            gravity,
            integrator,
            tolerance,
            max_iterations,
            contact_stiffness,
            friction_velocity,
            inextensible,
            quasistatic_twist,
        )?;
        let model = if closed {
            Model::closed(&points, material, settings)?
        } else {
            Model::new(&points, material, settings)?
        };
        Ok(Rod { rod: Core::from_model(model, twist.as_deref())?, saved: None })
    }

    /// Keep a copy of the state and stats (the scene's undo point).
    fn _mark(&mut self) {
        let rod = &self.rod;
        let saved = self.saved.get_or_insert_with(|| (rod.state().clone(), rod.stats));
        saved.0.clone_from(rod.state());
        saved.1 = rod.stats;
    }

    /// Put the state and stats back as they were at the last `_mark`, in place.
    fn _rollback(&mut self) {
        if let Some((state, stats)) = &self.saved {
            self.rod.state_mut().clone_from(state);
            self.rod.stats = *stats;
        }
    }

    /// Clamp the first (`last` false) or last end: its edge keeps position and frame.
    fn clamp(&mut self, last: bool) {
        self.rod.model_mut().clamp(if last { End::Last } else { End::First });
    }

    /// Move the first (`last` false) or last clamped end to its rest pose rotated by
    /// `rotation` (w, x, y, z) and shifted by `translation` (m) by the end of the next step
    /// or static solve.
    fn move_clamp(
        &mut self,
        last: bool,
        rotation: [f64; 4],
        translation: [f64; 3],
    ) -> PyResult<()> {
        let end = if last { End::Last } else { End::First };
        Ok(self.rod.move_clamp(end, quaternion(rotation), DVec3::from_array(translation))?)
    }

    /// Add a static collider: its kind and parameters ([`super::geometry::shape`]), then
    /// Coulomb's friction coefficient.
    fn add_collider(&mut self, kind: &str, p: Vec<f64>) -> PyResult<()> {
        let (shape, t) = super::geometry::shape(kind, &p, 1)?;
        Ok(self.rod.model_mut().add_collider(Collider { shape, friction: t[0] })?)
    }

    /// Make the rod naturally straight and untwisted ([`kinema::rods::Model::straighten`]).
    fn straighten(&mut self) {
        self.rod.model_mut().straighten();
    }

    /// Twist a ring by `angle` (rad) more, spread evenly ([`kinema::rods::State::twist_ring`]).
    fn twist_ring(&mut self, angle: f64) -> PyResult<()> {
        Ok(self.rod.twist_ring(angle)?)
    }

    /// Hold vertex `index` where it is.
    fn pin(&mut self, index: Int) -> PyResult<()> {
        Ok(self.rod.model_mut().pin(index.count("index")?)?)
    }

    /// Set the external force (N) on vertex `index` for the later steps.
    fn set_force(&mut self, index: Int, force: [f64; 3]) -> PyResult<()> {
        let index = index.count("index")?;
        Ok(self.rod.state_mut().set_force(index, DVec3::from_array(force))?)
    }

    /// Advance `steps` steps of `dt` seconds (GIL released).
    fn step(&mut self, py: Python<'_>, dt: f64, steps: Int) -> PyResult<()> {
        let steps = steps.count("steps")?;
        let rod = &mut self.rod;
        detached(py, || rod.step(dt, steps))
    }

    /// Move to the static equilibrium nearest the current shape (GIL released).
    fn solve_static(&mut self, py: Python<'_>) -> PyResult<()> {
        let rod = &mut self.rod;
        detached(py, || rod.solve_static())
    }

    /// Number of vertices.
    fn __len__(&self) -> usize {
        self.rod.state().positions().len()
    }

    /// Read-only view (N, 3) of the positions (m), updated in place by `step`.
    #[getter]
    fn positions<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().rod.state().positions().len();
        view(slf, &[n, 3], |r| bytemuck::cast_slice(r.rod.state().positions()))
    }

    /// Read-only view (N, 3) of the velocities (m/s), updated in place by `step`.
    #[getter]
    fn velocities<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().rod.state().velocities().len();
        view(slf, &[n, 3], |r| bytemuck::cast_slice(r.rod.state().velocities()))
    }

    /// Read-only view (N - 1,) of the twist angles (rad), updated in place by `step`.
    #[getter]
    fn twists<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().rod.state().twists().len();
        view(slf, &[n], |r| r.rod.state().twists())
    }

    /// The material frames (N - 1, 3, 3): per edge the rows tangent, m1, m2 (a new array).
    fn material_frames<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let frames = self.rod.material_frames();
        compute::<9>(py, frames.len(), &[3, 3], |out| {
            let out = zeroed(out);
            for (o, f) in out.iter_mut().zip(&frames) {
                for (r, v) in f.iter().enumerate() {
                    o[3 * r..3 * r + 3].copy_from_slice(&v.to_array());
                }
            }
            Ok(())
        })
    }

    /// The elastic energy (J).
    fn energy(&mut self) -> f64 {
        self.rod.energy()
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.rod.state().time()
    }

    /// The lumped vertex masses (N,) in kg (a new array).
    fn masses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let m = self.rod.model().masses();
        compute::<1>(py, m.len(), &[], |out| {
            let out = zeroed(out);
            out.iter_mut().zip(m).for_each(|(o, v)| o[0] = *v);
            Ok(())
        })
    }

    /// Stiffnesses: stretching `EA` (N), bending `(EI1, EI2)` (N m²), twisting `GJ` (N m²).
    fn stiffness(&self) -> (f64, [f64; 2], f64) {
        let m = self.rod.model();
        (m.stretching_stiffness(), m.bending_stiffness(), m.twisting_stiffness())
    }

    /// What the last `step` or `solve_static` did.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        stats_dict(py, self.rod.stats)
    }
}

/// The rod settings from their Python arguments (the integrator by name).
#[allow(clippy::too_many_arguments)] // one per setting, as Python passes them
fn settings(
    gravity: [f64; 3],
    integrator: &str,
    tolerance: f64,
    max_iterations: Int,
    contact_stiffness: f64,
    friction_velocity: f64,
    inextensible: bool,
    quasistatic_twist: bool,
) -> PyResult<Settings> {
    let integrator = match integrator {
        "implicit" => Integrator::ImplicitEuler,
        "symplectic" => Integrator::SymplecticEuler,
        _ => return Err(Error::invalid("integrator", "expected 'implicit' or 'symplectic'").into()),
    };
    Ok(Settings {
        gravity: DVec3::from_array(gravity),
        integrator,
        tolerance,
        max_iterations: max_iterations.range("max_iterations", 1, MAX_ITERATIONS)?,
        contact_stiffness,
        friction_velocity,
        inextensible,
        quasistatic_twist,
    })
}

/// A quaternion given as (w, x, y, z).
fn quaternion([w, x, y, z]: [f64; 4]) -> DQuat {
    DQuat::from_xyzw(x, y, z, w)
}

/// Many strands of one rod model on a moving head; see `kinema.rods.Hair` for the API.
#[pyclass(module = "kinema._kinema")]
pub struct Hair {
    hair: HairCore,
    /// The scene's undo point (`_mark`).
    saved: Motion,
}

#[pymethods]
impl Hair {
    /// Pickle support: the hair as a snapshot (model, placements, states, head).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.hair, vec![])
    }

    /// The object stored by `__reduce__`.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { hair: HairCore::from_snapshot(data)?, saved: Motion::default() })
    }

    /// Strands grown from the scalp `points` (S, 3) along `normals` (S, 3): `length` (m),
    /// `segments` edges, helix radius `curl` (m); the material and settings as for `Rod`;
    /// the repulsion's `repulsion_stiffness` (N/m, 0 for none) and `thickness` (m), and
    /// Coulomb's `strand_friction` between strands; `inextensible` and `quasistatic_twist` as
    /// for `Rod`.
    #[new]
    #[allow(clippy::too_many_arguments)]
    fn new(
        points: PyReadonlyArrayDyn<'_, f64>,
        normals: PyReadonlyArrayDyn<'_, f64>,
        length: f64,
        segments: Int,
        curl: f64,
        radius: [f64; 2],
        youngs_modulus: f64,
        shear_modulus: f64,
        density: f64,
        gravity: [f64; 3],
        tolerance: f64,
        max_iterations: Int,
        contact_stiffness: f64,
        friction_velocity: f64,
        inextensible: bool,
        quasistatic_twist: bool,
        repulsion_stiffness: f64,
        thickness: f64,
        strand_friction: f64,
    ) -> PyResult<Self> {
        let vectors = |a: &PyReadonlyArrayDyn<'_, f64>, name: &str| -> PyResult<Vec<DVec3>> {
            Ok(rows::<3>(a, name, &[3])?.iter().map(|p| DVec3::from_array(*p)).collect())
        };
        let (points, normals) = (vectors(&points, "points")?, vectors(&normals, "normals")?);
        let material = Material { youngs_modulus, shear_modulus, density, radius };
        let settings = settings(
            gravity,
            "implicit",
            tolerance,
            max_iterations,
            contact_stiffness,
            friction_velocity,
            inextensible,
            quasistatic_twist,
        )?;
        let repulsion =
            Repulsion { stiffness: repulsion_stiffness, thickness, friction: strand_friction };
        let segments = segments.range("segments", 1, 1 << 20)?;
        let hair = HairCore::groom(
            &points, &normals, length, segments, curl, material, settings, repulsion,
        )?;
        Ok(Hair { hair, saved: Motion::default() })
    }

    /// Keep a copy of what changes (the scene's undo point).
    fn _mark(&mut self) {
        self.hair.save(&mut self.saved);
    }

    /// Put back what changed since the last `_mark`.
    fn _rollback(&mut self) {
        self.hair.restore(&self.saved);
    }

    /// Move the head to `rotation` (w, x, y, z) and `translation` (m) by the end of the
    /// next step call.
    fn set_head(&mut self, rotation: [f64; 4], translation: [f64; 3]) -> PyResult<()> {
        Ok(self.hair.set_head(quaternion(rotation), DVec3::from_array(translation))?)
    }

    /// The head's pose after the last step: rotation (w, x, y, z), translation (m).
    fn head(&self) -> ([f64; 4], [f64; 3]) {
        let (q, t) = self.hair.head();
        ([q.w, q.x, q.y, q.z], t.to_array())
    }

    /// Add a static collider: its kind and parameters, then Coulomb's friction coefficient.
    fn add_collider(&mut self, kind: &str, p: Vec<f64>) -> PyResult<()> {
        let (shape, t) = super::geometry::shape(kind, &p, 1)?;
        Ok(self.hair.add_collider(Collider { shape, friction: t[0] })?)
    }

    /// Make the head a moving frictionless collider: the ball of `center` (m, in the head's
    /// frame) and `radius` (m).
    fn set_head_collider(&mut self, center: [f64; 3], radius: f64) -> PyResult<()> {
        let ball = Sphere { center: DVec3::from_array(center), radius };
        Ok(self.hair.set_head_collider(ball)?)
    }

    /// Advance `steps` steps of `dt` seconds (GIL released, strands in parallel).
    fn step(&mut self, py: Python<'_>, dt: f64, steps: Int) -> PyResult<()> {
        let steps = steps.count("steps")?;
        let hair = &mut self.hair;
        detached(py, || hair.step(dt, steps))
    }

    /// Number of strands.
    fn __len__(&self) -> usize {
        self.hair.states().len()
    }

    /// The positions (S N, 3) in m, strand after strand (a new array).
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let states = self.hair.states();
        let n = self.hair.model().edges() + 1;
        compute::<3>(py, states.len() * n, &[3], |out| {
            let out = zeroed(out);
            let all = states.iter().flat_map(|s| s.positions());
            out.iter_mut().zip(all).for_each(|(o, p)| *o = p.to_array());
            Ok(())
        })
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.hair.states()[0].time()
    }

    /// What the last `step` did, summed over the strands.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        stats_dict(py, self.hair.stats)
    }
}

/// A step's counters as a Python dict: steps, Newton iterations, line-search halvings.
fn stats_dict(py: Python<'_>, s: Stats) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("steps", s.steps)?;
    d.set_item("iterations", s.iterations)?;
    d.set_item("halvings", s.halvings)?;
    Ok(d)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Rod>()?;
    m.add_class::<Hair>()
}
