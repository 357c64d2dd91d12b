//! Material models: the Baraff–Witkin (1998) triangle conditions (stretch, shear, bend) and a
//! mass-spring model, each giving forces and the force Jacobians `∂f/∂x`, `∂f/∂v`.
//!
//! Every element is a condition `C(x)` with energy `E = k/2 C²`, force `f = -k (∂C/∂x) C`
//! and damping `d = -k_d (∂C/∂x) Ċ` (Baraff & Witkin 1998, eqs. 7, 11). The Jacobians are
//! `∂f/∂x = -k (∂C/∂x ∂C/∂xᵀ + ∂²C/∂x² C)` and `∂d/∂v = -k_d ∂C/∂x ∂C/∂xᵀ`; of `∂d/∂x` only the
//! symmetric part `-k_d ∂²C/∂x² Ċ` is kept (eq. 12 and the remark after it).
//!
//! **Definiteness.** `∂f/∂x` must keep the implicit matrix `A = M - h ∂f/∂v - h² ∂f/∂x`
//! symmetric positive definite. The Gauss–Newton part `-k ∂C/∂x ∂C/∂xᵀ` is always negative
//! semidefinite; the curvature part `-s ∂²C/∂x²`, `s = k C + k_d Ċ`, is not in general:
//! - stretch and springs: `∂²C/∂x²` is a positive semidefinite projector pattern
//!   (`(I - ŵŵᵀ)/‖w‖`), so the term is safe while stretched (`s > 0`) and indefinite under
//!   compression — the case Choi & Ko (2002, §4) identify as the cause of instability and
//!   drop;
//! - shear: `∂²C/∂x²` is indefinite for either sign of `s`;
//! - bend: only the Gauss–Newton part is used (the dihedral angle's Hessian is not formed).
//!
//! kinema keeps an indefinite curvature term while its most negative eigenvalue (bounded per
//! element) times `h²` stays below half of the mass share `mᵢ / (number of such conditions at
//! vertex i)` of each of its vertices, so that `A ⪰ M/2` always holds, and drops it otherwise
//! (Choi & Ko's fix). At the large steps of cloth animation the term is dropped; as `h → 0`
//! it is kept, the Jacobian becomes exact and BDF2 keeps its second order (tested).
//!
//! The forces themselves are always exact.
//!
//! The element functions are `#[inline(always)]`: the cloth compiles its loop over the
//! elements for AVX2 and AVX-512 as well as the baseline (`pulp` dispatch), and only code
//! inlined into that loop gets those builds.

use super::bsr::LOWER;
use crate::math::outer;
use glam::{DMat3, DVec3};

/// A Baraff–Witkin triangle: stretch and shear conditions.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Triangle {
    /// Vertex indices.
    pub verts: [usize; 3],
    /// `∂w_u/∂x_m` for the three corners.
    pub du: [f64; 3],
    /// `∂w_v/∂x_m` for the three corners.
    pub dv: [f64; 3],
    /// Rest area `a` in (u, v) (m²).
    pub area: f64,
    /// Half the smallest mass share (kg) of its vertices, the bound for indefinite terms.
    pub mass_share: f64,
    /// Block slots `(m, n)` row-major.
    pub slots: [usize; 9],
}

impl Triangle {
    /// The triangle `verts` with rest corner coordinates `uv` (m).
    pub fn new(verts: [usize; 3], uv: [[f64; 2]; 3]) -> Triangle {
        let (du1, dv1) = (uv[1][0] - uv[0][0], uv[1][1] - uv[0][1]);
        let (du2, dv2) = (uv[2][0] - uv[0][0], uv[2][1] - uv[0][1]);
        let det = du1 * dv2 - du2 * dv1;
        // [w_u w_v] = [Δx1 Δx2] [[Δu1 Δu2] [Δv1 Δv2]]⁻¹ (Baraff & Witkin 1998, eq. 9).
        let (wu1, wu2) = (dv2 / det, -dv1 / det);
        let (wv1, wv2) = (-du2 / det, du1 / det);
        Triangle {
            verts,
            du: [-(wu1 + wu2), wu1, wu2],
            dv: [-(wv1 + wv2), wv1, wv2],
            area: 0.5 * det.abs(),
            mass_share: 0.0,
            slots: [0; 9],
        }
    }

