//! Particle systems: physics against analytic answers, conservation, the spatial hash against
//! brute force, emitters, failures.

use glam::DVec3;
use kinema::geometry::{Material, Plane, Shape, Sphere};
use kinema::ode::Method;
use kinema::particles::{curl_noise, Appearance, Collider, Emitter, Force, ParticleSystem};

const G: DVec3 = DVec3::new(0.0, -9.81, 0.0);

fn one(x: DVec3, v: DVec3) -> ParticleSystem {
    ParticleSystem::new(&[x], &[v], &[1.0], 1).unwrap()
}

fn pos(s: &ParticleSystem, i: usize) -> DVec3 {
    DVec3::from_slice(&s.positions()[3 * i..])
}

fn vel(s: &ParticleSystem, i: usize) -> DVec3 {
    DVec3::from_slice(&s.velocities()[3 * i..])
}

#[test]
fn quadratic_drag_converges_to_terminal_velocity() {
    // m v' = m g - k |v| v: terminal speed sqrt(m g / k).
    let mut s = one(DVec3::ZERO, DVec3::new(0.0, 0.0, 0.0));
    s.add_force(Force::Gravity { g: G }).unwrap();
    s.add_force(Force::Drag { linear: 0.0, quadratic: 0.1, wind: DVec3::ZERO }).unwrap();
    s.step(0.01, 2000, Method::Rk4).unwrap();
    assert!((vel(&s, 0).y + (9.81f64 / 0.1).sqrt()).abs() < 1e-9);
    // The fall distance has a closed form: y(t) = -(v_t²/g) ln cosh(g t / v_t).
    let vt = (9.81f64 / 0.1).sqrt();
    let mut s = one(DVec3::ZERO, DVec3::ZERO);
    s.add_force(Force::Gravity { g: G }).unwrap();
    s.add_force(Force::Drag { linear: 0.0, quadratic: 0.1, wind: DVec3::ZERO }).unwrap();
    s.step(0.001, 2000, Method::Rk4).unwrap();
    let exact = -(vt * vt / 9.81) * (9.81 * 2.0 / vt).cosh().ln();
    assert!((pos(&s, 0).y - exact).abs() < 1e-9, "{} vs {exact}", pos(&s, 0).y);
}

#[test]
fn bouncing_ball_apex_heights_follow_restitution() {
    let e = 0.8;
    let mut s = one(DVec3::new(0.0, 1.0, 0.0), DVec3::ZERO);
    s.add_force(Force::Gravity { g: G }).unwrap();
    s.add_collider(Collider {
        shape: Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::Y }),
        material: Material { restitution: e, friction: 0.0 },
        velocity: DVec3::ZERO,
        inside: false,
    })
    .unwrap();
    let mut apexes = Vec::new();
    let mut prev_vy = 0.0;
    for _ in 0..200_000 {
        s.step(1e-5, 1, Method::SymplecticEuler).unwrap();
        let vy = vel(&s, 0).y;
        if prev_vy > 0.0 && vy <= 0.0 {
            apexes.push(pos(&s, 0).y);
        }
        prev_vy = vy;
        if apexes.len() == 3 {
            break;
        }
    }
    for (k, h) in apexes.iter().enumerate() {
        let expected = e.powi(2 * (k as i32 + 1));
        assert!((h - expected).abs() < 0.01 * expected, "apex {k}: {h} vs {expected}");
    }
}

#[test]
fn incline_sticks_or_slides_as_coulomb_says() {
    let mu = 0.5;
    for (deg, slides) in [(20.0f64, false), (35.0, true)] {
        let th = deg.to_radians();
        let normal = DVec3::new(-th.sin(), th.cos(), 0.0);
        let mut s = one(DVec3::ZERO, DVec3::ZERO);
        s.add_force(Force::Gravity { g: G }).unwrap();
        s.add_collider(Collider {
            shape: Shape::Plane(Plane { point: DVec3::ZERO, normal }),
            material: Material { restitution: 0.5, friction: mu },
            velocity: DVec3::ZERO,
            inside: false,
        })
        .unwrap();
        s.step(1e-3, 2000, Method::SymplecticEuler).unwrap();
        let travelled = pos(&s, 0).length();
        if slides {
            // s = ½ a t², a = g (sin θ - μ cos θ).
            let a = 9.81 * (th.sin() - mu * th.cos());
            assert!((travelled - 0.5 * a * 4.0).abs() < 0.01 * 0.5 * a * 4.0, "{travelled}");
        } else {
            assert!(travelled < 1e-9, "{deg}°: moved {travelled}");
        }
    }
}

#[test]
fn resting_particles_do_not_jitter() {
    let xs: Vec<DVec3> = (0..10).map(|i| DVec3::new(i as f64, 0.0, 0.0)).collect();
    let mut s = ParticleSystem::new(&xs, &vec![DVec3::ZERO; 10], &[1.0; 10], 10).unwrap();
    s.add_force(Force::Gravity { g: G }).unwrap();
    s.add_collider(Collider {
        shape: Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::Y }),
        material: Material { restitution: 0.9, friction: 0.3 },
        velocity: DVec3::ZERO,
        inside: false,
    })
    .unwrap();
    for _ in 0..600 {
        s.step(1.0 / 60.0, 1, Method::SymplecticEuler).unwrap();
        for i in 0..10 {
            assert!(pos(&s, i).y.abs() < 1e-12 && pos(&s, i).y >= 0.0, "{}", pos(&s, i).y);
        }
    }
    assert!(s.kinetic_energy() == 0.0);
}

