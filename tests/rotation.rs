//! The rotation core through the Rust API: round trips, composition, slerp and the extremes,
//! as property tests (proptest) and closed-form cases.

use glam::{DQuat, DVec3};
use kinema::rotation::*;
use proptest::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI};

const SEQUENCES: [&str; 12] =
    ["xyz", "xzy", "yxz", "yzx", "zxy", "zyx", "xyx", "xzx", "yxy", "yzy", "zxz", "zyz"];

fn all_sequences() -> Vec<EulerSequence> {
    SEQUENCES
        .iter()
        .flat_map(|s| {
            [EulerSequence::parse(s).unwrap(), EulerSequence::parse(&s.to_uppercase()).unwrap()]
        })
        .collect()
}

/// Angle (radians) of the rotation taking `b` to `a`.
fn distance(a: DQuat, b: DQuat) -> f64 {
    rotation_angle(a * b.conjugate())
}

fn unit_quat() -> impl Strategy<Value = DQuat> {
    prop::array::uniform4(-1.0f64..1.0)
        .prop_filter("non-zero", |q| q.iter().map(|c| c * c).sum::<f64>() > 1e-6)
        .prop_map(|q| quat_from_wxyz(&q).unwrap())
}

proptest! {
    #[test]
    fn matrix_round_trip(q in unit_quat()) {
        let m = quat_to_matrix(q);
        prop_assert!(is_rotation_matrix(&m, 1e-14));
        prop_assert!(distance(quat_from_matrix(&m, false).unwrap(), q) < 1e-14);
    }

    #[test]
    fn euler_round_trip_in_every_sequence(q in unit_quat()) {
        for seq in all_sequences() {
            let (angles, _) = seq.from_quat(q);
            prop_assert!(angles.iter().all(|a| a.is_finite()));
            prop_assert!(distance(seq.to_quat(&angles).unwrap(), q) < 1e-13, "{seq:?}");
        }
    }

    #[test]
    fn euler_angles_round_trip_away_from_lock(a in -3.1f64..3.1, b in 0.05f64..1.5, c in -3.1f64..3.1) {
        for seq in all_sequences() {
            let angles = if seq.is_proper() { [a, b * 2.0, c] } else { [a, b - 0.75, c] };
            let (back, locked) = seq.from_quat(seq.to_quat(&angles).unwrap());
            prop_assert!(!locked);
            for k in 0..3 {
                prop_assert!((back[k] - angles[k]).abs() < 1e-11, "{seq:?} {angles:?} {back:?}");
            }
        }
    }

    #[test]
    fn rotvec_round_trip(v in prop::array::uniform3(-1.8f64..1.8)) {
        let q = quat_from_rotvec(&v).unwrap();
        let back = quat_to_rotvec(q);
        for k in 0..3 {
            prop_assert!((back[k] - v[k]).abs() < 1e-14);
        }
    }

    #[test]
    fn composition_acts_like_matrix_product(p in unit_quat(), q in unit_quat(), v in prop::array::uniform3(-10.0f64..10.0)) {
        let v = DVec3::from_array(v);
        let lhs = (p * q) * v;
        let rhs = p * (q * v);
        prop_assert!((lhs - rhs).length() < 1e-13);
        let m = quat_to_matrix(p);
        let mv = DVec3::new(
            m[0] * v.x + m[1] * v.y + m[2] * v.z,
            m[3] * v.x + m[4] * v.y + m[5] * v.z,
            m[6] * v.x + m[7] * v.y + m[8] * v.z,
        );
        prop_assert!((mv - p * v).length() < 1e-13);
    }

    #[test]
    fn slerp_has_constant_angular_speed(p in unit_quat(), q in unit_quat()) {
        let total = distance(q, p);
        prop_assert!(distance(slerp(p, q, 0.0, true), p) < 1e-15);
        prop_assert!(distance(slerp(p, q, 1.0, true), q) < 1e-14);
        for k in 1..10 {
            let t = f64::from(k) / 10.0;
            prop_assert!((distance(slerp(p, q, t, true), p) - t * total).abs() < 1e-12);
        }
    }

    #[test]
    fn transform_inverse(q in unit_quat(), t in prop::array::uniform3(-5.0f64..5.0), s in prop::array::uniform3(0.1f64..3.0)) {
        let m = transform_from_parts(q, &t, &s).unwrap();
        let id = transform_compose(&transform_invert(&m).unwrap(), &m);
        for (k, x) in id.iter().enumerate() {
            let expected = if k % 5 == 0 { 1.0 } else { 0.0 };
            prop_assert!((x - expected).abs() < 1e-12);
        }
    }
}

