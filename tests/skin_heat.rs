//! Heat-diffusion weights (Baran & Popović 2007) against the diffusion's analytic solution on a
//! long tube, and their invariants.

use kinema::skin::heat_weights;

/// An open tube of radius `r` along y from `-h` to `h`: `rings` rings of `sides` vertices,
/// and its triangles. The rings are 2.5 times denser at the ends than at y = 0 (a mesh of
/// unequal areas: the weights must not depend on how the surface is sampled).
fn tube(rings: usize, sides: usize, r: f64, h: f64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let mut v = Vec::new();
    for i in 0..rings {
        let u = -1.0 + 2.0 * i as f64 / (rings - 1) as f64;
        let y = h * (u + 0.5 * u * u * u) / 1.5;
        for s in 0..sides {
            let a = std::f64::consts::TAU * s as f64 / sides as f64;
            v.push([r * a.cos(), y, r * a.sin()]);
        }
    }
    let mut t = Vec::new();
    let at = |i: usize, s: usize| (i * sides + s % sides) as u32;
    for i in 0..rings - 1 {
        for s in 0..sides {
            t.push([at(i, s), at(i + 1, s), at(i + 1, s + 1)]);
            t.push([at(i, s), at(i + 1, s + 1), at(i, s + 1)]);
        }
    }
    (v, t)
}

/// Bone segments (from, to) and the bone owning each.
type Bones = (Vec<([f64; 3], [f64; 3])>, Vec<u32>);

/// Two bones along the tube's axis meeting at y = 0: bone 0 below, bone 1 above.
fn two_bones(h: f64) -> Bones {
    (vec![([0.0, -h, 0.0], [0.0, 0.0, 0.0]), ([0.0, 0.0, 0.0], [0.0, h, 0.0])], vec![0, 1])
}

fn weight_of(bone: u32, j: usize, k: usize, bones: &[u32], weights: &[f64]) -> f64 {
    (0..k).filter(|&i| bones[j * k + i] == bone).map(|i| weights[j * k + i]).sum()
}

/// On a long tube of radius `r` every vertex is `r` from its nearest bone, so for weights that
/// depend on y alone the equation `−Δw + (c/r²) w = (c/r²) p` is `w'' = (w − p)/r²` (c = 1),
/// whose solution with `p = 1` below the joint and 0 above is `w₀ = ½ e^{−y/r}` above and
/// `1 − ½ e^{y/r}` below. The discrete weights follow it, converging as the mesh refines.
#[test]
fn heat_weights_on_a_tube_follow_the_exponential_profile_of_the_diffusion() {
    let (r, h) = (0.1, 1.0);
    let (segments, owners) = two_bones(h);
    let mut errors = Vec::new();
    for (rings, sides) in [(101, 24), (201, 48)] {
        let (v, t) = tube(rings, sides, r, h);
        let (b, w) = heat_weights(&v, &t, &segments, &owners, 2, 2).unwrap();
        let mut worst: f64 = 0.0;
        for (j, p) in v.iter().enumerate() {
            let y = p[1];
            let exact = if y > 0.0 { 0.5 * (-y / r).exp() } else { 1.0 - 0.5 * (y / r).exp() };
            if y.abs() < 1e-12 {
                continue; // on the joint both bones are equidistant: p = 1/2, w = 1/2 exactly
            }
            worst = worst.max((weight_of(0, j, 2, &b, &w) - exact).abs());
        }
        errors.push(worst);
    }
    // Measured: 1.1e-4 and 2.8e-5 (second order).
    assert!(errors[1] < 1e-4, "largest error {:.2e} at the finer mesh", errors[1]);
    assert!(errors[1] < 0.35 * errors[0], "not second order: {errors:?}");
}

/// With every bone kept, the weights of all bones sum to 1 at every vertex before
/// normalisation (`L 1 = 0` and `Σ pⁱ = 1`), lie in [0, 1], and the joint's ring gets ½ each.
#[test]
fn heat_weights_sum_to_one_and_split_the_joint_evenly() {
    let (v, t) = tube(41, 12, 0.1, 1.0);
    let (segments, owners) = two_bones(1.0);
    let (b, w) = heat_weights(&v, &t, &segments, &owners, 2, 2).unwrap();
    for j in 0..v.len() {
        let sum = w[2 * j] + w[2 * j + 1];
        assert!((sum - 1.0).abs() < 1e-12);
        assert!(w[2 * j] >= w[2 * j + 1] && w[2 * j + 1] >= 0.0);
        if v[j][1].abs() < 1e-12 {
            assert!((weight_of(0, j, 2, &b, &w) - 0.5).abs() < 1e-9);
        }
    }
    // Far from the joint a vertex follows its own bone almost alone.
    let far = v.iter().position(|p| p[1] == 1.0).unwrap();
    assert!(weight_of(1, far, 2, &b, &w) > 0.999);
}

