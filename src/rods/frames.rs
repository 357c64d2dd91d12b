//! The geometry of a discrete rod (Bergou et al. 2008, sec. 4): parallel transport between
//! tangents, the reference twist of two consecutive reference frames, material frames from
//! twist angles, and the discrete curvature binormal. Pure functions on unit vectors, plus
//! [`Frames`], the per-configuration cache the energies read.
//!
//! Reference frames are carried in time (Bergou et al. 2010, sec. 5.1, "time-parallel
//! transport"): a step transports each edge's reference director `d1` from the edge's
//! tangent at the start of the step to its tangent now, and keeps the reference twist on the
//! branch nearest last step's, so that twist is counted continuously beyond `±π`.

use glam::DVec3;
use std::f64::consts::TAU;

/// `d` parallel-transported from unit tangent `t0` to unit tangent `t1`: rotated about
/// `t0 × t1` by the angle between them (the rotation taking `t0` to `t1` with no twist),
/// written without trigonometry: `R d = c d + b × d + (b·d) b / (1 + c)` with `b = t0 × t1`,
/// `c = t0·t1`. Tangents that are opposite (`c = -1`) have no unique transport; the caller
/// never transports across a half turn within one step (a step that tried failed earlier).
#[inline]
pub fn transport(d: DVec3, t0: DVec3, t1: DVec3) -> DVec3 {
    let b = t0.cross(t1);
    let c = t0.dot(t1);
    c * d + b.cross(d) + b * (b.dot(d) / (1.0 + c))
}

/// The angle (rad, in `(-π, π]`) that turns `u` into `v` about the unit axis `n` (both
/// perpendicular to it).
#[inline]
pub fn signed_angle(u: DVec3, v: DVec3, n: DVec3) -> f64 {
    u.cross(v).dot(n).atan2(u.dot(v))
}

/// The discrete curvature binormal at a vertex between edges `e` and `f` (m):
/// `(κb) = 2 e × f / (|e||f| + e·f)` (Bergou et al. 2008, eq. 1), of length `2 tan(φ/2)` for
/// the turning angle `φ`.
#[inline]
pub fn curvature_binormal(e: DVec3, f: DVec3) -> DVec3 {
    2.0 * e.cross(f) / (e.length() * f.length() + e.dot(f))
}

/// The reference twist (rad) at the vertex between an edge of tangent `t0` and reference
/// director `d0` and the next edge of tangent `t1` and director `d1`: the angle from `d0`
/// transported onto the next edge to `d1`, about `t1` (Bergou et al. 2010, sec. 5.1), on the
/// branch (`+ 2πk`) nearest `previous`.
#[inline]
pub fn reference_twist(t0: DVec3, d0: DVec3, t1: DVec3, d1: DVec3, previous: f64) -> f64 {
    let a = signed_angle(transport(d0, t0, t1), d1, t1);
    a + TAU * ((previous - a) / TAU).round()
}

/// The material directors `(m1, m2)` of an edge of unit tangent `t` and reference director
/// `d1`, turned by the twist angle `theta` (rad): `m1 = cos θ d1 + sin θ d2`,
/// `m2 = -sin θ d1 + cos θ d2`, `d2 = t × d1` (Bergou et al. 2008, sec. 4.1).
#[inline]
pub fn directors(t: DVec3, d1: DVec3, theta: f64) -> (DVec3, DVec3) {
    let d2 = t.cross(d1);
    let (s, c) = theta.sin_cos();
    (c * d1 + s * d2, c * d2 - s * d1)
}

/// A unit vector perpendicular to the unit vector `t`: `t` crossed with the world axis least
/// aligned with it, made unit (the first reference director of a new rod).
pub fn perpendicular(t: DVec3) -> DVec3 {
    let a = t.abs();
    let axis = if a.x <= a.y && a.x <= a.z {
        DVec3::X
    } else if a.y <= a.z {
        DVec3::Y
    } else {
        DVec3::Z
    };
    t.cross(axis).normalize()
}

/// The frames of one configuration of a rod of `n` edges: what the energies read, computed
/// by [`Frames::update`] from the positions, the twist angles and the reference frames at
/// the start of the step.
#[derive(Clone, Debug, Default)]
pub struct Frames {
    /// Edge vectors `x_{(j+1) mod V} − x_j` (m), `n`.
    pub edges: Vec<DVec3>,
    /// Unit tangents, `n`.
    pub tangents: Vec<DVec3>,
    /// Reference directors `d1`, transported in time, `n`.
    pub reference: Vec<DVec3>,
    /// Material directors `m1`, `n`.
    pub m1: Vec<DVec3>,
    /// Material directors `m2`, `n`.
    pub m2: Vec<DVec3>,
    /// Reference twist at the stencils (rad): `n − 1` of an open rod (vertex `i` at
    /// `i − 1`), `n` of a closed one (the last, between edges `n − 1` and 0, with the ring's
    /// seam twist added).
    pub reference_twist: Vec<f64>,
    /// A closed rod's seam twist (rad, [`super::State::twist_ring`]): seen from the last
    /// edge, the first edge's material frame is turned by it.
    pub seam: f64,
}

