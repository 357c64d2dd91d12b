//! Particles with the implicit methods: the sparse Newton path against the dense one, stiff
//! spring chains and nets at dt = 1/60 up to k = 1e9, and no allocation per step.

mod common;
use common::thread_allocations;

use glam::DVec3;
use kinema::ode::Method;
use kinema::particles::{Force, ParticleSystem};

const G: DVec3 = DVec3::new(0.0, -9.81, 0.0);
const DT: f64 = 1.0 / 60.0;

fn pos(s: &ParticleSystem, i: usize) -> DVec3 {
    DVec3::from_slice(&s.positions()[3 * i..])
}

/// A chain of `n` particles of 1 g hanging straight down from a pinned first one, links 1 cm
/// long at their rest length, joined by springs of stiffness `k` with a little damping, under
/// gravity; every free particle starts with a sideways velocity growing along the chain, so
/// that the chain swings and stretches.
fn hanging_chain(n: usize, k: f64) -> ParticleSystem {
    let xs: Vec<DVec3> = (0..n).map(|i| DVec3::new(0.0, -0.01 * i as f64, 0.0)).collect();
    let vs: Vec<DVec3> = (0..n).map(|i| DVec3::new(0.5 * i as f64 / n as f64, 0.0, 0.0)).collect();
    let mut masses = vec![1e-3; n];
    masses[0] = f64::INFINITY;
    let mut s = ParticleSystem::new(&xs, &vs, &masses, n).unwrap();
    let pairs: Vec<[usize; 2]> = (0..n - 1).map(|i| [i, i + 1]).collect();
    s.add_force(Force::Springs { rest: vec![0.01; n - 1], pairs, stiffness: k, damping: 1e-4 })
        .unwrap();
    s.add_force(Force::Gravity { g: G }).unwrap();
    s
}

/// A `side x side` net of 10 g particles 2 cm apart hanging in the x-y plane (row `i` at
/// height `-0.02 i`; structural and shear springs of stiffness `k` at rest length), pinned at
/// the two top corners, under gravity and drag, pushed out of its plane by a velocity growing
/// down the net: a cloth-like sheet that swings about its top edge. Returns the system and its
/// springs with their rest lengths.
fn spring_net(side: usize, k: f64) -> (ParticleSystem, Vec<([usize; 2], f64)>) {
    let at = |i: usize, j: usize| DVec3::new(0.02 * j as f64, -0.02 * i as f64, 0.0);
    let xs: Vec<DVec3> = (0..side * side).map(|p| at(p / side, p % side)).collect();
    let vs: Vec<DVec3> = (0..side * side)
        .map(|p| DVec3::new(0.0, 0.0, 0.5 * (p / side) as f64 / side as f64))
        .collect();
    let mut springs = Vec::new();
    for i in 0..side {
        for j in 0..side {
            for (di, dj) in [(1, 0), (0, 1), (1, 1), (1, -1)] {
                let (a, b) = (i as i64 + di, j as i64 + dj);
                if a < side as i64 && b >= 0 && b < side as i64 {
                    let (a, b) = (a as usize, b as usize);
                    springs.push(([i * side + j, a * side + b], (at(i, j) - at(a, b)).length()));
                }
            }
        }
    }
    let mut masses = vec![0.01; side * side];
    masses[0] = f64::INFINITY;
    masses[side - 1] = f64::INFINITY;
    let mut s = ParticleSystem::new(&xs, &vs, &masses, xs.len()).unwrap();
    s.add_force(Force::Springs {
        pairs: springs.iter().map(|s| s.0).collect(),
        rest: springs.iter().map(|s| s.1).collect(),
        stiffness: k,
        damping: 0.01,
    })
    .unwrap();
    s.add_force(Force::Gravity { g: G }).unwrap();
    s.add_force(Force::Drag { linear: 1e-3, quadratic: 1e-3, wind: DVec3::new(0.0, 0.0, 0.5) })
        .unwrap();
    (s, springs)
}

