//! Crowd metrics on hand-built trajectories with known answers (the bottleneck flow of social
//! forces against experiments is in `crowd_bottleneck.rs`).

use glam::DVec2;
use kinema::crowd::{metrics, Model, Settings};

fn v(x: f64, y: f64) -> DVec2 {
    DVec2::new(x, y)
}

#[test]
fn collisions_count_pairs_and_obstacle_penetrations() {
    // Radius 0.5: pairs closer than 1 m collide. (0,1): 0.9 apart (depth 0.1); (1,2): 1.0
    // apart (touching, not a collision); (3,4): on one point (depth 1).
    let p = [v(0.0, 0.0), v(0.9, 0.0), v(1.9, 0.0), v(5.0, 5.0), v(5.0, 5.0)];
    let c = metrics::agent_collisions(&p, 0.5);
    assert_eq!(c.count, 2);
    assert!((c.depth - 1.0).abs() < 1e-12);
    let mut model = Model::new(Settings { radius: 0.5, ..Settings::rvo2_circle() }).unwrap();
    // A square [10, 12]²; the first agent 0.3 m from its left side (depth 0.2), the second
    // near its corner (0.4 m from both sides: one penetration of the polygon, depth 0.1 + ...).
    model.add_obstacle(&[v(10.0, 10.0), v(12.0, 10.0), v(12.0, 12.0), v(10.0, 12.0)]).unwrap();
    let q = [v(9.7, 11.0), v(12.4, 12.0), v(0.0, 0.0)];
    let c = metrics::obstacle_collisions(&model, &q);
    assert_eq!(c.count, 2);
    assert!((c.depth - 0.2).abs() < 1e-12, "{}", c.depth);
}

#[test]
fn time_to_goal_and_path_ratio_of_known_walks() {
    // Agent 0 walks straight at 1 m/s to (4, 0); agent 1 walks an L of 3 + 4 m to (3, 4),
    // one frame per second; agent 2 never arrives.
    let frames: Vec<Vec<DVec2>> = (0..8)
        .map(|t| {
            let t = t as f64;
            let l = if t <= 3.0 { v(t, 0.0) } else { v(3.0, (t - 3.0).min(4.0)) };
            vec![v(t.min(4.0), 0.0), l, v(-1.0, 0.0)]
        })
        .collect();
    let refs: Vec<&[DVec2]> = frames.iter().map(|f| f.as_slice()).collect();
    let times: Vec<f64> = (0..8).map(f64::from).collect();
    let goals = [v(4.0, 0.0), v(3.0, 4.0), v(100.0, 0.0)];
    let t = metrics::time_to_goal(&refs, &times, &goals, 0.5).unwrap();
    assert!((t[0].unwrap() - 3.5).abs() < 1e-12, "{t:?}");
    assert!((t[1].unwrap() - 6.5).abs() < 1e-12, "{t:?}");
    assert_eq!(t[2], None);
    let r = metrics::path_ratio(&refs, &times, &goals).unwrap();
    assert!((r[0] - 1.0).abs() < 1e-12 && (r[1] - 7.0 / 5.0).abs() < 1e-12 && r[2] == 1.0, "{r:?}");
    assert!(metrics::time_to_goal(&refs, &times[..3], &goals, 0.5).is_err());
    assert!(metrics::path_ratio(&refs, &times, &goals[..2]).is_err());
}

#[test]
fn flow_through_a_door_of_known_crossings() {
    // Four agents walk up through the door from (0, 0) to (2, 0) at 1 m/s, starting 1, 2, 3
    // and 4 m below it; a fifth walks down through it (not counted) and a sixth passes beside.
    let frames: Vec<Vec<DVec2>> = (0..=20)
        .map(|k| {
            let t = k as f64 * 0.5;
            let mut f: Vec<DVec2> = (1..=4).map(|d| v(1.0, t - d as f64)).collect();
            f.push(v(0.5, 3.0 - t));
            f.push(v(5.0, t - 2.0));
            f
        })
        .collect();
    let refs: Vec<&[DVec2]> = frames.iter().map(|f| f.as_slice()).collect();
    let times: Vec<f64> = (0..=20).map(|k| k as f64 * 0.5).collect();
    // The door from (0, 0) to (2, 0): its left is +y.
    let c = metrics::crossings(&refs, &times, v(0.0, 0.0), v(2.0, 0.0)).unwrap();
    let down = metrics::crossings(&refs, &times, v(2.0, 0.0), v(0.0, 0.0)).unwrap();
    assert_eq!(down, vec![3.0]);
    assert_eq!(c, vec![1.0, 2.0, 3.0, 4.0]);
    assert_eq!(metrics::flow_rate(&c), Some(1.0));
    assert!(metrics::crossings(&refs, &times, v(1.0, 1.0), v(1.0, 1.0)).is_err());
}

