//! The elastic energies of a discrete rod with their analytic gradients and Hessians, as pure
//! functions of one stencil (Bergou et al. 2008, sec. 4.2; derivatives after Kaufman et al.
//! 2014, appendix, and Bergou et al. 2010, sec. 7).
//!
//! - Stretching of edge `j` (rest length `l̄_j`): `E = ½ EA l̄ (|e|/l̄ − 1)²`.
//! - Bending at interior vertex `i` (edges `e = e^{i−1}`, `f = e^i`, Voronoi length
//!   `l_i = (l̄_{i−1} + l̄_i)/2`): material curvatures `κ1 = ½ (κb)·(m2^e + m2^f)`,
//!   `κ2 = −½ (κb)·(m1^e + m1^f)` (Bergou et al. 2008, eq. 2 with the frame averaged over the
//!   two edges) and `E = (EI1 (κ1 − κ̄1)² + EI2 (κ2 − κ̄2)²) / (2 l_i)` (eq. 4).
//! - Twisting at interior vertex `i`: `m = θ^i − θ^{i−1} + m_ref` (Bergou et al. 2010,
//!   eq. 30) and `E = GJ (m − m̄)² / (2 l_i)` (Bergou et al. 2008, eq. 5).
//!
//! A bending or twisting stencil has 11 degrees of freedom, in the rod's order
//! `x_{i−1}, θ^{i−1}, x_i, θ^i, x_{i+1}` ([`Local`]). The material frames' dependence on the
//! positions is the time-parallel transport (`frames.rs`): the derivatives are those of the
//! energy with the frames transported from the configuration they are taken at.

use super::band::Band;
use super::frames::{curvature_binormal, directors, Frames};
use super::Model;
use crate::math::{outer, skew};
use glam::{DMat3, DVec3};

/// Degrees of freedom of a bending or twisting stencil.
pub const STENCIL: usize = 11;

/// Offsets in a stencil of the three vertices and the two twist angles.
const NODES: [usize; 3] = [0, 4, 8];
const THETA_E: usize = 3;
const THETA_F: usize = 7;
/// How the vertices enter the edges: `e = x_b − x_a`, `f = x_c − x_b`.
const CE: [f64; 3] = [-1.0, 1.0, 0.0];
const CF: [f64; 3] = [0.0, -1.0, 1.0];

/// A scalar of one stencil with its gradient and Hessian in the stencil's 11 coordinates.
#[derive(Clone, Debug)]
pub struct Local {
    /// The value.
    pub value: f64,
    /// The gradient, 11.
    pub grad: [f64; STENCIL],
    /// The Hessian, 11 × 11 (symmetric).
    pub hess: [[f64; STENCIL]; STENCIL],
}

impl Local {
    fn zero() -> Self {
        Local { value: 0.0, grad: [0.0; STENCIL], hess: [[0.0; STENCIL]; STENCIL] }
    }

    /// Put derivatives taken with respect to the edge vectors on the vertices: first
    /// derivatives `ge`, `gf` (3) and second `hee`, `hef` (rows `e`, columns `f`), `hff`.
    fn place_edges(&mut self, ge: DVec3, gf: DVec3, hee: DMat3, hef: DMat3, hff: DMat3) {
        let hfe = hef.transpose();
        for p in 0..3 {
            let g = CE[p] * ge + CF[p] * gf;
            for r in 0..3 {
                self.grad[NODES[p] + r] += g[r];
            }
            for q in 0..3 {
                let block = hee * (CE[p] * CE[q])
                    + hef * (CE[p] * CF[q])
                    + hfe * (CF[p] * CE[q])
                    + hff * (CF[p] * CF[q]);
                for r in 0..3 {
                    for c in 0..3 {
                        self.hess[NODES[p] + r][NODES[q] + c] += block.col(c)[r];
                    }
                }
            }
        }
    }

    /// Put the mixed second derivatives of an edge pair and the angle at `col`: `ve` with
    /// respect to `e`, `vf` to `f`.
    fn place_mixed(&mut self, col: usize, ve: DVec3, vf: DVec3) {
        for p in 0..3 {
            let v = CE[p] * ve + CF[p] * vf;
            for r in 0..3 {
                self.hess[NODES[p] + r][col] += v[r];
                self.hess[col][NODES[p] + r] += v[r];
            }
        }
    }

