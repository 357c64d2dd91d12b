//! `kinema.mocap`: Acclaim skeletons, BVH hierarchies and their motions.

use super::args::Int;
use super::pickle::{reduce, Reduced};
use crate::error::Error;
use crate::mocap::{
    asf_to_bvh, parse_amc, parse_asf, parse_bvh, write_amc, write_asf, write_bvh, BvhSkeleton, Dof,
    Edit, Motion, Skeleton,
};
use crate::snapshot::Snapshot;
use numpy::{AllowTypeChange, PyArray1, PyArray2, PyArrayLike1, PyArrayMethods};
use pyo3::prelude::*;

/// An Acclaim skeleton; see `kinema.mocap.read_asf`.
#[pyclass(module = "kinema._kinema", name = "AsfSkeleton", frozen)]
pub struct PySkeleton {
    pub(super) skeleton: Skeleton,
}

/// A motion for one skeleton (Acclaim or BVH); see `kinema.mocap.read_amc` and
/// `kinema.mocap.read_bvh`.
#[pyclass(module = "kinema._kinema", name = "AmcMotion", frozen)]
pub struct PyMotion {
    pub(super) motion: Motion,
    /// The skeleton the motion was read for (or edited with), for `resample`.
    skeleton: Py<PyAny>,
}

/// A pose argument: one frame of values for `skeleton`, as a slice.
pub(super) fn pose_values<'a>(
    pose: &'a PyArrayLike1<'_, f64, AllowTypeChange>,
    arg: &str,
) -> PyResult<&'a [f64]> {
    pose.as_slice().map_err(|_| crate::Error::invalid(arg, "must be a contiguous 1-D array").into())
}

/// The motion `motion` is, or a one-frame motion of the pose (1-D values, `stride` of them)
/// it holds, made in `one`; and whether it was a pose.
fn motion_or_pose<'a, 'py>(
    motion: &'a Bound<'py, PyAny>,
    stride: usize,
    one: &'a mut Option<Motion>,
) -> PyResult<(&'a Motion, bool)> {
    if let Ok(m) = motion.cast::<PyMotion>() {
        return Ok((&m.get().motion, false));
    }
    let pose: PyArrayLike1<'py, f64, AllowTypeChange> = motion.extract().map_err(|_| {
        crate::Error::invalid("motion", "expected a motion or one pose (1-D values)")
    })?;
    let values = pose_values(&pose, "motion")?;
    if values.len() != stride {
        return Err(crate::Error::invalid(
            "motion",
            format!("a pose needs {stride} values, got {}", values.len()),
        )
        .into());
    }
    if values.iter().any(|v| !v.is_finite()) {
        return Err(crate::Error::invalid("motion", "contains NaN or infinity").into());
    }
    let frame_rate = crate::mocap::CMU_FRAME_RATE;
    Ok((one.insert(Motion { values: values.to_vec(), stride, frames: 1, frame_rate }), true))
}

/// Python's forward kinematics result: joint positions and orientations of `motion` (`j`
/// joints) computed by `fk` with the GIL released, `(F, J, 3)` and `(F, J, 4)`, or `(J, 3)`
/// and `(J, 4)` when the motion is a `single` pose.
fn joint_frames<'py>(
    py: Python<'py>,
    motion: &Motion,
    j: usize,
    single: bool,
    fk: impl FnOnce(&mut [[f64; 3]], &mut [[f64; 4]]) -> crate::Result<()> + Send,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let f = motion.frames;
    let mut pos = vec![[0.0; 3]; f * j];
    let mut ori = vec![[0.0; 4]; f * j];
    super::error::detached(py, || fk(&mut pos, &mut ori))?;
    let pos = PyArray1::from_vec(py, pos.into_flattened());
    let ori = PyArray1::from_vec(py, ori.into_flattened());
    if single {
        Ok((pos.reshape([j, 3])?.into_any(), ori.reshape([j, 4])?.into_any()))
    } else {
        Ok((pos.reshape([f, j, 3])?.into_any(), ori.reshape([f, j, 4])?.into_any()))
    }
}