#[test]
fn internal_forces_conserve_momentum() {
    let n = 60;
    let xs: Vec<DVec3> = (0..n)
        .map(|i| DVec3::new((i % 4) as f64 * 0.3, (i / 4 % 4) as f64 * 0.3, (i / 16) as f64 * 0.3))
        .collect();
    let vs: Vec<DVec3> = (0..n)
        .map(|i| DVec3::new((i as f64).sin(), (2.0 * i as f64).cos(), 0.1 * i as f64 - 3.0))
        .collect();
    let masses: Vec<f64> = (0..n).map(|i| 1.0 + (i % 3) as f64).collect();
    let mut s = ParticleSystem::new(&xs, &vs, &masses, n).unwrap();
    let pairs: Vec<[usize; 2]> = (0..n - 1).map(|i| [i, i + 1]).collect();
    s.add_force(Force::Springs {
        rest: vec![0.25; pairs.len()],
        pairs,
        stiffness: 50.0,
        damping: 0.5,
    })
    .unwrap();
    s.add_force(Force::NeighborRepulsion { radius: 0.4, stiffness: 100.0 }).unwrap();
    s.add_force(Force::NBodyGravity { constant: 0.01, softening: 0.1 }).unwrap();
    let momentum = |s: &ParticleSystem| (0..n).map(|i| masses[i] * vel(s, i)).sum::<DVec3>();
    let p0 = momentum(&s);
    s.step(1e-3, 500, Method::VelocityVerlet).unwrap();
    assert!((momentum(&s) - p0).length() < 1e-10 * p0.length().max(1.0));
}

#[test]
fn spatial_hash_matches_brute_force() {
    let n = 300;
    let mut state = 12345u64;
    let mut rnd = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64 * 3.0 - 1.5
    };
    let xs: Vec<DVec3> = (0..n).map(|_| DVec3::new(rnd(), rnd(), rnd())).collect();
    let (radius, k) = (0.35, 10.0);
    let mut s = ParticleSystem::new(&xs, &vec![DVec3::ZERO; n], &vec![1.0; n], n).unwrap();
    s.add_force(Force::NeighborRepulsion { radius, stiffness: k }).unwrap();
    let h = 1e-4;
    s.step(h, 1, Method::ExplicitEuler).unwrap(); // v₁ = h a(x₀)
    for i in 0..n {
        let mut f = DVec3::ZERO;
        for j in 0..n {
            let d = xs[i] - xs[j];
            let dist = d.length();
            if j != i && dist < radius {
                f += k * (radius - dist) / dist * d;
            }
        }
        assert!((vel(&s, i) - h * f).length() < 1e-12, "particle {i}");
    }
}

#[test]
fn curl_noise_is_divergence_free() {
    let eps = 1e-5;
    for k in 0..50 {
        let p = DVec3::new(0.37 * k as f64, 1.3 - 0.11 * k as f64, 0.05 * (k * k) as f64);
        let d = |e: DVec3| (curl_noise(7, p + e) - curl_noise(7, p - e)) / (2.0 * eps);
        let div = d(DVec3::X * eps).x + d(DVec3::Y * eps).y + d(DVec3::Z * eps).z;
        assert!(div.abs() < 1e-6, "{div}");
        assert!(curl_noise(7, p).length() > 0.0 || k == 0);
    }
}

#[test]
fn emitters_recycle_dead_slots() {
    let mut s = ParticleSystem::new(&[], &[], &[], 40).unwrap();
    s.add_emitter(Emitter {
        rate: 100.0,
        position: DVec3::ZERO,
        position_spread: 0.1,
        velocity: DVec3::Y,
        velocity_spread: 0.5,
        lifespan: 0.3,
        mass: 0.01,
        seed: 1,
        appearance: Appearance::default(),
    })
    .unwrap();
    let mut emitted = 0;
    for _ in 0..100 {
        s.step(0.01, 1, Method::SymplecticEuler).unwrap();
        emitted += s.stats.emitted;
        let alive = s.alive().iter().filter(|a| **a).count();
        assert!(alive <= 31, "{alive}");
        assert!(s.ages().iter().zip(s.alive()).all(|(a, l)| !*l || *a <= 0.3 + 1e-12));
    }
    assert!((99..=101).contains(&emitted), "{emitted}");
    // A pool too small drops emissions and says so.
    let mut s = ParticleSystem::new(&[], &[], &[], 5).unwrap();
    s.add_emitter(Emitter {
        rate: 1000.0,
        position: DVec3::ZERO,
        position_spread: 0.0,
        velocity: DVec3::ZERO,
        velocity_spread: 0.0,
        lifespan: 1.0,
        mass: 1.0,
        seed: 2,
        appearance: Appearance::default(),
    })
    .unwrap();
    s.step(0.01, 1, Method::SymplecticEuler).unwrap();
    assert_eq!((s.stats.emitted, s.stats.dropped), (5, 5));
}