    /// `(w_u, w_v)` at positions `x`.
    ///
    /// Inlined: called out of line it returned its 3-vectors through memory in pieces the
    /// caller read back across two stores, and each such read waits for the stores to
    /// retire (a failed store-to-load forward).
    #[inline(always)]
    pub fn warp(&self, x: &[DVec3]) -> (DVec3, DVec3) {
        let p = self.verts.map(|i| x[i]);
        let wu = p[0] * self.du[0] + p[1] * self.du[1] + p[2] * self.du[2];
        let wv = p[0] * self.dv[0] + p[1] * self.dv[1] + p[2] * self.dv[2];
        (wu, wv)
    }
}

/// A bending hinge: the dihedral angle across an interior edge.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Hinge {
    /// `[a, b, p, q]`: edge `(a, b)`, opposite vertices `p`, `q`.
    pub verts: [usize; 4],
    /// Rest angle (rad).
    pub rest_angle: f64,
    /// Stiffness `k` of `E = k/2 (θ - θ₀)²` (N m / rad²).
    pub k: f64,
    /// Block slots `(m, n)` row-major.
    pub slots: [usize; 16],
}

/// A spring with a damper between two vertices.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Spring {
    /// Vertex indices.
    pub verts: [usize; 2],
    /// Rest length (m).
    pub rest: f64,
    /// Stiffness (N/m).
    pub k: f64,
    /// Half the smallest mass share (kg) of its vertices, the bound for indefinite terms.
    pub mass_share: f64,
    /// Block slots `(m, n)` row-major.
    pub slots: [usize; 4],
}

/// The signed dihedral angle of hinge `(a, b, p, q)` and its gradient with respect to
/// `[a, b, p, q]` (Bridson, Marino & Fedkiw 2003, "Simulation of clothing with folds and
/// wrinkles", §4: the bending modes `u₁..u₄` are the angle's gradient). Zero when flat,
/// positive when the triangles fold towards their common normal.
///
/// The angle is `atan2((m̂₁ × m̂₂)·ê, m̂₁·m̂₂)` of the unit normals; `atan2` does not change when
/// both arguments are scaled by the same positive factor, here `|n₁| |n₂| |e|`, so it is
/// taken of the unnormalised normals: one square root and three divisions a hinge instead
/// of three and nineteen (the divisions and roots were most of its time). Inlined, so that
/// its arguments and results stay in registers (see [`Triangle::warp`]).
#[inline(always)]
pub fn dihedral_angle(a: DVec3, b: DVec3, p: DVec3, q: DVec3) -> (f64, [DVec3; 4]) {
    let e = b - a;
    let e_len = e.length();
    let inv_e = 1.0 / e_len;
    let n1 = (p - a).cross(p - b);
    let n2 = (q - b).cross(q - a);
    let (u1, u2) = (n1 * (1.0 / n1.length_squared()), n2 * (1.0 / n2.length_squared()));
    let gp = e_len * u1;
    let gq = e_len * u2;
    let ga = (p - b).dot(e) * inv_e * u1 + (q - b).dot(e) * inv_e * u2;
    let gb = -(p - a).dot(e) * inv_e * u1 - (q - a).dot(e) * inv_e * u2;
    let theta = n1.cross(n2).dot(e).atan2(n1.dot(n2) * e_len);
    (-theta, [ga, gb, gp, gq])
}

/// Where an element's contributions go: forces, and when `matrix` is set the implicit matrix
/// `A -= α ∂f/∂v + β ∂f/∂x` and the vector `K u` (`∂f/∂x` times the given displacement).
pub struct Accumulator<'a> {
    /// Velocities (m/s).
    pub v: &'a [DVec3],
    /// Force accumulator (N).
    pub f: &'a mut [DVec3],
    /// Matrix blocks and `(α, β)`, or `None` for forces only.
    pub matrix: Option<(&'a mut [DMat3], f64, f64)>,
    /// Displacement `u` and the accumulator for `(∂f/∂x) u`.
    pub ku: Option<(&'a [DVec3], &'a mut [DVec3])>,
    /// Elastic energy (J).
    pub energy: f64,
}

