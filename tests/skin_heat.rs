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
