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

use super::bsr::LOWER;
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
pub fn dihedral_angle(a: DVec3, b: DVec3, p: DVec3, q: DVec3) -> (f64, [DVec3; 4]) {
    let e = b - a;
    let e_len = e.length();
    let n1 = (p - a).cross(p - b);
    let n2 = (q - b).cross(q - a);
    let (l1, l2) = (n1.length_squared(), n2.length_squared());
    let (u1, u2) = (n1 / l1, n2 / l2);
    let gp = e_len * u1;
    let gq = e_len * u2;
    let ga = (p - b).dot(e) / e_len * u1 + (q - b).dot(e) / e_len * u2;
    let gb = -(p - a).dot(e) / e_len * u1 - (q - a).dot(e) / e_len * u2;
    let (m1, m2) = (n1 / l1.sqrt(), n2 / l2.sqrt());
    let theta = m1.cross(m2).dot(e / e_len).atan2(m1.dot(m2));
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
pub fn triangle(
    t: &Triangle,
    x: &[DVec3],
    stretch: f64,
    shear: f64,
    damping: f64,
    acc: &mut Accumulator,
) {
    let (wu, wv) = t.warp(x);
    let a = t.area;
    let mut stretch_axis = |w: DVec3, d: &[f64; 3]| {
        let len = w.length();
        let wh = w / len;
        let c = a * (len - 1.0);
        let g = [wh * (a * d[0]), wh * (a * d[1]), wh * (a * d[2])];
        // ∂²C/∂x_m∂x_n = a d_m d_n (I - ŵŵᵀ)/‖w‖, eigenvalues 0 and a |d|²/‖w‖.
        let projector =
            (DMat3::IDENTITY - DMat3::from_cols(wh * wh.x, wh * wh.y, wh * wh.z)) * (a / len);
        let curvature = Curvature {
            block: |m: usize, n: usize| projector * (d[m] * d[n]),
            // Σₙ d_m d_n P uₙ = d_m P (Σₙ d_n uₙ).
            apply: |u: &[DVec3; 3]| {
                let pu = projector * (u[0] * d[0] + u[1] * d[1] + u[2] * d[2]);
                [pu * d[0], pu * d[1], pu * d[2]]
            },
            psd: true,
            negative_bound: a * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) / len,
            mass_share: t.mass_share,
        };
        let k = stretch / a;
        acc.condition(&t.verts, &t.slots, c, &g, k, damping * k, Some(curvature));
    };
    stretch_axis(wu, &t.du);
    stretch_axis(wv, &t.dv);
    let c = a * wu.dot(wv);
    let g = [0, 1, 2].map(|m| (wv * t.du[m] + wu * t.dv[m]) * a);
    // ∂²C/∂x_m∂x_n = a (du_m dv_n + dv_m du_n) I, eigenvalues a (du·dv ± |du||dv|).
    let (du, dv) = (DVec3::from_array(t.du), DVec3::from_array(t.dv));
    let curvature = Curvature {
        block: |m: usize, n: usize| {
            DMat3::from_diagonal(DVec3::splat(a * (t.du[m] * t.dv[n] + t.dv[m] * t.du[n])))
        },
        // Σₙ a (du_m dv_n + dv_m du_n) uₙ = a (du_m U_v + dv_m U_u), U = Σₙ d_n uₙ.
        apply: |u: &[DVec3; 3]| {
            let uu = (u[0] * t.du[0] + u[1] * t.du[1] + u[2] * t.du[2]) * a;
            let uv = (u[0] * t.dv[0] + u[1] * t.dv[1] + u[2] * t.dv[2]) * a;
            [0, 1, 2].map(|m| uv * t.du[m] + uu * t.dv[m])
        },
        psd: false,
        negative_bound: a * (du.length() * dv.length() + du.dot(dv).abs()),
        mass_share: t.mass_share,
    };
    let k = shear / a;
    acc.condition(&t.verts, &t.slots, c, &g, k, damping * k, Some(curvature));
}

/// No curvature term.
type Flat = Curvature<fn(usize, usize) -> DMat3, fn(&[DVec3; 4]) -> [DVec3; 4]>;

/// Bending of one hinge on its dihedral angle (Baraff & Witkin 1998, §4.4), `k_d = damping · k`.
pub fn hinge(h: &Hinge, x: &[DVec3], damping: f64, acc: &mut Accumulator) {
    let [a, b, p, q] = h.verts.map(|i| x[i]);
    let (theta, g) = dihedral_angle(a, b, p, q);
    acc.condition(&h.verts, &h.slots, theta - h.rest_angle, &g, h.k, damping * h.k, None::<Flat>);
}

/// One spring: `C = l - L`, `k_d = damping · k`.
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
