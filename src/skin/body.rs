//! A procedural body for any skeleton: capsules around its bones merged into one closed
//! surface, the zero level set of the smooth union of the capsules' signed distances
//! (polynomial smooth minimum, Quílez 2013, "Smooth minimum"), polygonised on a grid
//! ([`crate::geometry::isosurface`]).

use crate::error::{Error, Result};
use crate::geometry::isosurface::{polygonise, Mesh};
use crate::geometry::segment::closest_point_on_segment;
use glam::DVec3;
use rayon::prelude::*;

/// Most grid samples a body may take (a guard against a `cell` far below the body's size).
const MAX_SAMPLES: usize = 50_000_000;

/// The surface around capsules `segments[s]` of radius `radii[s]` (the vertices' units), their
/// signed distances `d_s` merged by the smooth minimum `smin(a, b) = min(a, b) - h² blend / 4`
/// with `h = max(blend - |a - b|, 0) / blend` (the plain union for `blend = 0`; `blend` is the
/// width over which two capsules fillet, and the surface swells by at most `blend / 4` where
/// they meet), sampled every `cell` and polygonised: a closed, manifold, outward-facing
/// triangle mesh. Its error is of order `cell² / radius` (linear interpolation along grid
/// edges of a function whose curvature is `1 / radius`).
///
/// # Errors
/// [`Error::InvalidInput`] naming the argument: no segment, non-finite points, sizes that
/// disagree, a radius that is not positive and finite, a negative or non-finite `blend`, a
/// `cell` that is not positive and finite or that asks for more than 50 million samples.
pub fn capsule_union(
    segments: &[([f64; 3], [f64; 3])],
    radii: &[f64],
    blend: f64,
    cell: f64,
) -> Result<Mesh> {
    check(segments, radii, blend, cell)?;
    let ends: Vec<(DVec3, DVec3)> =
        segments.iter().map(|(a, b)| (DVec3::from_array(*a), DVec3::from_array(*b))).collect();
    let margin = radii.iter().fold(0.0_f64, |m, &r| m.max(r)) + blend + 2.0 * cell;
    let (lo, hi) = ends.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), (a, b)| {
        (lo.min(a.min(*b)), hi.max(a.max(*b)))
    });
    let origin = lo - DVec3::splat(margin);
    let extent = (hi - lo + DVec3::splat(2.0 * margin)) / cell;
    let counts = extent.to_array().map(|e| e.ceil() as usize + 1);
    let samples = counts.iter().try_fold(1_usize, |n, &c| n.checked_mul(c));
    let samples = samples.filter(|&n| n <= MAX_SAMPLES).ok_or_else(|| {
        Error::invalid("cell", "asks for more than 50 million grid samples for this body")
    })?;
    let [nx, ny, _] = counts;
    let mut values = vec![0.0; samples];
    values.par_iter_mut().enumerate().for_each(|(p, f)| {
        let ijk = DVec3::new((p % nx) as f64, (p / nx % ny) as f64, (p / (nx * ny)) as f64);
        *f = distance(&ends, radii, blend, origin + cell * ijk);
    });
    Ok(polygonise(&values, counts, origin, cell))
}

/// Signed distance of `x` to the smooth union of the capsules (see [`capsule_union`]).
fn distance(ends: &[(DVec3, DVec3)], radii: &[f64], blend: f64, x: DVec3) -> f64 {
    ends.iter().zip(radii).fold(f64::INFINITY, |d, (&(a, b), &r)| {
        let e = (x - closest_point_on_segment(a, b, x)).length() - r;
        smooth_min(d, e, blend)
    })
}

/// `min(a, b) - h² k / 4`, `h = max(k - |a - b|, 0) / k` (Quílez 2013): the minimum, filleted
/// where `a` and `b` are within `k` of each other; the minimum itself for `k = 0`.
fn smooth_min(a: f64, b: f64, k: f64) -> f64 {
    let h = if k > 0.0 { (k - (a - b).abs()).max(0.0) / k } else { 0.0 };
    a.min(b) - h * h * k * 0.25
}

/// The argument checks of [`capsule_union`].
fn check(segments: &[([f64; 3], [f64; 3])], radii: &[f64], blend: f64, cell: f64) -> Result<()> {
    if segments.is_empty() {
        return Err(Error::invalid("segments", "must hold at least one segment"));
    }
    if radii.len() != segments.len() {
        return Err(Error::invalid(
            "radius",
            format!("{} radii for {} segments", radii.len(), segments.len()),
        ));
    }
    if segments.iter().any(|(a, b)| a.iter().chain(b).any(|x| !x.is_finite())) {
        return Err(Error::invalid("segments", "contains NaN or infinity"));
    }
    if let Some(i) = radii.iter().position(|r| !(r.is_finite() && *r > 0.0)) {
        return Err(Error::invalid("radius", "must be positive and finite").at(i));
    }
    if !(blend.is_finite() && blend >= 0.0) {
        return Err(Error::invalid("blend", "must be non-negative and finite"));
    }
    if !(cell.is_finite() && cell > 0.0) {
        return Err(Error::invalid("cell", "must be positive and finite"));
    }
    Ok(())
}
