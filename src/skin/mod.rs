//! Skinning: a surface (vertices in a bind pose) deformed by the bones of a skeleton.
//!
//! Each vertex `v` follows up to `k` bones `b` with weights `w_b` (non-negative, normalised
//! to sum 1). A bone is a rigid frame: an origin (a point that moves with it) and an
//! orientation; its skinning transform at a pose is `S_b = F_b(pose) · F_b(bind)⁻¹`, the
//! motion that takes its bind frame to its posed frame. Two blends of the `S_b`:
//!
//! - **linear blend skinning** (LBS; Magnenat-Thalmann et al. 1988): `v' = Σ w_b S_b v`, the
//!   weighted average of the transformed points; a joint twisted by 180° collapses its
//!   cross-section (the "candy wrapper");
//! - **dual quaternion skinning** (DQS; Kavan, Collins, Žára & O'Sullivan 2008, "Geometric
//!   skinning with approximate dual quaternion blending", eq. 4–5): the unit dual
//!   quaternions of the `S_b` blended linearly, each with the sign that puts it in the
//!   hemisphere of the most weighted one (antipodality, section 4.1), normalised, applied as
//!   one rigid transform; it keeps the cross-section of a twisted joint.
//!
//! [`capsule_union`] makes a body for any skeleton: capsules around its bones merged into one
//! closed surface.
//!
//! Both are exact for a vertex with one bone (a rigid transform), and are computed in
//! parallel over blocks of vertices, the same bits for any thread count. Units are those of
//! the positions given (metres in kinema, file units for motion capture).

mod blend;
mod body;
mod heat;
mod snapshot;
mod weights;

pub use body::capsule_union;
pub use heat::heat_weights;
pub use weights::proximity_weights;

use crate::error::{Error, Result};
use crate::rotation::quat_from_wxyz;
use blend::{Dual, Matrix, Transform};
use glam::{DQuat, DVec3};
use rayon::prelude::*;

/// How the bones' transforms are blended at a vertex (see the module docs).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Linear blend skinning: the weighted average of the transformed points.
    Linear,
    /// Dual quaternion skinning (Kavan et al. 2008): one blended rigid transform.
    DualQuaternion,
}

/// Vertices in a bind pose bound to the bones of a skeleton.
///
/// Bone `b` is joint `b` of the skeleton's poses: its orientation is the joint's, its origin
/// the position of joint `origins[b]` (for an Acclaim skeleton the bone's parent joint, where
/// the bone starts; for BVH the joint itself).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct Skin {
    /// Vertex positions in the bind pose (`V` rows).
    rest: Vec<[f64; 3]>,
    /// Influences per vertex.
    k: usize,
    /// Bone of each influence (`V k` values, `k` per vertex).
    bones: Vec<u32>,
    /// Weight of each influence (`V k` values), normalised per vertex.
    weights: Vec<f64>,
    /// Joint whose position is each bone's origin (one per bone).
    origins: Vec<usize>,
    /// Each bone's frame in the bind pose, inverted.
    bind_inverse: Vec<Transform>,
}

impl Skin {
    /// Bind `rest` (`V` vertices) to the bones of a skeleton posed at `bind_positions` and
    /// `bind_orientations` (one row per joint: positions in the vertices' units,
    /// `(w, x, y, z)` orientations), bone `b` having its origin at joint `origins[b]`, with
    /// `k` influences per vertex: `bones[v k + i]` and `weights[v k + i]`. Weights are
    /// normalised per vertex; an influence of weight 0 is ignored.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] naming the argument: non-finite vertices or poses, a zero or
    /// non-finite orientation, sizes that disagree, `k = 0`, a bone or origin beyond the
    /// joints, a negative or non-finite weight, a vertex whose weights are all 0.
    pub fn new(
        rest: &[[f64; 3]],
        k: usize,
        bones: &[u32],
        weights: &[f64],
        origins: &[usize],
        bind_positions: &[[f64; 3]],
        bind_orientations: &[[f64; 4]],
    ) -> Result<Skin> {
        let joints = origins.len();
        check_pose(bind_positions, bind_orientations, joints, "bind_positions")?;
        if rest.iter().flatten().any(|x| !x.is_finite()) {
            return Err(Error::invalid("vertices", "contains NaN or infinity"));
        }
        if let Some(b) = origins.iter().position(|&o| o >= joints) {
            return Err(Error::invalid("origins", "names a joint beyond the skeleton").at(b));
        }
        let weights = influences(rest.len(), k, bones, weights, joints)?;
        let bind = frames(bind_positions, bind_orientations, origins)?;
        Ok(Skin {
            rest: rest.to_vec(),
            k,
            bones: bones.to_vec(),
            weights,
            origins: origins.to_vec(),
            bind_inverse: bind.iter().map(Transform::inverse).collect(),
        })
    }

    /// Number of vertices.
    pub fn vertices(&self) -> usize {
        self.rest.len()
    }

    /// Number of bones (joints of the skeleton's poses).
    pub fn bones(&self) -> usize {
        self.origins.len()
    }

