//! Keyframe tracks and subdivision curves: interpolation, continuity, derivatives,
//! extrapolation, limits of subdivision, bad input.

use kinema::anim::{subdivide, Extrapolation, Interpolation, Scheme, Track};

const T: [f64; 6] = [0.0, 0.5, 1.5, 2.0, 3.2, 4.0];
const V: [f64; 6] = [1.0, -0.5, 2.0, 0.3, 0.8, -1.0];

fn track(i: Interpolation) -> Track {
    Track::new(&T, &V, 1, i, Extrapolation::Hold).unwrap()
}

fn at(tr: &Track, t: f64, order: usize) -> f64 {
    let mut o = [0.0];
    tr.eval(t, order, &mut o);
    o[0]
}

fn interpolating() -> Vec<(&'static str, Interpolation)> {
    vec![
        ("step", Interpolation::Step),
        ("linear", Interpolation::Linear),
        ("polynomial", Interpolation::Polynomial),
        ("natural", Interpolation::NaturalCubic),
        ("clamped", Interpolation::ClampedCubic { start: vec![0.3], end: vec![-0.2] }),
        ("hermite", Interpolation::Hermite { tangents: vec![0.1, 0.2, -0.3, 0.4, 0.0, 1.0] }),
        ("cardinal", Interpolation::Cardinal { tension: 0.3 }),
        ("kb", Interpolation::KochanekBartels { tension: 0.2, continuity: -0.4, bias: 0.3 }),
        (
            "bezier",
            Interpolation::Bezier { handles: (0..10).map(|k| (k as f64 * 0.7).sin()).collect() },
        ),
    ]
}

#[test]
fn interpolating_schemes_pass_through_their_keys() {
    for (name, scheme) in interpolating() {
        let tr = track(scheme);
        for (t, v) in T.iter().zip(V) {
            assert!((at(&tr, *t, 0) - v).abs() < 1e-12, "{name} at {t}");
        }
    }
    // The B-spline approximates: it misses interior keys.
    let b = track(Interpolation::BSpline);
    assert!((at(&b, T[2], 0) - V[2]).abs() > 0.1);
}

/// Jump of the `order`-th derivative across key k.
fn jump(tr: &Track, k: usize, order: usize) -> f64 {
    let e = 1e-7;
    (at(tr, T[k] + e, order) - at(tr, T[k] - e, order)).abs()
}

#[test]
fn continuity_at_the_joins_is_what_each_scheme_promises() {
    for (name, scheme, c1, c2) in [
        ("natural", Interpolation::NaturalCubic, true, true),
        ("clamped", Interpolation::ClampedCubic { start: vec![0.0], end: vec![0.0] }, true, true),
        ("catmull-rom", Interpolation::Cardinal { tension: 0.0 }, true, false),
        (
            "kb continuity 0",
            Interpolation::KochanekBartels { tension: 0.3, continuity: 0.0, bias: 0.4 },
            true,
            false,
        ),
        (
            "kb continuity 0.5",
            Interpolation::KochanekBartels { tension: 0.0, continuity: 0.5, bias: 0.0 },
            false,
            false,
        ),
        // Linear: kinks at the keys; its second derivative is zero on both sides.
        ("linear", Interpolation::Linear, false, true),
    ] {
        let tr = track(scheme);
        for k in 1..T.len() - 1 {
            assert!(jump(&tr, k, 0) < 1e-5, "{name} C0 at {k}");
            assert_eq!(jump(&tr, k, 1) < 1e-5, c1, "{name} C1 at {k}: {}", jump(&tr, k, 1));
            assert_eq!(jump(&tr, k, 2) < 1e-4, c2, "{name} C2 at {k}: {}", jump(&tr, k, 2));
        }
    }
    // The uniform B-spline is C2 on equally spaced keys.
    let b = Track::new(
        &[0.0, 1.0, 2.0, 3.0, 4.0, 5.0],
        &V,
        1,
        Interpolation::BSpline,
        Extrapolation::Hold,
    )
    .unwrap();
    for k in 1..5 {
        let e = 1e-7;
        let kt = k as f64;
        for order in 0..3 {
            assert!(
                (at(&b, kt + e, order) - at(&b, kt - e, order)).abs() < 1e-4,
                "bspline C{order} at {k}"
            );
        }
    }
    let natural = track(Interpolation::NaturalCubic);
    assert!(at(&natural, 0.0, 2).abs() < 1e-12 && at(&natural, 4.0, 2).abs() < 1e-12);
    let clamped = track(Interpolation::ClampedCubic { start: vec![0.3], end: vec![-0.2] });
    assert!(
        (at(&clamped, 0.0, 1) - 0.3).abs() < 1e-12 && (at(&clamped, 4.0, 1) + 0.2).abs() < 1e-12
    );
}

