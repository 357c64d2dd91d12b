//! The certificate that lets a call of the explicit kernel skip its rollback copy: from a bound
//! on the state and the model's parameters, [`step_bound`] proves that no value a step forms
//! can overflow or be invalid, and bounds the state after the step.

use super::collide::Collider;
use super::Force;
use crate::geometry::{Capsule, Cuboid, Plane, Shape, Sphere};
use glam::DVec3;

/// The magnitude no value of a step may reach for [`step_bound`] to certify it: far enough
/// below `f64::MAX` (1.8e308) that neither the rounding of the bounds nor the small constant
/// factors they leave out can matter.
const LIMIT: f64 = 1e300;

/// A bound on |component| of the curl noise of [`super::forces::curl_noise`]: each gradient
/// component of a noise field is a sum over 8 corners of `w g + (g·d) s w w` with the weights
/// `w` in [0, 1], `|g_c| <= 1`, `|g·d| <= 2` and the fade's slope `|s| <= 1.875`, so at most
/// `8 (1 + 2 · 1.875) = 38`, and a curl component is the difference of two.
const CURL_BOUND: f64 = 100.0;

/// What a step reads besides the state and the model's forces and colliders, as bounds:
/// the largest mass and inverse mass of a slot that moves (kg, 1/kg) and the largest
/// |component| of the external forces (N).
#[derive(Clone, Copy, Debug)]
pub(super) struct Extremes {
    pub(super) mass: f64,
    pub(super) inv_mass: f64,
    pub(super) external: f64,
}

/// Bounds on the magnitudes of the values of a step, each checked as it is formed.
struct Magnitudes {
    /// Whether every bound so far was below [`LIMIT`] (false after a NaN or an infinity too).
    within: std::cell::Cell<bool>,
}

impl Magnitudes {
    /// Note `bound`, a bound on the magnitude of some value of the step, and return it.
    fn note(&self, bound: f64) -> f64 {
        self.within.set(self.within.get() & (bound < LIMIT));
        bound
    }
}

/// The largest |component| of `v`.
pub(super) fn mag(v: DVec3) -> f64 {
    v.abs().max_element()
}

/// A certificate that a step of the kernel cannot come out non-finite: given `bound`, a bound
/// on |component| of the positions and velocities of the particles that move (m, m/s), a
/// bound on those of the state after one step of `dt` with `forces` and `colliders` (and
/// `gravity`, the sum of the uniform gravity fields) — or infinity when it cannot certify the
/// step. A call whose steps are certified needs no copy of the state to undo them
/// ([`super::ParticleSystem::explicit_steps`]).
///
/// Floating-point arithmetic on finite values gives a non-finite value only by overflow or
/// by an invalid operation (`0/0`, the root or fractional power of a negative number). A step
/// has no invalid operation on finite values: it divides only by `(|r|² + s²)^1.5 >= s³ > 0`
/// (attractor, checked below not to underflow), by `|r⊥| + core >= core > 0` (vortex), by the
/// noise scale `> 0`, by lengths it has tested to be positive, or where the quotient is
/// clamped to a finite range (`min(1)`, `clamp(0, 1)`, which map ±∞ to a finite value); its
/// roots and powers take sums of squares. So it remains to bound the magnitude of every value
/// the step forms: this function follows the step's arithmetic ([`super::particle_force`], the
/// symplectic Euler update, [`super::collide::surface`] and [`super::collide::respond`]) with bounds on the
/// components — `|a·b| <= 3 A B`, `|a × b| <= 2 A B`, `|a| <= 2 A`, a vector divided by its own
/// length at most 2 per component (1.3 where the squares underflow), a unit quaternion's
/// rotation at most 16 times the vector's bound in its intermediate values — and requires
/// each of them to stay below [`LIMIT`], 10⁸ times below overflow. Forces between particles
/// are never certified (they do not take this kernel).
pub(super) fn step_bound(
    forces: &[Force],
    colliders: &[Collider],
    dt: f64,
    gravity: DVec3,
    extremes: Extremes,
    bound: f64,
) -> f64 {
    let m = Magnitudes { within: std::cell::Cell::new(true) };
    let b = m.note(bound);
    let Some(f) = force_bound(&m, forces, b, &extremes) else {
        return f64::INFINITY;
    };
    let f = m.note(f);
    let mut v = m.note(b + m.note(dt * m.note(f * extremes.inv_mass)));
    let mut x = m.note(b + m.note(dt * v));
    let gravity = mag(gravity);
    for collider in colliders {
        (x, v) = contact_bound(&m, collider, x, v, b, dt, gravity);
    }
    if m.within.get() {
        x.max(v)
    } else {
        f64::INFINITY
    }
}