#[test]
fn intrinsic_xyz_is_extrinsic_zyx_reversed() {
    let a = [0.3, -1.2, 2.5];
    let xyz = EulerSequence::parse("XYZ").unwrap().to_quat(&a).unwrap();
    let zyx = EulerSequence::parse("zyx").unwrap().to_quat(&[a[2], a[1], a[0]]).unwrap();
    assert!(distance(xyz, zyx) < 1e-15);
}

#[test]
fn gimbal_lock_sets_third_angle_to_zero() {
    for seq in all_sequences() {
        for middle in if seq.is_proper() { [0.0, PI] } else { [FRAC_PI_2, -FRAC_PI_2] } {
            let angles = [0.4, middle, -0.9];
            assert!(seq.is_gimbal_locked(&angles, GIMBAL_LOCK_TOL));
            let q = seq.to_quat(&angles).unwrap();
            let (out, locked) = seq.from_quat(q);
            assert!(locked, "{seq:?} {middle}");
            assert_eq!(out[2], 0.0);
            assert!(distance(seq.to_quat(&out).unwrap(), q) < 1e-14, "{seq:?} {out:?}");
        }
    }
}

proptest! {
    #[test]
    fn exact_gimbal_lock_is_always_detected(a in -PI..PI, c in -PI..PI, side in 0usize..2) {
        for seq in all_sequences() {
            let middle = match (seq.is_proper(), side) {
                (true, 0) => 0.0,
                (true, _) => PI,
                (false, 0) => FRAC_PI_2,
                (false, _) => -FRAC_PI_2,
            };
            let q = seq.to_quat(&[a, middle, c]).unwrap();
            let (out, locked) = seq.from_quat(q);
            prop_assert!(locked, "{seq:?} {a} {middle} {c}");
            prop_assert!(distance(seq.to_quat(&out).unwrap(), q) < 1e-14);
        }
    }
}

#[test]
fn closed_form_cases() {
    // 90° about z maps x to y.
    let q = quat_from_axis_angle(&[0.0, 0.0, 2.0], FRAC_PI_2).unwrap();
    assert!((q * DVec3::X - DVec3::Y).length() < 1e-15);
    let m = quat_to_matrix(q);
    let expected = [0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    assert!(m.iter().zip(expected).all(|(a, b)| (a - b).abs() < 1e-15));
    // A half turn about x: the quaternion is (0, 1, 0, 0) and the rotation vector (pi, 0, 0).
    let m = [1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0];
    let q = canonical(quat_from_matrix(&m, false).unwrap());
    assert_eq!(quat_to_wxyz(q), [0.0, 1.0, 0.0, 0.0]);
    assert_eq!(quat_to_rotvec(q), [PI, 0.0, 0.0]);
}

#[test]
fn tiny_and_near_pi_rotation_vectors() {
    for angle in [1e-300, 1e-12, 1e-6, PI - 1e-12] {
        let v = [angle * 0.6, 0.0, angle * 0.8];
        let q = quat_from_rotvec(&v).unwrap();
        assert!((rotation_angle(q) - angle).abs() <= 1e-15 * angle.max(1e-300), "{angle}");
        let back = quat_to_rotvec(q);
        assert!((back[0] - v[0]).abs() <= 1e-15 * angle && (back[2] - v[2]).abs() <= 1e-15 * angle);
    }
}

#[test]
fn huge_rotation_vectors_give_unit_quaternions() {
    // |v| overflows its squares beyond ~1e154. The angle of such a vector is only known to the
    // rounding of |v| (many turns), so what must hold is a unit quaternion about the axis v/|v|.
    for m in [1e10, 1e160, 1e300, f64::MAX] {
        let v = [m * 0.6, 0.0, -m * 0.8];
        let [w, x, y, z] = quat_to_wxyz(quat_from_rotvec(&v).unwrap());
        let s = x.hypot(z);
        assert!(((w * w + s * s) - 1.0).abs() < 1e-15 && y == 0.0, "{m}: {:?}", [w, x, y, z]);
        // (x, z) parallel to (0.6, -0.8): no component along (0.8, 0.6).
        assert!((0.8 * x + 0.6 * z).abs() < 1e-15, "{m}: {:?}", [w, x, y, z]);
    }
}

#[test]
fn bad_input_is_an_error_not_a_nan() {
    assert!(quat_from_wxyz(&[0.0; 4]).is_err());
    assert!(quat_from_wxyz(&[f64::INFINITY, 0.0, 0.0, 0.0]).is_err());
    assert!(quat_from_matrix(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0], false).is_err());
    assert!(quat_from_matrix(&[f64::NAN; 9], true).is_err());
    assert!(quat_from_axis_angle(&[0.0; 3], 1.0).is_err());
    assert!(EulerSequence::parse("XYZ").unwrap().to_quat(&[f64::NAN, 0.0, 0.0]).is_err());
    let singular = transform_from_parts(DQuat::IDENTITY, &[0.0; 3], &[1.0, 0.0, 1.0]).unwrap();
    assert!(transform_invert(&singular).is_err());
}