#[test]
fn derivatives_match_finite_differences() {
    for (name, scheme) in interpolating().into_iter().chain([("bspline", Interpolation::BSpline)]) {
        if name == "step" {
            continue;
        }
        let tr = track(scheme);
        for t in [0.2, 0.9, 1.7, 2.5, 3.9] {
            let e = 1e-6;
            let d1 = (at(&tr, t + e, 0) - at(&tr, t - e, 0)) / (2.0 * e);
            let d2 = (at(&tr, t + e, 1) - at(&tr, t - e, 1)) / (2.0 * e);
            assert!((at(&tr, t, 1) - d1).abs() < 1e-6 * (1.0 + d1.abs()), "{name} d1 at {t}");
            assert!((at(&tr, t, 2) - d2).abs() < 1e-5 * (1.0 + d2.abs()), "{name} d2 at {t}");
        }
    }
}

#[test]
fn polynomial_reproduces_a_cubic_and_catmull_rom_a_line() {
    let f = |t: f64| 2.0 - t + 0.5 * t * t - 0.25 * t * t * t;
    let v: Vec<f64> = T.iter().map(|&t| f(t)).collect();
    let tr = Track::new(&T, &v, 1, Interpolation::Polynomial, Extrapolation::Hold).unwrap();
    for t in [0.3, 1.1, 2.7, 3.5] {
        assert!((at(&tr, t, 0) - f(t)).abs() < 1e-12);
    }
    let line: Vec<f64> = T.iter().map(|&t| 3.0 * t - 1.0).collect();
    let tr =
        Track::new(&T, &line, 1, Interpolation::Cardinal { tension: 0.0 }, Extrapolation::Hold)
            .unwrap();
    for t in [0.3, 1.1, 2.7, 3.5] {
        assert!((at(&tr, t, 0) - (3.0 * t - 1.0)).abs() < 1e-12);
    }
}

#[test]
fn extrapolation_modes_and_small_tracks() {
    let mk = |e| Track::new(&T, &V, 1, Interpolation::NaturalCubic, e).unwrap();
    let hold = mk(Extrapolation::Hold);
    assert_eq!(at(&hold, -1.0, 0), V[0]);
    assert_eq!(at(&hold, 9.0, 1), 0.0);
    let lin = mk(Extrapolation::Linear);
    let slope = at(&lin, 4.0, 1);
    assert!((at(&lin, 5.0, 0) - (V[5] + slope)).abs() < 1e-12);
    let cyc = mk(Extrapolation::Cycle);
    assert!((at(&cyc, 4.0 + 1.7, 0) - at(&cyc, 1.7, 0)).abs() < 1e-12);
    assert!((at(&cyc, -4.0 + 0.9, 0) - at(&cyc, 0.9, 0)).abs() < 1e-12);
    let one =
        Track::new(&[1.0], &[5.0], 1, Interpolation::NaturalCubic, Extrapolation::Linear).unwrap();
    assert_eq!((at(&one, -3.0, 0), at(&one, 7.0, 1)), (5.0, 0.0));
    let two =
        Track::new(&[0.0, 1.0], &[0.0, 2.0], 1, Interpolation::NaturalCubic, Extrapolation::Hold)
            .unwrap();
    assert!((at(&two, 0.25, 0) - 0.5).abs() < 1e-15);
    // Keys 1e-9 apart stay finite and interpolating.
    let close = Track::new(
        &[0.0, 1e-9, 1.0],
        &[0.0, 1e-9, 1.0],
        1,
        Interpolation::NaturalCubic,
        Extrapolation::Hold,
    )
    .unwrap();
    assert!(at(&close, 0.5e-9, 0).is_finite() && (at(&close, 1e-9, 0) - 1e-9).abs() < 1e-18);
}

