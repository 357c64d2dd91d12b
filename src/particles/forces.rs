//! Forces on particles, each a pure function of positions and velocities that adds into a
//! force buffer. Conservative forces also report their potential energy.

use crate::error::{Error, Result};
use glam::DVec3;

/// A force acting on the particles of a [`super::ParticleSystem`].
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub enum Force {
    /// Uniform field `f = m g` (N); potential `-m g·x`.
    Gravity {
        /// Acceleration (m/s²).
        g: DVec3,
    },
    /// Drag against the air moving at `wind` (m/s): `f = -k₁ u - k₂ |u| u`, `u = v - wind`,
    /// with `k₂ = ½ ρ C_d A` (kg/m) and `k₁` (kg/s) per particle.
    Drag {
        /// Linear coefficient k₁ (kg/s).
        linear: f64,
        /// Quadratic coefficient k₂ = ½ ρ C_d A (kg/m).
        quadratic: f64,
        /// Air velocity (m/s).
        wind: DVec3,
    },
    /// Velocity damping `f = -c m v` (c in 1/s): every particle loses speed at the same rate.
    Damping {
        /// Rate (1/s).
        rate: f64,
    },
    /// Hookean springs with dampers between particle pairs:
    /// `f_i = -[k (|d| - L) + c (v_i - v_j)·d̂] d̂`, `d = x_i - x_j`, `f_j = -f_i`.
    Springs {
        /// Particle pairs.
        pairs: Vec<[usize; 2]>,
        /// Rest lengths (m), one per pair.
        rest: Vec<f64>,
        /// Stiffness (N/m).
        stiffness: f64,
        /// Damping along the spring (N s/m).
        damping: f64,
    },
    /// Softened inverse-square attraction to a point, `f = s m (c - x) / (|c - x|² + ε²)^{3/2}`
    /// (negative `strength` repels); potential `-s m / sqrt(|c - x|² + ε²)`.
    Attractor {
        /// Centre (m).
        center: DVec3,
        /// Strength s (m³/s²).
        strength: f64,
        /// Softening length ε (m) > 0.
        softening: f64,
    },
    /// Swirl around an axis through `center`: `f = s m (â × r⊥) / (|r⊥| + ε)` with `r⊥` the
    /// offset from the axis, a force of nearly constant magnitude `s m` tangent to circles.
    Vortex {
        /// A point of the axis (m).
        center: DVec3,
        /// Axis direction (normalised here).
        axis: DVec3,
        /// Strength s (m/s²).
        strength: f64,
        /// Core radius ε (m) > 0.
        core: f64,
    },
    /// Divergence-free turbulence: `f = s m curl ψ(x / L)` with `ψ` three independent smooth
    /// gradient-noise fields (curl noise, Bridson, Houriham & Nordenstam 2007).
    Turbulence {
        /// Strength s (m/s²).
        strength: f64,
        /// Length scale L of the eddies (m).
        scale: f64,
        /// Seed of the noise.
        seed: u64,
    },
    /// Soft pairwise repulsion within `radius`: `f = k (r - d) d̂` for `d < r`, found with a
    /// spatial hash grid of cell size `radius` (O(N) neighbours, never all pairs).
    NeighborRepulsion {
        /// Interaction radius r (m).
        radius: f64,
        /// Stiffness k (N/m).
        stiffness: f64,
    },
    /// Newtonian gravity between every pair of free particles (O(N²); pinned ones take no
    /// part), softened: `f_i = Σ G m_i m_j d / (|d|² + ε²)^{3/2}`.
    NBodyGravity {
        /// Gravitational constant G (m³ kg⁻¹ s⁻²).
        constant: f64,
        /// Softening length ε (m).
        softening: f64,
    },
}

fn check(arg: &str, ok: bool, why: &str) -> Result<()> {
    if ok {
        Ok(())
    } else {
        Err(Error::invalid(arg, why))
    }
}

/// `value` must be finite and `>= 0`.
fn non_negative(arg: &str, value: f64) -> Result<()> {
    check(arg, value.is_finite() && value >= 0.0, "must be finite and >= 0")
}

/// `value` must be finite and `> 0`.
fn positive(arg: &str, value: f64) -> Result<()> {
    check(arg, value.is_finite() && value > 0.0, "must be positive")
}