impl Accumulator<'_> {
    /// Add one condition `C` with gradient `g` over `verts`, stiffness `k`, damping `kd`,
    /// and optionally its curvature (see [`Curvature`]).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn condition<
        const N: usize,
        H: Fn(usize, usize) -> DMat3,
        P: Fn(&[DVec3; N]) -> [DVec3; N],
    >(
        &mut self,
        verts: &[usize; N],
        slots: &[usize],
        c: f64,
        g: &[DVec3; N],
        k: f64,
        kd: f64,
        curvature: Option<Curvature<H, P>>,
    ) {
        let c_dot: f64 = (0..N).map(|m| g[m].dot(self.v[verts[m]])).sum();
        let scale = k * c + kd * c_dot;
        for m in 0..N {
            self.f[verts[m]] -= scale * g[m];
        }
        self.energy += 0.5 * k * c * c;
        let Some((blocks, alpha, beta)) = self.matrix.as_mut() else { return };
        let (alpha, beta) = (*alpha, *beta);
        let curvature = curvature.filter(|h| {
            let definite = h.psd && scale >= 0.0;
            definite || beta * scale.abs() * h.negative_bound <= h.mass_share
        });
        let weight = alpha * kd + beta * k;
        for m in 0..N {
            let gw = g[m] * weight;
            for n in 0..N {
                let slot = slots[N * m + n];
                if slot == LOWER {
                    continue; // the transpose of a stored block
                }
                // -(α ∂d/∂v + β ∂f/∂x) = (α k_d + β k) g_m g_nᵀ + β s H_mn.
                let mut block = DMat3::from_cols(gw * g[n].x, gw * g[n].y, gw * g[n].z);
                if let Some(h) = &curvature {
                    block += (h.block)(m, n) * (scale * beta);
                }
                blocks[slot] += block;
            }
        }
        // (∂f/∂x) u = -k g (gᵀu) - s H u.
        if let Some((u, ku)) = self.ku.as_mut() {
            let ue = verts.map(|i| u[i]);
            let gu: f64 = (0..N).map(|n| g[n].dot(ue[n])).sum();
            let hu = curvature.as_ref().map(|h| (h.apply)(&ue));
            for m in 0..N {
                let mut v = g[m] * (-k * gu);
                if let Some(hu) = &hu {
                    v -= hu[m] * scale;
                }
                ku[verts[m]] += v;
            }
        }
    }
}

/// The second derivative `∂²C/∂x_m∂x_n` of a condition, as the function `block(m, n)`.
pub struct Curvature<H, P> {
    /// `∂²C/∂x_m∂x_n`.
    pub block: H,
    /// The product `(∂²C/∂x²) u` for the element's displacements `u` (m), by the structure of
    /// the blocks rather than block by block.
    pub apply: P,
    /// Whether `∂²C/∂x²` is positive semidefinite.
    pub psd: bool,
    /// A bound on `-λ_min(s ∂²C/∂x²) / |s|` (the most negative eigenvalue per unit `s`).
    pub negative_bound: f64,
    /// The mass share (kg) the term may not exceed after multiplication by `h²`.
    pub mass_share: f64,
}