/// The largest relative stretch `|ℓ / L - 1|` over the springs.
fn worst_strain(s: &ParticleSystem, springs: &[([usize; 2], f64)]) -> f64 {
    springs
        .iter()
        .map(|&([a, b], rest)| ((pos(s, a) - pos(s, b)).length() / rest - 1.0).abs())
        .fold(0.0, f64::max)
}

#[test]
fn implicit_euler_keeps_a_thousand_particle_chain_bounded_up_to_k_1e9() {
    // The sparse Newton path: a 6000 x 6000 system per step, stiffness up to 1e9 N/m on
    // 1 g particles (h ω up to 1e6 / 60 at dt = 1/60).
    let n = 1000;
    for k in [1.0, 1e3, 1e6, 1e9] {
        let mut s = hanging_chain(n, k);
        let e0 = s.kinetic_energy() + s.potential_energy();
        for _ in 0..30 {
            s.step(DT, 1, Method::ImplicitEuler).unwrap_or_else(|e| panic!("k = {k}: {e}"));
            let e = s.kinetic_energy() + s.potential_energy();
            // Backward Euler only dissipates: the energy never rises above the start.
            assert!(e <= e0 + 1e-9 * e0.abs(), "k = {k}: energy {e} > {e0}");
            assert!(s.positions().iter().all(|x| x.is_finite() && x.abs() < 100.0), "k = {k}");
        }
        assert_eq!(pos(&s, 0), DVec3::ZERO, "the pinned end stays");
        // The chain swung to the side.
        assert!(pos(&s, n - 1).x > 0.01, "k = {k}: free end at {}", pos(&s, n - 1));
        if k >= 1e6 {
            // Stiff springs barely stretch: the top link carries the weight of the chain,
            // 9.81 N over k and the 1 cm link, a static strain of 981 / k.
            let springs: Vec<([usize; 2], f64)> = (0..n - 1).map(|i| ([i, i + 1], 0.01)).collect();
            let worst = worst_strain(&s, &springs);
            assert!(worst < 2e3 / k, "k = {k}: strain {worst}");
        }
    }
}

/// `steps` steps of `method` on the 30 x 30 net (5400 unknowns) with stiffness `k` at
/// dt = 1/60: bounded, dissipative, swinging, pinned corners fixed, and stiff springs barely
/// stretched.
fn swing_net(method: Method, k: f64, steps: usize) {
    let name = method.name();
    let (mut s, springs) = spring_net(30, k);
    let e0 = s.kinetic_energy() + s.potential_energy();
    for step in 0..steps {
        s.step(DT, 1, method).unwrap_or_else(|e| panic!("{name} k = {k} step {step}: {e}"));
        assert!(s.positions().iter().all(|x| x.is_finite() && x.abs() < 10.0));
    }
    let e = s.kinetic_energy() + s.potential_energy();
    // Implicit Euler only dissipates; BDF2 damps the stiff modes but is not monotone in the
    // energy (its stability norm is another one), so it may gain a little.
    let gain = if method == Method::Bdf2 { 1e-3 * e0.abs() } else { 0.0 };
    assert!(e <= e0 + gain, "{name} k = {k}: energy {e} > {e0}");
    // The bottom edge swung out of the plane; the pinned corners stayed.
    assert!(pos(&s, 30 * 29 + 15).z > 0.01, "{name} k = {k}");
    assert_eq!(pos(&s, 29), DVec3::new(0.02 * 29.0, 0.0, 0.0));
    if k >= 1e6 {
        // 9 kg of net hang from two corners: stiff springs stretch by ~(load / k).
        let worst = worst_strain(&s, &springs);
        assert!(worst < 1e6 / k, "{name} k = {k}: strain {worst}");
    }
}

#[test]
fn implicit_methods_keep_a_soft_spring_net_bounded() {
    for method in [Method::ImplicitEuler, Method::Bdf2] {
        for k in [1.0, 1e3] {
            swing_net(method, k, 20);
        }
    }
}

