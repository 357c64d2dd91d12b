//! Skinning: exactness for rigid weights, the candy-wrapper twist, antipodal quaternions,
//! proximity weights, determinism and bad input.

use glam::{DQuat, DVec3};
use kinema::skin::{proximity_weights, Method, Skin};

const IDENTITY: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

fn wxyz(q: DQuat) -> [f64; 4] {
    [q.w, q.x, q.y, q.z]
}

/// A tube of radius `r` along +x from 0 to 2: `rings` rings of `sides` vertices.
fn tube(rings: usize, sides: usize, r: f64) -> Vec<[f64; 3]> {
    let mut v = Vec::new();
    for i in 0..rings {
        let x = 2.0 * i as f64 / (rings - 1) as f64;
        for j in 0..sides {
            let a = std::f64::consts::TAU * j as f64 / sides as f64;
            v.push([x, r * a.cos(), r * a.sin()]);
        }
    }
    v
}

/// Two bones along the tube, meeting at x = 1; the second's weight rises smoothly over
/// x in [0.5, 1.5].
fn two_bone_skin(rest: &[[f64; 3]]) -> Skin {
    let mut bones = Vec::new();
    let mut weights = Vec::new();
    for v in rest {
        let s = ((v[0] - 0.5).clamp(0.0, 1.0)).powi(2) * (3.0 - 2.0 * (v[0] - 0.5).clamp(0.0, 1.0));
        bones.extend([0, 1]);
        weights.extend([1.0 - s, s]);
    }
    let bind_positions = [[0.0; 3], [1.0, 0.0, 0.0]];
    Skin::new(rest, 2, &bones, &weights, &[0, 1], &bind_positions, &[IDENTITY; 2]).unwrap()
}

/// Area of the polygon of `ring` (vertices around the x axis) projected on the yz plane.
fn ring_area(ring: &[[f64; 3]]) -> f64 {
    let n = ring.len();
    0.5 * (0..n)
        .map(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            a[1] * b[2] - b[1] * a[2]
        })
        .sum::<f64>()
        .abs()
}

fn deform(
    skin: &Skin,
    positions: &[[f64; 3]],
    orientations: &[[f64; 4]],
    m: Method,
) -> Vec<[f64; 3]> {
    let poses = positions.len() / skin.bones();
    let mut out = vec![[0.0; 3]; poses * skin.vertices()];
    skin.deform(positions, orientations, m, &mut out).unwrap();
    out
}

#[test]
fn one_bone_per_vertex_moves_rigidly_with_both_methods() {
    let rest = tube(5, 8, 0.1);
    let bones: Vec<u32> = rest.iter().map(|v| u32::from(v[0] > 1.0)).collect();
    let weights = vec![1.0; rest.len()];
    let bind_p = [[0.0; 3], [1.0, 0.0, 0.0]];
    let bind_q = [IDENTITY, wxyz(DQuat::from_rotation_y(0.3))];
    let skin = Skin::new(&rest, 1, &bones, &weights, &[0, 1], &bind_p, &bind_q).unwrap();
    let q = [
        DQuat::from_rotation_z(0.7),
        DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 2.5),
    ];
    let p = [[0.3, -0.2, 0.5], [1.0, 2.0, -1.0]];
    let posed_q = [wxyz(q[0]), wxyz(q[1])];
    for method in [Method::Linear, Method::DualQuaternion] {
        let out = deform(&skin, &p, &posed_q, method);
        for (i, (v, x)) in rest.iter().zip(&out).enumerate() {
            let b = bones[i] as usize;
            let bind = DQuat::from_xyzw(bind_q[b][1], bind_q[b][2], bind_q[b][3], bind_q[b][0]);
            let local = bind.conjugate() * (DVec3::from_array(*v) - DVec3::from_array(bind_p[b]));
            let expected = q[b] * local + DVec3::from_array(p[b]);
            assert!((DVec3::from_array(*x) - expected).length() < 1e-12, "{method:?} vertex {i}");
        }
    }
}

