//! `kinema.anim`: compiled keyframe tracks and subdivision.

use super::args::Int;
use super::array::rows;
use super::array::{compute, zeroed};
use super::error::detached;
use super::pickle::{reduce, Reduced};
use crate::anim::{
    subdivide, ArcLengthCurve, Channel, Clip, Easing, Extrapolation, Interpolation,
    RotationInterpolation, RotationTrack, Samples, Scheme, Track,
};
use crate::error::Error;
use crate::snapshot::Snapshot;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

fn matrix<'a>(arr: &'a PyReadonlyArrayDyn<'_, f64>, arg: &str) -> PyResult<(&'a [f64], usize)> {
    let shape = arr.shape();
    if shape.len() != 2 {
        return Err(Error::Shape {
            arg: arg.into(),
            expected: "(N, D)".into(),
            got: shape.to_vec(),
        }
        .into());
    }
    let flat =
        arr.as_slice().map_err(|_| PyErr::from(Error::invalid(arg, "must be contiguous")))?;
    Ok((flat, shape[1]))
}

/// A keyframed channel; see `kinema.anim.Track` for the documented API.
#[pyclass(module = "kinema._kinema", frozen)]
pub struct KeyTrack {
    pub(crate) track: Track,
}

#[pymethods]
impl KeyTrack {
    /// Pickle support: the object as a snapshot (model and state, see `kinema::snapshot`).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.track, vec![])
    }

    /// The object stored by `__reduce__`.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { track: Track::from_snapshot(data)? })
    }

    /// `times` (N, 1), `values` (N, D), the scheme's name (or one per segment) and its
    /// parameters.
    #[new]
    #[pyo3(signature = (times, values, interpolation, extrapolate, params, extra=None))]
    fn new(
        times: PyReadonlyArrayDyn<'_, f64>,
        values: PyReadonlyArrayDyn<'_, f64>,
        interpolation: Vec<String>,
        extrapolate: &str,
        params: Vec<f64>,
        extra: Option<PyReadonlyArrayDyn<'_, f64>>,
    ) -> PyResult<Self> {
        let t: Vec<f64> = rows::<1>(&times, "times", &[1])?.iter().map(|r| r[0]).collect();
        let (v, dim) = matrix(&values, "values")?;
        let extra = match &extra {
            Some(e) => Some(matrix(e, "tangents")?.0.to_vec()),
            None => None,
        };
        let need_extra = |name: &str| {
            extra.clone().ok_or_else(|| {
                PyErr::from(Error::invalid(name, "is required for this interpolation"))
            })
        };
        let p = |k: usize| params.get(k).copied().unwrap_or(0.0);
        let scheme = |name: &str| -> PyResult<Interpolation> {
            Ok(match name {
                "step" => Interpolation::Step,
                "linear" => Interpolation::Linear,
                "polynomial" => Interpolation::Polynomial,
                "natural_cubic" => Interpolation::NaturalCubic,
                "clamped_cubic" => {
                    let e = extra.clone().unwrap_or_else(|| vec![0.0; 2 * dim]);
                    if e.len() != 2 * dim {
                        return Err(Error::invalid(
                            "end_tangents",
                            format!("expected 2 x {dim} values, got {}", e.len()),
                        )
                        .into());
                    }
                    Interpolation::ClampedCubic { start: e[..dim].to_vec(), end: e[dim..].to_vec() }
                }
                "hermite" => Interpolation::Hermite { tangents: need_extra("tangents")? },
                "catmull_rom" => Interpolation::Cardinal { tension: 0.0 },
                "cardinal" => Interpolation::Cardinal { tension: p(0) },
                "kochanek_bartels" => {
                    Interpolation::KochanekBartels { tension: p(0), continuity: p(1), bias: p(2) }
                }
                "bezier" => Interpolation::Bezier { handles: need_extra("handles")? },
                "bspline" => Interpolation::BSpline,
                other => {
                    return Err(Error::invalid(
                        "interpolation",
                        format!("{other:?} is not a known interpolation"),
                    )
                    .into())
                }
            })
        };
        let schemes = interpolation.iter().map(|n| scheme(n)).collect::<PyResult<Vec<_>>>()?;
        let extrapolate = Extrapolation::parse(extrapolate)?;
        let track = match schemes.as_slice() {
            [one] => Track::new(&t, v, dim, one.clone(), extrapolate)?,
            many => Track::per_segment(&t, v, dim, many, extrapolate)?,
        };
        Ok(KeyTrack { track })
    }

    /// Values (order 0) or time derivatives (order 1, 2) at times `t` (M, 1): (M, D).
    fn eval<'py>(
        &self,
        py: Python<'py>,
        t: PyReadonlyArrayDyn<'py, f64>,
        order: Int,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let order = order.count("order")?;
        let ts = rows::<1>(&t, "t", &[1])?.as_flattened();
        let dim = self.track.dim();
        let mut out = vec![0.0; ts.len() * dim];
        let track = &self.track;
        super::error::detached(py, || track.eval_many(ts, order, &mut out))?;
        PyArray1::from_vec(py, out).reshape([ts.len(), dim])
    }

    /// Channel width D.
    #[getter]
    fn dim(&self) -> usize {
        self.track.dim()
    }
}