/// From k = 1e4 N/m (h² k / m = 280) the full step's Newton iteration stalls on the swinging
/// net (k = 1e6 at the second step; backtracking and Jacobian updates do not make the
/// corrections contract, the full Newton updates going far along a soft direction, which
/// points at compressed springs making the iteration matrix nearly singular); the stepper
/// then retries the step as 2, 4, ... 16 substeps, which converge.
#[test]
fn implicit_methods_keep_a_stiff_spring_net_bounded() {
    for method in [Method::ImplicitEuler, Method::Bdf2] {
        for k in [1e4, 1e6, 1e9] {
            swing_net(method, k, 6);
        }
    }
}

#[test]
fn sparse_and_dense_newton_give_the_same_steps() {
    // 8 x 8 particles: a 384 x 384 Newton matrix, dense by differences or sparse analytic.
    for method in [Method::ImplicitEuler, Method::Trapezoidal, Method::Bdf2] {
        let (start, _) = spring_net(8, 1e4);
        let (mut sparse, mut dense) = (start.clone(), start.clone());
        for _ in 0..10 {
            sparse.step_with_jacobian(DT, 1, method, true).unwrap();
            dense.step_with_jacobian(DT, 1, method, false).unwrap();
        }
        let diff =
            |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
        let moved = diff(sparse.positions(), start.positions());
        assert!(moved > 1e-2, "{}: moved {moved}", method.name());
        // Both converge to the Newton tolerance (1e-10 relative to the state).
        let (dx, dv) = (
            diff(sparse.positions(), dense.positions()),
            diff(sparse.velocities(), dense.velocities()),
        );
        assert!(dx < 1e-8 && dv < 1e-6, "{}: {dx:e} {dv:e}", method.name());
    }
}

#[test]
fn sparse_implicit_steps_allocate_nothing_after_the_first() {
    for method in [Method::ImplicitEuler, Method::Trapezoidal, Method::Bdf2] {
        let mut s = hanging_chain(1000, 1e6);
        s.step(DT, 1, method).unwrap();
        let before = thread_allocations();
        s.step(DT, 10, method).unwrap();
        assert_eq!(thread_allocations() - before, 0, "{}", method.name());
    }
}

/// A chain of `n` particles of 1 g joined by zero-length undamped springs of stiffness `k`
/// (the linear force `-k d`), pinned at the first, under gravity, swinging sideways: its
/// Newton matrix `I - h J` is the same at every step.
fn linear_chain(n: usize, k: f64) -> ParticleSystem {
    linear_chain_of(n, k, 1e-3)
}

/// [`linear_chain`] of particles of mass `m` (kg).
fn linear_chain_of(n: usize, k: f64, m: f64) -> ParticleSystem {
    let xs: Vec<DVec3> = (0..n).map(|i| DVec3::new(0.0, -0.01 * i as f64, 0.0)).collect();
    let vs: Vec<DVec3> = (0..n).map(|i| DVec3::new(0.5 * i as f64 / n as f64, 0.0, 0.0)).collect();
    let mut masses = vec![m; n];
    masses[0] = f64::INFINITY;
    let mut s = ParticleSystem::new(&xs, &vs, &masses, n).unwrap();
    let pairs: Vec<[usize; 2]> = (0..n - 1).map(|i| [i, i + 1]).collect();
    s.add_force(Force::Springs { rest: vec![0.0; n - 1], pairs, stiffness: k, damping: 0.0 })
        .unwrap();
    s.add_force(Force::Gravity { g: G }).unwrap();
    s
}