    /// Add `w (a − rest)² / 2` for the scalar `a` of the same stencil, its gradient
    /// `w (a − rest) ∇a` and Hessian `w (∇a ∇aᵀ + (a − rest) ∇²a)`.
    fn add_quadratic(&mut self, a: &Local, rest: f64, w: f64) {
        let d = a.value - rest;
        self.value += 0.5 * w * d * d;
        for r in 0..STENCIL {
            self.grad[r] += w * d * a.grad[r];
            for c in 0..STENCIL {
                self.hess[r][c] += w * (a.grad[r] * a.grad[c] + d * a.hess[r][c]);
            }
        }
    }
}

/// Stretching energy of an edge `e` (m) of rest length `rest` (m) and stiffness `ea` (N):
/// `(E, ∂E/∂e, ∂²E/∂e²)`. A compressed edge's Hessian keeps only its axial part (the
/// transverse term `ea (|e|/l̄ − 1)/|e| (I − t tᵀ)` is negative there and is dropped, a
/// positive-definite approximation, as in Kaufman et al. 2014, sec. 5).
pub fn stretch(e: DVec3, rest: f64, ea: f64) -> (f64, DVec3, DMat3) {
    let len = e.length();
    let t = e / len;
    let strain = len / rest - 1.0;
    let energy = stretch_energy(e, rest, ea);
    let grad = ea * strain * t;
    let tt = outer(t, t);
    let mut hess = tt * (ea / rest);
    if strain > 0.0 {
        hess += (DMat3::IDENTITY - tt) * (ea * strain / len);
    }
    (energy, grad, hess)
}

/// The stretching energy of [`stretch`] alone (J).
fn stretch_energy(e: DVec3, rest: f64, ea: f64) -> f64 {
    let strain = e.length() / rest - 1.0;
    0.5 * ea * rest * strain * strain
}

/// The two edges of a stencil and their material directors.
#[derive(Clone, Copy, Debug)]
pub struct Stencil {
    /// Edge `e^{i−1}` (m).
    pub e: DVec3,
    /// Edge `e^i` (m).
    pub f: DVec3,
    /// Material directors `(m1, m2)` of `e`.
    pub me: (DVec3, DVec3),
    /// Material directors `(m1, m2)` of `f`.
    pub mf: (DVec3, DVec3),
}

/// Quantities shared by the curvature derivatives of one stencil.
struct Shared {
    ne: f64,
    nf: f64,
    te: DVec3,
    tf: DVec3,
    kb: DVec3,
    chi: f64,
    tt: DVec3,
}

impl Shared {
    fn new(s: &Stencil) -> Self {
        let (ne, nf) = (s.e.length(), s.f.length());
        let (te, tf) = (s.e / ne, s.f / nf);
        let chi = 1.0 + te.dot(tf);
        Shared { ne, nf, te, tf, kb: curvature_binormal(s.e, s.f), chi, tt: (te + tf) / chi }
    }
}