/// A core error about `pose` as one about the Python argument `motion`.
fn renamed(e: Error) -> Error {
    match e {
        Error::InvalidInput { index, reason, .. } => {
            Error::InvalidInput { arg: "motion".into(), index, reason }
        }
        other => other,
    }
}

#[pymethods]
impl PySkeleton {
    /// Pickle support: the object as a snapshot (model and state, see `kinema::snapshot`).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.skeleton, vec![])
    }

    /// The object stored by `__reduce__`, validated (a bad parent index, a non-unit axis...
    /// raises `ValueError`).
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        let skeleton = Skeleton::from_snapshot(data)?;
        Ok(Self { skeleton })
    }

    /// Joint names: "root" then the bones, parents first.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.skeleton.joint_names()
    }

    /// `:units length` as read.
    #[getter]
    fn length_unit(&self) -> f64 {
        self.skeleton.length_unit
    }

    /// `:units mass` as read (1.0 when absent; kept and written back, never applied).
    #[getter]
    fn mass_unit(&self) -> f64 {
        self.skeleton.mass_unit
    }

    /// Metres per file unit under the CMU reading (never applied automatically).
    #[getter]
    fn metres_per_unit(&self) -> f64 {
        self.skeleton.metres_per_unit()
    }

    /// Bone lengths in file units, in joint order after the root.
    #[getter]
    fn bone_lengths(&self) -> Vec<f64> {
        self.skeleton.bones.iter().map(|b| b.length).collect()
    }

    /// Parent joint index of every joint (-1 for the root).
    #[getter]
    fn parents(&self) -> Vec<i64> {
        std::iter::once(-1)
            .chain(self.skeleton.bones.iter().map(|b| b.parent.map_or(0, |p| p as i64 + 1)))
            .collect()
    }

    /// Whether every dof is within the ASF limits: for a motion, per frame, `(F,)` bool; for
    /// one pose `(stride,)`, a bool; for a batch of poses `(N, stride)`, `(N,)` bool.
    fn within_limits<'py>(
        &self,
        py: Python<'py>,
        motion: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let sk = &self.skeleton;
        if let Ok(m) = motion.cast::<PyMotion>() {
            let ok = sk.within_limits(&m.get().motion)?;
            return Ok(PyArray1::from_vec(py, ok).into_any());
        }
        // Two dimensions first: an empty (0, stride) batch also converts to an empty pose.
        let Ok(poses) = motion.extract::<numpy::PyArrayLike2<'py, f64, AllowTypeChange>>() else {
            let pose: PyArrayLike1<'py, f64, AllowTypeChange> = motion.extract().map_err(|_| {
                crate::Error::invalid("motion", "expected a motion, one pose or (N, stride) poses")
            })?;
            let ok = sk.pose_within_limits(pose_values(&pose, "motion")?).map_err(renamed)?;
            return Ok(pyo3::types::PyBool::new(py, ok).to_owned().into_any());
        };
        let view = poses.as_array();
        let ok = view
            .rows()
            .into_iter()
            .enumerate()
            .map(|(i, row)| {
                let row: Vec<f64> = row.iter().copied().collect();
                sk.pose_within_limits(&row).map_err(|e| match renamed(e) {
                    Error::InvalidInput { arg, reason, .. } => {
                        Error::InvalidInput { arg, index: Some(i), reason }
                    }
                    other => other,
                })
            })
            .collect::<Result<Vec<bool>, Error>>()?;
        Ok(PyArray1::from_vec(py, ok).into_any())
    }

    /// Values per pose (per frame): root dofs then each bone's dofs.
    #[getter]
    fn stride(&self) -> usize {
        self.skeleton.stride()
    }

    /// Positions (F, J, 3) in file units and orientations (F, J, 4) of every joint of a
    /// motion; for one pose (values of one frame), (J, 3) and (J, 4).
    fn forward_kinematics<'py>(
        &self,
        py: Python<'py>,
        motion: &Bound<'py, PyAny>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let sk = &self.skeleton;
        let mut one = None;
        let (m, single) = motion_or_pose(motion, sk.stride(), &mut one)?;
        joint_frames(py, m, 1 + sk.bones.len(), single, |p, o| sk.forward_kinematics(m, p, o))
    }
}