/// On a linear chain the implicit methods factorise the Newton matrix once per call (BDF2
/// twice: its starting implicit Euler step has another `γ`) and the steps are bitwise those
/// of a solver that factorises afresh at every step; a nonlinear chain factorises at every
/// Jacobian update.
#[test]
fn linear_chain_keeps_one_factorisation_bitwise_as_refactorising() {
    use kinema::particles::Solver;
    let steps = 40;
    for (method, once) in [(Method::ImplicitEuler, 1), (Method::Trapezoidal, 1), (Method::Bdf2, 2)]
    {
        let mut s = linear_chain(200, 1e4);
        let (model, mut fresh) = (s.model().clone(), s.state().clone());
        s.step(DT, steps, method).unwrap();
        assert_eq!(s.stats.factorizations, once, "{method:?}");
        let mut each = 0;
        for _ in 0..steps {
            let stats = Solver::new(&model).unwrap().step(&model, &mut fresh, DT, 1, method);
            each += stats.unwrap().factorizations;
        }
        assert!(each >= steps, "{method:?}: a fresh solver factorises every step");
        let kept: Vec<u64> =
            s.positions().iter().chain(s.velocities()).map(|v| v.to_bits()).collect();
        let refactored: Vec<u64> =
            fresh.positions().iter().chain(fresh.velocities()).map(|v| v.to_bits()).collect();
        assert_eq!(kept, refactored, "{method:?}");
        assert!(s.positions().iter().all(|v| v.is_finite()));
    }
    let mut nonlinear = hanging_chain(200, 1e4);
    nonlinear.step(DT, 10, Method::ImplicitEuler).unwrap();
    assert!(nonlinear.stats.factorizations >= 10);
}

/// On a linear chain (affine equations) implicit Euler takes one Newton update per step and
/// keeps its factors across calls: every step solves `y₁ = y₀ + h f(y₁)` to rounding (the
/// residual computed here from the chain's forces written out by hand, an oracle independent
/// of the solver), and a second call at the same step factorises nothing.
#[test]
fn linear_chain_steps_solve_implicit_euler_exactly_and_keep_the_factors_across_calls() {
    let (n, k, h) = (50, 1e4, 1e-3);
    let mut s = linear_chain(n, k);
    s.step(h, 3, Method::ImplicitEuler).unwrap();
    assert_eq!(s.stats.factorizations, 1);
    for _ in 0..5 {
        let (x0, v0) = (s.positions().to_vec(), s.velocities().to_vec());
        s.step(h, 1, Method::ImplicitEuler).unwrap();
        assert_eq!(s.stats.factorizations, 0, "the factors of the last call are kept");
        let (x1, v1) = (s.positions(), s.velocities());
        let p = |x: &[f64], i: usize| DVec3::from_slice(&x[3 * i..]);
        let mut worst: f64 = 0.0;
        for i in 1..n {
            let mut force = -k * (p(x1, i) - p(x1, i - 1));
            if i + 1 < n {
                force -= k * (p(x1, i) - p(x1, i + 1));
            }
            let a = force / 1e-3 + G;
            let rx = p(x1, i) - p(&x0, i) - h * p(v1, i);
            let rv = p(v1, i) - p(&v0, i) - h * a;
            worst = worst.max(rx.abs().max_element() / h).max(rv.abs().max_element());
        }
        // Velocities of order 1 m/s, accelerations of order h k / m · |v| = 1e4 m/s².
        assert!(worst < 1e-9, "implicit Euler residual {worst:e}");
    }
    for method in [Method::ImplicitEuler, Method::Trapezoidal, Method::Bdf2] {
        s.step(h, 2, method).unwrap();
        let before = thread_allocations();
        s.step(h, 10, method).unwrap();
        assert_eq!(thread_allocations() - before, 0, "{}", method.name());
    }
}