#[test]
fn a_call_of_many_steps_moves_particles_emitted_into_recycled_slots() {
    // The general path (RK4) keeps the slots that stay put (dead or pinned) from moving; with
    // an emitter they change during the call (slots die and are emitted into again), so one
    // call of 60 steps must give the positions and velocities of 60 calls of one step.
    let make = || {
        let mut s =
            ParticleSystem::new(&[DVec3::ZERO], &[DVec3::ZERO], &[f64::INFINITY], 12).unwrap();
        s.add_emitter(Emitter {
            rate: 400.0,
            position: DVec3::ZERO,
            position_spread: 0.1,
            velocity: DVec3::Y,
            velocity_spread: 0.5,
            lifespan: 0.02,
            mass: 0.01,
            seed: 3,
            appearance: Appearance::default(),
        })
        .unwrap();
        s
    };
    let (mut once, mut each) = (make(), make());
    once.step(1e-3, 60, Method::Rk4).unwrap();
    for _ in 0..60 {
        each.step(1e-3, 1, Method::Rk4).unwrap();
    }
    assert!(once.stats.emitted > 12, "slots are recycled: {} emitted", once.stats.emitted);
    let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(once.alive(), each.alive());
    assert_eq!(bits(once.positions()), bits(each.positions()));
    assert_eq!(bits(once.velocities()), bits(each.velocities()));
}

#[test]
fn emitter_with_huge_rate_fills_free_slots_in_one_step() {
    // 1e300 /s owes ~1e298 particles a step: the free slots fill, the rest are counted as
    // dropped at once (saturating) instead of one loop turn per dropped particle.
    let mut s = ParticleSystem::new(&[DVec3::X], &[DVec3::ZERO], &[1.0], 8).unwrap();
    let emitter = |rate, seed| Emitter {
        rate,
        position: DVec3::ZERO,
        position_spread: 0.5,
        velocity: DVec3::ZERO,
        velocity_spread: 1.0,
        lifespan: 1.0,
        mass: 1.0,
        seed,
        appearance: Appearance::default(),
    };
    s.add_emitter(emitter(1e300, 3)).unwrap();
    s.add_emitter(emitter(250.0, 4)).unwrap();
    s.step(0.01, 1, Method::SymplecticEuler).unwrap();
    assert_eq!(s.stats.emitted, 7);
    // The first emitter owes usize::MAX (saturated): 7 emitted, the rest dropped; the second
    // owes 2 (2.5 accumulated), both dropped.
    assert_eq!(s.stats.dropped, usize::MAX - 7 + 2);
    assert!(s.alive().iter().all(|a| *a));
    assert!(s.positions().iter().all(|x| x.is_finite()));
    // The accumulator keeps counting the fraction as before: 2.5 owed → 2 now, 0.5 kept.
    let mut t = ParticleSystem::new(&[], &[], &[], 10).unwrap();
    t.add_emitter(emitter(250.0, 4)).unwrap();
    t.step(0.01, 1, Method::SymplecticEuler).unwrap();
    t.step(0.01, 1, Method::SymplecticEuler).unwrap();
    assert_eq!(t.alive().iter().filter(|a| **a).count(), 5);
}

#[test]
fn capacity_too_large_for_memory_is_an_error_naming_capacity() {
    for capacity in [1usize << 40, usize::MAX / 2, usize::MAX] {
        let e = ParticleSystem::new(&[], &[], &[], capacity).unwrap_err();
        assert!(e.to_string().starts_with("capacity: needs "), "{e}");
    }
}

#[test]
fn pinned_particles_stay_and_failures_roll_back() {
    let mut s =
        ParticleSystem::new(&[DVec3::ZERO, DVec3::X], &[DVec3::ZERO; 2], &[f64::INFINITY, 1.0], 2)
            .unwrap();
    s.add_force(Force::Gravity { g: G }).unwrap();
    s.add_force(Force::Springs {
        pairs: vec![[0, 1]],
        rest: vec![1.0],
        stiffness: 100.0,
        damping: 1.0,
    })
    .unwrap();
    s.step(1e-3, 1000, Method::VelocityVerlet).unwrap();
    assert_eq!(pos(&s, 0), DVec3::ZERO);
    assert!(pos(&s, 1).y < -0.05);

    let mut s = one(DVec3::ZERO, DVec3::new(1e300, 0.0, 0.0));
    s.add_force(Force::Drag { linear: 0.0, quadratic: 1e10, wind: DVec3::ZERO }).unwrap();
    let before = s.velocities().to_vec();
    let err = s.step(0.1, 3, Method::ExplicitEuler).unwrap_err();
    assert!(matches!(err, kinema::Error::Diverged { step: 0, index: 0, .. }), "{err}");
    assert_eq!(s.velocities(), &before[..]);

    assert!(ParticleSystem::new(&[DVec3::ZERO], &[DVec3::ZERO], &[-1.0], 1).is_err());
    assert!(ParticleSystem::new(&[DVec3::NAN], &[DVec3::ZERO], &[1.0], 1).is_err());
    let mut s = one(DVec3::ZERO, DVec3::ZERO);
    assert!(s
        .add_force(Force::Springs {
            pairs: vec![[0, 3]],
            rest: vec![1.0],
            stiffness: 1.0,
            damping: 0.0
        })
        .is_err());
    assert!(s
        .add_collider(Collider {
            shape: Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::Y }),
            material: Material { restitution: 1.5, friction: 0.0 },
            velocity: DVec3::ZERO,
            inside: false
        })
        .is_err());
    assert!(s.step(-1.0, 1, Method::Rk4).is_err());
}

