//! Weights by bone proximity: each vertex follows the bones nearest to it, with a weight
//! that falls off smoothly with the distance to the bone's segment.

use crate::error::{Error, Result};
use crate::geometry::segment::closest_point_on_segment;
use glam::DVec3;
use rayon::prelude::*;

/// The `k` nearest bones of every vertex and their weights, by distance to the bones'
/// segments: bone `bones_of[s]` owns segment `s` from `segments[s].0` to `segments[s].1` (a
/// bone may own several, e.g. a BVH joint with several children, or none). A vertex at
/// distance `d_b` from bone `b` (its nearest segment) gets `w_b ∝ d_b^{-falloff}` over its
/// `k` nearest bones, normalised to sum 1; a vertex on a segment follows that bone alone.
/// Returns `(bones, weights)`, `k` per vertex (nearest first; unused slots have weight 0).
///
/// # Errors
/// [`Error::InvalidInput`] naming the argument: `k = 0`, no segments, non-finite points, a
/// segment's bone beyond `bones`, a falloff that is not positive and finite.
pub fn proximity_weights(
    vertices: &[[f64; 3]],
    segments: &[([f64; 3], [f64; 3])],
    bones_of: &[u32],
    bones: usize,
    k: usize,
    falloff: f64,
) -> Result<(Vec<u32>, Vec<f64>)> {
    check_bones(vertices, segments, bones_of, bones, k)?;
    if !(falloff.is_finite() && falloff > 0.0) {
        return Err(Error::invalid("falloff", "must be positive and finite"));
    }
    let k = k.min(bones);
    let mut out_bones = vec![0u32; vertices.len() * k];
    let mut out_weights = vec![0.0; vertices.len() * k];
    out_bones
        .par_chunks_mut(k)
        .zip(out_weights.par_chunks_mut(k))
        .zip(vertices.par_iter())
        .for_each_init(
            || vec![f64::INFINITY; bones],
            |distance, ((ob, ow), v)| {
                nearest(DVec3::from_array(*v), segments, bones_of, distance, ob, ow, falloff);
            },
        );
    Ok((out_bones, out_weights))
}

/// The checks shared by the weight computations: `k ≥ 1`, one bone per segment and at least
/// one segment, bones within `bones`, finite vertices and segments.
pub(super) fn check_bones(
    vertices: &[[f64; 3]],
    segments: &[([f64; 3], [f64; 3])],
    bones_of: &[u32],
    bones: usize,
    k: usize,
) -> Result<()> {
    if k == 0 {
        return Err(Error::invalid("influences", "must be at least 1"));
    }
    if segments.is_empty() || segments.len() != bones_of.len() {
        return Err(Error::invalid("segments", "needs one bone per segment, at least one"));
    }
    if let Some(s) = bones_of.iter().position(|&b| b as usize >= bones) {
        return Err(Error::invalid("segments", "names a bone beyond the skeleton").at(s));
    }
    let finite = |p: &[f64; 3]| p.iter().all(|x| x.is_finite());
    if !vertices.iter().all(finite) {
        return Err(Error::invalid("vertices", "contains NaN or infinity"));
    }
    if !segments.iter().all(|(a, b)| finite(a) && finite(b)) {
        return Err(Error::invalid("segments", "contains NaN or infinity"));
    }
    Ok(())
}

/// The distance from `x` to each bone (its nearest segment) into `distance` (one per bone;
/// infinite for a bone with no segment).
pub(super) fn bone_distances(
    x: DVec3,
    segments: &[([f64; 3], [f64; 3])],
    bones_of: &[u32],
    distance: &mut [f64],
) {
    distance.fill(f64::INFINITY);
    for ((a, b), &bone) in segments.iter().zip(bones_of) {
        let (a, b) = (DVec3::from_array(*a), DVec3::from_array(*b));
        let d = x.distance(closest_point_on_segment(a, b, x));
        let slot = &mut distance[bone as usize];
        *slot = slot.min(d);
    }
}

/// The nearest bones of `x` into `bones`/`weights` (see [`proximity_weights`]), with
/// `distance` (one per bone) as scratch.
fn nearest(
    x: DVec3,
    segments: &[([f64; 3], [f64; 3])],
    bones_of: &[u32],
    distance: &mut [f64],
    bones: &mut [u32],
    weights: &mut [f64],
    falloff: f64,
) {
    bone_distances(x, segments, bones_of, distance);
    // The k smallest, nearest first; ties by bone index (deterministic).
    for (i, slot) in bones.iter_mut().enumerate() {
        let best = (0..distance.len())
            .filter(|&b| distance[b].is_finite())
            .min_by(|&p, &q| distance[p].total_cmp(&distance[q]).then(p.cmp(&q)));
        match best {
            Some(b) => {
                *slot = b as u32;
                weights[i] = distance[b];
                distance[b] = f64::INFINITY;
            }
            None => {
                *slot = 0;
                weights[i] = f64::INFINITY;
            }
        }
    }
    if weights[0] == 0.0 {
        weights.iter_mut().enumerate().for_each(|(i, w)| *w = if i == 0 { 1.0 } else { 0.0 });
        return;
    }
    let mut sum = 0.0;
    for w in weights.iter_mut() {
        *w = if w.is_finite() { w.powf(-falloff) } else { 0.0 };
        sum += *w;
    }
    weights.iter_mut().for_each(|w| *w /= sum);
}