/// The material curvature `κ1` (`k = 0`) or `κ2` (`k = 1`) of a stencil (1, dimensionless
/// integrated curvature) with its gradient and Hessian (Kaufman et al. 2014, eqs. A.5–A.12).
pub fn curvature(s: &Stencil, k: usize) -> Local {
    let g = Shared::new(s);
    // κ1 pairs with d̃ = d̃2 and the sign σ = +1; κ2 with d̃1 and σ = −1, from
    // κ1 = ½ κb·(m2e + m2f), κ2 = −½ κb·(m1e + m1f).
    let (sigma, de, df, oe, of) = if k == 0 {
        (1.0, s.me.1, s.mf.1, s.me.0, s.mf.0)
    } else {
        (-1.0, s.me.0, s.mf.0, s.me.1, s.mf.1)
    };
    let dt = (de + df) / g.chi;
    let kappa = sigma * 0.5 * g.kb.dot(de + df);
    let (ne, nf, te, tf, tt, chi, kb) = (g.ne, g.nf, g.te, g.tf, g.tt, g.chi, g.kb);
    let ge = (-kappa * tt + sigma * tf.cross(dt)) / ne;
    let gf = (-kappa * tt - sigma * te.cross(dt)) / nf;
    let ttt = outer(tt, tt);
    let a = tf.cross(dt);
    let b = te.cross(dt);
    let sym = |u: DVec3, v: DVec3| outer(u, v) + outer(v, u);
    let hee = (ttt * (2.0 * kappa) - sym(a, tt) * sigma) / (ne * ne)
        - (DMat3::IDENTITY - outer(te, te)) * (kappa / (chi * ne * ne))
        + sym(kb, de) * (sigma / (4.0 * ne * ne));
    let hff = (ttt * (2.0 * kappa) + sym(b, tt) * sigma) / (nf * nf)
        - (DMat3::IDENTITY - outer(tf, tf)) * (kappa / (chi * nf * nf))
        + sym(kb, df) * (sigma / (4.0 * nf * nf));
    let hef = -(DMat3::IDENTITY + outer(te, tf)) * (kappa / (chi * ne * nf))
        + (ttt * (2.0 * kappa) + (outer(tt, b) - outer(a, tt) - skew(dt)) * sigma) / (ne * nf);
    let mut out = Local::zero();
    out.value = kappa;
    out.place_edges(ge, gf, hee, hef, hff);
    // θ derivatives: ∂m1/∂θ = m2, ∂m2/∂θ = −m1, so ∂d/∂θ = −σ o (o the other director).
    out.grad[THETA_E] = -0.5 * kb.dot(oe);
    out.grad[THETA_F] = -0.5 * kb.dot(of);
    out.hess[THETA_E][THETA_E] = -0.5 * sigma * kb.dot(de);
    out.hess[THETA_F][THETA_F] = -0.5 * sigma * kb.dot(df);
    for (col, o) in [(THETA_E, oe), (THETA_F, of)] {
        let ve = (0.5 * kb.dot(o) * tt - tf.cross(o) / chi) / ne;
        let vf = (0.5 * kb.dot(o) * tt + te.cross(o) / chi) / nf;
        out.place_mixed(col, ve, vf);
    }
    out
}

/// The twist `m = θ^f − θ^e + m_ref` (rad) of a stencil of reference twist `reference` and
/// twist angles `theta = (θ^e, θ^f)`, with its gradient and Hessian (Kaufman et al. 2014,
/// eqs. A.13–A.15; Bergou et al. 2010, eq. 31).
pub fn twist(s: &Stencil, reference: f64, theta: (f64, f64)) -> Local {
    let g = Shared::new(s);
    let (ne, nf, te, tf, tt, chi, kb) = (g.ne, g.nf, g.te, g.tf, g.tt, g.chi, g.kb);
    let sym = |u: DVec3, v: DVec3| outer(u, v) + outer(v, u);
    let hee = sym(kb, te + tt) * (-0.25 / (ne * ne));
    let hff = sym(kb, tf + tt) * (-0.25 / (nf * nf));
    let hef = (skew(te) * (2.0 / chi) - outer(kb, tt)) * (0.5 / (ne * nf));
    let mut out = Local::zero();
    out.value = theta.1 - theta.0 + reference;
    out.place_edges(kb / (2.0 * ne), kb / (2.0 * nf), hee, hef, hff);
    out.grad[THETA_E] = -1.0;
    out.grad[THETA_F] = 1.0;
    out
}

/// Bending and twisting energy of stencil `k` of `model` (the vertex between edges `k` and
/// `(k + 1) mod n`; J) with gradient and Hessian.
pub fn bend_twist(model: &Model, frames: &Frames, theta: &[f64], k: usize) -> Local {
    let (s, a, b) = stencil(frames, theta, k);
    let w = 1.0 / model.voronoi[k];
    let [b1, b2] = model.bending_stiffness();
    let rest = model.rest_curvatures[k];
    let mut out = Local::zero();
    out.add_quadratic(&curvature(&s, 0), rest[0], w * b1);
    out.add_quadratic(&curvature(&s, 1), rest[1], w * b2);
    let m = twist(&s, frames.reference_twist[k], (theta[a], theta[b]));
    out.add_quadratic(&m, model.rest_twists[k], w * model.twisting_stiffness());
    out
}