#[test]
fn fused_symplectic_path_is_bitwise_the_general_path() {
    let n = 1500;
    let xs: Vec<DVec3> = (0..n)
        .map(|i| {
            DVec3::new((i % 50) as f64 * 0.1, 1.0 + (i / 50) as f64 * 0.01, (i as f64 * 0.37).sin())
        })
        .collect();
    let vs: Vec<DVec3> =
        (0..n).map(|i| DVec3::new((i as f64).cos(), -1.0, (i as f64 * 0.5).sin())).collect();
    let build = |pairwise: bool| {
        let mut s = ParticleSystem::new(&xs, &vs, &vec![0.5; n], n).unwrap();
        s.add_force(Force::Gravity { g: G }).unwrap();
        s.add_force(Force::Drag { linear: 0.01, quadratic: 0.02, wind: DVec3::X }).unwrap();
        s.add_force(Force::Turbulence { strength: 2.0, scale: 0.5, seed: 3 }).unwrap();
        s.add_collider(Collider {
            shape: Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::Y }),
            material: Material { restitution: 0.4, friction: 0.3 },
            velocity: DVec3::ZERO,
            inside: false,
        })
        .unwrap();
        s.add_collider(Collider {
            shape: Shape::Sphere(Sphere { center: DVec3::new(2.0, 0.0, 0.0), radius: 0.7 }),
            material: Material { restitution: 0.2, friction: 0.1 },
            velocity: DVec3::ZERO,
            inside: false,
        })
        .unwrap();
        if pairwise {
            // No pairs: changes nothing but routes the step through the general integrator.
            s.add_force(Force::Springs {
                pairs: vec![],
                rest: vec![],
                stiffness: 1.0,
                damping: 0.0,
            })
            .unwrap();
        }
        s.step(1e-2, 100, Method::SymplecticEuler).unwrap();
        (s.positions().to_vec(), s.velocities().to_vec(), s.ages().to_vec(), s.stats.contacts)
    };
    let (fused, general) = (build(false), build(true));
    assert!(fused.3 > 0);
    assert_eq!(fused, general);
}

#[test]
fn oriented_box_distance_matches_brute_force() {
    use glam::DQuat;
    use kinema::geometry::Cuboid;
    let oriented_box = |center, rotation, half, p| Cuboid { center, rotation, half }.distance(p);
    let q = DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1);
    let (c, h) = (DVec3::new(0.5, -0.2, 1.0), DVec3::new(0.3, 0.1, 0.6));
    // The distance to a box is that to the nearest of a dense sample of its surface (outside),
    // minus the distance to the nearest face (inside).
    let mut surface = Vec::new();
    let n = 40;
    for axis in 0..3 {
        for sign in [-1.0, 1.0] {
            for i in 0..=n {
                for j in 0..=n {
                    let (u, v) = (i as f64 / n as f64 * 2.0 - 1.0, j as f64 / n as f64 * 2.0 - 1.0);
                    let mut p = DVec3::ZERO;
                    p[axis] = sign;
                    p[(axis + 1) % 3] = u;
                    p[(axis + 2) % 3] = v;
                    surface.push(c + q * (p * h));
                }
            }
        }
    }
    for k in 0..200 {
        let t = k as f64;
        let p = c + DVec3::new((1.7 * t).sin(), (2.3 * t).cos(), (0.9 * t).sin()) * 0.9;
        let (d, normal) = oriented_box(c, q, h, p);
        let nearest = surface.iter().map(|s| (*s - p).length()).fold(f64::INFINITY, f64::min);
        assert!((d.abs() - nearest).abs() < 0.02, "{d} vs {nearest}");
        assert!((normal.length() - 1.0).abs() < 1e-12);
        // Moving along the normal by the distance lands on the surface.
        let (on, _) = oriented_box(c, q, h, p - d * normal);
        assert!(on.abs() < 1e-12, "{on}");
    }
}

/// A scene for the explicit symplectic-Euler kernel: `n` particles on a grid above a tilted
/// ground under gravity, quadratic drag with wind, a vortex, a sphere and an emitter whose
/// particles expire (if `emitter`), and a few pinned particles (at rest: the general path
/// moves a pinned particle with its velocity, the kernel keeps it in place).
fn kernel_scene(n: usize, emitter: bool) -> ParticleSystem {
    let live = n - n / 4; // room for the emitter
    let x: Vec<DVec3> = (0..live)
        .map(|i| {
            DVec3::new((i % 97) as f64 * 0.1 - 4.8, 0.002 * (i % 13) as f64, (i / 97) as f64 * 0.1)
        })
        .collect();
    let pinned = |i: usize| i % 1000 == 3;
    let v: Vec<DVec3> = (0..live)
        .map(|i| {
            let v = DVec3::new(((i * 7) % 11) as f64 - 5.0, -((i % 5) as f64), 0.3);
            if pinned(i) {
                DVec3::ZERO
            } else {
                v
            }
        })
        .collect();
    let m: Vec<f64> =
        (0..live).map(|i| if pinned(i) { f64::INFINITY } else { 1.0 + (i % 3) as f64 }).collect();
    let mut s = ParticleSystem::new(&x, &v, &m, n).unwrap();
    s.add_force(Force::Gravity { g: G }).unwrap();
    s.add_force(Force::Drag { linear: 0.01, quadratic: 0.05, wind: DVec3::new(1.0, 0.0, 0.5) })
        .unwrap();
    s.add_force(Force::Vortex { center: DVec3::ZERO, axis: DVec3::Y, strength: 2.0, core: 0.1 })
        .unwrap();
    s.add_collider(Collider {
        shape: Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::new(0.1, 1.0, 0.0) }),
        material: Material { restitution: 0.5, friction: 0.3 },
        velocity: DVec3::ZERO,
        inside: false,
    })
    .unwrap();
    s.add_collider(Collider {
        shape: Shape::Sphere(Sphere { center: DVec3::new(1.0, 0.0, 1.0), radius: 0.5 }),
        material: Material { restitution: 0.2, friction: 0.6 },
        velocity: DVec3::ZERO,
        inside: false,
    })
    .unwrap();
    if emitter {
        s.add_emitter(Emitter {
            rate: 20_000.0,
            position: DVec3::new(0.0, 1.0, 0.0),
            position_spread: 0.2,
            velocity: DVec3::new(0.0, 3.0, 0.0),
            velocity_spread: 1.0,
            lifespan: 0.05,
            mass: 0.5,
            seed: 7,
            appearance: Appearance::default(),
        })
        .unwrap();
    }
    s
}