/// Stretch and shear of one triangle (Baraff & Witkin 1998, §4.2–4.3), with
/// `k_stretch = stretch / a`, `k_shear = shear / a` so that the energy per unit area does not
/// depend on the mesh resolution, and `k_d = damping · k`.
///
/// The three conditions share one structure: `w_u = Σₘ du_m x_m`, `w_v = Σₘ dv_m x_m`, so
/// each gradient is `∂C/∂x_m = du_m ∂C/∂w_u + dv_m ∂C/∂w_v` and each block of the
/// triangle's matrix (Gauss–Newton and curvature parts of all three conditions) is
/// `du_m du_n W_uu + dv_m dv_n W_vv + du_m dv_n W_uv + dv_m du_n W_uvᵀ` with four 3x3
/// matrices summed over the conditions: the blocks are formed once per triangle from them,
/// as are the forces and `(∂f/∂x) u`. Each condition's curvature term is kept or dropped
/// as [`Accumulator::condition`] does it.
#[inline(always)]
pub fn triangle(
    t: &Triangle,
    x: &[DVec3],
    stretch: f64,
    shear: f64,
    damping: f64,
    acc: &mut Accumulator,
) {
    let (wu, wv) = t.warp(x);
    // By reference: a copy of the arrays to the stack is read back across two stores.
    let (a, du, dv) = (t.area, &t.du, &t.dv);
    let v = t.verts.map(|i| acc.v[i]);
    // ẇ_u, ẇ_v.
    let (vu, vv) =
        (v[0] * du[0] + v[1] * du[1] + v[2] * du[2], v[0] * dv[0] + v[1] * dv[1] + v[2] * dv[2]);
    let (lu, lv) = (wu.length(), wv.length());
    // Reciprocals once: a division costs several multiplications.
    let (inv_lu, inv_lv) = (1.0 / lu, 1.0 / lv);
    let (hu, hv) = (wu * inv_lu, wv * inv_lv);
    let (ks, kh) = (stretch / a, shear / a);
    // Stretch in u, stretch in v, shear: C, Ċ and s = k C + k_d Ċ.
    let c = [a * (lu - 1.0), a * (lv - 1.0), a * wu.dot(wv)];
    let c_dot = [a * hu.dot(vu), a * hv.dot(vv), a * (wv.dot(vu) + wu.dot(vv))];
    let k = [ks, ks, kh];
    let s = [0, 1, 2].map(|i| k[i] * c[i] + damping * k[i] * c_dot[i]);
    acc.energy += 0.5 * (k[0] * c[0] * c[0] + k[1] * c[1] * c[1] + k[2] * c[2] * c[2]);
    // f_m = -Σ s ∂C/∂x_m = -(du_m F_u + dv_m F_v).
    let fu = (hu * s[0] + wv * s[2]) * a;
    let fv = (hv * s[1] + wu * s[2]) * a;
    for m in 0..3 {
        acc.f[t.verts[m]] -= fu * du[m] + fv * dv[m];
    }
    let warp = Warp { wu, wv, hu, hv, inv_lu, inv_lv, ks, kh, s };
    triangle_jacobian(t, &warp, damping, acc);
}

/// A triangle's deformation at the current positions, shared by its forces and Jacobian:
/// `w_u`, `w_v`, their directions `ŵ` and inverse lengths, the stiffnesses per rest area and
/// `s = k C + k_d Ċ` of its three conditions (stretch u, stretch v, shear).
struct Warp {
    wu: DVec3,
    wv: DVec3,
    hu: DVec3,
    hv: DVec3,
    inv_lu: f64,
    inv_lv: f64,
    ks: f64,
    kh: f64,
    s: [f64; 3],
}