/// The value of [`bend_twist`] alone (J), without its derivatives: the same floating-point
/// operations in the same order, so bitwise equal to `bend_twist(..).value`, at a fraction
/// of its cost (the line search and the predictor need only values).
fn bend_twist_energy(model: &Model, frames: &Frames, theta: &[f64], k: usize) -> f64 {
    let (s, a, b) = stencil(frames, theta, k);
    let w = 1.0 / model.voronoi[k];
    let [b1, b2] = model.bending_stiffness();
    let rest = model.rest_curvatures[k];
    let kb = curvature_binormal(s.e, s.f);
    let quadratic = |value: f64, rest: f64, w: f64| {
        let d = value - rest;
        0.5 * w * d * d
    };
    // As `curvature`: κ = σ ½ κb·(d_e + d_f), σ ½ = ±½ exactly.
    let mut energy = 0.0;
    energy += quadratic(0.5 * kb.dot(s.me.1 + s.mf.1), rest[0], w * b1);
    energy += quadratic(-0.5 * kb.dot(s.me.0 + s.mf.0), rest[1], w * b2);
    let m = theta[b] - theta[a] + frames.reference_twist[k];
    energy += quadratic(m, model.rest_twists[k], w * model.twisting_stiffness());
    energy
}

/// Stencil `k` of a configuration (its two edges and their material frames) with the
/// indices of its two edges.
fn stencil(frames: &Frames, theta: &[f64], k: usize) -> (Stencil, usize, usize) {
    let (a, b) = (k, (k + 1) % theta.len());
    // A ring's seam stencil sees its first edge's material frame turned by the seam twist.
    let mf = if b == 0 {
        directors(frames.tangents[0], frames.reference[0], theta[0] + frames.seam)
    } else {
        (frames.m1[b], frames.m2[b])
    };
    let s =
        Stencil { e: frames.edges[a], f: frames.edges[b], me: (frames.m1[a], frames.m2[a]), mf };
    (s, a, b)
}

/// The elastic energy of a configuration (J) alone: the value of [`elastic`], bitwise.
pub fn elastic_energy(model: &Model, frames: &Frames, theta: &[f64]) -> f64 {
    let ea = model.stretching_stiffness();
    let mut energy = 0.0;
    for (&e, &rest) in frames.edges.iter().zip(&model.rest_lengths) {
        energy += stretch_energy(e, rest, ea);
    }
    for k in 0..model.stencils() {
        energy += bend_twist_energy(model, frames, theta, k);
    }
    energy
}

/// The elastic energy of a configuration (J), its gradient added to `grad` (the rod's
/// [`Model::dofs`] interleaved degrees of freedom, `x_0, θ^0, x_1, θ^1, …`) and, with `hess`,
/// its Hessian added to the band.
pub fn elastic(
    model: &Model,
    frames: &Frames,
    theta: &[f64],
    grad: &mut [f64],
    mut hess: Option<&mut Band>,
) -> f64 {
    let ea = model.stretching_stiffness();
    let v = model.vertices();
    let mut energy = 0.0;
    for (j, (&e, &rest)) in frames.edges.iter().zip(&model.rest_lengths).enumerate() {
        let (en, g, h) = stretch(e, rest, ea);
        energy += en;
        let (a, b) = (4 * j, 4 * ((j + 1) % v));
        for r in 0..3 {
            grad[a + r] -= g[r];
            grad[b + r] += g[r];
        }
        if let Some(band) = hess.as_deref_mut() {
            for r in 0..3 {
                for c in 0..3 {
                    let val = h.col(c)[r];
                    if r >= c {
                        band.add(a + r, a + c, val);
                        band.add(b + r, b + c, val);
                    }
                    band.add(b + r, a + c, -val);
                }
            }
        }
    }
    for k in 0..model.stencils() {
        let local = bend_twist(model, frames, theta, k);
        energy += local.value;
        // Stencil coordinate `l` is vertex or edge `k + l / 4` (mod V), component `l mod 4`.
        let global: [usize; STENCIL] = std::array::from_fn(|l| 4 * ((k + l / 4) % v) + l % 4);
        for r in 0..STENCIL {
            grad[global[r]] += local.grad[r];
        }
        if let Some(band) = hess.as_deref_mut() {
            for r in 0..STENCIL {
                for c in 0..=r {
                    band.add(global[r], global[c], local.hess[r][c]);
                }
            }
        }
    }
    energy
}