/// Springs: one rest length per pair, coefficients finite and `>= 0`, each pair two different
/// particles below `n`, each rest length finite and `>= 0` (the offending pair named).
fn check_springs(
    pairs: &[[usize; 2]],
    rest: &[f64],
    coefficients: [f64; 2],
    n: usize,
) -> Result<()> {
    check("rest", rest.len() == pairs.len(), "needs one rest length per pair")?;
    non_negative("stiffness", coefficients[0])?;
    non_negative("damping", coefficients[1])?;
    for (k, (p, l)) in pairs.iter().zip(rest).enumerate() {
        if p[0] >= n || p[1] >= n || p[0] == p[1] {
            return Err(Error::InvalidInput {
                arg: "pairs".into(),
                index: Some(k),
                reason: format!("{p:?} must be two different particles below {n}"),
            });
        }
        if !(l.is_finite() && *l >= 0.0) {
            return Err(Error::InvalidInput {
                arg: "rest".into(),
                index: Some(k),
                reason: "must be finite and >= 0".into(),
            });
        }
    }
    Ok(())
}

impl Force {
    /// Whether this force acts on each particle alone (gravity, drag, damping, attractor,
    /// vortex, turbulence) rather than between particles (springs, repulsion, all-pairs
    /// gravity).
    pub(super) fn acts_alone(&self) -> bool {
        !matches!(
            self,
            Force::Springs { .. } | Force::NeighborRepulsion { .. } | Force::NBodyGravity { .. }
        )
    }

    /// Check the parameters against a system of `n` particles.
    ///
    /// # Errors
    /// Non-finite parameters, non-positive lengths where positive ones are required, spring
    /// indices out of range or equal, rest lengths of the wrong count or negative.
    pub fn validate(&self, n: usize) -> Result<()> {
        let finite = |arg: &str, v: f64| check(arg, v.is_finite(), "must be finite");
        match self {
            Force::Gravity { g } => check("g", g.is_finite(), "must be finite"),
            Force::Drag { linear, quadratic, wind } => {
                non_negative("linear", *linear)?;
                non_negative("quadratic", *quadratic)?;
                check("wind", wind.is_finite(), "must be finite")
            }
            Force::Damping { rate } => non_negative("rate", *rate),
            Force::Springs { pairs, rest, stiffness, damping } => {
                check_springs(pairs, rest, [*stiffness, *damping], n)
            }
            Force::Attractor { center, strength, softening } => {
                check("center", center.is_finite(), "must be finite")?;
                finite("strength", *strength)?;
                positive("softening", *softening)
            }
            Force::Vortex { center, axis, strength, core } => {
                check("center", center.is_finite(), "must be finite")?;
                let unit = axis.is_finite() && axis.length() > 0.0;
                check("axis", unit, "must be a finite non-zero vector")?;
                finite("strength", *strength)?;
                positive("core", *core)
            }
            Force::Turbulence { strength, scale, .. } => {
                finite("strength", *strength)?;
                positive("scale", *scale)
            }
            Force::NeighborRepulsion { radius, stiffness } => {
                positive("radius", *radius)?;
                non_negative("stiffness", *stiffness)
            }
            Force::NBodyGravity { constant, softening } => {
                non_negative("constant", *constant)?;
                non_negative("softening", *softening)
            }
        }
    }
}

// ------------------------------------------------------------------ gradient noise

