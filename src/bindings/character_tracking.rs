//! `kinema.character.Tracker`: a ragdoll tracking an ASF/AMC clip (mocap tracking with a
//! measured root assistance, `crate::character::Tracker`).

use super::args::Int;
use super::array::{compute, zeroed};
use super::character::CapsuleTuple;
use super::error::detached;
use super::mocap::{PyBvhSkeleton, PyMotion, PySkeleton};
use super::pickle::{reduce, Reduced};
use crate::character::{
    FrameReport, RagdollOptions, Settings, State, TrackedSkeleton, Tracker as Core, TrackingOptions,
};
use crate::error::Error;
use crate::snapshot::Snapshot;
use numpy::PyArrayDyn;
use pyo3::prelude::*;

/// A ragdoll tracking a clip; see `kinema.character.Tracker`.
#[pyclass(module = "kinema._kinema")]
pub struct Tracker {
    tracker: Core,
    /// The undo point of `_mark` (the ragdoll's state and the frame; none before the first).
    saved: Option<(State, usize)>,
}

#[pymethods]
impl Tracker {
    /// The tracker of `motion` by the ragdoll of `skeleton` (ragdoll options as
    /// `ArticulatedBody.ragdoll`; gains and stepping as `TrackingOptions`), started at clip
    /// frame `start_frame` (`Tracker::start_at`).
    #[new]
    #[allow(clippy::too_many_arguments)]
    fn new(
        skeleton: &Bound<'_, PyAny>,
        motion: PyRef<'_, PyMotion>,
        ragdoll: [f64; 5],
        scale: Option<f64>,
        kp: f64,
        kd: f64,
        max_torque: f64,
        assist_frequency: f64,
        assist_damping: f64,
        substeps: Int,
        start_frame: Int,
    ) -> PyResult<Self> {
        let (skeleton, unit): (TrackedSkeleton, _) = if let Ok(sk) = skeleton.cast::<PySkeleton>() {
            let sk = &sk.borrow().skeleton;
            (sk.into(), Some(sk.metres_per_unit()))
        } else if let Ok(sk) = skeleton.cast::<PyBvhSkeleton>() {
            (TrackedSkeleton::from(&sk.borrow().skeleton), None)
        } else {
            return Err(Error::invalid("skeleton", "expected an ASF or a BVH skeleton").into());
        };
        let [density, radius_ratio, min_radius, damping, clearance] = ragdoll;
        let Some(scale) = scale.or(unit) else {
            return Err(Error::invalid("scale", "required for a BVH skeleton (m per unit)").into());
        };
        let ragdoll =
            RagdollOptions { density, scale, radius_ratio, min_radius, damping, clearance };
        let options = TrackingOptions {
            kp,
            kd,
            max_torque,
            assist_frequency,
            assist_damping,
            substeps: substeps.count("substeps")?,
        };
        let start = start_frame.count("start_frame")?;
        let mut tracker =
            Core::new(skeleton, &motion.motion, &ragdoll, Settings::default(), options)?;
        tracker.start_at(start)?;
        Ok(Tracker { tracker, saved: None })
    }

    /// Pickle support: the tracker as a snapshot (skeleton, clip, options, ragdoll, frame).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.tracker, vec![])
    }

    /// The object stored by `__reduce__`.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { tracker: Core::from_snapshot(data)?, saved: None })
    }

    /// Remember the ragdoll's state and the frame (a scene's undo point).
    fn _mark(&mut self) {
        let frame = self.tracker.frame();
        match &mut self.saved {
            Some((state, saved)) => {
                state.clone_from(self.tracker.body().state());
                *saved = frame;
            }
            None => self.saved = Some((self.tracker.body().state().clone(), frame)),
        }
    }

    /// Put the state and the frame back as they were at the last `_mark`.
    fn _rollback(&mut self) {
        if let Some((state, frame)) = &self.saved {
            self.tracker.restore(state, *frame);
        }
    }

    /// The clip's frame rate (Hz).
    #[getter]
    fn frame_rate(&self) -> f64 {
        self.tracker.frame_rate()
    }

    /// Track `frames` frames (GIL released); per frame `[time, root_error, joint_error,
    /// assist_force, assist_torque]` (frames, 5).
    fn step<'py>(&mut self, py: Python<'py>, frames: Int) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let frames = frames.count("frames")?;
        let tracker = &mut self.tracker;
        let rows: Vec<FrameReport> =
            detached(py, || (0..frames).map(|_| tracker.step()).collect())?;
        compute::<5>(py, rows.len(), &[5], |out| {
            let out = zeroed(out);
            for (o, r) in out.iter_mut().zip(&rows) {
                *o = [r.time, r.root_error, r.joint_error, r.assist_force, r.assist_torque];
            }
            Ok(())
        })
    }

    /// The ragdoll's coordinates (nq,) (a copy).
    #[getter]
    fn q(&self) -> Vec<f64> {
        self.tracker.body().state().q().to_vec()
    }

    /// The reference coordinates of the current frame (nq,) (a copy).
    #[getter]
    fn reference_q(&self) -> Vec<f64> {
        self.tracker.reference_q().to_vec()
    }

    /// The clip frame the ragdoll is at (the start frame plus the frames tracked).
    #[getter]
    fn frame(&self) -> usize {
        self.tracker.frame()
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.tracker.body().state().time()
    }

    /// `(a, b)`: the clip's frames `a..b` repeat after frame `b − 1`.
    #[getter]
    fn loop_span(&self) -> (usize, usize) {
        self.tracker.loop_span()
    }

    /// Total mass of the ragdoll (kg).
    #[getter]
    fn mass(&self) -> f64 {
        self.tracker.body().model().mass()
    }

    /// Body names, in order.
    fn names(&self) -> Vec<String> {
        self.tracker.body().model().bodies().iter().map(|b| b.name.clone()).collect()
    }

    /// World positions of the body frames (n, 3) in m.
    fn positions<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        super::character::positions(py, self.tracker.body_mut().kinematics())
    }

    /// World orientations of the body frames (n, 4) as (w, x, y, z).
    fn orientations<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        super::character::orientations(py, self.tracker.body_mut().kinematics())
    }

    /// Each body's capsule `(a, b, radius)` (m, body frame), or None.
    fn capsules(&self) -> Vec<Option<CapsuleTuple>> {
        super::character::capsules(self.tracker.body().model())
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Tracker>()
}