#[pymethods]
impl PyMotion {
    /// Pickle support: the skeleton and the motion as a snapshot.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        let skeleton = slf.borrow().skeleton.clone_ref(slf.py()).into_bound(slf.py());
        reduce(slf, |s| &s.motion, vec![skeleton])
    }

    /// The motion stored by `__reduce__`, for `skeleton`, validated.
    #[staticmethod]
    fn _from_snapshot(data: &[u8], skeleton: Py<PyAny>) -> PyResult<Self> {
        let motion = Motion::from_snapshot(data)?;
        Ok(Self { motion, skeleton })
    }

    /// Frame `i` as a pose: its values (root dofs then each bone's), radians / file units.
    fn pose<'py>(&self, py: Python<'py>, i: Int) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (m, i) = (&self.motion, i.count("i")?);
        if i >= m.frames {
            return Err(crate::Error::invalid(
                "i",
                format!("frame {i} does not exist; the motion has {}", m.frames),
            )
            .into());
        }
        Ok(PyArray1::from_slice(py, &m.values[i * m.stride..(i + 1) * m.stride]))
    }

    /// Number of frames.
    #[getter]
    fn frames(&self) -> usize {
        self.motion.frames
    }

    /// Frames per second (Hz).
    #[getter]
    fn frame_rate(&self) -> f64 {
        self.motion.frame_rate
    }

    /// The motion resampled from its frame rate to `to_rate` Hz over the same time span.
    fn resample(&self, py: Python<'_>, to_rate: f64) -> PyResult<PyMotion> {
        let m = &self.motion;
        let out = editable(self.skeleton.bind(py), |e| {
            super::error::detached(py, || e.resample(m, m.frame_rate, to_rate))
        })??;
        Ok(PyMotion { motion: out, skeleton: self.skeleton.clone_ref(py) })
    }

    /// Frames start..end as a new motion.
    fn slice(&self, py: Python<'_>, start: Int, end: Int) -> PyResult<PyMotion> {
        Ok(PyMotion {
            motion: self.motion.slice(start.count("start")?, end.count("end")?)?,
            skeleton: self.skeleton.clone_ref(py),
        })
    }

    /// All dof values (F, values per frame): root dofs then each bone's, radians / file units.
    fn values<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        PyArray1::from_vec(py, self.motion.values.clone())
            .reshape([self.motion.frames, self.motion.stride])
    }
}

/// Run `f` on the editing view of an Acclaim or BVH skeleton.
fn editable<R>(skeleton: &Bound<'_, PyAny>, f: impl FnOnce(&dyn Edit) -> R) -> PyResult<R> {
    if let Ok(s) = skeleton.cast::<PySkeleton>() {
        Ok(f(&s.get().skeleton))
    } else if let Ok(s) = skeleton.cast::<PyBvhSkeleton>() {
        Ok(f(&s.get().skeleton))
    } else {
        Err(Error::invalid("skeleton", "expected a skeleton from read_asf or read_bvh").into())
    }
}

/// The motion sampled at fractional frame positions `at` (non-decreasing).
#[pyfunction]
fn mocap_time_warp(
    py: Python<'_>,
    skeleton: &Bound<'_, PyAny>,
    motion: &PyMotion,
    at: Vec<f64>,
) -> PyResult<PyMotion> {
    let m = &motion.motion;
    let out = editable(skeleton, |e| super::error::detached(py, || e.time_warp(m, &at)))??;
    Ok(PyMotion { motion: out, skeleton: skeleton.clone().unbind() })
}

/// Frame-by-frame blend of `a` and `b` with the share `weights` of `b` (one or per frame).
#[pyfunction]
fn mocap_blend(
    py: Python<'_>,
    skeleton: &Bound<'_, PyAny>,
    a: &PyMotion,
    b: &PyMotion,
    weights: Vec<f64>,
) -> PyResult<PyMotion> {
    let (a, b) = (&a.motion, &b.motion);
    let out = editable(skeleton, |e| super::error::detached(py, || e.blend(a, b, &weights)))??;
    Ok(PyMotion { motion: out, skeleton: skeleton.clone().unbind() })
}