#[test]
fn candy_wrapper_linear_collapses_dual_quaternion_keeps_the_section() {
    let (rings, sides) = (41, 32);
    let rest = tube(rings, sides, 0.1);
    let skin = two_bone_skin(&rest);
    let p = [[0.0; 3], [1.0, 0.0, 0.0]];
    let q = [IDENTITY, wxyz(DQuat::from_rotation_x(std::f64::consts::PI))];
    let middle = (rings / 2) * sides..(rings / 2 + 1) * sides;
    let area0 = ring_area(&rest[middle.clone()]);
    let lbs = ring_area(&deform(&skin, &p, &q, Method::Linear)[middle.clone()]);
    let dqs = ring_area(&deform(&skin, &p, &q, Method::DualQuaternion)[middle]);
    assert!(lbs < 1e-6 * area0, "LBS keeps {:.3} of the section", lbs / area0);
    assert!((dqs / area0 - 1.0).abs() < 0.05, "DQS keeps {:.3} of the section", dqs / area0);
}

#[test]
fn dual_quaternion_skinning_ignores_the_sign_of_a_quaternion() {
    // q and -q are one rotation: with the antipodality fix the blend does not change.
    let rest = tube(21, 16, 0.1);
    let skin = two_bone_skin(&rest);
    let p = [[0.0; 3], [1.0, 0.0, 0.0]];
    let twist = DQuat::from_rotation_x(2.0);
    let a = deform(&skin, &p, &[IDENTITY, wxyz(twist)], Method::DualQuaternion);
    let b = deform(&skin, &p, &[IDENTITY, wxyz(-twist)], Method::DualQuaternion);
    for (x, y) in a.iter().zip(&b) {
        assert!((DVec3::from_array(*x) - DVec3::from_array(*y)).length() < 1e-12);
    }
}

#[test]
fn proximity_weights_follow_the_nearest_bone_and_sum_to_one() {
    let segments = [([0.0; 3], [1.0, 0.0, 0.0]), ([1.0, 0.0, 0.0], [2.0, 0.0, 0.0])];
    let vertices = [[0.5, 0.0, 0.0], [1.0, 0.3, 0.0], [1.9, 0.1, 0.0], [0.2, 0.4, 0.0]];
    let (bones, weights) = proximity_weights(&vertices, &segments, &[0, 1], 2, 2, 4.0).unwrap();
    // On bone 0's segment: bone 0 alone.
    assert_eq!((bones[0], weights[0], weights[1]), (0, 1.0, 0.0));
    // Equally far from both: equal weights.
    assert!((weights[2] - 0.5).abs() < 1e-15 && (weights[3] - 0.5).abs() < 1e-15);
    // Near the end of bone 1: mostly bone 1, by (d0 / d1)^4.
    assert_eq!(bones[4], 1);
    let (d1, d0) = (0.1_f64, DVec3::new(0.9, 0.1, 0.0).length());
    assert!((weights[4] - d1.powi(-4) / (d1.powi(-4) + d0.powi(-4))).abs() < 1e-14);
    for w in weights.chunks(2) {
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-15);
    }
}

#[test]
fn results_are_the_same_bits_on_one_and_two_threads() {
    let rest = tube(101, 64, 0.1);
    let skin = two_bone_skin(&rest);
    let (mut p, mut q) = (Vec::new(), Vec::new());
    for f in 0..7 {
        p.extend([[0.0; 3], [1.0, 0.01 * f as f64, 0.0]]);
        q.extend([IDENTITY, wxyz(DQuat::from_rotation_x(0.4 * f as f64))]);
    }
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| deform(&skin, &p, &q, Method::DualQuaternion))
    };
    let bits = |v: Vec<[f64; 3]>| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(run(1)), bits(run(2)));
}