#[test]
fn bad_keys_are_named() {
    let e = Track::new(&[0.0, 2.0, 1.0], &[0.0; 3], 1, Interpolation::Linear, Extrapolation::Hold)
        .unwrap_err();
    assert!(e.to_string().contains("times[1] = 2 and times[2] = 1"), "{e}");
    let e = Track::new(&[0.0, 1.0, 1.0], &[0.0; 3], 1, Interpolation::Linear, Extrapolation::Hold)
        .unwrap_err();
    assert!(e.to_string().contains("strictly increasing"));
    assert!(Track::new(
        &[0.0, 1.0],
        &[0.0, f64::NAN],
        1,
        Interpolation::Linear,
        Extrapolation::Hold
    )
    .is_err());
    assert!(Track::new(&[], &[], 1, Interpolation::Linear, Extrapolation::Hold).is_err());
    assert!(Track::new(
        &[0.0, 1.0],
        &[0.0, 1.0],
        1,
        Interpolation::Hermite { tangents: vec![1.0] },
        Extrapolation::Hold
    )
    .is_err());
    let tr = track(Interpolation::Linear);
    let mut out = [0.0; 2];
    assert!(tr.eval_many(&[0.0, f64::NAN], 0, &mut out).is_err());
}

fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt()
}

#[test]
fn subdivision_limits() {
    let square = [0.0, 0.0, 1.0, 0.0, 1.3, 1.0, -0.2, 0.8];
    // Cubic B-spline subdivision: vertex i converges to (p_{i-1} + 4 p_i + p_{i+1}) / 6.
    let mut errors = Vec::new();
    for k in 1..6 {
        let r = subdivide(&square, 2, Scheme::BSpline, k, true).unwrap();
        let i = 1;
        let limit = [
            (square[0] + 4.0 * square[2] + square[4]) / 6.0,
            (square[1] + 4.0 * square[3] + square[5]) / 6.0,
        ];
        let j = i << k;
        errors.push(dist(&r[2 * j..2 * j + 2], &limit));
    }
    for w in errors.windows(2) {
        assert!(w[1] < w[0] / 3.5, "{errors:?}"); // ~4x per round
    }
    // Chaikin converges to the closed quadratic B-spline of the polygon:
    // C(u) = (1-u)²/2 p_i + (1 + 2u - 2u²)/2 p_{i+1} + u²/2 p_{i+2}.
    let curve: Vec<[f64; 2]> = (0..4)
        .flat_map(|i| {
            (0..8000).map(move |s| {
                let u = s as f64 / 8000.0;
                let w = [(1.0 - u).powi(2) / 2.0, (1.0 + 2.0 * u - 2.0 * u * u) / 2.0, u * u / 2.0];
                let p = |j: usize| [square[2 * ((i + j) % 4)], square[2 * ((i + j) % 4) + 1]];
                [0, 1].map(|c| w[0] * p(0)[c] + w[1] * p(1)[c] + w[2] * p(2)[c])
            })
        })
        .collect();
    let gaps: Vec<f64> = (1..5)
        .map(|k| {
            let r = subdivide(&square, 2, Scheme::Chaikin, k, true).unwrap();
            r.chunks(2)
                .map(|p| curve.iter().map(|c| dist(p, c)).fold(f64::INFINITY, f64::min))
                .fold(0.0, f64::max)
        })
        .collect();
    for w in gaps.windows(2) {
        assert!(w[1] < w[0] / 3.0, "{gaps:?}"); // ~4x per round
    }
    // The 4-point scheme interpolates: the original points stay at indices i 2^k.
    for closed in [true, false] {
        let r = subdivide(&square, 2, Scheme::FourPoint, 3, closed).unwrap();
        for i in 0..4 {
            assert_eq!(&r[2 * (i << 3)..2 * (i << 3) + 2], &square[2 * i..2 * i + 2]);
        }
    }
    // Open curves keep their end points.
    for scheme in [Scheme::Chaikin, Scheme::BSpline, Scheme::FourPoint] {
        let r = subdivide(&square, 2, scheme, 4, false).unwrap();
        assert_eq!(&r[..2], &square[..2]);
        assert_eq!(&r[r.len() - 2..], &square[6..]);
    }
    assert!(subdivide(&square[..2], 2, Scheme::Chaikin, 1, false).is_err());
    assert!(subdivide(&[0.0, f64::NAN, 1.0, 1.0], 2, Scheme::Chaikin, 1, false).is_err());
}