#[test]
fn heat_weights_refuse_bad_triangles_naming_the_argument() {
    let (v, mut t) = tube(5, 6, 0.1, 1.0);
    let (segments, owners) = two_bones(1.0);
    t.push([0, 1, 999]);
    let e = heat_weights(&v, &t, &segments, &owners, 2, 2).unwrap_err().to_string();
    assert!(e.contains("triangles"), "{e}");
    t.pop();
    t.push([0, 0, 1]);
    let e = heat_weights(&v, &t, &segments, &owners, 2, 2).unwrap_err().to_string();
    assert!(e.contains("triangles"), "{e}");
    t.pop();
    let e = heat_weights(&v, &t, &segments, &owners, 2, 0).unwrap_err().to_string();
    assert!(e.contains("influences"), "{e}");
    // A vertex in no triangle takes its nearest bone alone.
    let mut v2 = v.clone();
    v2.push([0.0, 0.9, 0.0]);
    let (b, w) = heat_weights(&v2, &t, &segments, &owners, 2, 2).unwrap();
    let last = v2.len() - 1;
    assert_eq!((b[2 * last], w[2 * last]), (1, 1.0));
}

/// Append to `(v, t)` a closed cylinder along y of radius `r` about `(x, ·, 0)` from `y0` to
/// `y1`: `rings` rings of `sides` vertices and a fan on each end (outward facing).
fn closed_cylinder(v: &mut Vec<[f64; 3]>, t: &mut Vec<[u32; 3]>, x: f64, r: f64, y: [f64; 2]) {
    let (rings, sides) = (21, 16);
    let base = v.len() as u32;
    for i in 0..rings {
        let yi = y[0] + (y[1] - y[0]) * i as f64 / (rings - 1) as f64;
        for s in 0..sides {
            let a = std::f64::consts::TAU * s as f64 / sides as f64;
            v.push([x + r * a.cos(), yi, r * a.sin()]);
        }
    }
    let at = |i: usize, s: usize| base + (i * sides + s % sides) as u32;
    for i in 0..rings - 1 {
        for s in 0..sides {
            t.push([at(i, s), at(i + 1, s), at(i + 1, s + 1)]);
            t.push([at(i, s), at(i + 1, s + 1), at(i, s + 1)]);
        }
    }
    let (bottom, top) = (v.len() as u32, v.len() as u32 + 1);
    v.push([x, y[0], 0.0]);
    v.push([x, y[1], 0.0]);
    for s in 0..sides {
        t.push([bottom, at(0, s + 1), at(0, s)]);
        t.push([top, at(rings - 1, s), at(rings - 1, s + 1)]);
    }
}

/// Two legs pressed together (a gap of 1 cm), the left leg's bone off its centre away from
/// the right leg: the inner side of the left leg is nearer to the right leg's bone than to its
/// own, but that bone is behind the right leg's surface. With the visibility test of Baran &
/// Popović (§4) every vertex of the left leg follows its own bone alone; without it the inner
/// side would follow the other leg.
#[test]
fn heat_weights_of_legs_pressed_together_follow_the_visible_bone() {
    let (r, gap) = (0.1, 0.01);
    let centre = r + gap / 2.0;
    let (mut v, mut t) = (Vec::new(), Vec::new());
    closed_cylinder(&mut v, &mut t, -centre, r, [-0.05, 1.05]);
    let left = v.len();
    closed_cylinder(&mut v, &mut t, centre, r, [-0.05, 1.05]);
    let bone_x = [-centre - 0.6 * r, centre];
    let segments: Vec<_> = bone_x.iter().map(|&x| ([x, 0.0, 0.0], [x, 1.0, 0.0])).collect();
    let (b, w) = heat_weights(&v, &t, &segments, &[0, 1], 2, 2).unwrap();
    let mut nearer_the_other = 0;
    for (j, p) in v.iter().enumerate() {
        let own = usize::from(j >= left);
        let d = |x: f64| ((p[0] - x).powi(2) + p[2].powi(2)).sqrt();
        nearer_the_other += usize::from(d(bone_x[1 - own]) < d(bone_x[own]));
        let weight = weight_of(own as u32, j, 2, &b, &w);
        assert!(weight > 1.0 - 1e-9, "vertex {j} of leg {own} follows its bone by {weight}");
    }
    assert!(nearer_the_other >= 60, "only {nearer_the_other} vertices nearer the other bone");
}

/// A closed part of the surface from which no bone is visible (a box inside a shell, the
/// bones outside both) would make the system singular: it takes its nearest bone without the
/// visibility test, and the shell (which sees the bones) is held by them as usual.
#[test]
fn heat_weights_of_a_part_that_sees_no_bone_take_the_nearest() {
    let (mut v, mut t) = (Vec::new(), Vec::new());
    closed_cylinder(&mut v, &mut t, 0.0, 0.1, [0.0, 0.2]);
    let inner = v.len();
    closed_cylinder(&mut v, &mut t, 0.0, 0.5, [-0.5, 0.7]);
    let segments = [([-2.0, 0.0, 0.0], [-2.0, 0.2, 0.0]), ([3.0, 0.0, 0.0], [3.0, 0.2, 0.0])];
    let (b, w) = heat_weights(&v, &t, &segments, &[0, 1], 2, 2).unwrap();
    for j in 0..inner {
        assert!(weight_of(0, j, 2, &b, &w) > 1.0 - 1e-9, "inner vertex {j}");
    }
    assert!(w.iter().all(|x| x.is_finite()));
    let shell_left = (inner..v.len()).find(|&j| v[j][0] < -0.49).unwrap();
    assert!(weight_of(0, shell_left, 2, &b, &w) > 0.5);
}
