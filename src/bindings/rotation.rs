//! Rotation kernels for `kinema.rotation`: every function maps batches of rows and
//! broadcasts a batch of one against a batch of N.

use super::array::{compute, rows, zeroed};
use crate::batch::{broadcast_len, fill, item, map, map2};
use crate::error::{ensure_finite, Error, Result};
use crate::rotation::{self as rot, EulerSequence};
use glam::{DQuat, DVec3};
use numpy::{PyArrayDyn, PyReadonlyArrayDyn};
use pyo3::prelude::*;

type Array<'py> = Bound<'py, PyArrayDyn<f64>>;

fn q(row: &[f64; 4]) -> Result<DQuat> {
    rot::quat_from_wxyz(row)
}

fn wxyz(q: DQuat) -> [f64; 4] {
    rot::quat_to_wxyz(q)
}

/// Unit quaternions (N, 4) from any non-zero finite 4-vectors (N, 4); `canonical` picks w >= 0.
#[pyfunction]
fn quat_normalize<'py>(
    py: Python<'py>,
    quat: PyReadonlyArrayDyn<'py, f64>,
    canonical: bool,
) -> PyResult<Array<'py>> {
    let input = rows::<4>(&quat, "quat", &[4])?;
    compute(py, input.len(), &[4], |out| rot::normalize_quats(input, canonical, out))
}

/// Hamilton products a * b (N, 4) of quaternion batches broadcast one against N (the product
/// of unit quaternions is unit to rounding; any later kernel renormalises if it drifts).
#[pyfunction]
fn quat_multiply<'py>(
    py: Python<'py>,
    a: PyReadonlyArrayDyn<'py, f64>,
    b: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let (a, b) = (rows::<4>(&a, "a", &[4])?, rows::<4>(&b, "b", &[4])?);
    let n = broadcast_len(("a", a.len()), ("b", b.len()))?;
    compute(py, n, &[4], |out| rot::multiply_quats(a, b, out))
}

/// Rotation matrices (N, 3, 3) of quaternions (N, 4).
#[pyfunction]
fn quat_to_matrix<'py>(
    py: Python<'py>,
    quat: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let input = rows::<4>(&quat, "quat", &[4])?;
    compute(py, input.len(), &[3, 3], |out| rot::quats_to_matrices(input, out))
}

/// Quaternions (N, 4) of rotation matrices (N, 3, 3); non-rotations are refused unless
/// `orthonormalize` projects them onto the nearest rotation.
#[pyfunction]
fn matrix_to_quat<'py>(
    py: Python<'py>,
    matrix: PyReadonlyArrayDyn<'py, f64>,
    orthonormalize: bool,
) -> PyResult<Array<'py>> {
    let input = rows::<9>(&matrix, "matrix", &[3, 3])?;
    compute(py, input.len(), &[4], |out| {
        map(input, out, |m| Ok(wxyz(rot::quat_from_matrix(m, orthonormalize)?)))
    })
}

/// Rotation vectors (N, 3) of quaternions (N, 4), angle in [0, pi].
#[pyfunction]
fn quat_to_rotvec<'py>(
    py: Python<'py>,
    quat: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let input = rows::<4>(&quat, "quat", &[4])?;
    compute(py, input.len(), &[3], |out| map(input, out, |r| Ok(rot::quat_to_rotvec(q(r)?))))
}

/// Quaternions (N, 4) of rotation vectors (N, 3).
#[pyfunction]
fn rotvec_to_quat<'py>(
    py: Python<'py>,
    rotvec: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let input = rows::<3>(&rotvec, "rotvec", &[3])?;
    compute(py, input.len(), &[4], |out| rot::quats_from_rotvecs(input, out))
}

/// Quaternions (N, 4) of axes (N, 3) and angles (N, 1), broadcast one against N.
#[pyfunction]
fn axis_angle_to_quat<'py>(
    py: Python<'py>,
    axis: PyReadonlyArrayDyn<'py, f64>,
    angle: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let (axis, angle) = (rows::<3>(&axis, "axis", &[3])?, rows::<1>(&angle, "angle", &[1])?);
    let n = broadcast_len(("axis", axis.len()), ("angle", angle.len()))?;
    compute(py, n, &[4], |out| {
        map2(axis, angle, out, |a, t| Ok(wxyz(rot::quat_from_axis_angle(a, t[0])?)))
    })
}