/// A solver kept across calls keeps its factorisation only while the model's forces, the
/// state's masses and live slots and the step are those it was set up for: stepping another
/// state of other masses, the first state again, another step, and the model after a force
/// was added each factorise anew, and every call's steps are bitwise those of a fresh solver.
#[test]
fn a_kept_linear_solver_follows_the_model_the_state_and_the_step() {
    use kinema::particles::{Model, Solver, State};
    let (light, heavy) = (linear_chain_of(60, 1e4, 1e-3), linear_chain_of(60, 1e4, 2e-3));
    let mut model = light.model().clone();
    let (mut a, mut b) = (light.state().clone(), heavy.state().clone());
    let mut kept = Solver::new(&model).unwrap();
    let bits = |s: &State| -> Vec<u64> {
        s.positions().iter().chain(s.velocities()).map(|v| v.to_bits()).collect()
    };
    let mut check = |model: &Model, state: &mut State, dt: f64, factorises: usize, case: &str| {
        let mut copy = state.clone();
        let stats = kept.step(model, state, dt, 3, Method::ImplicitEuler).unwrap();
        Solver::new(model).unwrap().step(model, &mut copy, dt, 3, Method::ImplicitEuler).unwrap();
        assert_eq!(bits(state), bits(&copy), "{case}");
        assert_eq!(stats.factorizations, factorises, "{case}");
    };
    check(&model, &mut a, 1e-3, 1, "first call");
    check(&model, &mut a, 1e-3, 0, "the same again");
    check(&model, &mut b, 1e-3, 1, "another state, heavier");
    check(&model, &mut a, 1e-3, 1, "the first state again");
    check(&model, &mut a, 2e-3, 1, "another step");
    model.add_force(Force::Damping { rate: 0.5 }).unwrap();
    check(&model, &mut a, 2e-3, 1, "the model with damping");
    check(&model, &mut a, 2e-3, 0, "the same again");
}

/// A linear net (the `side x side` grid of [`spring_net`] with zero-length undamped springs,
/// so its factor fills in under the AMD ordering), pinned at one corner, with one dead slot,
/// under gravity, damping, linear drag with wind and external forces: every implicit Euler
/// step of the velocity form solves `y₁ = y₀ + h f(y₁)` to rounding (the residual computed
/// from the forces written out by hand), the pinned and dead slots keep their bits, and a
/// step that goes non-finite leaves the state as it was.
#[test]
fn linear_net_steps_solve_implicit_euler_exactly() {
    let (side, k, h, m) = (7, 50.0, 1e-2, 0.01);
    let (rate, linear, wind) = (0.3, 2e-3, DVec3::new(0.1, 0.0, -0.2));
    let (template, springs) = spring_net(side, k);
    let n = side * side;
    let (xs, vs): (Vec<DVec3>, Vec<DVec3>) = (0..n)
        .map(|i| (pos(&template, i), DVec3::from_slice(&template.velocities()[3 * i..])))
        .unzip();
    let mut masses = vec![m; n];
    masses[0] = f64::INFINITY;
    let mut s = ParticleSystem::new(&xs, &vs, &masses, n + 1).unwrap();
    let mut pairs: Vec<[usize; 2]> = springs.iter().map(|s| s.0).collect();
    pairs.push([3, n]); // to the dead slot (at the origin), which stays put
    let rest = vec![0.0; pairs.len()];
    s.add_force(Force::Springs { pairs: pairs.clone(), rest, stiffness: k, damping: 0.0 }).unwrap();
    s.add_force(Force::Gravity { g: G }).unwrap();
    s.add_force(Force::Damping { rate }).unwrap();
    s.add_force(Force::Drag { linear, quadratic: 0.0, wind }).unwrap();
    let external: Vec<f64> = (0..3 * (n + 1)).map(|c| 1e-3 * ((c * 7) % 5) as f64).collect();
    s.set_external_forces(&external).unwrap();
    let bits = |s: &ParticleSystem, i: usize| -> Vec<u64> {
        let (x, v) = (&s.positions()[3 * i..3 * i + 3], &s.velocities()[3 * i..3 * i + 3]);
        x.iter().chain(v).map(|v| v.to_bits()).collect()
    };
    let kept = [bits(&s, 0), bits(&s, n)];
    for _ in 0..5 {
        let (x0, v0) = (s.positions().to_vec(), s.velocities().to_vec());
        s.step(h, 1, Method::ImplicitEuler).unwrap();
        let (x1, v1) = (s.positions(), s.velocities());
        let p = |x: &[f64], i: usize| DVec3::from_slice(&x[3 * i..]);
        let mut force = vec![DVec3::ZERO; n + 1];
        for &[a, b] in &pairs {
            let f = -k * (p(x1, a) - p(x1, b));
            force[a] += f;
            force[b] -= f;
        }
        let mut worst: f64 = 0.0;
        // Slots 1..n move (0 is pinned, n dead).
        for (i, spring) in force.iter().enumerate().take(n).skip(1) {
            let v = p(v1, i);
            let f = *spring + m * G - rate * m * v - linear * (v - wind) + p(&external, i);
            let rx = p(x1, i) - p(&x0, i) - h * v;
            let rv = v - p(&v0, i) - h * f / m;
            worst = worst.max(rx.abs().max_element() / h).max(rv.abs().max_element());
        }
        assert!(worst < 1e-12, "implicit Euler residual {worst:e}");
        assert_eq!([bits(&s, 0), bits(&s, n)], kept, "the pinned and dead slots stay put");
    }
    // Particle 20 at 1.7e308 m/s pushed on by 1e308 N: the step overflows (which particle
    // first depends on how the overflow spreads through the solve).
    s.state_mut()[3 * (n + 1) + 3 * 20 + 1] = 1.7e308;
    s.state_changed();
    let mut huge = external.clone();
    huge[3 * 20 + 1] = 1e308;
    s.set_external_forces(&huge).unwrap();
    let before: Vec<u64> =
        s.positions().iter().chain(s.velocities()).map(|v| v.to_bits()).collect();
    let err = s.step(h, 1, Method::ImplicitEuler).unwrap_err();
    assert!(err.to_string().contains("diverged at step 0"), "{err}");
    let after: Vec<u64> = s.positions().iter().chain(s.velocities()).map(|v| v.to_bits()).collect();
    assert_eq!(before, after, "a failed step leaves the state as it was");
}

