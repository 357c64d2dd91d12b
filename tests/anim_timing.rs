//! Arc length, easing and clips against analytic answers: the length of a parabola, of a
//! cusp and of a helix, easing endpoints and symmetries, clip frame timing; and the
//! bounded-error contract (an unmet tolerance is an error).

use kinema::anim::{
    frame_times, ArcLengthCurve, Channel, Clip, Easing, Extrapolation, Interpolation,
    RotationInterpolation, RotationTrack, Samples, Track,
};
use kinema::snapshot::Snapshot;
use kinema::Error;
use std::f64::consts::{PI, TAU};

/// `x(t) = (f(t), g(t))` through keys at `t` by Lagrange interpolation: exact for cubics.
fn polynomial_curve(t: &[f64], f: impl Fn(f64) -> [f64; 2]) -> Track {
    let values: Vec<f64> = t.iter().flat_map(|&t| f(t)).collect();
    Track::new(t, &values, 2, Interpolation::Polynomial, Extrapolation::Hold).unwrap()
}

/// Arc length of the parabola `(t, t²)` from 0 to `t`.
fn parabola_length(t: f64) -> f64 {
    let r = (1.0 + 4.0 * t * t).sqrt();
    t * r / 2.0 + (2.0 * t).asinh() / 4.0
}

#[test]
fn the_length_of_a_parabola_is_its_closed_form_and_time_at_inverts_it() {
    let track = polynomial_curve(&[0.0, 1.0, 2.0], |t| [t, t * t]);
    let curve = ArcLengthCurve::new(track, 1e-13).unwrap();
    let exact = parabola_length(2.0);
    assert!((curve.length() - exact).abs() <= 1e-13 * exact, "{}", curve.length() - exact);
    for k in 0..=20 {
        let s = exact * k as f64 / 20.0;
        let t = curve.time_at(s).unwrap();
        assert!((parabola_length(t) - s).abs() <= 2e-12 * exact, "s = {s}");
    }
    // Clamped to [0, length]; the ends are the first and last key.
    assert_eq!(curve.time_at(-1.0).unwrap(), 0.0);
    assert_eq!(curve.time_at(1e9).unwrap(), 2.0);
    let s: Vec<[f64; 1]> = (0..50).map(|k| [k as f64 * 0.1]).collect();
    let mut out = vec![[0.0]; 50];
    curve.times_at(&s, &mut out).unwrap();
    for (si, ti) in s.iter().zip(&out) {
        assert_eq!(ti[0], curve.time_at(si[0]).unwrap());
    }
}

#[test]
fn the_length_of_a_cubic_hermite_helix_converges_at_fourth_order() {
    // Helix of radius r and pitch p, one and a half turns, keyed at its exact points and
    // tangents: the Hermite cubics are within O(h⁴) of it, and so is their length.
    let (r, p, turns) = (0.7_f64, 0.4_f64, 1.5_f64);
    let exact = turns * (TAU * TAU * r * r + p * p).sqrt();
    let mut errors = vec![];
    for keys in [16, 32, 64] {
        let t: Vec<f64> = (0..=keys).map(|k| turns * TAU * k as f64 / keys as f64).collect();
        let values: Vec<f64> =
            t.iter().flat_map(|&u| [r * u.cos(), r * u.sin(), p * u / TAU]).collect();
        let tangents: Vec<f64> =
            t.iter().flat_map(|&u| [-r * u.sin(), r * u.cos(), p / TAU]).collect();
        let scheme = Interpolation::Hermite { tangents };
        let track = Track::new(&t, &values, 3, scheme, Extrapolation::Hold).unwrap();
        let curve = ArcLengthCurve::new(track, 1e-12).unwrap();
        errors.push((curve.length() - exact).abs() / exact);
    }
    for w in errors.windows(2) {
        let order = (w[0] / w[1]).log2();
        assert!((3.7..4.3).contains(&order), "order {order} from {errors:?}");
    }
    assert!(errors[2] < 1e-6, "{errors:?}");
}

#[test]
fn an_unreachable_tolerance_is_an_error_not_a_capped_answer() {
    // The cusp x(t) = (t², t³): speed |t|·sqrt(4 + 9t²) has a kink at t = 0, inside a key
    // interval and at no dyadic subdivision of it, so the quadrature converges at second
    // order only: 1e-6 is reached, 1e-12 is not within 4096 subintervals.
    let keys = [-1.0, -0.35, 0.6, 1.2];
    let cusp = || polynomial_curve(&keys, |t| [t * t, t * t * t]);
    let half = |t: f64| ((4.0 + 9.0 * t * t).powf(1.5) - 8.0) / 27.0;
    let exact = half(1.0) + half(1.2);
    let curve = ArcLengthCurve::new(cusp(), 1e-6).unwrap();
    assert!((curve.length() - exact).abs() <= 1e-6 * exact, "{}", curve.length() - exact);
    match ArcLengthCurve::new(cusp(), 1e-12) {
        Err(Error::InvalidInput { arg, reason, .. }) => {
            assert_eq!(arg, "tol");
            assert!(reason.contains("cannot be met"), "{reason}");
        }
        other => panic!("expected an error, got {other:?}"),
    }
}

