//! `kinema.anim`: compiled keyframe tracks and subdivision.

use super::args::Int;
use super::array::compute;
use super::array::rows;
use super::error::{detached, reduce, Reduced};
use crate::anim::{
    subdivide, Extrapolation, Interpolation, RotationInterpolation, RotationTrack, Scheme, Track,
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
        let this = slf.borrow();
        let inner = &this.track;
        let bytes = detached(slf.py(), || inner.to_snapshot())?;
        reduce(slf.as_any(), bytes, vec![])
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
    track: RotationTrack,
}

#[pymethods]
impl KeyRotationTrack {
    /// Pickle support: the object as a snapshot (model and state, see `kinema::snapshot`).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        let this = slf.borrow();
        let inner = &this.track;
        let bytes = detached(slf.py(), || inner.to_snapshot())?;
        reduce(slf.as_any(), bytes, vec![])
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
        compute(py, ts.len(), &[4], |out| track.eval_many(ts, out))
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
        compute(py, ts.len(), &[3], |out| track.rates_many(ts, order, out))
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<KeyTrack>()?;
    m.add_class::<KeyRotationTrack>()?;
    m.add_function(wrap_pyfunction!(anim_subdivide, m)?)
}
