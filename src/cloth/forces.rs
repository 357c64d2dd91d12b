//! Forces and energies of a cloth model at a state: gravity, air damping and the elements'
//! elastic and damping forces (Baraff & Witkin 1998, §4; [`super::elements`]), the energies,
//! and the fastest mode of small vibrations an explicit method must resolve.

use super::elements::{self, Accumulator};
use super::{Elasticity, Material, Model, State, VertexConstraint};
use glam::DVec3;

/// The elements' contributions ([`Model::add_elements`]), compiled through
/// [`pulp::Arch::dispatch`] for the baseline instruction set, AVX2 and AVX-512, taken at run
/// time as the CPU has them. The AVX builds have three-operand instructions (no register
/// copies) and wider vectors: 64² assembly 1.07–1.09 ms with AVX2 instead of 1.29–1.37 ms,
/// about 0.98 ms with AVX-512. No fused multiply-add is introduced, so the results are bit
/// for bit the same on every build.
struct Elements<'a, 'b> {
    model: &'a Model,
    x: &'a [DVec3],
    acc: &'a mut Accumulator<'b>,
}

impl pulp::WithSimd for Elements<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let Elements { model, x, acc } = self;
        let Material { stretch, shear, damping, .. } = model.material;
        for t in model.elements.iter().filter(|_| model.elasticity == Elasticity::BaraffWitkin) {
            elements::triangle(t, x, stretch, shear, damping, acc);
        }
        for h in &model.hinges {
            elements::hinge(h, x, damping, acc);
        }
        for s in &model.springs {
            elements::spring(s, x, damping, acc);
        }
    }
}

impl Model {
    /// Internal and external forces (N) at positions `x` (m) and velocities `v` (m/s), each
    /// `(N, 3)`, written into `out`; the elastic energy (J) is returned.
    pub(super) fn forces_into(&self, x: &[DVec3], v: &[DVec3], out: &mut [DVec3]) -> f64 {
        let air = self.material.air_damping;
        for ((o, m), v) in out.iter_mut().zip(&self.mass).zip(v) {
            *o = (self.gravity - air * *v) * *m;
        }
        let mut acc = Accumulator { v, f: out, matrix: None, ku: None, energy: 0.0 };
        self.add_elements(x, &mut acc);
        acc.energy
    }

    /// Every element's contributions at positions `x` into `acc`.
    pub(super) fn add_elements(&self, x: &[DVec3], acc: &mut Accumulator) {
        pulp::Arch::new().dispatch(Elements { model: self, x, acc });
    }

    /// Total force on every vertex (N), `(N, 3)`, at `state`: gravity, elastic and damping
    /// forces (constraint and contact forces not included).
    pub fn forces(&self, state: &State) -> Vec<DVec3> {
        let mut f = vec![DVec3::ZERO; state.len()];
        self.forces_into(&state.x, &state.v, &mut f);
        f
    }

    /// `(kinetic, gravitational potential, elastic)` energy (J) at `state`; the potential is
    /// `-Σ m g·x`.
    pub fn energy(&self, state: &State) -> (f64, f64, f64) {
        let kinetic =
            0.5 * state.v.iter().zip(&self.mass).map(|(v, m)| m * v.length_squared()).sum::<f64>();
        let potential =
            -state.x.iter().zip(&self.mass).map(|(x, m)| m * self.gravity.dot(*x)).sum::<f64>();
        let mut f = vec![DVec3::ZERO; state.len()];
        let elastic = self.forces_into(&state.x, &vec![DVec3::ZERO; state.len()], &mut f);
        (kinetic, potential, elastic)
    }