/// `b` after `a`, root-aligned, blended over `transition` frames.
#[pyfunction]
fn mocap_stitch(
    py: Python<'_>,
    skeleton: &Bound<'_, PyAny>,
    a: &PyMotion,
    b: &PyMotion,
    transition: Int,
) -> PyResult<PyMotion> {
    let (a, b, transition) = (&a.motion, &b.motion, transition.count("transition")?);
    let out = editable(skeleton, |e| super::error::detached(py, || e.stitch(a, b, transition)))??;
    Ok(PyMotion { motion: out, skeleton: skeleton.clone().unbind() })
}

/// Motion warping through the key poses `keys` (frame, pose values).
#[pyfunction]
fn mocap_warp(
    py: Python<'_>,
    skeleton: &Bound<'_, PyAny>,
    motion: &PyMotion,
    keys: Vec<(Int, Vec<f64>)>,
) -> PyResult<PyMotion> {
    let m = &motion.motion;
    let keys = keys
        .into_iter()
        .map(|(frame, pose)| Ok((frame.count("keys")?, pose)))
        .collect::<PyResult<Vec<_>>>()?;
    let out = editable(skeleton, |e| super::error::detached(py, || e.warp(m, &keys)))??;
    Ok(PyMotion { motion: out, skeleton: skeleton.clone().unbind() })
}

/// Parse ASF text; `file` names it in errors (kinema.ParseError with the line).
#[pyfunction]
fn mocap_parse_asf(text: &str, file: &str) -> PyResult<PySkeleton> {
    Ok(PySkeleton { skeleton: parse_asf(text, file)? })
}

/// Parse AMC text for `skeleton`, captured at `frame_rate` Hz (AMC files do not store it).
#[pyfunction]
fn mocap_parse_amc(
    text: &str,
    file: &str,
    skeleton: &Bound<'_, PySkeleton>,
    frame_rate: f64,
) -> PyResult<PyMotion> {
    if !(frame_rate.is_finite() && frame_rate > 0.0) {
        return Err(Error::invalid(
            "frame_rate",
            format!("must be positive and finite, got {frame_rate}"),
        )
        .into());
    }
    let mut motion = parse_amc(text, file, &skeleton.get().skeleton)?;
    motion.frame_rate = frame_rate;
    Ok(PyMotion { motion, skeleton: skeleton.clone().into_any().unbind() })
}

/// The skeleton as ASF text.
#[pyfunction]
fn mocap_write_asf(skeleton: &PySkeleton) -> String {
    write_asf(&skeleton.skeleton)
}

/// The motion as AMC text for `skeleton`.
#[pyfunction]
fn mocap_write_amc(skeleton: &PySkeleton, motion: &PyMotion) -> PyResult<String> {
    Ok(write_amc(&skeleton.skeleton, &motion.motion)?)
}

/// A BVH hierarchy; see `kinema.mocap.read_bvh`.
#[pyclass(module = "kinema._kinema", name = "BvhSkeleton", frozen)]
pub struct PyBvhSkeleton {
    pub(super) skeleton: BvhSkeleton,
}