/// Subdivide the polygon `points` (N, D) by `scheme` `iterations` times; (M, D).
#[pyfunction]
fn anim_subdivide<'py>(
    py: Python<'py>,
    points: PyReadonlyArrayDyn<'py, f64>,
    scheme: &str,
    iterations: Int,
    closed: bool,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let iterations = iterations.count("iterations")?;
    let (p, dim) = matrix(&points, "points")?;
    let out = subdivide(p, dim, Scheme::parse(scheme)?, iterations, closed)?;
    let m = out.len() / dim;
    PyArray1::from_vec(py, out).reshape([m, dim])
}

/// A keyframed orientation; see `kinema.anim.RotationTrack` for the documented API.
#[pyclass(module = "kinema._kinema", frozen)]
pub struct KeyRotationTrack {
    pub(crate) track: RotationTrack,
}

#[pymethods]
impl KeyRotationTrack {
    /// Pickle support: the object as a snapshot (model and state, see `kinema::snapshot`).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.track, vec![])
    }

    /// The object stored by `__reduce__`.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { track: RotationTrack::from_snapshot(data)? })
    }

    /// `times` (N, 1), `quats` (N, 4) scalar-first, `interpolation` slerp | squad | spline,
    /// `shortest` one flag per segment (empty: shorter arcs everywhere).
    #[new]
    fn new(
        times: PyReadonlyArrayDyn<'_, f64>,
        quats: PyReadonlyArrayDyn<'_, f64>,
        interpolation: &str,
        shortest: Vec<bool>,
    ) -> PyResult<Self> {
        let t: Vec<f64> = rows::<1>(&times, "times", &[1])?.iter().map(|r| r[0]).collect();
        let q = rows::<4>(&quats, "rotations", &[4])?;
        let mode = RotationInterpolation::parse(interpolation)?;
        Ok(KeyRotationTrack { track: RotationTrack::new(&t, q, mode, &shortest)? })
    }

    /// Orientations (M, 4) at times `t` (M, 1).
    fn eval<'py>(
        &self,
        py: Python<'py>,
        t: PyReadonlyArrayDyn<'py, f64>,
    ) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
        let ts = rows::<1>(&t, "t", &[1])?.as_flattened();
        let track = &self.track;
        compute(py, ts.len(), &[4], |out| track.eval_many(ts, zeroed(out)))
    }

    /// Angular velocities (`order` 1, rad/s) or accelerations (`order` 2, rad/s²), world
    /// frame, (M, 3) at times `t` (M, 1).
    fn rates<'py>(
        &self,
        py: Python<'py>,
        t: PyReadonlyArrayDyn<'py, f64>,
        order: Int,
    ) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
        let order = order.count("order")?;
        let ts = rows::<1>(&t, "t", &[1])?.as_flattened();
        let track = &self.track;
        compute(py, ts.len(), &[3], |out| track.rates_many(ts, order, zeroed(out)))
    }
}

/// A value track reparameterised by arc length; see `kinema.anim.ArcLengthCurve`.
#[pyclass(module = "kinema._kinema", frozen)]
pub struct ArcLengthTable {
    curve: ArcLengthCurve,
}