/// A fixed stream of numbers in [-1, 1) (xorshift64).
fn xorshift(mut s: u64) -> impl FnMut() -> f64 {
    move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}

#[test]
fn batched_euler_angles_equal_the_row_by_row_ones_bitwise() {
    // 20 011 rows (not a multiple of the lane block or the parallel chunk): random unit
    // quaternions, some scaled (normalised first), some at and near gimbal lock, so the SIMD
    // lanes, the row-by-row fallback and the chunk edges all occur.
    let mut rnd = xorshift(7);
    for seq in all_sequences() {
        let quats: Vec<[f64; 4]> = (0..20_011)
            .map(|r| {
                let q = DQuat::from_xyzw(rnd(), rnd(), rnd(), rnd()).normalize();
                let q = match r % 97 {
                    0 => seq
                        .to_quat(&[rnd(), if seq.is_proper() { 0.0 } else { FRAC_PI_2 }, 0.3])
                        .unwrap(),
                    1 => seq
                        .to_quat(&[rnd(), if seq.is_proper() { PI } else { -FRAC_PI_2 }, 0.0])
                        .unwrap(),
                    _ => q,
                };
                let scale = if r % 13 == 0 { 3.5 } else { 1.0 };
                quat_to_wxyz(q).map(|c| c * scale)
            })
            .collect();
        let mut out = vec![[0.0; 3]; quats.len()];
        let locked = seq.from_quats(&quats, &mut out).unwrap();
        let mut expected_locked = 0;
        for (q, o) in quats.iter().zip(&out) {
            let (angles, lock) = seq.from_quat(quat_from_wxyz(q).unwrap());
            assert_eq!(angles.map(f64::to_bits), o.map(f64::to_bits), "{seq:?} {q:?}");
            expected_locked += usize::from(lock);
        }
        assert_eq!(locked, expected_locked);
        assert!(locked >= 2 * 20_011 / 97, "{seq:?}: {locked} locked");
    }
    // The lowest bad row is reported, whatever the chunking.
    let seq = EulerSequence::parse("xyz").unwrap();
    let mut quats = vec![[1.0, 0.0, 0.0, 0.0]; 50_000];
    quats[30_001] = [0.0; 4];
    quats[12_345] = [f64::NAN, 0.0, 0.0, 0.0];
    let mut out = vec![[0.0; 3]; quats.len()];
    let err = seq.from_quats(&quats, &mut out).unwrap_err().to_string();
    assert!(err.contains("12345"), "{err}");
}

#[test]
fn batched_rotation_vectors_equal_the_row_by_row_ones_bitwise() {
    // Rows of every size class: tiny (series), ordinary, many turns (libm's reduction beyond
    // 2e6 rad), overflowing squares, zero; 10 007 rows so blocks and chunks have ragged ends.
    let mut rnd = xorshift(11);
    let scales = [0.0, 1e-300, 1e-6, 1e-3, 1.0, 3.0, 100.0, 1e5, 1e7, 1e200];
    let vs: Vec<[f64; 3]> = (0..10_007)
        .map(|r| {
            let m = if r % 5 == 0 { scales[(r / 5) % scales.len()] } else { 3.0 };
            [m * rnd(), m * rnd(), m * rnd()]
        })
        .collect();
    let mut out = vec![[0.0; 4]; vs.len()];
    quats_from_rotvecs(&vs, &mut out).unwrap();
    for (v, o) in vs.iter().zip(&out) {
        let q = quat_to_wxyz(quat_from_rotvec(v).unwrap());
        assert_eq!(q.map(f64::to_bits), o.map(f64::to_bits), "{v:?}");
        assert!((o.iter().map(|c| c * c).sum::<f64>() - 1.0).abs() < 1e-15, "{v:?}");
    }
    let mut bad = vs.clone();
    bad[9_000] = [f64::INFINITY, 0.0, 0.0];
    bad[4_321] = [0.0, f64::NAN, 0.0];
    let err = quats_from_rotvecs(&bad, &mut out).unwrap_err().to_string();
    assert!(err.contains("4321") && err.contains("rotvec"), "{err}");
}