#[pymethods]
impl PyBvhSkeleton {
    /// Pickle support: the object as a snapshot (model and state, see `kinema::snapshot`).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.skeleton, vec![])
    }

    /// The object stored by `__reduce__`, validated (a bad parent index, a non-unit axis...
    /// raises `ValueError`).
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        let skeleton = BvhSkeleton::from_snapshot(data)?;
        Ok(Self { skeleton })
    }

    /// Joint names in file order (depth first, parents first).
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.skeleton.joint_names()
    }

    /// Parent joint index of every joint (-1 for a ROOT).
    #[getter]
    fn parents(&self) -> Vec<i64> {
        self.skeleton.joints.iter().map(|j| j.parent.map_or(-1, |p| p as i64)).collect()
    }

    /// OFFSET of every joint (J, 3), file units, in the parent's frame.
    #[getter]
    fn offsets<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let v: Vec<f64> = self.skeleton.joints.iter().flat_map(|j| j.offset.to_array()).collect();
        PyArray1::from_vec(py, v).reshape([self.skeleton.joints.len(), 3])
    }

    /// Channel names of every joint in file order, e.g. ["Zrotation", "Yrotation", "Xrotation"].
    #[getter]
    fn channels(&self) -> Vec<Vec<String>> {
        let name = |d: &Dof| match *d {
            Dof::Translation(a) => format!("{}position", ["X", "Y", "Z"][a]),
            Dof::Rotation(a) => format!("{}rotation", ["X", "Y", "Z"][a]),
            Dof::Length => "length".to_string(),
        };
        self.skeleton.joints.iter().map(|j| j.channels.iter().map(name).collect()).collect()
    }

    /// End Site OFFSET of every joint (None where there is none), in the joint's frame.
    #[getter]
    fn end_sites(&self) -> Vec<Option<[f64; 3]>> {
        self.skeleton.joints.iter().map(|j| j.end_site.map(|e| e.to_array())).collect()
    }

    /// Frame Time: seconds per frame.
    #[getter]
    fn frame_time(&self) -> f64 {
        self.skeleton.frame_time
    }

    /// Values per pose (per frame): every joint's channels in file order.
    #[getter]
    fn stride(&self) -> usize {
        self.skeleton.stride()
    }

    /// Positions (F, J, 3) in file units and orientations (F, J, 4) of every joint of a
    /// motion; for one pose (values of one frame), (J, 3) and (J, 4).
    fn forward_kinematics<'py>(
        &self,
        py: Python<'py>,
        motion: &Bound<'py, PyAny>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let sk = &self.skeleton;
        let mut one = None;
        let (m, single) = motion_or_pose(motion, sk.stride(), &mut one)?;
        joint_frames(py, m, sk.joints.len(), single, |p, o| sk.forward_kinematics(m, p, o))
    }
}

/// Parse BVH text; `file` names it in errors (kinema.ParseError with the line).
#[pyfunction]
fn mocap_parse_bvh(
    py: Python<'_>,
    text: &str,
    file: &str,
) -> PyResult<(Py<PyBvhSkeleton>, PyMotion)> {
    let (skeleton, motion) = super::error::detached(py, || parse_bvh(text, file))?;
    let skeleton = Py::new(py, PyBvhSkeleton { skeleton })?;
    Ok((skeleton.clone_ref(py), PyMotion { motion, skeleton: skeleton.into_any() }))
}

/// The skeleton and motion as BVH text.
#[pyfunction]
fn mocap_write_bvh(
    py: Python<'_>,
    skeleton: &PyBvhSkeleton,
    motion: &PyMotion,
) -> PyResult<String> {
    super::error::detached(py, || write_bvh(&skeleton.skeleton, &motion.motion))
}

/// The BVH hierarchy and motion of an ASF skeleton and its motion (`kinema::mocap::asf_to_bvh`).
#[pyfunction]
fn mocap_asf_to_bvh(
    py: Python<'_>,
    skeleton: &PySkeleton,
    motion: &PyMotion,
) -> PyResult<(Py<PyBvhSkeleton>, PyMotion)> {
    let (skeleton, motion) =
        super::error::detached(py, || asf_to_bvh(&skeleton.skeleton, &motion.motion))?;
    let skeleton = Py::new(py, PyBvhSkeleton { skeleton })?;
    Ok((skeleton.clone_ref(py), PyMotion { motion, skeleton: skeleton.into_any() }))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyBvhSkeleton>()?;
    m.add_function(wrap_pyfunction!(mocap_asf_to_bvh, m)?)?;
    m.add_function(wrap_pyfunction!(mocap_parse_bvh, m)?)?;
    m.add_function(wrap_pyfunction!(mocap_write_bvh, m)?)?;
    m.add_function(wrap_pyfunction!(mocap_write_asf, m)?)?;
    m.add_function(wrap_pyfunction!(mocap_write_amc, m)?)?;
    m.add_class::<PySkeleton>()?;
    m.add_class::<PyMotion>()?;
    m.add_function(wrap_pyfunction!(mocap_parse_asf, m)?)?;
    m.add_function(wrap_pyfunction!(mocap_time_warp, m)?)?;
    m.add_function(wrap_pyfunction!(mocap_blend, m)?)?;
    m.add_function(wrap_pyfunction!(mocap_stitch, m)?)?;
    m.add_function(wrap_pyfunction!(mocap_warp, m)?)?;
    m.add_function(wrap_pyfunction!(mocap_parse_amc, m)?)
}