/// A bound on |component| of the sum of `forces` on one particle (N) whose position and
/// velocity are within `b` (the external force included); `None` for a force the kernel
/// does not take or whose quotient cannot be bounded (an attractor whose `s³` underflows).
fn force_bound(m: &Magnitudes, forces: &[Force], b: f64, extremes: &Extremes) -> Option<f64> {
    let Extremes { mass, external, .. } = *extremes;
    let mut f = m.note(external);
    for force in forces {
        f += match *force {
            Force::Gravity { g } => m.note(mass * mag(g)),
            Force::Drag { linear, quadratic, wind } => {
                let u = m.note(b + mag(wind));
                m.note(3.0 * u * u);
                let speed = m.note(quadratic.abs() * 2.0 * u);
                m.note((linear.abs() + speed) * u)
            }
            Force::Damping { rate } => m.note(m.note(rate.abs() * mass) * b),
            Force::Attractor { center, strength, softening } => {
                let r = m.note(b + mag(center));
                let s2 = softening * softening;
                let least = s2.powf(1.5);
                if least == 0.0 {
                    return None;
                }
                m.note((m.note(3.0 * r * r) + s2).powf(1.5));
                let q = m.note(m.note(strength.abs() * mass) / least);
                m.note(q * r)
            }
            Force::Vortex { center, axis, strength, core } => {
                let (r, a) = (m.note(b + mag(center)), mag(axis));
                let perp = m.note(r + m.note(m.note(3.0 * r * a) * a));
                m.note(3.0 * perp * perp);
                let q = m.note(m.note(strength.abs() * mass) / core);
                m.note(q * m.note(2.0 * a * perp))
            }
            Force::Turbulence { strength, scale, .. } => {
                m.note(b / scale + 100.0);
                m.note(m.note(strength.abs() * mass) * CURL_BOUND)
            }
            Force::Springs { .. }
            | Force::NeighborRepulsion { .. }
            | Force::NBodyGravity { .. } => {
                return None;
            }
        };
    }
    Some(f)
}

/// The bounds `(x, v)` on position and velocity after the contact response to `collider` of a
/// particle within `(x, v)` that was within `b` before the step.
fn contact_bound(
    m: &Magnitudes,
    collider: &Collider,
    mut x: f64,
    mut v: f64,
    b: f64,
    dt: f64,
    gravity: f64,
) -> (f64, f64) {
    // The contact: distance, normal and collider velocity, bounded.
    let sphere = |m: &Magnitudes, center: f64, radius: f64| {
        let d = m.note(x + center);
        m.note(3.0 * d * d);
        (m.note(2.0 * d + radius), 2.0)
    };
    let (mu, vc) = (collider.material.friction, mag(collider.velocity));
    let (d, n) = match collider.shape {
        Shape::Plane(Plane { point, normal }) => {
            let n = mag(normal);
            (m.note(3.0 * m.note(x + mag(point)) * n), n)
        }
        Shape::Sphere(Sphere { center, radius }) => sphere(m, mag(center), radius),
        Shape::Capsule(Capsule { a, b: end, radius }) => {
            let ab = m.note(mag(a) + mag(end));
            m.note(3.0 * ab * ab);
            m.note(3.0 * m.note(x + mag(a)) * ab);
            let center = m.note(mag(a) + ab);
            sphere(m, center, radius)
        }
        Shape::Box(Cuboid { center, half, .. }) => {
            let q = m.note(16.0 * m.note(x + mag(center)));
            let excess = m.note(q + mag(half));
            m.note(3.0 * excess * excess);
            (m.note(2.0 * excess), 32.0)
        }
    };
    // The response, as `respond` forms it (restitution at most 1).
    let x1 = m.note(x + m.note(d * n));
    let moved = m.note(x1 + b + m.note(vc * dt));
    let moved_t = m.note(moved + m.note(m.note(3.0 * moved * n) * n));
    m.note(3.0 * moved_t * moved_t);
    m.note(mu * d);
    x = m.note(x1 + moved_t);
    let u = m.note(v + vc);
    let vn = m.note(3.0 * u * n);
    m.note(2.0 * m.note(3.0 * gravity * n) * dt);
    let jn = m.note(2.0 * vn);
    let vt = m.note(u + m.note(vn * n));
    m.note(3.0 * vt * vt);
    m.note(mu * jn);
    v = v.max(m.note(vc + m.note((vn + jn) * n) + vt));
    (x, v)
}