/// The kernel scene twice: symplectic Euler without forces between particles runs the
/// blocked SIMD kernel on the first; a spring set without pairs sends the second down the
/// general path (Stepper + collide_one).
fn kernel_and_general(emitter: bool) -> (ParticleSystem, ParticleSystem) {
    let mut general = kernel_scene(20_000, emitter);
    general
        .add_force(Force::Springs { pairs: vec![], rest: vec![], stiffness: 1.0, damping: 0.0 })
        .unwrap();
    (kernel_scene(20_000, emitter), general)
}

#[test]
fn explicit_kernel_matches_the_general_path_bitwise() {
    // Without the emitter the ages are left pending until read.
    for emitter in [true, false] {
        let (mut fast, mut general) = kernel_and_general(emitter);
        for _ in 0..4 {
            fast.step(1e-3, 25, Method::SymplecticEuler).unwrap();
            general.step(1e-3, 25, Method::SymplecticEuler).unwrap();
            // Positions, velocities, ages, flags, masses, time and counters, bit for bit.
            assert!(same_state(&fast, &general));
        }
        assert!(fast.stats.contacts > 0);
        assert_eq!(fast.stats.expired > 0 && fast.stats.emitted > 0, emitter);
    }
}

#[test]
fn explicit_kernel_does_not_depend_on_the_thread_count() {
    // With an emitter, and with one mass for all (masses and flags not read per particle).
    let scenes: [fn() -> ParticleSystem; 2] =
        [|| kernel_scene(50_000, true), || runaway(50_000, 50_000, 7, 1000)];
    for scene in scenes {
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let mut s = scene();
                s.step(1e-3, 60, Method::SymplecticEuler).unwrap();
                s
            })
        };
        let one = run(1);
        assert!(one.stats.contacts > 0);
        for threads in [2, 3] {
            assert!(same_state(&one, &run(threads)));
        }
    }
}

#[test]
fn explicit_kernel_failure_keeps_the_last_good_step() {
    // Particle 30_000 (in a later parallel task) moves by 2e307 m per step from 1e308 m: its
    // position overflows at the fourth step (step index 3).
    let system = || {
        let mut x = vec![DVec3::new(0.0, 1.0, 0.0); 40_000];
        let mut v = vec![DVec3::new(0.5, 0.0, 0.0); 40_000];
        x[30_000] = DVec3::new(1e308, 1.0, 0.0);
        v[30_000] = DVec3::new(2e307, 0.0, 0.0);
        let mut s = ParticleSystem::new(&x, &v, &vec![1.0; 40_000], 40_000).unwrap();
        s.add_force(Force::Gravity { g: G }).unwrap();
        s.add_collider(Collider {
            shape: Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::Y }),
            material: Material { restitution: 0.5, friction: 0.3 },
            velocity: DVec3::ZERO,
            inside: false,
        })
        .unwrap();
        s
    };
    let mut reference = system();
    reference.step(1.0, 3, Method::SymplecticEuler).unwrap();

    // In one call: step 3 goes non-finite, so the state at the start of the call is restored
    // and steps 0 to 2 are stepped again.
    let mut s = system();
    let err = s.step(1.0, 10, Method::SymplecticEuler).unwrap_err();
    assert!(matches!(err, kinema::Error::Diverged { step: 3, index: 30_000, .. }), "{err}");
    assert_eq!(s.positions(), reference.positions());
    assert_eq!(s.velocities(), reference.velocities());
    assert_eq!(s.ages(), reference.ages());
    assert_eq!(s.time(), reference.time());

    // Across calls (the second step of the second call fails).
    let mut s = system();
    s.step(1.0, 2, Method::SymplecticEuler).unwrap();
    let err = s.step(1.0, 10, Method::SymplecticEuler).unwrap_err();
    assert!(matches!(err, kinema::Error::Diverged { step: 1, index: 30_000, .. }), "{err}");
    assert_eq!(s.positions(), reference.positions());
    assert_eq!(s.velocities(), reference.velocities());
    // The state is unchanged by further failed calls, and a smaller step still works.
    assert!(s.step(1.0, 1, Method::SymplecticEuler).is_err());
    assert_eq!(s.positions(), reference.positions());
    s.step(1e-3, 1, Method::SymplecticEuler).unwrap();
}