mod rotation_tracks {
    use glam::{DQuat, DVec3};
    use kinema::anim::{Extrapolation, Interpolation, RotationInterpolation, RotationTrack, Track};
    use kinema::rotation::{quat_from_rotvec, quat_to_wxyz};

    const TIMES: [f64; 6] = [0.0, 0.4, 1.1, 1.5, 2.6, 3.0];

    fn keys() -> Vec<[f64; 4]> {
        let vs = [
            [0.1, 0.2, 0.3],
            [0.9, -0.4, 0.2],
            [1.5, 0.3, -0.8],
            [0.4, 1.8, 0.5],
            [-1.2, 0.6, 1.0],
            [-0.3, -0.2, 2.2],
        ];
        vs.iter().map(|v| quat_to_wxyz(quat_from_rotvec(v).unwrap())).collect()
    }

    fn spline() -> RotationTrack {
        RotationTrack::new(&TIMES, &keys(), RotationInterpolation::Spline, &[]).unwrap()
    }

    fn angle(a: DQuat, b: DQuat) -> f64 {
        2.0 * (a.conjugate() * b).xyz().length().atan2((a.conjugate() * b).w.abs())
    }

    #[test]
    fn spline_passes_through_keys_with_continuous_rate_and_acceleration() {
        let tr = spline();
        for (t, k) in TIMES.iter().zip(keys()) {
            let q = DQuat::from_xyzw(k[1], k[2], k[3], k[0]);
            assert!(angle(tr.eval(*t), q) < 1e-12);
        }
        for &t in &TIMES[1..5] {
            let e = 1e-7;
            let dw = (tr.angular_velocity(t + e) - tr.angular_velocity(t - e)).length();
            let da = (tr.angular_acceleration(t + e) - tr.angular_acceleration(t - e)).length();
            assert!(dw < 1e-5, "angular velocity jumps by {dw} at {t}");
            assert!(da < 1e-4, "angular acceleration jumps by {da} at {t}");
        }
        // Slerp's angular velocity jumps at the same keys: the test can tell.
        let sl = RotationTrack::new(&TIMES, &keys(), RotationInterpolation::Slerp, &[]).unwrap();
        let jump = (sl.angular_velocity(1.1 + 1e-7) - sl.angular_velocity(1.1 - 1e-7)).length();
        assert!(jump > 0.1);
    }

    #[test]
    fn spline_rates_match_finite_differences_of_the_orientation() {
        let tr = spline();
        for t in [0.13, 0.77, 1.3, 2.0, 2.9] {
            let e = 1e-5;
            let w_fd = DVec3::from_array(kinema::rotation::quat_to_rotvec(
                tr.eval(t + e) * tr.eval(t - e).conjugate(),
            )) / (2.0 * e);
            assert!((w_fd - tr.angular_velocity(t)).length() < 1e-7);
            let a_fd = (tr.angular_velocity(t + e) - tr.angular_velocity(t - e)) / (2.0 * e);
            assert!((a_fd - tr.angular_acceleration(t)).length() < 1e-6);
        }
    }

    #[test]
    fn squad_angular_velocity_matches_finite_differences_of_the_orientation() {
        // Five-point central differences of the orientation at e = 5e-5 s (truncation ~e⁴,
        // rounding ~1e-16/e: 6e-11 measured), on the short arcs and with a long-arc segment.
        let w_fd = |tr: &RotationTrack, t: f64| {
            let e = 5e-5;
            let d = |a: f64, b: f64| {
                DVec3::from_array(kinema::rotation::quat_to_rotvec(
                    tr.eval(t + b) * tr.eval(t + a).conjugate(),
                ))
            };
            (8.0 * d(-e, e) - d(-2.0 * e, 2.0 * e)) / (12.0 * e)
        };
        let sq = RotationTrack::new(&TIMES, &keys(), RotationInterpolation::Squad, &[]).unwrap();
        let long = [true, false, true, true, true];
        let sq_long =
            RotationTrack::new(&TIMES, &keys(), RotationInterpolation::Squad, &long).unwrap();
        for tr in [&sq, &sq_long] {
            for t in [0.13, 0.55, 0.77, 1.3, 1.8, 2.0, 2.9] {
                let err = (w_fd(tr, t) - tr.angular_velocity(t)).length();
                assert!(err < 1e-9, "at {t}: {err}");
            }
        }
    }

