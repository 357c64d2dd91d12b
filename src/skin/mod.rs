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
//! Both are exact for a vertex with one bone (a rigid transform), and are computed with the
//! poses in SIMD lanes, in parallel over blocks of poses × vertices, the same bits for any
//! thread count. Units are those of
//! the positions given (metres in kinema, file units for motion capture).

mod blend;
mod body;
mod heat;
mod snapshot;
mod weights;

pub use body::capsule_union;
pub use heat::heat_weights;
pub use weights::proximity_weights;

use crate::batch::{self, vectorize, Output, LANES};
use crate::error::{Error, Result};
use crate::rotation::quat_from_wxyz;
use blend::{Blend, Transform};
use glam::{DQuat, DVec3};
use rayon::prelude::*;
use std::marker::PhantomData;
use std::mem::MaybeUninit;

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
    /// rows, pose by pose, each written once (a new buffer need not be initialised).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] naming the argument: sizes that are not whole poses or do not
    /// match `out`, non-finite values, a zero orientation. `out` is then untouched.
    pub fn deform(
        &self,
        positions: &[[f64; 3]],
        orientations: &[[f64; 4]],
        method: Method,
        out: &mut (impl Output<3> + ?Sized),
    ) -> Result<()> {
        let out = batch::write_only(out);
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
        let skinning = frames(positions, orientations, &self.origins)?;
        match method {
            Method::Linear => self.each_vertex::<blend::Linear>(&skinning, out),
            Method::DualQuaternion => self.each_vertex::<blend::DualQuaternion>(&skinning, out),
        }
        Ok(())
    }

    /// `out[p V + v]` = the blend `B` of the bones' skinning transforms of pose `p` at vertex
    /// `v`, for the bones' frames `posed` (`P J`, pose by pose).
    ///
    /// The transforms' numbers are laid out with the poses in lanes (`[f64; LANES]` per
    /// block of [`LANES`] poses, bone and number), so that a vertex is skinned in eight
    /// poses at once by SIMD arithmetic on contiguous loads, and the work is split over
    /// blocks of poses × blocks of vertices, in parallel. The last block's poses (fewer than
    /// eight) run one at a time through the same arithmetic, so every row has the same bits
    /// on any thread count and in any block.
    fn each_vertex<B: Blend>(&self, posed: &[Transform], out: &mut [[MaybeUninit<f64>; 3]]) {
        const VERTICES: usize = 1024;
        let (joints, v) = (self.bones(), self.rest.len());
        if v == 0 {
            return;
        }
        let blocks = posed.len().div_ceil(joints * LANES);
        let mut table = vec![[0.0; LANES]; blocks * joints * B::VALUES];
        for (i, s) in posed.iter().enumerate() {
            let (pose, b) = (i / joints, i % joints);
            let values = B::values(&s.then(&self.bind_inverse[b]));
            let at = ((pose / LANES) * joints + b) * B::VALUES;
            for (lanes, value) in table[at..at + B::VALUES].iter_mut().zip(values) {
                lanes[pose % LANES] = value;
            }
        }
        let mut tasks: Vec<Vertices<B>> = Vec::new();
        for (block, rows) in out.chunks_mut(LANES * v).enumerate() {
            let mut poses: Vec<_> = rows.chunks_mut(v).map(|p| p.chunks_mut(VERTICES)).collect();
            for first in (0..v).step_by(VERTICES) {
                let rows: Vec<_> = poses.iter_mut().filter_map(Iterator::next).collect();
                let values = block * joints * B::VALUES..(block + 1) * joints * B::VALUES;
                tasks.push(Vertices {
                    skin: self,
                    table: &table[values],
                    first,
                    rows,
                    blend: PhantomData,
                });
            }
        }
        tasks.into_par_iter().for_each(vectorize);
    }
}

/// One task of [`Skin::each_vertex`]: the vertices from `first` on, in up to [`LANES`] poses
/// (`rows[p]`: the rows of pose `p` of the block), with the block's values `table`.
struct Vertices<'a, B> {
    skin: &'a Skin,
    table: &'a [[f64; LANES]],
    first: usize,
    rows: Vec<&'a mut [[MaybeUninit<f64>; 3]]>,
    blend: PhantomData<fn() -> B>,
}

impl<B: Blend> pulp::WithSimd for Vertices<'_, B> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        // Four influences (the default, and glTF's one set) get loops compiled for four.
        if self.skin.k == 4 {
            self.run::<4>();
        } else {
            self.run::<0>();
        }
    }
}

impl<B: Blend> Vertices<'_, B> {
    /// The task with `K` influences per vertex (`K = 0`: the skin's `k`).
    #[inline(always)]
    fn run<const K: usize>(self) {
        let Vertices { skin, table, first, mut rows, .. } = self;
        let k = if K == 0 { skin.k } else { K };
        let value = |b: u32, i: usize| &table[b as usize * B::VALUES + i];
        let (mut lanes, mut one) = (vec![[0.0; LANES]; k], vec![[0.0; 1]; k]);
        let n = rows.first().map_or(0, |r| r.len());
        for j in 0..n {
            let v = first + j;
            let (bones, weights) = (&skin.bones[v * k..][..k], &skin.weights[v * k..][..k]);
            let x = skin.rest[v];
            if rows.len() == LANES {
                let moved = B::blend(|b, i| *value(b, i), bones, weights, x, &mut lanes);
                for (l, rows) in rows.iter_mut().enumerate() {
                    let m = |i: usize| MaybeUninit::new(moved[i][l]);
                    rows[j] = [m(0), m(1), m(2)];
                }
            } else {
                for (l, rows) in rows.iter_mut().enumerate() {
                    let moved = B::blend(|b, i| [value(b, i)[l]], bones, weights, x, &mut one);
                    let m = |i: usize| MaybeUninit::new(moved[i][0]);
                    rows[j] = [m(0), m(1), m(2)];
                }
            }
        }
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