/// Unit axes (N, 3) and angles in [0, pi] (N, 1) of quaternions (N, 4).
#[pyfunction]
fn quat_to_axis_angle<'py>(
    py: Python<'py>,
    quat: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let input = rows::<4>(&quat, "quat", &[4])?;
    compute(py, input.len(), &[4], |out| {
        map(input, out, |r| {
            let ([x, y, z], angle) = rot::quat_to_axis_angle(q(r)?);
            Ok([x, y, z, angle])
        })
    })
}

/// Quaternions (N, 4) of Euler angles (N, 3) in sequence `seq`.
#[pyfunction]
fn euler_to_quat<'py>(
    py: Python<'py>,
    seq: &str,
    angles: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let seq = EulerSequence::parse(seq)?;
    let input = rows::<3>(&angles, "angles", &[3])?;
    compute(py, input.len(), &[4], |out| map(input, out, |a| Ok(wxyz(seq.to_quat(a)?))))
}

/// Euler angles (N, 3) in sequence `seq` of quaternions (N, 4), and how many of them are
/// gimbal-locked (third angle set to 0).
#[pyfunction]
fn quat_to_euler<'py>(
    py: Python<'py>,
    seq: &str,
    quat: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<(Array<'py>, usize)> {
    let seq = EulerSequence::parse(seq)?;
    let input = rows::<4>(&quat, "quat", &[4])?;
    let mut locked = 0;
    let angles = compute(py, input.len(), &[3], |out| {
        locked = seq.from_quats(input, out)?;
        Ok(())
    })?;
    Ok((angles, locked))
}

/// Davenport angles (N, 3) of quaternions (N, 4) about unit axes (M, 9) (row-major
/// `[n1, n2, n3]`, M = 1 or N), extrinsic or intrinsic, and how many are gimbal-locked.
#[pyfunction]
fn quat_to_davenport<'py>(
    py: Python<'py>,
    axes: PyReadonlyArrayDyn<'py, f64>,
    intrinsic: bool,
    quat: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<(Array<'py>, usize)> {
    let (axes, input) = (rows::<9>(&axes, "axes", &[9])?, rows::<4>(&quat, "quat", &[4])?);
    let n = broadcast_len(("axes", axes.len()), ("quat", input.len()))?;
    let mut locked = 0;
    let angles = compute(py, n, &[3], |out| {
        locked = rot::davenport_from_quats(axes, intrinsic, input, out)?;
        Ok(())
    })?;
    Ok((angles, locked))
}

/// Whether Euler angles (N, 3) in `seq` are within `atol` of gimbal lock: (N, 1) of 0.0/1.0.
#[pyfunction]
fn euler_gimbal_lock<'py>(
    py: Python<'py>,
    seq: &str,
    angles: PyReadonlyArrayDyn<'py, f64>,
    atol: f64,
) -> PyResult<Array<'py>> {
    let seq = EulerSequence::parse(seq)?;
    let input = rows::<3>(&angles, "angles", &[3])?;
    compute(py, input.len(), &[1], |out| {
        map(input, out, |a| {
            ensure_finite("angles", a)?;
            Ok([f64::from(u8::from(seq.is_gimbal_locked(a, atol)))])
        })
    })
}

/// Rotation angles in [0, pi] (N, 1) of quaternions (N, 4).
#[pyfunction]
fn quat_angle<'py>(py: Python<'py>, quat: PyReadonlyArrayDyn<'py, f64>) -> PyResult<Array<'py>> {
    let input = rows::<4>(&quat, "quat", &[4])?;
    compute(py, input.len(), &[1], |out| map(input, out, |r| Ok([rot::rotation_angle(q(r)?)])))
}

/// Vectors (N, 3) rotated by quaternions (N, 4), broadcast one against N; `inverse` applies
/// the inverse rotations.
#[pyfunction]
fn quat_apply<'py>(
    py: Python<'py>,
    quat: PyReadonlyArrayDyn<'py, f64>,
    vectors: PyReadonlyArrayDyn<'py, f64>,
    inverse: bool,
) -> PyResult<Array<'py>> {
    let (qs, vs) = (rows::<4>(&quat, "quat", &[4])?, rows::<3>(&vectors, "vectors", &[3])?);
    let n = broadcast_len(("rotations", qs.len()), ("vectors", vs.len()))?;
    compute(py, n, &[3], |out| {
        map2(qs, vs, out, |r, v| {
            ensure_finite("vectors", v)?;
            let q = q(r)?;
            let q = if inverse { q.conjugate() } else { q };
            Ok((q * DVec3::from_array(*v)).to_array())
        })
    })
}