/// The matrix blocks `-(α ∂d/∂v + β ∂f/∂x)` and the product `(∂f/∂x) u` of one triangle (see
/// [`triangle`]), when `acc` asks for them.
#[inline(always)]
fn triangle_jacobian(t: &Triangle, warp: &Warp, damping: f64, acc: &mut Accumulator) {
    let Warp { wu, wv, hu, hv, inv_lu, inv_lv, ks, kh, s } = *warp;
    let (a, du, dv) = (t.area, &t.du, &t.dv);
    let Some((blocks, alpha, beta)) = acc.matrix.as_mut() else { return };
    let (alpha, beta) = (*alpha, *beta);
    // Gauss–Newton part Σ k (∂C/∂w)(∂C/∂w)ᵀ, with ∂C/∂w_u = a ŵ_u for stretch in u and a w_v
    // for shear, ∂C/∂w_v = a ŵ_v for stretch in v and a w_u for shear.
    let a2 = a * a;
    let g_uu = (outer(hu, hu) * ks + outer(wv, wv) * kh) * a2;
    let g_vv = (outer(hv, hv) * ks + outer(wu, wu) * kh) * a2;
    let g_uv = outer(wv, wu) * (kh * a2);
    // Curvature part Σ s ∂²C/∂w∂w: a (I - ŵŵᵀ)/‖w‖ for stretch (positive semidefinite,
    // eigenvalues up to a |d|²/‖w‖ per unit s), a I between w_u and w_v for shear
    // (indefinite, eigenvalues a (du·dv ± |du||dv|)).
    let dot3 = |p: &[f64; 3], q: &[f64; 3]| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
    let keep =
        |s: f64, psd: bool, bound: f64| (psd && s >= 0.0) || beta * s.abs() * bound <= t.mass_share;
    let projector = |h: DVec3, inv_len: f64| (DMat3::IDENTITY - outer(h, h)) * (a * inv_len);
    let mut h_uu = DMat3::ZERO;
    let mut h_vv = DMat3::ZERO;
    let mut h_uv = 0.0;
    let (du2, dv2) = (dot3(du, du), dot3(dv, dv));
    if keep(s[0], true, a * du2 * inv_lu) {
        h_uu = projector(hu, inv_lu) * s[0];
    }
    if keep(s[1], true, a * dv2 * inv_lv) {
        h_vv = projector(hv, inv_lv) * s[1];
    }
    let shear_bound = a * ((du2 * dv2).sqrt() + dot3(du, dv).abs());
    if keep(s[2], false, shear_bound) {
        h_uv = a * s[2];
    }
    // -(α ∂d/∂v + β ∂f/∂x) = (α k_d + β k) ∂C/∂x ∂C/∂xᵀ + β s ∂²C/∂x².
    let weight = alpha * damping + beta;
    let w_uu = g_uu * weight + h_uu * beta;
    let w_vv = g_vv * weight + h_vv * beta;
    let w_uv = g_uv * weight + DMat3::from_diagonal(DVec3::splat(h_uv * beta));
    let w_vu = w_uv.transpose();
    for n in 0..3 {
        // Block (m, n) = du_m X_n + dv_m Y_n.
        let xn = w_uu * du[n] + w_uv * dv[n];
        let yn = w_vu * du[n] + w_vv * dv[n];
        for m in 0..3 {
            let slot = t.slots[3 * m + n];
            if slot != LOWER {
                blocks[slot] += xn * du[m] + yn * dv[m];
            }
        }
    }
    // (∂f/∂x) u = -(K u) with K of the same structure, K = G + H.
    if let Some((u, ku)) = acc.ku.as_mut() {
        let ue = t.verts.map(|i| u[i]);
        let uu = ue[0] * du[0] + ue[1] * du[1] + ue[2] * du[2];
        let uv = ue[0] * dv[0] + ue[1] * dv[1] + ue[2] * dv[2];
        let ku_u = (g_uu + h_uu) * uu + g_uv * uv + uv * h_uv;
        let ku_v = g_uv.transpose() * uu + uu * h_uv + (g_vv + h_vv) * uv;
        for m in 0..3 {
            ku[t.verts[m]] -= ku_u * du[m] + ku_v * dv[m];
        }
    }
}

/// No curvature term.
type Flat = Curvature<fn(usize, usize) -> DMat3, fn(&[DVec3; 4]) -> [DVec3; 4]>;

/// Bending of one hinge on its dihedral angle (Baraff & Witkin 1998, §4.4), `k_d = damping · k`.
#[inline(always)]
pub fn hinge(h: &Hinge, x: &[DVec3], damping: f64, acc: &mut Accumulator) {
    let [a, b, p, q] = h.verts.map(|i| x[i]);
    let (theta, g) = dihedral_angle(a, b, p, q);
    acc.condition(&h.verts, &h.slots, theta - h.rest_angle, &g, h.k, damping * h.k, None::<Flat>);
}

/// One spring: `C = l - L`, `k_d = damping · k`.
#[inline(always)]
pub fn spring(s: &Spring, x: &[DVec3], damping: f64, acc: &mut Accumulator) {
    let d = x[s.verts[1]] - x[s.verts[0]];
    let l = d.length();
    let n = d / l;
    let g = [-n, n];
    // ∂²l/∂x² = [[P, -P], [-P, P]], P = (I - n̂n̂ᵀ)/l; eigenvalues 0 and 2/l.
    let projector = (DMat3::IDENTITY - DMat3::from_cols(n * n.x, n * n.y, n * n.z)) / l;
    let curvature = Curvature {
        block: |m: usize, k: usize| if m == k { projector } else { -projector },
        apply: |u: &[DVec3; 2]| {
            let pu = projector * (u[0] - u[1]);
            [pu, -pu]
        },
        psd: true,
        negative_bound: 2.0 / l,
        mass_share: s.mass_share,
    };
    acc.condition(&s.verts, &s.slots, l - s.rest, &g, s.k, damping * s.k, Some(curvature));
}