#[test]
fn arc_length_refuses_bad_input_and_survives_a_snapshot() {
    let one_key = Track::new(&[0.0], &[1.0], 1, Interpolation::Linear, Extrapolation::Hold);
    assert!(ArcLengthCurve::new(one_key.unwrap(), 1e-8).is_err());
    let track = polynomial_curve(&[0.0, 1.0, 2.0], |t| [t, t * t]);
    for tol in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(ArcLengthCurve::new(track.clone(), tol).is_err(), "tol {tol}");
    }
    let curve = ArcLengthCurve::new(track, 1e-10).unwrap();
    assert!(curve.time_at(f64::NAN).is_err());
    let again = ArcLengthCurve::from_snapshot(&curve.to_snapshot().unwrap()).unwrap();
    assert_eq!(again.table(), curve.table());
    assert_eq!(again.time_at(1.234).unwrap(), curve.time_at(1.234).unwrap());
}

#[test]
fn easings_rest_where_they_say_and_are_symmetric() {
    let names = Easing::NAMES;
    for name in names {
        let e = Easing::parse(name).unwrap();
        assert_eq!(e.eval(0.0).unwrap(), 0.0, "{name}");
        assert_eq!(e.eval(1.0).unwrap(), 1.0, "{name}");
        assert_eq!(e.eval(-3.0).unwrap(), 0.0, "{name}: clamped");
        assert_eq!(e.eval(7.0).unwrap(), 1.0, "{name}: clamped");
        assert!(e.eval(f64::NAN).is_err());
        // Monotone on [0, 1].
        let v: Vec<f64> = (0..=100).map(|k| e.eval(k as f64 / 100.0).unwrap()).collect();
        assert!(v.windows(2).all(|w| w[0] <= w[1]), "{name}");
    }
    let slope = |e: Easing, u: f64| (e.eval(u + 1e-6).unwrap() - e.eval(u - 1e-6).unwrap()) / 2e-6;
    for u in [0.1, 0.25, 0.4, 0.5, 0.77] {
        for e in [Easing::Linear, Easing::EaseInOut, Easing::Smoothstep] {
            let sum = e.eval(u).unwrap() + e.eval(1.0 - u).unwrap();
            assert!((sum - 1.0).abs() < 1e-15, "{e:?} at {u}");
        }
        let mirrored = 1.0 - Easing::EaseIn.eval(1.0 - u).unwrap();
        assert!((Easing::EaseOut.eval(u).unwrap() - mirrored).abs() < 1e-15);
        assert!((Easing::EaseInOut.eval(u).unwrap() - (1.0 - (PI * u).cos()) / 2.0).abs() == 0.0);
        assert!((Easing::Smoothstep.eval(u).unwrap() - u * u * (3.0 - 2.0 * u)).abs() < 1e-16);
        assert!((slope(Easing::EaseIn, u) - 2.0 * u).abs() < 1e-8);
    }
    // At rest: zero slope at the ends that rest (one-sided differences).
    let d0 = |e: Easing| e.eval(1e-6).unwrap() / 1e-6;
    let d1 = |e: Easing| (1.0 - e.eval(1.0 - 1e-6).unwrap()) / 1e-6;
    for e in [Easing::EaseIn, Easing::EaseInOut, Easing::Smoothstep] {
        assert!(d0(e) < 1e-5, "{e:?}");
    }
    for e in [Easing::EaseOut, Easing::EaseInOut, Easing::Smoothstep] {
        assert!(d1(e) < 1e-5, "{e:?}");
    }
    assert!((d0(Easing::Linear) - 1.0).abs() < 1e-9 && (d0(Easing::EaseOut) - 2.0).abs() < 1e-5);
    match Easing::parse("bounce") {
        Err(Error::InvalidInput { arg, reason, .. }) => {
            assert_eq!(arg, "kind");
            assert!(!reason.contains("bounce"));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_clip_spans_all_its_channels_and_samples_them_on_one_grid() {
    let a = Track::new(&[0.5, 2.0], &[0.0, 3.0], 1, Interpolation::Linear, Extrapolation::Hold);
    let q = [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
    let b = RotationTrack::new(&[1.0, 3.0], &q, RotationInterpolation::Slerp, &[]).unwrap();
    let clip = Clip::new(vec![
        ("x".into(), Channel::Value(a.unwrap())),
        ("turn".into(), Channel::Rotation(b)),
    ])
    .unwrap();
    assert_eq!((clip.start(), clip.end(), clip.duration()), (0.5, 3.0, 2.5));
    let (t, samples) = clip.sample(24.0).unwrap();
    assert_eq!(t.len(), 61, "2.5 s at 24 fps: 60 intervals, both ends");
    assert_eq!((t[0], t[60]), (0.5, 3.0));
    for (k, &tk) in t.iter().enumerate() {
        assert_eq!(tk, 0.5 + k as f64 / 24.0);
    }
    let Samples::Value(x) = &samples[0] else { panic!() };
    for (tk, xk) in t.iter().zip(x) {
        let want = 2.0 * (tk.clamp(0.5, 2.0) - 0.5);
        assert!((xk - want).abs() < 1e-15, "{tk}: {xk}");
    }
    let Samples::Rotation(r) = &samples[1] else { panic!() };
    // Slerp about y by π over 2 s: at t = 2 the half-angle is π/4.
    let at2 = r[36];
    assert!((at2[0] - (PI / 4.0).cos()).abs() < 1e-15 && (at2[2] - (PI / 4.0).sin()).abs() < 1e-15);
    // A frame rate that does not divide the duration stops at the last frame within it.
    assert_eq!(clip.frame_times(10.0 / 3.0).unwrap().len(), 9);
    for fps in [0.0, -24.0, f64::NAN, f64::INFINITY] {
        assert!(clip.frame_times(fps).is_err(), "fps {fps}");
    }
    assert!(frame_times(0.0, 1e300, 1e10).is_err(), "more frames than memory");
    assert!(Clip::new(vec![]).is_err());
}