/// `live` particles (room for `capacity`) above a ground plane under gravity, some falling
/// onto it, and one, `runaway`, moving along x so fast that its position overflows in step
/// `fail` of 1 ms (counting from 0).
fn runaway(live: usize, capacity: usize, runaway: usize, fail: usize) -> ParticleSystem {
    let dx = 1e304; // metres per step
    let mut x: Vec<DVec3> = (0..live)
        .map(|i| DVec3::new((i % 101) as f64 * 0.01, 0.001 * (i % 7) as f64, (i / 101) as f64))
        .collect();
    let mut v: Vec<DVec3> =
        (0..live).map(|i| DVec3::new(0.5, -((i % 3) as f64), 0.1 * (i % 5) as f64)).collect();
    x[runaway].x = f64::MAX - (fail as f64 + 0.5) * dx;
    v[runaway] = DVec3::new(dx / 1e-3, 0.0, 0.0);
    let mut s = ParticleSystem::new(&x, &v, &vec![2.0; live], capacity).unwrap();
    s.add_force(Force::Gravity { g: G }).unwrap();
    s.add_force(Force::Damping { rate: 0.1 }).unwrap();
    s.add_collider(Collider {
        shape: Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::Y }),
        material: Material { restitution: 0.5, friction: 0.3 },
        velocity: DVec3::ZERO,
        inside: false,
    })
    .unwrap();
    s
}

/// Whether two systems hold bitwise the same state, ages, flags, masses, time and counters.
fn same_state(a: &ParticleSystem, b: &ParticleSystem) -> bool {
    let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    bits(a.positions()) == bits(b.positions())
        && bits(a.velocities()) == bits(b.velocities())
        && bits(&a.ages()) == bits(&b.ages())
        && bits(a.masses()) == bits(b.masses())
        && a.alive() == b.alive()
        && a.time().to_bits() == b.time().to_bits()
        && a.stats == b.stats
}

#[test]
fn explicit_kernel_failure_in_any_step_rolls_back_to_the_last_good_step() {
    // (live particles, runaway particle, step that fails, steps in the call): the first step,
    // a middle step, the last step of the call, and the runaway in the last, partial block
    // (10_003 = 312 blocks of 32 and 19).
    for (live, index, fail, steps) in [
        (40_000, 30_000, 0, 5),
        (40_000, 123, 4, 10),
        (40_000, 39_999, 6, 7),
        (10_003, 10_002, 2, 9),
    ] {
        let mut s = runaway(live, live, index, fail + 2);
        s.step(1e-3, 2, Method::SymplecticEuler).unwrap(); // an earlier call
        let mut reference = s.clone();
        reference.step(1e-3, fail, Method::SymplecticEuler).unwrap();
        let err = s.step(1e-3, steps, Method::SymplecticEuler).unwrap_err();
        let named = matches!(err, kinema::Error::Diverged { step, index: i, .. }
            if step == fail && i == index);
        assert!(named, "{err}");
        assert!(same_state(&s, &reference), "live {live}, fail {fail}");
        if fail > 2 {
            assert!(s.stats.contacts > 0);
        }
        // Smaller steps go on from there.
        s.step(1e-6, 2, Method::SymplecticEuler).unwrap();
        reference.step(1e-6, 2, Method::SymplecticEuler).unwrap();
        assert!(same_state(&s, &reference));
    }
}

#[test]
fn explicit_kernel_failure_names_the_first_step_then_the_first_particle() {
    // Particle 123 (first block) would overflow in step 6, particle 30_000 in step 4: the
    // error names step 4 and particle 30_000 although a block before it fails too, later.
    let mut s = runaway(40_000, 40_000, 30_000, 4);
    let y = s.state_mut();
    y[3 * 123] = f64::MAX - 6.5 * 1e304;
    y[3 * 40_000 + 3 * 123] = 1e304 / 1e-3;
    s.state_changed();
    let mut reference = s.clone();
    reference.step(1e-3, 4, Method::SymplecticEuler).unwrap();
    let err = s.step(1e-3, 10, Method::SymplecticEuler).unwrap_err();
    assert!(matches!(err, kinema::Error::Diverged { step: 4, index: 30_000, .. }), "{err}");
    assert!(same_state(&s, &reference));
}

#[test]
fn explicit_kernel_failure_with_emitters_restores_slots_and_emitters() {
    // Emitted particles live three steps, so slots die and are emitted into again within
    // the failing call; the emitter's accumulator and random state must come back too.
    let mut s = runaway(2000, 2600, 1500, 9);
    s.add_emitter(Emitter {
        rate: 45_500.0,
        position: DVec3::new(0.0, 1.0, 0.0),
        position_spread: 0.2,
        velocity: DVec3::new(0.0, 3.0, 0.0),
        velocity_spread: 1.0,
        lifespan: 0.003,
        mass: 0.25,
        seed: 11,
        appearance: Appearance::default(),
    })
    .unwrap();
    s.step(1e-3, 4, Method::SymplecticEuler).unwrap();
    let mut reference = s.clone();
    reference.step(1e-3, 5, Method::SymplecticEuler).unwrap();
    assert!(reference.stats.emitted > 0 && reference.stats.expired > 0);
    let err = s.step(1e-3, 20, Method::SymplecticEuler).unwrap_err();
    assert!(matches!(err, kinema::Error::Diverged { step: 5, index: 1500, .. }), "{err}");
    assert!(same_state(&s, &reference));
    s.step(1e-4, 3, Method::SymplecticEuler).unwrap();
    reference.step(1e-4, 3, Method::SymplecticEuler).unwrap();
    assert!(s.stats.emitted > 0);
    assert!(same_state(&s, &reference));
    // A call of one step that fails (the slots are not copied then: the aging and the
    // emission come after the step) leaves everything as it was, counters reset.
    let err = s.step(1e-3, 1, Method::SymplecticEuler).unwrap_err();
    assert!(matches!(err, kinema::Error::Diverged { step: 0, index: 1500, .. }), "{err}");
    reference.stats = Default::default();
    assert!(same_state(&s, &reference));
}

