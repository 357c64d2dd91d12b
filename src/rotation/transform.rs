//! Homogeneous 4x4 affine transforms, row-major `[f64; 16]`, acting on column vectors:
//! `p' = M [p; 1]` for points, `d' = M [d; 0]` for directions. The translation is the last
//! column; the last row is `(0, 0, 0, 1)`.

use crate::error::{ensure_finite, Error, Result};
use glam::DQuat;

/// Check that `m` is a finite affine transform (last row `(0, 0, 0, 1)`).
///
/// # Errors
/// Non-finite entries or a last row that is not `(0, 0, 0, 1)` (projective matrices are not
/// transforms of this kind).
pub fn validate_transform(m: &[f64; 16]) -> Result<()> {
    ensure_finite("matrix", m)?;
    if m[12..] != [0.0, 0.0, 0.0, 1.0] {
        return Err(Error::invalid("matrix", "last row must be (0, 0, 0, 1)"));
    }
    Ok(())
}

/// `M = T R S`: scale by `scale` along the body axes, rotate by `q`, translate by
/// `translation`.
///
/// # Errors
/// Non-finite translation or scale (the quaternion is assumed unit and checked upstream).
pub fn transform_from_parts(
    q: DQuat,
    translation: &[f64; 3],
    scale: &[f64; 3],
) -> Result<[f64; 16]> {
    ensure_finite("translation", translation)?;
    ensure_finite("scale", scale)?;
    let r = super::quat_to_matrix(q);
    let mut m = [0.0; 16];
    for row in 0..3 {
        for col in 0..3 {
            m[4 * row + col] = r[3 * row + col] * scale[col];
        }
        m[4 * row + 3] = translation[row];
    }
    m[15] = 1.0;
    Ok(m)
}

/// Matrix product `a b` (apply `b`, then `a`).
pub fn transform_compose(a: &[f64; 16], b: &[f64; 16]) -> [f64; 16] {
    let mut m = [0.0; 16];
    for row in 0..4 {
        for col in 0..4 {
            m[4 * row + col] = (0..4).map(|k| a[4 * row + k] * b[4 * k + col]).sum();
        }
    }
    m
}

/// Inverse of affine `m`: `[A t; 0 1]⁻¹ = [A⁻¹ -A⁻¹t; 0 1]`.
///
/// # Errors
/// An invalid transform (see [`validate_transform`]) or a linear part that is singular
/// (determinant below `1e-14` times the product of its column norms).
pub fn transform_invert(m: &[f64; 16]) -> Result<[f64; 16]> {
    validate_transform(m)?;
    let a = glam::DMat3::from_cols_array(&[m[0], m[4], m[8], m[1], m[5], m[9], m[2], m[6], m[10]]);
    let det = a.determinant();
    let scale = a.x_axis.length() * a.y_axis.length() * a.z_axis.length();
    if det.abs() <= 1e-14 * scale {
        return Err(Error::invalid(
            "matrix",
            "linear part is singular; the transform has no inverse",
        ));
    }
    let inv = a.inverse();
    let t = -(inv * glam::DVec3::new(m[3], m[7], m[11]));
    let c = inv.to_cols_array();
    Ok([c[0], c[3], c[6], t.x, c[1], c[4], c[7], t.y, c[2], c[5], c[8], t.z, 0.0, 0.0, 0.0, 1.0])
}

/// `M [p; 1]`: the transformed point.
pub fn transform_apply_point(m: &[f64; 16], p: &[f64; 3]) -> [f64; 3] {
    let row = |r: usize| m[4 * r] * p[0] + m[4 * r + 1] * p[1] + m[4 * r + 2] * p[2] + m[4 * r + 3];
    [row(0), row(1), row(2)]
}

/// `M [d; 0]`: the transformed direction (no translation). Surface normals need the
/// inverse transpose instead when the scale is not uniform.
pub fn transform_apply_direction(m: &[f64; 16], d: &[f64; 3]) -> [f64; 3] {
    let row = |r: usize| m[4 * r] * d[0] + m[4 * r + 1] * d[1] + m[4 * r + 2] * d[2];
    [row(0), row(1), row(2)]
}