#[test]
fn batched_matrices_equal_the_row_by_row_ones_bitwise() {
    let mut rnd = xorshift(5);
    // Unit rows, scaled rows (normalised first) and a ragged end.
    let quats: Vec<[f64; 4]> = (0..10_007)
        .map(|r| {
            let q = quat_to_wxyz(DQuat::from_xyzw(rnd(), rnd(), rnd(), rnd()).normalize());
            q.map(|c| if r % 11 == 0 { 1e-200 * c } else { c })
        })
        .collect();
    let mut out = vec![[0.0; 9]; quats.len()];
    quats_to_matrices(&quats, &mut out).unwrap();
    for (q, o) in quats.iter().zip(&out) {
        let m = quat_to_matrix(quat_from_wxyz(q).unwrap());
        assert_eq!(m.map(f64::to_bits), o.map(f64::to_bits), "{q:?}");
    }
    let mut bad = quats.clone();
    bad[777] = [0.0; 4];
    let err = quats_to_matrices(&bad, &mut out).unwrap_err().to_string();
    assert!(err.contains("777"), "{err}");
}

#[test]
fn batched_normalisation_equals_the_row_by_row_one_bitwise() {
    let mut rnd = xorshift(11);
    // Unit rows, scaled rows, rows beyond the fast range (huge, subnormal) and a ragged end.
    let quats: Vec<[f64; 4]> = (0..10_007)
        .map(|r| {
            let q = [rnd(), rnd(), rnd(), rnd()];
            let s = match r % 19 {
                0 => 1e-160,
                1 => 1e155,
                _ if r % 3 == 0 => {
                    1.0 / (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt()
                }
                _ => 2.5,
            };
            q.map(|c| s * c)
        })
        .collect();
    let mut out = vec![[0.0; 4]; quats.len()];
    for canon in [false, true] {
        normalize_quats(&quats, canon, &mut out).unwrap();
        for (q, o) in quats.iter().zip(&out) {
            let want = quat_from_wxyz(q).unwrap();
            let want = if canon { canonical(want) } else { want };
            assert_eq!(quat_to_wxyz(want).map(f64::to_bits), o.map(f64::to_bits), "{q:?}");
        }
    }
    let mut bad = quats.clone();
    bad[2_222] = [0.0; 4];
    let err = normalize_quats(&bad, false, &mut out).unwrap_err().to_string();
    assert!(err.contains("2222"), "{err}");
}

#[test]
fn batched_mrps_equal_the_row_by_row_ones_bitwise() {
    let mut rnd = xorshift(13);
    // Unit rows (both signs of w), scaled rows, rows past the fast range (huge MRPs, whose
    // squared norm overflows, and their shadows) and a ragged end.
    let quats: Vec<[f64; 4]> = (0..10_007)
        .map(|r| {
            let q = quat_to_wxyz(DQuat::from_xyzw(rnd(), rnd(), rnd(), rnd()).normalize());
            if r % 17 == 0 {
                q.map(|c| 3.0 * c)
            } else {
                q
            }
        })
        .collect();
    let mut mrps = vec![[0.0; 3]; quats.len()];
    quats_to_mrps(&quats, &mut mrps).unwrap();
    for (q, p) in quats.iter().zip(&mrps) {
        let want = quat_to_mrp(quat_from_wxyz(q).unwrap());
        assert_eq!(want.map(f64::to_bits), p.map(f64::to_bits), "{q:?}");
    }
    for (r, p) in mrps.iter_mut().enumerate() {
        match r % 23 {
            0 => *p = p.map(|c| c * 1e160),
            1 => *p = p.map(|c| c * 1e-160),
            _ => {}
        }
    }
    let mut back = vec![[0.0; 4]; mrps.len()];
    mrps_to_quats(&mrps, &mut back).unwrap();
    for (p, q) in mrps.iter().zip(&back) {
        let want = quat_to_wxyz(quat_from_mrp(p).unwrap());
        assert_eq!(want.map(f64::to_bits), q.map(f64::to_bits), "{p:?}");
    }
    let mut bad = mrps.clone();
    bad[3_333] = [f64::NAN, 0.0, 0.0];
    let err = mrps_to_quats(&bad, &mut back).unwrap_err().to_string();
    assert!(err.contains("3333"), "{err}");
    let mut zero = quats.clone();
    zero[4_444] = [0.0; 4];
    let err = quats_to_mrps(&zero, &mut mrps).unwrap_err().to_string();
    assert!(err.contains("4444"), "{err}");
}

#[test]
fn batched_products_equal_the_row_by_row_ones_bitwise() {
    let mut rnd = xorshift(9);
    let mut unit = || quat_to_wxyz(DQuat::from_xyzw(rnd(), rnd(), rnd(), rnd()).normalize());
    // Unit rows, scaled rows (normalised first) on either side, and a ragged end.
    let a: Vec<[f64; 4]> =
        (0..10_007).map(|r| unit().map(|c| if r % 13 == 0 { 3.0 * c } else { c })).collect();
    let b: Vec<[f64; 4]> =
        (0..10_007).map(|r| unit().map(|c| if r % 17 == 0 { 1e-200 * c } else { c })).collect();
    let row = |x: &[f64; 4], y: &[f64; 4]| {
        quat_to_wxyz(quat_from_wxyz(x).unwrap() * quat_from_wxyz(y).unwrap()).map(f64::to_bits)
    };
    let mut out = vec![[0.0; 4]; a.len()];
    multiply_quats(&a, &b, &mut out).unwrap();
    for ((x, y), o) in a.iter().zip(&b).zip(&out) {
        assert_eq!(row(x, y), o.map(f64::to_bits), "{x:?} {y:?}");
    }
    // Pairs scaled by 2 and 1/2 have a unit product, kept as it is: the product of the
    // normalised pair to rounding, and the same in a block as alone.
    let halves: Vec<[f64; 4]> = b
        .iter()
        .enumerate()
        .map(|(r, y)| if r % 19 == 0 { y.map(|c| 0.5 * c) } else { *y })
        .collect();
    let doubles: Vec<[f64; 4]> = a
        .iter()
        .enumerate()
        .map(|(r, x)| if r % 19 == 0 { x.map(|c| 2.0 * c) } else { *x })
        .collect();
    multiply_quats(&doubles, &halves, &mut out).unwrap();
    let mut alone = [[0.0; 4]];
    for ((x, y), o) in doubles.iter().zip(&halves).zip(&out) {
        multiply_quats(&[*x], &[*y], &mut alone).unwrap();
        assert_eq!(alone[0].map(f64::to_bits), o.map(f64::to_bits), "{x:?} {y:?}");
        let normalised = row(x, y).map(f64::from_bits);
        assert!(normalised.iter().zip(o).all(|(n, o)| (n - o).abs() <= 2e-15), "{x:?} {y:?}");
    }
    // One against N, both ways.
    multiply_quats(&a[..1], &b, &mut out).unwrap();
    assert_eq!(out[5000].map(f64::to_bits), row(&a[0], &b[5000]));
    multiply_quats(&a, &b[..1], &mut out).unwrap();
    assert_eq!(out[5000].map(f64::to_bits), row(&a[5000], &b[0]));
    let mut bad = b.clone();
    bad[4_099] = [0.0; 4];
    let err = multiply_quats(&a, &bad, &mut out).unwrap_err().to_string();
    assert!(err.contains("4099"), "{err}");
    assert!(multiply_quats(&a[..3], &b[..2], &mut out[..3]).is_err());
}

/// The nearest rotation does not depend on the matrix's scale: huge and tiny (even subnormal)
/// multiples of a rotation orthonormalise to that rotation, not to NaN; non-finite and zero
/// matrices are refused.
#[test]
fn orthonormalize_scaled_matrices_without_overflow() {
    let q = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
    let r = quat_to_matrix(q);
    // Subnormal entries (5e-320) carry only ~10 significant bits: close, not exact.
    for (scale, tol) in [(1e160, 1e-14), (1e300, 1e-14), (f64::MAX / 2.0, 1e-14)]
        .into_iter()
        .chain([(1e-160, 1e-14), (1e-300, 1e-14), (5e-320, 1e-4)])
    {
        let m = r.map(|x| x * scale);
        let got = quat_from_matrix(&m, true).unwrap();
        assert!(got.dot(q).abs() > 1.0 - tol, "scale {scale}: {got:?}");
        let o = orthonormalize(&m).unwrap();
        assert!(is_rotation_matrix(&o, 1e-14), "scale {scale}: {o:?}");
    }
    let identity = [1e160, 0.0, 0.0, 0.0, 1e160, 0.0, 0.0, 0.0, 1e160];
    assert_eq!(quat_from_matrix(&identity, true).unwrap(), DQuat::IDENTITY);
    for bad in [f64::INFINITY, f64::NAN] {
        let mut m = r;
        m[4] = bad;
        assert!(quat_from_matrix(&m, true).is_err());
    }
    assert!(orthonormalize(&[0.0; 9]).is_err());
}