/// Spherical linear interpolation between q0 and q1 (N, 4) at parameters t (N, 1); all three
/// broadcast one against N.
#[pyfunction]
fn quat_slerp<'py>(
    py: Python<'py>,
    q0: PyReadonlyArrayDyn<'py, f64>,
    q1: PyReadonlyArrayDyn<'py, f64>,
    t: PyReadonlyArrayDyn<'py, f64>,
    shortest: bool,
) -> PyResult<Array<'py>> {
    let (a, b, t) =
        (rows::<4>(&q0, "r0", &[4])?, rows::<4>(&q1, "r1", &[4])?, rows::<1>(&t, "t", &[1])?);
    let n = broadcast_len(("r0", a.len()), ("r1", b.len()))?;
    let n = broadcast_len(("t", t.len()), ("rotations", n))?;
    compute(py, n, &[4], |out| {
        fill(out, |i| {
            let tt = item(t, i)[0];
            if !tt.is_finite() {
                return Err(Error::invalid("t", "is NaN or infinite"));
            }
            Ok(wxyz(rot::slerp(q(item(a, i))?, q(item(b, i))?, tt, shortest)))
        })
    })
}

/// Modified Rodrigues parameters (N, 3) of quaternions (N, 4), norm at most 1.
#[pyfunction]
fn quat_to_mrp<'py>(py: Python<'py>, quat: PyReadonlyArrayDyn<'py, f64>) -> PyResult<Array<'py>> {
    let input = rows::<4>(&quat, "quat", &[4])?;
    compute(py, input.len(), &[3], |out| rot::quats_to_mrps(input, out))
}

/// Quaternions (N, 4) of modified Rodrigues parameters (N, 3).
#[pyfunction]
fn mrp_to_quat<'py>(py: Python<'py>, mrp: PyReadonlyArrayDyn<'py, f64>) -> PyResult<Array<'py>> {
    let input = rows::<3>(&mrp, "mrp", &[3])?;
    compute(py, input.len(), &[4], |out| rot::mrps_to_quats(input, out))
}

/// Weighted mean rotations (M, 4) of M consecutive groups of `size` quaternions each
/// (M * size, 4), with weights (M * size, 1).
#[pyfunction]
fn quat_mean<'py>(
    py: Python<'py>,
    quat: PyReadonlyArrayDyn<'py, f64>,
    weights: PyReadonlyArrayDyn<'py, f64>,
    size: usize,
) -> PyResult<Array<'py>> {
    let (quat, weights) = (rows::<4>(&quat, "quat", &[4])?, rows::<1>(&weights, "weights", &[1])?);
    if size == 0 || quat.len() % size != 0 || weights.len() != quat.len() {
        return Err(Error::invalid("weights", "must hold one weight per rotation").into());
    }
    compute(py, quat.len() / size, &[4], |out| {
        fill(out, |i| {
            let group = i * size..(i + 1) * size;
            rot::mean(&quat[group.clone()], weights[group].as_flattened())
        })
    })
}

/// The elements (M, 4) of rotation group `group` (`"I"`, `"O"`, `"T"`, `"Cn"`, `"Dn"`) about
/// `axis` (`"X"`, `"Y"`, `"Z"`).
#[pyfunction]
fn rotation_group<'py>(py: Python<'py>, group: &str, axis: &str) -> PyResult<Array<'py>> {
    let g = rot::create_group(group, axis)?;
    compute(py, g.len(), &[4], |out| {
        let out = zeroed(out);
        out.copy_from_slice(&g);
        Ok(())
    })
}

/// Rows (N, 6): the reduced quaternion `l p r` of each p (N, 4) with the smallest angle over
/// l in `left` (L, 4) and r in `right` (R, 4) (empty: the identity), then the indices of l
/// and r (-1 for an empty list).
#[pyfunction]
fn quat_reduce<'py>(
    py: Python<'py>,
    quat: PyReadonlyArrayDyn<'py, f64>,
    left: PyReadonlyArrayDyn<'py, f64>,
    right: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let input = rows::<4>(&quat, "quat", &[4])?;
    let left = rows::<4>(&left, "left", &[4])?.iter().map(q).collect::<Result<Vec<_>>>()?;
    let right = rows::<4>(&right, "right", &[4])?.iter().map(q).collect::<Result<Vec<_>>>()?;
    compute(py, input.len(), &[6], |out| {
        map(input, out, |r| {
            let (p, i, j) = rot::reduce(q(r)?, &left, &right);
            let [w, x, y, z] = wxyz(p);
            Ok([w, x, y, z, i as f64, j as f64])
        })
    })
}

