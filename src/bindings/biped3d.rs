//! `kinema.character.Biped(dims=3)`: the compiled 3-D SIMBICON walker.

use super::args::Int;
use super::array::{compute, zeroed};
use super::character::{gait, gait_values, walker_settings};
use super::error::detached;
use super::pickle::{reduce, Reduced};
use super::view::view;
use crate::character::{link_boxes_3d, Coronal, Phase, State, Walker3d as Core};
use crate::snapshot::Snapshot;
use glam::{DQuat, DVec3};
use numpy::PyArrayDyn;
use pyo3::prelude::*;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Walker3d>()
}

/// The 3-D SIMBICON walker; see `kinema.character.Biped` (`dims=3`) for the API.
#[pyclass(module = "kinema._kinema")]
pub struct Walker3d {
    walker: Core,
    /// The undo point of [`Walker3d::_mark`] (state and phase; none before the first).
    saved: Option<(State, Phase)>,
}

#[pymethods]
impl Walker3d {
    /// Pickle support: the walker as a snapshot (model, state, phase, gait, coronal).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.walker, vec![])
    }

    /// The object stored by `__reduce__`.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { walker: Core::from_snapshot(data)?, saved: None })
    }

    /// Remember the state and the controller's phase (a scene's undo point).
    fn _mark(&mut self) {
        let phase = self.walker.phase();
        match &mut self.saved {
            Some((state, saved)) => {
                state.clone_from(self.walker.state());
                *saved = phase;
            }
            None => self.saved = Some((self.walker.state().clone(), phase)),
        }
    }

    /// Put the state and the phase back as they were at the last [`Walker3d::_mark`].
    fn _rollback(&mut self) {
        if let Some((state, phase)) = &self.saved {
            self.walker.restore(state, *phase);
        }
    }

    /// The walker at `speed` (m/s) with the gait's `lift` and `strike` poses (8 values
    /// each), `[duration, kp, kd, torso_kp, torso_kd, max_torque]`, the coronal feedback
    /// `[cd, cv, swing_hip]`, the ground's `contact_frequency` (rad/s) and `friction`, on a
    /// `slope` (rad, positive climbs +x; gravity turns by it).
    #[new]
    #[allow(clippy::too_many_arguments)]
    fn new(
        lift: [f64; 8],
        strike: [f64; 8],
        control: [f64; 6],
        coronal: [f64; 3],
        speed: f64,
        contact_frequency: f64,
        friction: f64,
        slope: f64,
    ) -> PyResult<Self> {
        let settings = walker_settings(contact_frequency, friction, slope)?;
        let [cd, cv, swing_hip] = coronal;
        let coronal = Coronal { cd, cv, swing_hip };
        let walker = Core::new(settings, gait(lift, strike, control), coronal, speed)?;
        Ok(Walker3d { walker, saved: None })
    }

    /// The gait: `(lift, strike, [duration, kp, kd, torso_kp, torso_kd, max_torque])`.
    fn gait(&self) -> ([f64; 8], [f64; 8], [f64; 6]) {
        gait_values(&self.walker.gait)
    }

    /// The coronal feedback `[cd, cv, swing_hip]`.
    fn coronal(&self) -> [f64; 3] {
        let c = self.walker.coronal;
        [c.cd, c.cv, c.swing_hip]
    }

    /// Advance `steps` steps of `dt` seconds (GIL released).
    fn step(&mut self, py: Python<'_>, dt: f64, steps: Int) -> PyResult<()> {
        let steps = steps.count("steps")?;
        let walker = &mut self.walker;
        detached(py, || walker.step(dt, steps))
    }

    /// Push a body with `force` (N, world) for `duration` s.
    fn push(&mut self, body: Int, force: [f64; 3], duration: f64) -> PyResult<()> {
        let body = body.count("body")?;
        let (model, state) = self.walker.parts_mut();
        Ok(state.push(model, body, DVec3::from_array(force), duration)?)
    }

    /// Read-only view of the coordinates (25,), updated in place by `step`.
    #[getter]
    fn q<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().walker.model().nq();
        view(slf, &[n], |r| r.walker.state().q())
    }

    /// Read-only view of the rates (20,), updated in place by `step`.
    #[getter]
    fn qd<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().walker.model().nv();
        view(slf, &[n], |r| r.walker.state().qd())
    }

    /// Centre of mass (m, world).
    #[getter]
    fn com(&mut self) -> [f64; 3] {
        self.walker.com().to_array()
    }

    /// Whether the right and left feet touch the ground.
    #[getter]
    fn feet_in_contact(&mut self) -> (bool, bool) {
        let [r, l] = self.walker.feet_in_contact();
        (r, l)
    }

    /// `(FSM state, time in it (s), steps taken)`.
    fn phase(&self) -> (u8, f64, u64) {
        let p = self.walker.phase();
        (p.state, p.time, p.steps)
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.walker.state().time()
    }

    /// World positions of the body frames (9, 3) in m.
    fn positions<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let p: Vec<DVec3> = self.walker.kinematics().positions().to_vec();
        compute::<3>(py, p.len(), &[3], |out| {
            let out = zeroed(out);
            out.iter_mut().zip(&p).for_each(|(o, v)| *o = v.to_array());
            Ok(())
        })
    }

    /// World orientations of the body frames (9, 4) as (w, x, y, z) (a new array).
    fn orientations<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let r: Vec<DQuat> = self.walker.kinematics().orientations().to_vec();
        compute::<4>(py, r.len(), &[4], |out| {
            let out = zeroed(out);
            out.iter_mut().zip(&r).for_each(|(o, q)| *o = [q.w, q.x, q.y, q.z]);
            Ok(())
        })
    }

    /// The box drawn for each body, in its body frame: `(centre, half extents)` (m).
    #[staticmethod]
    fn link_boxes() -> Vec<([f64; 3], [f64; 3])> {
        link_boxes_3d().iter().map(|(c, h)| (c.to_array(), h.to_array())).collect()
    }

    /// Body names, in order.
    fn names(&self) -> Vec<String> {
        self.walker.model().bodies().iter().map(|b| b.name.clone()).collect()
    }
}
