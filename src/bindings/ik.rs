//! `kinema.ik`: inverse kinematics on Acclaim skeletons.

use super::args::{counts, Int, MAX_ITERATIONS};
use super::array::rows;
use super::error::detached;
use super::mocap::{pose_values, PySkeleton};
use crate::error::Error;
use crate::ik::{self, Method, Options, Report, Target};
use crate::rotation::quat_from_wxyz;
use glam::DVec3;
use numpy::{AllowTypeChange, PyArray1, PyArrayLike1, PyArrayMethods, PyReadonlyArrayDyn};
use pyo3::prelude::*;

/// What an IK solve achieved: converged, error (length units), orientation_error (rad),
/// iterations.
#[pyclass(module = "kinema._kinema", name = "IkReport", frozen)]
pub struct PyIkReport {
    report: Report,
}

#[pymethods]
impl PyIkReport {
    /// Every effector within tol of its target position (and orientation).
    #[getter]
    fn converged(&self) -> bool {
        self.report.converged
    }

    /// Largest position error over the effectors (skeleton length units).
    #[getter]
    fn error(&self) -> f64 {
        self.report.error
    }

    /// Largest orientation error over the effectors (radians; 0 without orientation targets).
    #[getter]
    fn orientation_error(&self) -> f64 {
        self.report.orientation_error
    }

    /// Iterations made (Jacobian steps or CCD sweeps; 1 for two-bone).
    #[getter]
    fn iterations(&self) -> usize {
        self.report.iterations
    }

    fn __repr__(&self) -> String {
        let r = &self.report;
        format!(
            "IkReport(converged={}, error={:e}, orientation_error={:e}, iterations={})",
            if r.converged { "True" } else { "False" },
            r.error,
            r.orientation_error,
            r.iterations
        )
    }
}

/// Solve IK; arguments as checked by `kinema.ik.solve` (positions (E, 3), one orientation
/// (w, x, y, z) or None per target, at most `MAX_ITERATIONS` (10^6) iterations). Returns the new pose and the report.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn ik_solve<'py>(
    py: Python<'py>,
    skeleton: &PySkeleton,
    pose: PyArrayLike1<'py, f64, AllowTypeChange>,
    joints: Vec<Int>,
    positions: PyReadonlyArrayDyn<'py, f64>,
    orientations: Vec<Option<[f64; 4]>>,
    method: &str,
    joint_limits: bool,
    rest_weight: f64,
    limit_weight: f64,
    rest: Option<PyArrayLike1<'py, f64, AllowTypeChange>>,
    free_root: bool,
    tol: f64,
    max_iters: Int,
) -> PyResult<(Bound<'py, PyArray1<f64>>, PyIkReport)> {
    let joints = counts(&joints, "joints")?;
    let max_iters = max_iters.range("max_iters", 0, MAX_ITERATIONS)?;
    let positions = rows::<3>(&positions, "targets", &[3])?;
    if positions.len() != joints.len() || orientations.len() != joints.len() {
        return Err(
            Error::invalid("targets", "needs one position and orientation per joint").into()
        );
    }
    let mut targets = Vec::with_capacity(joints.len());
    for (i, ((&joint, p), o)) in joints.iter().zip(positions).zip(&orientations).enumerate() {
        let orientation = match o {
            Some(q) => Some(quat_from_wxyz(q).map_err(|_| {
                Error::invalid("targets", "orientation must be a finite, non-zero quaternion").at(i)
            })?),
            None => None,
        };
        targets.push(Target { joint, position: DVec3::from_array(*p), orientation });
    }
    let options = Options {
        method: Method::parse(method)?,
        joint_limits,
        rest_weight,
        limit_weight,
        rest: rest.as_ref().map(|r| pose_values(r, "rest").map(<[f64]>::to_vec)).transpose()?,
        free_root,
        tol,
        max_iters,
    };
    let mut values = pose_values(&pose, "pose")?.to_vec();
    let sk = &skeleton.skeleton;
    let report = detached(py, || ik::solve(sk, &mut values, &targets, &options))?;
    Ok((PyArray1::from_vec(py, values), PyIkReport { report }))
}

/// The Jacobian (rows, columns) of the joints' positions (and orientations) at `pose`, and the
/// pose index of every column.
#[pyfunction]
fn ik_jacobian<'py>(
    py: Python<'py>,
    skeleton: &PySkeleton,
    pose: PyArrayLike1<'py, f64, AllowTypeChange>,
    joints: Vec<Int>,
    orientation: bool,
    free_root: bool,
) -> PyResult<(Bound<'py, numpy::PyArray2<f64>>, Vec<usize>)> {
    let joints = counts(&joints, "joints")?;
    let values = pose_values(&pose, "pose")?;
    let sk = &skeleton.skeleton;
    let (jac, cols) = detached(py, || ik::jacobian(sk, values, &joints, orientation, free_root))?;
    let n = cols.len();
    let m = joints.len() * if orientation { 6 } else { 3 };
    Ok((PyArray1::from_vec(py, jac).reshape([m, n])?, cols))
}

/// A serial chain skeleton (see `kinema.ik.chain`).
#[pyfunction]
fn ik_chain(
    lengths: Vec<f64>,
    dofs: Vec<String>,
    limits: Option<Vec<(f64, f64)>>,
) -> PyResult<PySkeleton> {
    let dofs: Vec<&str> = dofs.iter().map(String::as_str).collect();
    Ok(PySkeleton { skeleton: ik::chain(&lengths, &dofs, limits.as_deref())? })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyIkReport>()?;
    m.add_function(wrap_pyfunction!(ik_solve, m)?)?;
    m.add_function(wrap_pyfunction!(ik_jacobian, m)?)?;
    m.add_function(wrap_pyfunction!(ik_chain, m)?)
}