/// The rotation best aligning vectors b (N, 3) onto a (N, 3) with weights (N, 1) (one may be
/// infinite): one row (1, 15) of the quaternion, the rssd, the row-major 3x3 sensitivity (NaN
/// with a primary pair) and 1.0 when the rotation is not unique.
#[pyfunction]
fn align_vectors<'py>(
    py: Python<'py>,
    a: PyReadonlyArrayDyn<'py, f64>,
    b: PyReadonlyArrayDyn<'py, f64>,
    weights: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let (a, b) = (rows::<3>(&a, "a", &[3])?, rows::<3>(&b, "b", &[3])?);
    let weights = rows::<1>(&weights, "weights", &[1])?;
    compute(py, 1, &[15], |out| {
        let out = zeroed(out);
        let w: Vec<f64> = weights.iter().map(|w| w[0]).collect();
        let r = rot::align_vectors(a, b, &w)?;
        let mut row = [f64::NAN; 15];
        row[..4].copy_from_slice(&wxyz(r.rotation));
        row[4] = r.rssd;
        if let Some(s) = r.sensitivity {
            row[5..14].copy_from_slice(&s);
        }
        row[14] = f64::from(u8::from(r.degenerate));
        out[0] = row;
        Ok(())
    })
}

/// Affine transforms (N, 4, 4) from unit quaternions (N, 4), translations (N, 3) and per-axis
/// scales (N, 3), all broadcast one against N: `M = T R S`.
#[pyfunction]
fn transform_from_parts<'py>(
    py: Python<'py>,
    quat: PyReadonlyArrayDyn<'py, f64>,
    translation: PyReadonlyArrayDyn<'py, f64>,
    scale: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let qs = rows::<4>(&quat, "rotation", &[4])?;
    let ts = rows::<3>(&translation, "translation", &[3])?;
    let ss = rows::<3>(&scale, "scale", &[3])?;
    let n = broadcast_len(("rotation", qs.len()), ("translation", ts.len()))?;
    let n = broadcast_len(("scale", ss.len()), ("rotation", n))?;
    compute(py, n, &[4, 4], |out| {
        fill(out, |i| rot::transform_from_parts(q(item(qs, i))?, item(ts, i), item(ss, i)))
    })
}

/// Checked affine transforms (N, 4, 4): finite, last row (0, 0, 0, 1).
#[pyfunction]
fn transform_validate<'py>(
    py: Python<'py>,
    matrix: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let ms = rows::<16>(&matrix, "matrix", &[4, 4])?;
    compute(py, ms.len(), &[4, 4], |out| map(ms, out, |m| rot::validate_transform(m).map(|_| *m)))
}

/// Products a @ b (N, 4, 4) of transform batches broadcast one against N.
#[pyfunction]
fn transform_compose<'py>(
    py: Python<'py>,
    a: PyReadonlyArrayDyn<'py, f64>,
    b: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let (a, b) = (rows::<16>(&a, "a", &[4, 4])?, rows::<16>(&b, "b", &[4, 4])?);
    let n = broadcast_len(("a", a.len()), ("b", b.len()))?;
    compute(py, n, &[4, 4], |out| map2(a, b, out, |x, y| Ok(rot::transform_compose(x, y))))
}

/// Inverses (N, 4, 4) of affine transforms (N, 4, 4).
#[pyfunction]
fn transform_invert<'py>(
    py: Python<'py>,
    matrix: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let ms = rows::<16>(&matrix, "matrix", &[4, 4])?;
    compute(py, ms.len(), &[4, 4], |out| map(ms, out, rot::transform_invert))
}

/// Points (or, with `directions`, direction vectors) (N, 3) mapped by transforms (N, 4, 4),
/// broadcast one against N.
#[pyfunction]
fn transform_apply<'py>(
    py: Python<'py>,
    matrix: PyReadonlyArrayDyn<'py, f64>,
    points: PyReadonlyArrayDyn<'py, f64>,
    directions: bool,
) -> PyResult<Array<'py>> {
    let ms = rows::<16>(&matrix, "matrix", &[4, 4])?;
    let ps = rows::<3>(&points, "points", &[3])?;
    let n = broadcast_len(("transforms", ms.len()), ("points", ps.len()))?;
    compute(py, n, &[3], |out| {
        map2(ms, ps, out, |m, p| {
            ensure_finite("points", p)?;
            Ok(if directions {
                rot::transform_apply_direction(m, p)
            } else {
                rot::transform_apply_point(m, p)
            })
        })
    })
}