/// The fields of Helbing, Johansson & Al-Abideen 2007 on known crowds: one agent gives the
/// Gaussian `exp(-d²/R²) / (π R²)` and its own velocity, nothing beyond the cut-off; a
/// square lattice of spacing `a` gives the density `1/a²` inside it (the lattice sum of the
/// Gaussian is `1/a²` to `~4 exp(-π² R²/a²)`, Poisson summation) and a linear velocity field
/// `v = (0.5 y, -0.25 x)` its value at the point (a symmetric weight reproduces linear fields
/// there, to the same order).
#[test]
fn density_and_velocity_fields_of_known_crowds() {
    let r = 0.8;
    let xs: Vec<f64> = (0..41).map(|i| -4.0 + 0.2 * i as f64).collect();
    let ys: Vec<f64> = (0..31).map(|j| -3.0 + 0.2 * j as f64).collect();
    let (mut rho, mut vel) = (vec![0.0; 41 * 31], vec![DVec2::ZERO; 41 * 31]);
    let (p, u) = (v(0.3, -0.1), v(1.2, -0.7));
    metrics::fields(&[p], &[u], &xs, &ys, r, &mut rho, &mut vel).unwrap();
    for (j, &y) in ys.iter().enumerate() {
        for (i, &x) in xs.iter().enumerate() {
            let d = p - v(x, y);
            let k = j * xs.len() + i;
            if d.x.abs() < 4.0 * r && d.y.abs() < 4.0 * r {
                let want = (-d.length_squared() / (r * r)).exp() / (std::f64::consts::PI * r * r);
                assert!((rho[k] - want).abs() <= 1e-13 * want, "{x} {y}: {} {want}", rho[k]);
                assert!((vel[k] - u).length() < 1e-15, "{x} {y}: {}", vel[k]);
            } else {
                assert_eq!((rho[k], vel[k]), (0.0, DVec2::ZERO), "{x} {y}");
            }
        }
    }
    // A lattice of spacing 0.5 m (4 agents/m²) over [-10, 10]², measured inside [-2, 2]².
    let a = 0.5;
    let lattice: Vec<DVec2> =
        (-20..=20).flat_map(|j| (-20..=20).map(move |i| v(a * i as f64, a * j as f64))).collect();
    let flow: Vec<DVec2> = lattice.iter().map(|q| v(0.5 * q.y, -0.25 * q.x)).collect();
    let xs: Vec<f64> = (0..9).map(|i| -2.0 + 0.5 * i as f64 + 0.13).collect();
    let ys: Vec<f64> = (0..9).map(|j| -2.0 + 0.5 * j as f64 - 0.21).collect();
    let (mut rho, mut vel) = (vec![0.0; 81], vec![DVec2::ZERO; 81]);
    metrics::fields(&lattice, &flow, &xs, &ys, 1.0, &mut rho, &mut vel).unwrap();
    for (j, &y) in ys.iter().enumerate() {
        for (i, &x) in xs.iter().enumerate() {
            let k = j * 9 + i;
            assert!((rho[k] - 4.0).abs() < 2e-6, "{x} {y}: {}", rho[k]);
            assert!((vel[k] - v(0.5 * y, -0.25 * x)).length() < 2e-6, "{x} {y}: {}", vel[k]);
        }
    }
    // Bad input is named and nothing is written.
    let mut rho = vec![7.0; 81];
    let bad = |e: kinema::Error| e.to_string();
    for (xs_, ys_, radius, arg) in [
        (vec![0.0, 0.0], vec![0.0], 1.0, "xs"),
        (vec![0.0], vec![f64::NAN], 1.0, "ys"),
        (vec![0.0], vec![0.0], 0.0, "radius"),
        (vec![0.0, 1.0], vec![0.0], 1.0, "density"),
    ] {
        let e = metrics::fields(&lattice, &flow, &xs_, &ys_, radius, &mut rho[..1], &mut vel[..1]);
        assert!(bad(e.unwrap_err()).contains(arg), "{arg}");
    }
    let e = metrics::fields(&lattice, &flow[1..], &xs, &ys, 1.0, &mut rho, &mut vel).unwrap_err();
    assert!(bad(e).contains("velocities"));
    assert!(rho.iter().all(|&d| d == 7.0));
}