/// A linear chain with gaps (`particles/chain_implicit.rs`): 40 slots, springs from `a` to
/// `a + 1` except at 12 and 25, slot 0 and slot 17 pinned, slot 39 dead, under gravity,
/// damping and external forces. Implicit Euler by the chain's tridiagonal factor: every step
/// solves `y₁ = y₀ + h f(y₁)` to rounding (the residual from the forces written out by hand),
/// the pinned and dead slots keep their bits, the steps equal those of the general velocity
/// form (`particles/linear.rs`, taken when a zero drag is added) to rounding, the factor is
/// made once, in calls of one step and of several, and a step that overflows fails at its
/// step and leaves the state as it was.
#[test]
fn chain_implicit_euler_solves_each_step_and_matches_the_general_velocity_form() {
    let (n, k, h, m, rate) = (40, 2e3, 1e-2, 0.02, 0.4);
    let xs: Vec<DVec3> =
        (0..n - 1).map(|i| DVec3::new(0.02 * i as f64, 0.01 * (i % 3) as f64, 0.0)).collect();
    let vs: Vec<DVec3> = (0..n - 1).map(|i| DVec3::new(0.0, 0.1, 0.3 * (i % 5) as f64)).collect();
    let mut masses = vec![m; n - 1];
    (masses[0], masses[17]) = (f64::INFINITY, f64::INFINITY);
    let make = |general: bool| {
        let mut s = ParticleSystem::new(&xs, &vs, &masses, n).unwrap();
        let pairs: Vec<[usize; 2]> =
            (0..n - 1).filter(|&a| a != 12 && a != 25).map(|a| [a, a + 1]).collect();
        let rest = vec![0.0; pairs.len()];
        s.add_force(Force::Springs { pairs, rest, stiffness: k, damping: 0.0 }).unwrap();
        s.add_force(Force::Gravity { g: G }).unwrap();
        s.add_force(Force::Damping { rate }).unwrap();
        if general {
            s.add_force(Force::Drag { linear: 0.0, quadratic: 0.0, wind: DVec3::ZERO }).unwrap();
        }
        let external: Vec<f64> = (0..3 * n).map(|c| 1e-2 * ((c * 7) % 5) as f64).collect();
        s.set_external_forces(&external).unwrap();
        (s, external)
    };
    let ((mut s, external), (mut general, _)) = (make(false), make(true));
    let bits = |s: &ParticleSystem, i: usize| -> Vec<u64> {
        let (x, v) = (&s.positions()[3 * i..3 * i + 3], &s.velocities()[3 * i..3 * i + 3]);
        x.iter().chain(v).map(|v| v.to_bits()).collect()
    };
    let kept = [bits(&s, 0), bits(&s, 17), bits(&s, n - 1)];
    let p = |x: &[f64], i: usize| DVec3::from_slice(&x[3 * i..]);
    for call in 0..6 {
        let (x0, v0) = (s.positions().to_vec(), s.velocities().to_vec());
        s.step(h, 1, Method::ImplicitEuler).unwrap();
        general.step(h, 1, Method::ImplicitEuler).unwrap();
        assert_eq!(s.stats.factorizations, usize::from(call == 0), "one factorisation");
        let (x1, v1) = (s.positions(), s.velocities());
        let mut worst: f64 = 0.0;
        for i in (1..n - 1).filter(|&i| i != 17) {
            let mut f = m * G - rate * m * p(v1, i) + p(&external, i);
            if i > 0 && i - 1 != 12 && i - 1 != 25 {
                f -= k * (p(x1, i) - p(x1, i - 1));
            }
            if i + 1 < n && i != 12 && i != 25 {
                f -= k * (p(x1, i) - p(x1, i + 1));
            }
            let rx = p(x1, i) - p(&x0, i) - h * p(v1, i);
            let rv = p(v1, i) - p(&v0, i) - h * f / m;
            worst = worst.max(rx.abs().max_element() / h).max(rv.abs().max_element());
        }
        assert!(worst < 1e-12, "implicit Euler residual {worst:e}");
        assert_eq!([bits(&s, 0), bits(&s, 17), bits(&s, n - 1)], kept, "still slots stay put");
        let differ = s
            .positions()
            .iter()
            .chain(s.velocities())
            .zip(general.positions().iter().chain(general.velocities()));
        let largest = differ.map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(largest < 1e-13, "chain and general velocity form differ by {largest:e}");
    }
    // A call of several steps (the slots that stay put are held inside the call too).
    s.step(h, 10, Method::ImplicitEuler).unwrap();
    general.step(h, 10, Method::ImplicitEuler).unwrap();
    assert_eq!([bits(&s, 0), bits(&s, 17), bits(&s, n - 1)], kept, "still slots stay put");
    let differ = s
        .positions()
        .iter()
        .chain(s.velocities())
        .zip(general.positions().iter().chain(general.velocities()));
    let largest = differ.map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(largest < 1e-13, "chain and general velocity form differ by {largest:e}");
    // Particle 20 at y = 1.7e308 m: the springs' forces on it and its neighbours overflow.
    s.state_mut()[3 * 20 + 1] = 1.7e308;
    s.state_changed();
    let before: Vec<u64> =
        s.positions().iter().chain(s.velocities()).map(|v| v.to_bits()).collect();
    let err = s.step(h, 3, Method::ImplicitEuler).unwrap_err();
    assert!(err.to_string().contains("diverged at step 0"), "{err}");
    let after: Vec<u64> = s.positions().iter().chain(s.velocities()).map(|v| v.to_bits()).collect();
    assert_eq!(before, after, "a failed step leaves the state as it was");
}