/// Rigid transforms (N, 4, 4) from exponential coordinates (N, 6): rotation vector (rad),
/// then the twist's translational part.
#[pyfunction]
fn transform_from_exp_coords<'py>(
    py: Python<'py>,
    exp_coords: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let xs = rows::<6>(&exp_coords, "exp_coords", &[6])?;
    compute(py, xs.len(), &[4, 4], |out| map(xs, out, rot::transform_from_exp_coords))
}

/// Exponential coordinates (N, 6) of rigid transforms (N, 4, 4).
#[pyfunction]
fn transform_to_exp_coords<'py>(
    py: Python<'py>,
    matrix: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let ms = rows::<16>(&matrix, "matrix", &[4, 4])?;
    compute(py, ms.len(), &[6], |out| map(ms, out, rot::transform_to_exp_coords))
}

/// Rigid transforms (N, 4, 4) from dual quaternions (N, 8), scalar-first halves, normalised.
#[pyfunction]
fn transform_from_dual_quat<'py>(
    py: Python<'py>,
    dual_quat: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let ds = rows::<8>(&dual_quat, "dual_quat", &[8])?;
    compute(py, ds.len(), &[4, 4], |out| map(ds, out, rot::transform_from_dual_quat))
}

/// Unit dual quaternions (N, 8), scalar-first halves, of rigid transforms (N, 4, 4).
#[pyfunction]
fn transform_to_dual_quat<'py>(
    py: Python<'py>,
    matrix: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Array<'py>> {
    let ms = rows::<16>(&matrix, "matrix", &[4, 4])?;
    compute(py, ms.len(), &[8], |out| map(ms, out, rot::transform_to_dual_quat))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("GIMBAL_LOCK_TOL", rot::GIMBAL_LOCK_TOL)?;
    m.add("ROTATION_MATRIX_TOL", rot::ROTATION_MATRIX_TOL)?;
    m.add_function(wrap_pyfunction!(quat_normalize, m)?)?;
    m.add_function(wrap_pyfunction!(quat_multiply, m)?)?;
    m.add_function(wrap_pyfunction!(quat_to_matrix, m)?)?;
    m.add_function(wrap_pyfunction!(matrix_to_quat, m)?)?;
    m.add_function(wrap_pyfunction!(quat_to_rotvec, m)?)?;
    m.add_function(wrap_pyfunction!(rotvec_to_quat, m)?)?;
    m.add_function(wrap_pyfunction!(axis_angle_to_quat, m)?)?;
    m.add_function(wrap_pyfunction!(quat_to_axis_angle, m)?)?;
    m.add_function(wrap_pyfunction!(euler_to_quat, m)?)?;
    m.add_function(wrap_pyfunction!(quat_to_euler, m)?)?;
    m.add_function(wrap_pyfunction!(quat_to_davenport, m)?)?;
    m.add_function(wrap_pyfunction!(euler_gimbal_lock, m)?)?;
    m.add_function(wrap_pyfunction!(quat_angle, m)?)?;
    m.add_function(wrap_pyfunction!(quat_apply, m)?)?;
    m.add_function(wrap_pyfunction!(quat_slerp, m)?)?;
    m.add_function(wrap_pyfunction!(quat_to_mrp, m)?)?;
    m.add_function(wrap_pyfunction!(mrp_to_quat, m)?)?;
    m.add_function(wrap_pyfunction!(quat_mean, m)?)?;
    m.add_function(wrap_pyfunction!(rotation_group, m)?)?;
    m.add_function(wrap_pyfunction!(quat_reduce, m)?)?;
    m.add_function(wrap_pyfunction!(align_vectors, m)?)?;
    m.add_function(wrap_pyfunction!(transform_from_parts, m)?)?;
    m.add_function(wrap_pyfunction!(transform_validate, m)?)?;
    m.add_function(wrap_pyfunction!(transform_compose, m)?)?;
    m.add_function(wrap_pyfunction!(transform_invert, m)?)?;
    m.add_function(wrap_pyfunction!(transform_apply, m)?)?;
    m.add_function(wrap_pyfunction!(transform_from_exp_coords, m)?)?;
    m.add_function(wrap_pyfunction!(transform_to_exp_coords, m)?)?;
    m.add_function(wrap_pyfunction!(transform_from_dual_quat, m)?)?;
    m.add_function(wrap_pyfunction!(transform_to_dual_quat, m)?)?;
    Ok(())
}