impl Frames {
    /// Size every buffer for `n` edges and `stencils` stencils (allocates only when they
    /// grow).
    fn resize(&mut self, n: usize, stencils: usize) {
        for v in
            [&mut self.edges, &mut self.tangents, &mut self.reference, &mut self.m1, &mut self.m2]
        {
            v.resize(n, DVec3::ZERO);
        }
        self.reference_twist.resize(stencils, 0.0);
    }

    /// The frames of positions `x` (`V`) and twists `theta` (`n`; the rod is closed when
    /// `V = n`), the reference directors transported from `(base_tangents, base_reference)`
    /// (the start of the step) and the reference twists taken on the branch nearest
    /// `base_twist`. A closed rod's last stencil adds `seam` (rad, the ring's twist beyond
    /// its twist angles, [`super::State::twist_ring`]; 0 for an open rod). Returns `false`
    /// (frames unusable) when an edge has zero or non-finite length or turned by a half turn
    /// from its base tangent.
    pub fn update(
        &mut self,
        x: &[DVec3],
        theta: &[f64],
        base_tangents: &[DVec3],
        base_reference: &[DVec3],
        base_twist: &[f64],
        seam: f64,
    ) -> bool {
        let (n, v) = (theta.len(), x.len());
        let stencils = if v == n { n } else { n.saturating_sub(1) };
        self.resize(n, stencils);
        self.seam = seam;
        for j in 0..n {
            let e = x[(j + 1) % v] - x[j];
            let len = e.length();
            let t = e / len;
            if !(len > 0.0 && t.is_finite()) || t.dot(base_tangents[j]) <= -1.0 + 1e-12 {
                return false;
            }
            let d1 = transport(base_reference[j], base_tangents[j], t);
            // Keep d1 unit and perpendicular to t against rounding drift over many steps.
            let d1 = (d1 - d1.dot(t) * t).normalize();
            let (m1, m2) = directors(t, d1, theta[j]);
            self.edges[j] = e;
            self.tangents[j] = t;
            self.reference[j] = d1;
            self.m1[j] = m1;
            self.m2[j] = m2;
        }
        for (k, &base) in base_twist[..stencils].iter().enumerate() {
            let (a, b) = (k, (k + 1) % n);
            let (ta, da, tb, db) =
                (self.tangents[a], self.reference[a], self.tangents[b], self.reference[b]);
            self.reference_twist[k] = if b == 0 {
                seam + reference_twist(ta, da, tb, db, base - seam)
            } else {
                reference_twist(ta, da, tb, db, base)
            };
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transport_is_the_rotation_taking_one_tangent_to_the_other() {
        let t0 = DVec3::new(1.0, 2.0, -0.5).normalize();
        let t1 = DVec3::new(-0.3, 1.0, 2.0).normalize();
        let d = perpendicular(t0);
        let p = transport(d, t0, t1);
        assert!(transport(t0, t0, t1).abs_diff_eq(t1, 1e-15));
        assert!(p.dot(t1).abs() < 1e-15 && (p.length() - 1.0).abs() < 1e-15);
        // No twist: the transported director keeps its component along t0 × t1.
        let b = t0.cross(t1).normalize();
        assert!((p.dot(b) - d.dot(b)).abs() < 1e-15);
        // Back again is the identity.
        assert!(transport(p, t1, t0).abs_diff_eq(d, 1e-15));
    }

    #[test]
    fn curvature_binormal_has_length_two_tan_half_the_turning_angle() {
        for phi in [0.0f64, 0.1, 1.0, 2.5] {
            let e = DVec3::new(2.0, 0.0, 0.0);
            let f = 0.5 * DVec3::new(phi.cos(), phi.sin(), 0.0);
            let kb = curvature_binormal(e, f);
            assert!((kb.length() - 2.0 * (phi / 2.0).tan()).abs() < 1e-13, "{phi}");
            assert!(kb.dot(DVec3::Z) >= 0.0);
        }
    }

    #[test]
    fn reference_twist_counts_turns_continuously() {
        let t = DVec3::X;
        let d0 = DVec3::Y;
        for k in -3..=3 {
            let a = 0.4 + TAU * f64::from(k);
            let d1 = directors(t, d0, a).0;
            let got = reference_twist(t, d0, t, d1, a - 0.3);
            assert!((got - a).abs() < 1e-12, "{k}: {got}");
        }
    }
}