#[pymethods]
impl ArcLengthTable {
    /// Pickle support: the object as a snapshot (track and table, see `kinema::snapshot`).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.curve, vec![])
    }

    /// The object stored by `__reduce__`.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { curve: ArcLengthCurve::from_snapshot(data)? })
    }

    /// Tabulate the arc length of `track` to relative accuracy `tol`.
    #[new]
    fn new(py: Python<'_>, track: &KeyTrack, tol: f64) -> PyResult<Self> {
        let track = track.track.clone();
        Ok(Self { curve: detached(py, || ArcLengthCurve::new(track, tol))? })
    }

    /// Total arc length.
    #[getter]
    fn length(&self) -> f64 {
        self.curve.length()
    }

    /// Track times (M, 1) at arc lengths `s` (M, 1), clamped to [0, length].
    fn time_at<'py>(
        &self,
        py: Python<'py>,
        s: PyReadonlyArrayDyn<'py, f64>,
    ) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
        let s = rows::<1>(&s, "s", &[1])?;
        let curve = &self.curve;
        compute(py, s.len(), &[1], |out| curve.times_at(s, out))
    }
}

/// The easing `kind` of `u` (M, 1), clamped to [0, 1]: (M, 1).
#[pyfunction]
fn anim_ease<'py>(
    py: Python<'py>,
    u: PyReadonlyArrayDyn<'py, f64>,
    kind: &str,
) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
    let easing = Easing::parse(kind)?;
    let u = rows::<1>(&u, "u", &[1])?;
    compute(py, u.len(), &[1], |out| easing.eval_many(u, out))
}

/// Named channels sampled together; see `kinema.anim.Clip`.
#[pyclass(module = "kinema._kinema", frozen)]
pub struct AnimClip {
    clip: Clip,
    /// The tracks it was made of, for pickling.
    tracks: Vec<Py<PyAny>>,
}

#[pymethods]
impl AnimClip {
    /// Pickle support: the clip is rebuilt from its names and tracks.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        let py = slf.py();
        let this = slf.borrow();
        let names: Vec<&str> = this.clip.channels().iter().map(|(n, _)| n.as_str()).collect();
        let args = (names, this.tracks.iter().map(|t| t.bind(py)).collect::<Vec<_>>());
        Ok((slf.get_type().into_any(), args.into_pyobject(py)?))
    }

    /// A clip of `tracks` (each a `KeyTrack` or `KeyRotationTrack`) called `names`.
    #[new]
    fn new(names: Vec<String>, tracks: Vec<Bound<'_, PyAny>>) -> PyResult<Self> {
        if names.len() != tracks.len() {
            return Err(Error::invalid("channels", "needs one name per track").into());
        }
        let mut channels = Vec::with_capacity(tracks.len());
        for (name, t) in names.into_iter().zip(&tracks) {
            let channel = if let Ok(v) = t.cast::<KeyTrack>() {
                Channel::Value(v.get().track.clone())
            } else if let Ok(r) = t.cast::<KeyRotationTrack>() {
                Channel::Rotation(r.get().track.clone())
            } else {
                return Err(Error::invalid("channels", "expected Track or RotationTrack").into());
            };
            channels.push((name, channel));
        }
        let tracks = tracks.into_iter().map(Bound::unbind).collect();
        Ok(Self { clip: Clip::new(channels)?, tracks })
    }

    /// Time of the first key of any channel (s).
    #[getter]
    fn start(&self) -> f64 {
        self.clip.start()
    }

    /// Time of the last key of any channel (s).
    #[getter]
    fn end(&self) -> f64 {
        self.clip.end()
    }

    /// Frame times (F,) at `fps` and each channel's samples: (F, D) values or (F, 4)
    /// quaternions, in channel order.
    #[allow(clippy::type_complexity)]
    fn sample<'py>(
        &self,
        py: Python<'py>,
        fps: f64,
    ) -> PyResult<(Bound<'py, PyArray1<f64>>, Vec<Bound<'py, PyArray2<f64>>>)> {
        let clip = &self.clip;
        let (t, samples) = detached(py, || clip.sample(fps))?;
        let frames = t.len();
        let arrays = samples
            .into_iter()
            .map(|s| match s {
                Samples::Value(v) => {
                    let dim = v.len() / frames;
                    PyArray1::from_vec(py, v).reshape([frames, dim])
                }
                Samples::Rotation(q) => {
                    PyArray1::from_vec(py, q.into_flattened()).reshape([frames, 4])
                }
            })
            .collect::<PyResult<_>>()?;
        Ok((PyArray1::from_vec(py, t), arrays))
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<KeyTrack>()?;
    m.add_class::<KeyRotationTrack>()?;
    m.add_class::<ArcLengthTable>()?;
    m.add_class::<AnimClip>()?;
    m.add_function(wrap_pyfunction!(anim_ease, m)?)?;
    m.add_function(wrap_pyfunction!(anim_subdivide, m)?)
}