#[test]
fn one_step_calls_match_the_general_path_and_still_roll_back() {
    // After a call the kernel keeps a bound on the state, and a call of one step from a
    // bounded state is certified not to overflow: it is taken without a copy of the state.
    // Such calls give bitwise the general path's results, and a step that does overflow
    // (external forces far beyond anything certified) is still undone.
    for emitter in [false, true] {
        let (mut fast, mut general) = kernel_and_general(emitter);
        for _ in 0..40 {
            fast.step(1e-3, 1, Method::SymplecticEuler).unwrap();
            general.step(1e-3, 1, Method::SymplecticEuler).unwrap();
            assert!(same_state(&fast, &general));
        }
        let n = fast.capacity();
        let mut before = fast.clone();
        fast.set_external_forces(&vec![1e300; 3 * n]).unwrap();
        before.set_external_forces(&vec![1e300; 3 * n]).unwrap();
        let err = fast.step(1e10, 1, Method::SymplecticEuler).unwrap_err();
        assert!(matches!(err, kinema::Error::Diverged { step: 0, .. }), "{err}");
        before.stats = Default::default();
        assert!(same_state(&fast, &before));
    }
}

#[test]
fn ages_are_added_when_read() {
    // Without emitters a call leaves the ages to their next reader; what it reads is bitwise
    // each step added in turn to the live slots, whatever the calls and their steps, also
    // after a snapshot.
    use kinema::snapshot::Snapshot;
    let mut s = kernel_scene(2000, false);
    let mut expected = 0.0;
    for (dt, steps) in [(1e-3, 3), (1e-3, 1), (2e-3, 2), (1e-3, 1)] {
        s.step(dt, steps, Method::SymplecticEuler).unwrap();
        (0..steps).for_each(|_| expected += dt);
    }
    let restored = ParticleSystem::from_snapshot(&s.to_snapshot().unwrap()).unwrap();
    for system in [&s, &restored] {
        let ages = system.ages();
        for (age, &alive) in ages.iter().zip(system.alive()) {
            assert_eq!(age.to_bits(), if alive { expected } else { 0.0f64 }.to_bits());
        }
    }
    assert!(s.alive().iter().any(|a| !a));
}

#[test]
fn general_path_calls_leave_the_ages_pending_and_count_only_good_steps() {
    // Springs (or any method but symplectic Euler) take the general path; without emitters
    // its calls too leave the ages to their reader, bitwise each good step added in turn, and
    // a call that fails counts the steps before the failure. The pinned particle stays, with
    // its velocity.
    let mut s = ParticleSystem::new(
        &[DVec3::ZERO, DVec3::X],
        &[DVec3::Z, DVec3::Y],
        &[f64::INFINITY, 1.0],
        2,
    )
    .unwrap();
    s.add_force(Force::Springs {
        pairs: vec![[0, 1]],
        rest: vec![1.0],
        stiffness: 100.0,
        damping: 0.0,
    })
    .unwrap();
    let mut expected = 0.0;
    for (dt, steps, method) in [
        (1e-3, 3, Method::Rk4),
        (2e-3, 2, Method::ImplicitEuler),
        (1e-3, 1, Method::SymplecticEuler),
    ] {
        s.step(dt, steps, method).unwrap();
        (0..steps).for_each(|_| expected += dt);
    }
    assert!(s.ages().iter().all(|a| a.to_bits() == expected.to_bits()), "{:?}", s.ages());
    // Its velocity too: symplectic Euler's drift `x += h v` does not move it.
    assert_eq!(pos(&s, 0), DVec3::ZERO);
    assert_eq!(vel(&s, 0), DVec3::Z);
    // Quadratic drag on 1e100 m/s: the first explicit Euler step is finite, the second not.
    let mut s = one(DVec3::ZERO, DVec3::new(1e100, 0.0, 0.0));
    s.add_force(Force::Drag { linear: 0.0, quadratic: 1e10, wind: DVec3::ZERO }).unwrap();
    let err = s.step(0.1, 5, Method::ExplicitEuler).unwrap_err();
    assert!(matches!(err, kinema::Error::Diverged { step: 1, .. }), "{err}");
    assert_eq!(s.ages()[0].to_bits(), 0.1f64.to_bits());
    assert!(vel(&s, 0).x.is_finite());
}