    /// The normalised weights (`V k` values, `k` per vertex).
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// The skinned vertices of every pose: `positions` and `orientations` hold one row per
    /// joint of each pose (`P` poses, as [`Skin::new`]'s bind pose), `out` receives `P V`
    /// rows, pose by pose.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] naming the argument: sizes that are not whole poses or do not
    /// match `out`, non-finite values, a zero orientation.
    pub fn deform(
        &self,
        positions: &[[f64; 3]],
        orientations: &[[f64; 4]],
        method: Method,
        out: &mut [[f64; 3]],
    ) -> Result<()> {
        let joints = self.bones();
        check_pose(positions, orientations, joints, "positions")?;
        let poses = positions.len() / joints.max(1);
        let v = self.rest.len();
        if out.len() != poses * v {
            return Err(Error::invalid(
                "out",
                format!("has {} rows for {poses} poses of {v} vertices", out.len()),
            ));
        }
        let mut skinning = frames(positions, orientations, &self.origins)?;
        for (i, s) in skinning.iter_mut().enumerate() {
            *s = s.then(&self.bind_inverse[i % joints]);
        }
        match method {
            Method::Linear => {
                let m: Vec<Matrix> = skinning.iter().map(Matrix::from).collect();
                self.each_vertex(&m, joints, out, blend::linear);
            }
            Method::DualQuaternion => {
                let d: Vec<Dual> = skinning.iter().map(Dual::from).collect();
                self.each_vertex(&d, joints, out, blend::dual_quaternion);
            }
        }
        Ok(())
    }

    /// `out[p V + v] = blend(skinning of pose p, influences of v, rest[v])` for every pose `p`
    /// and vertex `v`, in parallel over blocks of rows (the same bits on any thread count).
    /// Four influences per vertex (the default, and glTF's one set) get a loop compiled for
    /// exactly four.
    fn each_vertex<T: Sync>(
        &self,
        skinning: &[T],
        joints: usize,
        out: &mut [[f64; 3]],
        blend: impl Fn(&[T], &[u32], &[f64], [f64; 3]) -> [f64; 3] + Sync,
    ) {
        if self.k == 4 {
            self.rows::<T, 4>(skinning, joints, out, &blend);
        } else {
            self.rows::<T, 0>(skinning, joints, out, &blend);
        }
    }

    /// [`Skin::each_vertex`] with `K` influences per vertex (`K = 0`: `self.k`).
    fn rows<T: Sync, const K: usize>(
        &self,
        skinning: &[T],
        joints: usize,
        out: &mut [[f64; 3]],
        blend: &(impl Fn(&[T], &[u32], &[f64], [f64; 3]) -> [f64; 3] + Sync),
    ) {
        const BLOCK: usize = 1024;
        let (v, k) = (self.rest.len(), if K == 0 { self.k } else { K });
        out.par_chunks_mut(BLOCK).enumerate().for_each(|(c, rows)| {
            let (mut pose, mut vertex) = ((c * BLOCK) / v, (c * BLOCK) % v);
            for row in rows {
                let s = &skinning[pose * joints..(pose + 1) * joints];
                let span = vertex * k..(vertex + 1) * k;
                *row = blend(s, &self.bones[span.clone()], &self.weights[span], self.rest[vertex]);
                vertex += 1;
                if vertex == v {
                    (pose, vertex) = (pose + 1, 0);
                }
            }
        });
    }
}

/// Check that `positions` and `orientations` are whole poses of `joints` rows, finite.
fn check_pose(
    positions: &[[f64; 3]],
    orientations: &[[f64; 4]],
    joints: usize,
    arg: &str,
) -> Result<()> {
    if positions.len() != orientations.len()
        || joints == 0
        || !positions.len().is_multiple_of(joints)
    {
        return Err(Error::invalid(
            arg,
            format!(
                "{} positions and {} orientations are not whole poses of {joints} joints",
                positions.len(),
                orientations.len()
            ),
        ));
    }
    if positions.iter().flatten().any(|x| !x.is_finite()) {
        return Err(Error::invalid(arg, "contains NaN or infinity"));
    }
    Ok(())
}

/// Validate the influences of `n` vertices (`k` each) on `joints` bones and return their
/// weights normalised per vertex.
fn influences(
    n: usize,
    k: usize,
    bones: &[u32],
    weights: &[f64],
    joints: usize,
) -> Result<Vec<f64>> {
    if k == 0 {
        return Err(Error::invalid("influences", "must be at least 1"));
    }
    if bones.len() != n * k || weights.len() != n * k {
        return Err(Error::invalid(
            "weights",
            format!(
                "{} bones and {} weights for {n} vertices of {k} influences",
                bones.len(),
                weights.len()
            ),
        ));
    }
    if let Some(i) = bones.iter().position(|&b| b as usize >= joints) {
        return Err(
            Error::invalid("bones", format!("names a bone beyond the {joints} joints")).at(i)
        );
    }
    if let Some(i) = weights.iter().position(|w| !(w.is_finite() && *w >= 0.0)) {
        return Err(Error::invalid("weights", "must be finite and non-negative").at(i));
    }
    let mut normalised = weights.to_vec();
    for (v, w) in normalised.chunks_exact_mut(k).enumerate() {
        let sum: f64 = w.iter().sum();
        if !sum.is_finite() || sum <= 0.0 {
            return Err(Error::invalid(
                "weights",
                "are all zero (or their sum overflows) for a vertex",
            )
            .at(v));
        }
        w.iter_mut().for_each(|x| *x /= sum);
    }
    Ok(normalised)
}

/// Every bone's frame of every pose: the orientation of its joint, the position of its origin.
fn frames(
    positions: &[[f64; 3]],
    orientations: &[[f64; 4]],
    origins: &[usize],
) -> Result<Vec<Transform>> {
    let joints = origins.len();
    positions
        .chunks_exact(joints)
        .zip(orientations.chunks_exact(joints))
        .flat_map(|(p, q)| {
            origins.iter().zip(q).map(|(&o, q)| {
                let rotation: DQuat = quat_from_wxyz(q).map_err(|_| {
                    Error::invalid("orientations", "contains a zero or non-finite quaternion")
                })?;
                Ok(Transform { rotation, translation: DVec3::from_array(p[o]) })
            })
        })
        .collect()
}