#[cfg(test)]
mod tests {
    use super::super::kernel::{commit, Guard, Model, BLOCK};
    use super::*;
    use crate::geometry::Material;
    use glam::DQuat;

    /// Random numbers for the cases (SplitMix64).
    struct Rng(u64);

    impl Rng {
        /// Uniform in [0, 1).
        fn unit(&mut self) -> f64 {
            (super::super::emit::splitmix(&mut self.0) >> 11) as f64 / (1u64 << 53) as f64
        }
        /// A positive value with a magnitude from `10^lo` to `10^hi`, uniform in the exponent.
        fn magnitude(&mut self, lo: f64, hi: f64) -> f64 {
            10f64.powf(lo + (hi - lo) * self.unit())
        }
        fn signed(&mut self, lo: f64, hi: f64) -> f64 {
            let m = self.magnitude(lo, hi);
            if self.unit() < 0.5 {
                -m
            } else {
                m
            }
        }
        fn vector(&mut self, lo: f64, hi: f64) -> DVec3 {
            DVec3::new(self.signed(lo, hi), self.signed(lo, hi), self.signed(lo, hi))
        }
        fn direction(&mut self) -> DVec3 {
            self.vector(-1.0, 0.0).normalize()
        }
        fn force(&mut self) -> Force {
            match (6.0 * self.unit()) as usize {
                0 => Force::Gravity { g: self.vector(-2.0, 8.0) },
                1 => Force::Drag {
                    linear: self.magnitude(-6.0, 6.0),
                    quadratic: self.magnitude(-6.0, 6.0),
                    wind: self.vector(-2.0, 6.0),
                },
                2 => Force::Damping { rate: self.magnitude(-3.0, 8.0) },
                3 => Force::Attractor {
                    center: self.vector(-2.0, 6.0),
                    strength: self.signed(-3.0, 12.0),
                    softening: self.magnitude(-170.0, 1.0),
                },
                4 => Force::Vortex {
                    center: self.vector(-2.0, 6.0),
                    axis: self.direction(),
                    strength: self.signed(-3.0, 12.0),
                    core: self.magnitude(-12.0, 1.0),
                },
                _ => Force::Turbulence {
                    strength: self.signed(-3.0, 8.0),
                    scale: self.magnitude(-150.0, 2.0),
                    seed: 7,
                },
            }
        }
        fn collider(&mut self) -> Collider {
            let (restitution, friction) = (self.unit(), self.magnitude(-3.0, 1.0));
            let velocity = self.vector(-3.0, 4.0);
            let shape = match (4.0 * self.unit()) as usize {
                0 => {
                    Shape::Plane(Plane { point: self.vector(-2.0, 4.0), normal: self.direction() })
                }
                1 => Shape::Sphere(Sphere {
                    center: self.vector(-2.0, 4.0),
                    radius: self.magnitude(-3.0, 4.0),
                }),
                2 => Shape::Capsule(Capsule {
                    a: self.vector(-2.0, 4.0),
                    b: self.vector(-2.0, 4.0),
                    radius: self.magnitude(-3.0, 4.0),
                }),
                _ => Shape::Box(Cuboid {
                    center: self.vector(-2.0, 4.0),
                    rotation: DQuat::from_axis_angle(self.direction(), 6.0 * self.unit()),
                    half: DVec3::new(self.magnitude(-3.0, 3.0), 1.0, self.magnitude(-3.0, 3.0)),
                }),
            };
            let inside = self.unit() < 0.5;
            Collider { shape, material: Material { restitution, friction }, velocity, inside }
        }
    }

    /// The largest |component| of a slice.
    fn largest(values: &[f64]) -> f64 {
        values.iter().fold(0.0, |m, v| m.max(v.abs()))
    }