fn hash(mut x: u64) -> u64 {
    // SplitMix64 finaliser.
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

fn gradient(seed: u64, i: i64, j: i64, k: i64) -> DVec3 {
    let h = hash(
        seed ^ hash(
            (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ hash((j as u64) ^ hash(k as u64)),
        ),
    );
    // A direction from 12 cube-edge vectors (Perlin 2002).
    const G: [[f64; 3]; 12] = [
        [1.0, 1.0, 0.0],
        [-1.0, 1.0, 0.0],
        [1.0, -1.0, 0.0],
        [-1.0, -1.0, 0.0],
        [1.0, 0.0, 1.0],
        [-1.0, 0.0, 1.0],
        [1.0, 0.0, -1.0],
        [-1.0, 0.0, -1.0],
        [0.0, 1.0, 1.0],
        [0.0, -1.0, 1.0],
        [0.0, 1.0, -1.0],
        [0.0, -1.0, -1.0],
    ];
    DVec3::from_array(G[(h % 12) as usize])
}

/// Perlin gradient noise and its gradient at `p` (quintic fade, C2).
pub fn noise_with_gradient(seed: u64, p: DVec3) -> (f64, DVec3) {
    let base = p.floor();
    let f = p - base;
    let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let dfade = |t: f64| 30.0 * t * t * (t * (t - 2.0) + 1.0);
    let (u, du) = (
        DVec3::new(fade(f.x), fade(f.y), fade(f.z)),
        DVec3::new(dfade(f.x), dfade(f.y), dfade(f.z)),
    );
    let (i0, j0, k0) = (base.x as i64, base.y as i64, base.z as i64);
    let mut value = 0.0;
    let mut grad = DVec3::ZERO;
    for c in 0..8 {
        let (di, dj, dk) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
        // Wrapping: the lattice indices of far points (|p| >= 2^63) saturate.
        let (i, j, k) = (i0.wrapping_add(di), j0.wrapping_add(dj), k0.wrapping_add(dk));
        let g = gradient(seed, i, j, k);
        let d = f - DVec3::new(di as f64, dj as f64, dk as f64);
        let dot = g.dot(d);
        let wx = if di == 1 { u.x } else { 1.0 - u.x };
        let wy = if dj == 1 { u.y } else { 1.0 - u.y };
        let wz = if dk == 1 { u.z } else { 1.0 - u.z };
        let sx = if di == 1 { du.x } else { -du.x };
        let sy = if dj == 1 { du.y } else { -du.y };
        let sz = if dk == 1 { du.z } else { -du.z };
        let w = wx * wy * wz;
        value += w * dot;
        grad += w * g + dot * DVec3::new(sx * wy * wz, wx * sy * wz, wx * wy * sz);
    }
    (value, grad)
}

/// `curl ψ` at `p` for the vector potential ψ made of three noise fields seeded apart.
pub fn curl_noise(seed: u64, p: DVec3) -> DVec3 {
    let (_, g1) = noise_with_gradient(seed, p);
    let (_, g2) =
        noise_with_gradient(seed.wrapping_add(0x51ed_270b), p + DVec3::new(31.4, 15.9, 26.5));
    let (_, g3) =
        noise_with_gradient(seed.wrapping_add(0xa3b1_9d7f), p + DVec3::new(-27.1, 82.8, 18.2));
    // ψ = (n1, n2, n3): curl = (∂n3/∂y - ∂n2/∂z, ∂n1/∂z - ∂n3/∂x, ∂n2/∂x - ∂n1/∂y).
    DVec3::new(g3.y - g2.z, g1.z - g3.x, g2.x - g1.y)
}

/// The sum of the forces of `forces` that act on one particle alone (gravity, drag, damping,
/// attractor, vortex, turbulence), in the order they were added.
pub(super) fn particle_force(forces: &[Force], x: DVec3, v: DVec3, m: f64) -> DVec3 {
    let mut acc = DVec3::ZERO;
    for force in forces {
        acc += match *force {
            Force::Gravity { g } => gravity(g, m),
            Force::Drag { linear, quadratic, wind } => drag(linear, quadratic, wind, v),
            Force::Damping { rate } => damping(rate, m, v),
            Force::Attractor { center, strength, softening } => {
                attractor(center, strength, softening, x, m)
            }
            Force::Vortex { center, axis, strength, core } => {
                vortex(center, axis, strength, core, x, m)
            }
            Force::Turbulence { strength, scale, seed } => turbulence(strength, scale, seed, x, m),
            Force::Springs { .. }
            | Force::NeighborRepulsion { .. }
            | Force::NBodyGravity { .. } => DVec3::ZERO,
        };
    }
    acc
}

#[inline(always)]
pub(super) fn gravity(g: DVec3, m: f64) -> DVec3 {
    m * g
}

#[inline(always)]
pub(super) fn drag(linear: f64, quadratic: f64, wind: DVec3, v: DVec3) -> DVec3 {
    let u = v - wind;
    -(linear + quadratic * u.length()) * u
}

#[inline(always)]
pub(super) fn damping(rate: f64, m: f64, v: DVec3) -> DVec3 {
    -rate * m * v
}

#[inline(always)]
pub(super) fn attractor(center: DVec3, strength: f64, softening: f64, x: DVec3, m: f64) -> DVec3 {
    let r = center - x;
    strength * m / (r.length_squared() + softening * softening).powf(1.5) * r
}

#[inline(always)]
pub(super) fn vortex(
    center: DVec3,
    axis: DVec3,
    strength: f64,
    core: f64,
    x: DVec3,
    m: f64,
) -> DVec3 {
    let r = x - center;
    let perp = r - r.dot(axis) * axis;
    strength * m / (perp.length() + core) * axis.cross(perp)
}

#[inline(always)]
pub(super) fn turbulence(strength: f64, scale: f64, seed: u64, x: DVec3, m: f64) -> DVec3 {
    strength * m * curl_noise(seed, x / scale)
}