    #[test]
    fn spline_of_two_keys_is_slerp_and_of_a_steady_spin_is_exact() {
        let two = &keys()[..2];
        let sp = RotationTrack::new(&TIMES[..2], two, RotationInterpolation::Spline, &[]).unwrap();
        let sl = RotationTrack::new(&TIMES[..2], two, RotationInterpolation::Slerp, &[]).unwrap();
        for s in 0..=10 {
            let t = 0.04 * s as f64;
            assert!(angle(sp.eval(t), sl.eval(t)) < 1e-14);
        }
        // Keys of a constant spin at unequal spacing: the spline reproduces the spin.
        let w = DVec3::new(0.3, -1.1, 0.7);
        let spin: Vec<[f64; 4]> = TIMES
            .iter()
            .map(|&t| quat_to_wxyz(quat_from_rotvec(&(w * t).to_array()).unwrap()))
            .collect();
        let tr = RotationTrack::new(&TIMES, &spin, RotationInterpolation::Spline, &[]).unwrap();
        for t in [0.2, 0.9, 1.7, 2.8] {
            let exact = quat_from_rotvec(&(w * t).to_array()).unwrap();
            assert!(angle(tr.eval(t), exact) < 1e-12);
            assert!((tr.angular_velocity(t) - w).length() < 1e-12);
            assert!(tr.angular_acceleration(t).length() < 1e-11);
        }
    }

    #[test]
    fn a_segment_can_take_the_long_arc() {
        let q0 = [1.0, 0.0, 0.0, 0.0];
        let q1 = quat_to_wxyz(quat_from_rotvec(&[0.0, 0.5, 0.0]).unwrap());
        for mode in [
            RotationInterpolation::Slerp,
            RotationInterpolation::Squad,
            RotationInterpolation::Spline,
        ] {
            let short = RotationTrack::new(&[0.0, 1.0], &[q0, q1], mode, &[true]).unwrap();
            let long = RotationTrack::new(&[0.0, 1.0], &[q0, q1], mode, &[false]).unwrap();
            assert!((short.angular_velocity(0.5).y - 0.5).abs() < 1e-12);
            let w = long.angular_velocity(0.5);
            assert!((w.y + (2.0 * std::f64::consts::PI - 0.5)).abs() < 1e-9, "{w}");
        }
        assert!(RotationTrack::new(
            &[0.0, 1.0],
            &[q0, q1],
            RotationInterpolation::Slerp,
            &[true, true]
        )
        .is_err());
    }

    #[test]
    fn per_segment_schemes_take_each_segment_from_its_own_scheme() {
        let t = [0.0, 1.0, 2.0, 3.5, 4.0];
        let v = [0.0, 1.0, -1.0, 2.0, 0.5];
        let schemes = [
            Interpolation::Step,
            Interpolation::Cardinal { tension: 0.0 },
            Interpolation::Linear,
            Interpolation::NaturalCubic,
        ];
        let mixed = Track::per_segment(&t, &v, 1, &schemes, Extrapolation::Hold).unwrap();
        for (k, scheme) in schemes.iter().enumerate() {
            let whole = Track::new(&t, &v, 1, scheme.clone(), Extrapolation::Hold).unwrap();
            for s in [0.1, 0.5, 0.9] {
                let tt = t[k] + s * (t[k + 1] - t[k]);
                let (mut a, mut b) = ([0.0], [0.0]);
                mixed.eval(tt, 0, &mut a);
                whole.eval(tt, 0, &mut b);
                assert_eq!(a, b, "segment {k}");
            }
        }
        let bad = [Interpolation::Linear, Interpolation::Polynomial, Interpolation::Linear];
        assert!(Track::per_segment(&t, &v, 1, &bad, Extrapolation::Hold).is_err());
        assert!(Track::per_segment(&t, &v, 1, &schemes[..2], Extrapolation::Hold).is_err());
    }
}