/// A pose of `n` bones from a seed: positions in [-1, 1)³, rotations of any sign.
fn pose(n: usize, seed: u64) -> (Vec<[f64; 3]>, Vec<[f64; 4]>) {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    };
    let p = (0..n).map(|_| [next(), next(), next()]).collect();
    let q = (0..n).map(|_| [next(), next(), next(), next()]).collect();
    (p, q)
}

#[test]
fn poses_skinned_eight_at_a_time_have_the_bits_of_poses_skinned_alone() {
    // Poses are skinned in SIMD lanes by blocks of eight; the poses of a last, partial block
    // one at a time. 11 poses: the block of 8, then 3 alone, each compared with the same pose
    // skinned in a call of its own (a partial block of one), with 4 influences of mixed signs.
    let rest = tube(9, 12, 0.1);
    let joints = 6;
    let bones: Vec<u32> = (0..rest.len() * 4).map(|i| ((i * 7 + i / 4) % joints) as u32).collect();
    let weights: Vec<f64> = (0..rest.len() * 4).map(|i| ((i * 5) % 11) as f64 + 0.5).collect();
    let bind = pose(joints, 99);
    let origins: Vec<usize> = (0..joints).collect();
    let skin = Skin::new(&rest, 4, &bones, &weights, &origins, &bind.0, &bind.1).unwrap();
    let (mut p, mut q) = (Vec::new(), Vec::new());
    for f in 0..11 {
        let (pf, qf) = pose(joints, f);
        p.extend(pf);
        q.extend(qf);
    }
    let bits = |v: &[[f64; 3]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    for m in [Method::Linear, Method::DualQuaternion] {
        let all = deform(&skin, &p, &q, m);
        for f in 0..11 {
            let span = f * joints..(f + 1) * joints;
            let alone = deform(&skin, &p[span.clone()], &q[span], m);
            let rows = &all[f * rest.len()..(f + 1) * rest.len()];
            assert_eq!(bits(rows), bits(&alone), "{m:?}, pose {f}");
        }
    }
}

#[test]
fn bad_input_names_the_argument() {
    let rest = [[0.0; 3]];
    let arg = |r: kinema::Result<Skin>| match r.unwrap_err() {
        kinema::Error::InvalidInput { arg, .. } => arg,
        e => panic!("{e}"),
    };
    let bind = ([[0.0; 3]], [IDENTITY]);
    assert_eq!(arg(Skin::new(&rest, 1, &[0], &[0.0], &[0], &bind.0, &bind.1)), "weights");
    assert_eq!(arg(Skin::new(&rest, 1, &[0], &[-1.0], &[0], &bind.0, &bind.1)), "weights");
    assert_eq!(arg(Skin::new(&rest, 1, &[1], &[1.0], &[0], &bind.0, &bind.1)), "bones");
    assert_eq!(arg(Skin::new(&rest, 1, &[0], &[1.0], &[3], &bind.0, &bind.1)), "origins");
    assert_eq!(arg(Skin::new(&rest, 0, &[], &[], &[0], &bind.0, &bind.1)), "influences");
    assert_eq!(
        arg(Skin::new(&[[f64::NAN; 3]], 1, &[0], &[1.0], &[0], &bind.0, &bind.1)),
        "vertices"
    );
    assert_eq!(arg(Skin::new(&rest, 1, &[0], &[1.0], &[0], &bind.0, &[[0.0; 4]])), "orientations");
    let skin = Skin::new(&rest, 1, &[0], &[1.0], &[0], &bind.0, &bind.1).unwrap();
    let mut out = vec![[0.0; 3]; 2];
    let err = skin.deform(&bind.0, &bind.1, Method::Linear, &mut out).unwrap_err();
    assert!(err.to_string().contains("out"), "{err}");
    let err = skin.deform(&[[0.0; 3]; 2], &bind.1, Method::Linear, &mut out).unwrap_err();
    assert!(err.to_string().contains("positions"), "{err}");
}