    /// `step_bound` is a certificate: whenever it is finite, a step of the kernel from a state
    /// within the given bound comes out finite and within the bound it returns. The cases
    /// span the magnitudes on both sides of the limit (states from 1e-30 to 1e200, masses
    /// from 1e-20 to 1e20 kg, steps from 1e-8 to 1e3 s, every force of the kernel and every
    /// collider with parameters over many decades, softenings down to 1e-170 and noise scales
    /// down to 1e-150, where squares underflow and quotients overflow), and the test checks
    /// that a good share is
    /// certified, some of them close to the limit, so that it cannot pass by certifying
    /// nothing.
    #[test]
    fn step_bound_certifies_finite_steps_and_bounds_them() {
        const N: usize = 2 * BLOCK + 5;
        let mut rng = Rng(1);
        let (mut certified, mut near_limit) = (0, 0);
        let cases = 6000;
        for case in 0..cases {
            let forces: Vec<Force> =
                (0..1 + (3.0 * rng.unit()) as usize).map(|_| rng.force()).collect();
            let colliders: Vec<Collider> =
                (0..(3.0 * rng.unit()) as usize).map(|_| rng.collider()).collect();
            let gravity = forces
                .iter()
                .map(|f| if let Force::Gravity { g } = f { *g } else { DVec3::ZERO })
                .sum();
            let m = rng.magnitude(-20.0, 20.0);
            let dt = rng.magnitude(-8.0, 3.0);
            let external =
                if rng.unit() < 0.3 { vec![rng.signed(-3.0, 10.0); 3 * N] } else { vec![] };
            let top = rng.magnitude(-1.0, 2.3);
            let mut state: Vec<f64> = (0..6 * N).map(|_| rng.signed(-30.0, top)).collect();
            let bound = largest(&state);
            let (mass, inv_mass) = (vec![m; N], vec![1.0 / m; N]);
            let extremes = Extremes { mass: m, inv_mass: 1.0 / m, external: largest(&external) };
            let after = step_bound(&forces, &colliders, dt, gravity, extremes, bound);
            let model = Model {
                forces: &forces,
                colliders: &colliders,
                mass: &mass,
                inv_mass: &inv_mass,
                external: &external,
                dt,
                gravity,
                uniform: Some((m, 1.0 / m)),
            };
            let mut kept = vec![0.0; 6 * N];
            let (xs, vs) = state.split_at_mut(3 * N);
            let done = commit(&model, xs, vs, &[true; N], &mut kept, Guard::Check, 1);
            if after.is_finite() {
                certified += 1;
                near_limit += usize::from(after > 1e150);
                assert!(done.bad.is_none(), "case {case}: a certified step went non-finite");
                let reached = largest(&state);
                assert!(reached <= after, "case {case}: {reached:e} beyond the bound {after:e}");
                assert_eq!(done.bound, reached, "case {case}: the kernel's bound");
            }
        }
        assert!(certified > cases / 5 && certified < cases * 19 / 20, "certified {certified}");
        assert!(near_limit > 20, "certified close to the limit: {near_limit}");
    }

    /// The bench's scene (gravity, quadratic drag, a ground plane): one step from any state
    /// within 10 km and 10 km/s is certified, with a bound within a small factor of the
    /// state's; the bound compounds over the steps of a call (a factor of about 24 in the
    /// first step of 1 ms from 100 m and 100 m/s, more after), and a call of 4 such steps is
    /// certified too.
    #[test]
    fn an_ordinary_scene_is_certified() {
        let forces = [
            Force::Gravity { g: DVec3::new(0.0, -9.81, 0.0) },
            Force::Drag { linear: 0.0, quadratic: 1e-3, wind: DVec3::ZERO },
        ];
        let colliders = [Collider {
            shape: Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::Y }),
            material: Material { restitution: 0.5, friction: 0.3 },
            velocity: DVec3::ZERO,
            inside: false,
        }];
        let extremes = Extremes { mass: 1.0, inv_mass: 1.0, external: 0.0 };
        let gravity = DVec3::new(0.0, -9.81, 0.0);
        let once = step_bound(&forces, &colliders, 1.0 / 60.0, gravity, extremes, 1e4);
        assert!(once < 1e8, "{once:e}");
        let mut bound = 100.0;
        for _ in 0..4 {
            bound = step_bound(&forces, &colliders, 1e-3, gravity, extremes, bound);
        }
        assert!(bound.is_finite());
    }
}