    /// The fastest mode of small vibrations about the shape of `state`, `(ω, c)`: the highest
    /// angular frequency `ω` (rad/s), `ω² = λ_max(M⁻¹ K)` with `K = -∂f/∂x`, and the highest
    /// damping rate `c` (1/s), `c = λ_max(M⁻¹ D)` with `D = -∂f/∂v` (stiffness-proportional and
    /// air damping), over the free (not pinned) vertices. Each by 60 power iterations with the
    /// products `K u`, `D u` from central differences of the forces (an estimate from below,
    /// within a few per cent). The mode `x'' + c x' + ω² x = 0` has the eigenvalues an explicit
    /// method must keep inside its stability region, which `kinema.Scene` checks before a run
    /// (`ode::max_stable_dt`). Allocates; not for a step.
    pub fn fastest_mode(&self, state: &State) -> (f64, f64) {
        let free: Vec<bool> = (0..state.len())
            .map(|i| {
                !matches!(state.constraints[i], Some(VertexConstraint::Pinned(_)))
                    && self.mass[i] > 0.0
            })
            .collect();
        let mut probe = Probe::new(self, &state.x, &free);
        let stiffness = probe.dominant(false);
        let damping = probe.dominant(true);
        (stiffness.abs().sqrt(), damping.max(0.0))
    }
}

/// The products `M⁻¹ K u` and `M⁻¹ D u` over the free vertices by central differences of the
/// forces about positions `x` at rest, and their dominant eigenvalue by power iteration.
struct Probe<'a> {
    model: &'a Model,
    x: &'a [DVec3],
    free: &'a [bool],
    zero: Vec<DVec3>,
    plus: Vec<DVec3>,
    minus: Vec<DVec3>,
    fp: Vec<DVec3>,
    fm: Vec<DVec3>,
}

impl<'a> Probe<'a> {
    fn new(model: &'a Model, x: &'a [DVec3], free: &'a [bool]) -> Probe<'a> {
        let zero = vec![DVec3::ZERO; x.len()];
        let (plus, minus, fp, fm) = (zero.clone(), zero.clone(), zero.clone(), zero.clone());
        Probe { model, x, free, zero, plus, minus, fp, fm }
    }

    /// `-M⁻¹ ∂f/∂x u` (or `-M⁻¹ ∂f/∂v u`) by central differences with step `eps` into `out`.
    fn derivative(&mut self, u: &[DVec3], eps: f64, in_velocity: bool, out: &mut [DVec3]) {
        let n = u.len();
        let base = if in_velocity { &self.zero } else { self.x };
        for i in 0..n {
            self.plus[i] = base[i] + eps * u[i];
            self.minus[i] = base[i] - eps * u[i];
        }
        if in_velocity {
            self.model.forces_into(self.x, &self.plus, &mut self.fp);
            self.model.forces_into(self.x, &self.minus, &mut self.fm);
        } else {
            self.model.forces_into(&self.plus, &self.zero, &mut self.fp);
            self.model.forces_into(&self.minus, &self.zero, &mut self.fm);
        }
        for (i, o) in out.iter_mut().enumerate() {
            *o = if self.free[i] {
                -(self.fp[i] - self.fm[i]) / (2.0 * eps * self.model.mass[i])
            } else {
                DVec3::ZERO
            };
        }
    }

    /// The dominant eigenvalue of `M⁻¹ D` (`in_velocity`) or `M⁻¹ K`: the Rayleigh quotient
    /// after 60 power iterations from a fixed start with every mode in it (no randomness:
    /// reproducible).
    fn dominant(&mut self, in_velocity: bool) -> f64 {
        let n = self.x.len();
        let scale = self.x.iter().map(|p| p.abs().max_element()).fold(1.0, f64::max);
        let mut u: Vec<DVec3> = (0..n)
            .map(|i| {
                let t = i as f64;
                let s = DVec3::new((1.3 * t).sin(), (2.1 * t + 0.5).cos(), (0.7 * t + 1.0).sin());
                if self.free[i] {
                    s
                } else {
                    DVec3::ZERO
                }
            })
            .collect();
        let mut w = vec![DVec3::ZERO; n];
        let eps = if in_velocity { 1e-6 } else { 1e-7 * scale };
        let mut rate = 0.0;
        for _ in 0..60 {
            let norm = u.iter().map(|v| v.length_squared()).sum::<f64>().sqrt();
            if !(norm > 0.0 && norm.is_finite()) {
                break;
            }
            u.iter_mut().for_each(|v| *v /= norm);
            self.derivative(&u, eps, in_velocity, &mut w);
            // The Rayleigh quotient uᵀ w estimates the dominant eigenvalue.
            rate = u.iter().zip(&w).map(|(a, b)| a.dot(*b)).sum::<f64>();
            std::mem::swap(&mut u, &mut w);
        }
        rate
    }
}