/// A random system that `Solver::step` steps by the chain path (`particles/chain.rs`): up to
/// 60 live particles and a few dead slots, some pinned, values with signed zeros and springs
/// of zero length among them, gravity, damping and one set of springs from slot `a` to `a + 1`
/// with gaps (or, for every third seed, linear and without gaps), in a random order, external
/// forces on some; for every fourth seed, one mass for every slot that moves and neither
/// damping nor external forces (the chain path's passes then read the mass and the forces on
/// single particles as constants). With `general`, an emitter that
/// emits nothing routes every step through the general path (an emitter rules the chain path
/// out) without changing any value.
fn random_chain(seed: u64, general: bool) -> ParticleSystem {
    let mut state = seed;
    let mut draw = move || {
        // SplitMix64, as a uniform number in [0, 1).
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    let live = 2 + (draw() * 59.0) as usize;
    let capacity = live + (draw() * 3.0) as usize;
    // A signed zero or a uniform number in [-scale, scale).
    fn value(draw: &mut impl FnMut() -> f64, scale: f64) -> f64 {
        match (draw() * 8.0) as u32 {
            0 => -0.0,
            1 => 0.0,
            _ => scale * (2.0 * draw() - 1.0),
        }
    }
    let mut vector = |scale: f64| {
        DVec3::new(value(&mut draw, scale), value(&mut draw, scale), value(&mut draw, scale))
    };
    let mut x: Vec<DVec3> = (0..live).map(|_| vector(1.0)).collect();
    let v: Vec<DVec3> = (0..live).map(|_| vector(3.0)).collect();
    x[1] = x[0]; // a spring of zero length, if one joins them
    let uniform = seed % 4 == 1;
    let masses: Vec<f64> = (0..live)
        .map(|_| match draw() < 0.1 {
            true => f64::INFINITY,
            false if uniform => 1.25,
            false => 0.5 + 1.5 * draw(),
        })
        .collect();
    let mut s = ParticleSystem::new(&x, &v, &masses, capacity).unwrap();
    // Every third seed a rope through every slot, with linear springs (no gaps, as the chain
    // path's loop without masks takes it); the others with gaps.
    let rope = seed % 3 == 2;
    let linear = draw() < 0.3 || rope;
    let pairs: Vec<[usize; 2]> =
        (0..capacity - 1).filter(|_| draw() < 0.8 || rope).map(|a| [a, a + 1]).collect();
    let rest =
        pairs.iter().map(|_| if linear || draw() < 0.3 { 0.0 } else { 0.5 * draw() }).collect();
    let springs = Force::Springs {
        pairs,
        rest,
        stiffness: 50.0 + 200.0 * draw(),
        damping: if linear { 0.0 } else { 2.0 * draw() },
    };
    let mut forces = vec![springs];
    if draw() < 0.7 {
        forces.push(Force::Gravity { g: G });
    }
    if draw() < 0.5 && !uniform {
        forces.push(Force::Damping { rate: 0.5 * draw() });
    }
    if draw() < 0.3 {
        forces.push(Force::Gravity { g: DVec3::new(0.3, 0.0, -0.2) });
    }
    let first = (draw() * forces.len() as f64) as usize;
    forces.rotate_left(first);
    for force in forces {
        s.add_force(force).unwrap();
    }
    if draw() < 0.5 && !uniform {
        let external: Vec<f64> = (0..3 * capacity).map(|_| value(&mut draw, 2.0)).collect();
        s.set_external_forces(&external).unwrap();
    }
    if general {
        s.add_emitter(Emitter {
            rate: 0.0,
            position: DVec3::ZERO,
            position_spread: 0.0,
            velocity: DVec3::ZERO,
            velocity_spread: 0.0,
            lifespan: 1.0,
            mass: 1.0,
            seed: 0,
            appearance: Appearance::default(),
        })
        .unwrap();
    }
    s
}

#[test]
fn chain_path_is_bitwise_the_general_path() {
    // Every explicit method on 40 random chains, in calls of several steps and of one.
    let methods = [
        Method::ExplicitEuler,
        Method::Midpoint,
        Method::Heun,
        Method::Rk4,
        Method::SymplecticEuler,
        Method::VelocityVerlet,
    ];
    for seed in 0..40 {
        for method in methods {
            let (mut chain, mut general) = (random_chain(seed, false), random_chain(seed, true));
            for steps in [7, 1, 12] {
                chain.step(1e-3, steps, method).unwrap();
                general.step(1e-3, steps, method).unwrap();
                assert!(same_state(&chain, &general), "seed {seed}, {method:?}");
            }
            assert!(chain.positions().iter().any(|&x| x != 0.0));
        }
    }
}

#[test]
fn chain_path_failure_keeps_the_last_good_step_and_names_it() {
    // A chain at a step far beyond its stability limit grows by orders of magnitude a step until it
    // overflows; the chain path stops where the general path does, names the same step and
    // particle, and leaves the state of the steps before.
    for (seed, method) in
        [(3, Method::ExplicitEuler), (8, Method::Rk4), (5, Method::SymplecticEuler)]
    {
        let (mut chain, mut general) = (random_chain(seed, false), random_chain(seed, true));
        let (dt, steps) = (30.0, 400);
        let err = chain.step(dt, steps, method).unwrap_err();
        let reference = general.step(dt, steps, method).unwrap_err();
        let (
            kinema::Error::Diverged { step, index, .. },
            kinema::Error::Diverged { step: s2, index: i2, .. },
        ) = (&err, &reference)
        else {
            panic!("{err} / {reference}");
        };
        assert_eq!((step, index), (s2, i2), "{method:?}");
        assert!(*step > 2, "{err}");
        assert!(same_state(&chain, &general));
        let mut fresh = random_chain(seed, false);
        fresh.step(dt, *step, method).unwrap();
        assert!(same_state(&chain, &fresh));
        assert!(chain.positions().iter().chain(chain.velocities()).all(|x| x.is_finite()));
    }
}
