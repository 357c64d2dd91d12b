//! Social forces through a bottleneck: the flow through a door against its width, compared
//! with the Jülich experiments, and the "faster is slower" clogging of Helbing, Farkas &
//! Vicsek (2000, "Simulating dynamical features of escape panic", Fig. 1c).
//!
//! The room is `x < 0`, its wall `0 ≤ x ≤ 0.2` (two thick wall pieces with the door between
//! them). As in Helbing et al. 2000, where `e⁰` points to the exit, every agent inside walks
//! towards the nearest point of the door's opening narrowed by its radius at each jamb, and,
//! once in the door, straight on (`door_goals`).

use glam::DVec2;
use kinema::crowd::{metrics, Crowd, Kind, Settings, SocialForce};

fn v(x: f64, y: f64) -> DVec2 {
    DVec2::new(x, y)
}

/// Flow (1/s) through a bottleneck 4 m long against its width (m), Jülich experiments
/// (Liddle, Seyfried, Steffen, Klingsch, Rupprecht, Winkens & Boltes 2011, "Microscopic
/// insights into pedestrian motion through a bottleneck", arXiv:1105.1532): 150 persons,
/// flow `150 / (t_last - t_first)`, as tabulated in JuPedSim's validation script
/// (PedestrianDynamics/jupedsim, `Utest/testflow.py`). Specific flow 1.90–2.22 /(m s);
/// Seyfried, Passon, Steffen, Boltes, Rupprecht & Klingsch 2009 ("New insights into
/// pedestrian flow through bottlenecks", Transp. Sci. 43) find the flow linear in the
/// width, about 1.9 /(m s), and Kretz, Grünebohm & Schreckenberg 2006 (J. Stat. Mech.
/// P10014) a specific flow constant for widths of two persons and more.
const LIDDLE_2011: [(f64, f64); 10] = [
    (0.9, 1.710),
    (1.0, 2.025),
    (1.1, 2.194),
    (1.2, 2.532),
    (1.4, 2.911),
    (1.6, 3.115),
    (1.8, 3.906),
    (2.0, 3.910),
    (2.2, 4.524),
    (2.5, 5.547),
];

/// A uniform number in [-1, 1) from `seed` and `i` (splitmix64).
fn jitter(seed: u64, i: u64) -> f64 {
    let mut z = seed
        .wrapping_mul(0x9e37_79b9_7f4a_7c15)
        .wrapping_add(i.wrapping_mul(0xbf58_476d_1ce4_e5b9));
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// `n` agents of radius `r` on a grid of 10 rows 0.7 m apart (each moved by up to 0.1 m,
/// from `seed`: a symmetric start jams symmetrically) in front of a door of `width` (m),
/// walking at `speed` (m/s, at most twice that), at most `seconds` s of steps of 0.05 s;
/// the times (s) at which they leave the door. `gap` is the time gap (s; 0: Helbing et al.
/// 2000 as published).
fn evacuate(
    width: f64,
    n: usize,
    r: f64,
    speed: f64,
    seed: u64,
    seconds: f64,
    gap: f64,
) -> Vec<f64> {
    let settings = Settings {
        radius: r,
        max_speed: 2.0 * speed,
        preferred_speed: speed,
        neighbour_distance: 2.0,
        kind: Kind::SocialForce(SocialForce { time_gap: gap, ..SocialForce::default() }),
        ..Settings::rvo2_circle()
    };
    let mut crowd = Crowd::new(settings).unwrap();
    let h = width / 2.0;
    for (lo, hi) in [(h, 20.0), (-20.0, -h)] {
        crowd.add_obstacle(&[v(0.0, lo), v(0.2, lo), v(0.2, hi), v(0.0, hi)]).unwrap();
    }
    let rows = 10;
    let p: Vec<DVec2> = (0..n)
        .map(|i| {
            let grid = v(-0.5 - r - 0.7 * (i / rows) as f64, 0.7 * ((i % rows) as f64 - 4.5));
            let k = 2 * i as u64;
            grid + 0.1 * v(jitter(seed, k), jitter(seed, k + 1))
        })
        .collect();
    crowd.add_agents(&p, &p).unwrap();
    let dt = 0.05;
    let mut goals = p.clone();
    let mut frames = vec![p];
    while (frames.len() as f64) * dt < seconds {
        // The far side x = 0.2, from y = h to -h: agents at x < 0.2 are on its right.
        metrics::door_goals(crowd.state().positions(), v(0.2, h), v(0.2, -h), r, 100.0, &mut goals)
            .unwrap();
        crowd.state_mut().set_goals(&goals).unwrap();
        crowd.step(dt, 1).unwrap();
        frames.push(crowd.state().positions().to_vec());
        if frames.last().unwrap().iter().all(|q| q.x > 0.2) {
            break;
        }
    }
    let refs: Vec<&[DVec2]> = frames.iter().map(|f| f.as_slice()).collect();
    let times: Vec<f64> = (0..frames.len()).map(|k| k as f64 * dt).collect();
    metrics::crossings(&refs, &times, v(0.2, h), v(0.2, -h)).unwrap()
}

/// The steady flow (1/s): crossings after the first 10 and before the last 10 (the queue
/// forming and emptying), `(N - 1) / (t_N - t_1)` over them.
fn steady_flow(c: &[f64]) -> f64 {
    assert!(c.len() > 30, "{} crossings", c.len());
    metrics::flow_rate(&c[10..c.len() - 10]).unwrap()
}

/// The slope of the least-squares line through the origin, `Σ w J / Σ w²`.
fn slope(points: &[(f64, f64)]) -> f64 {
    points.iter().map(|(w, j)| w * j).sum::<f64>() / points.iter().map(|(w, _)| w * w).sum::<f64>()
}

/// 100 agents (radius 0.25 m, 1.34 m/s) through doors of 0.8–2.4 m: the steady flow grows
/// with the width, the slope of its line through the origin within 15 % of the experiments'
/// (measured: 1.35, 2.35, 3.83, 4.98, 5.83 /s, 1.69–2.49 /(m s), slope 2.36 /(m s) against
/// Liddle's 2.08 and Seyfried's 1.9), each width within 30 % of the experiments (at 0.8 m,
/// below Liddle's range, Seyfried's 1.9 w).
#[test]
fn bottleneck_flow_grows_with_width_as_in_the_experiments() {
    let mut flows = Vec::new();
    for width in [0.8, 1.2, 1.6, 2.0, 2.4] {
        let c = evacuate(width, 100, 0.25, 1.34, 0, 60.0, 0.0);
        let j = steady_flow(&c);
        eprintln!(
            "door {width:.1} m: {} out, steady flow {j:.3} /s ({:.2} /(m s))",
            c.len(),
            j / width
        );
        let experiment = match LIDDLE_2011.windows(2).find(|p| p[0].0 <= width && width <= p[1].0) {
            Some(p) => p[0].1 + (width - p[0].0) / (p[1].0 - p[0].0) * (p[1].1 - p[0].1),
            None => 1.9 * width,
        };
        assert!((j / experiment - 1.0).abs() < 0.3, "door {width}: {j} against {experiment}");
        flows.push((width, j));
    }
    for w in flows.windows(2) {
        assert!(w[1].1 > w[0].1, "the flow grows with the width: {flows:?}");
    }
    let (ours, theirs) = (slope(&flows), slope(&LIDDLE_2011));
    assert!((ours / theirs - 1.0).abs() < 0.15, "specific flow {ours} against {theirs}");
}

/// "Faster is slower" (Helbing et al. 2000, Fig. 1c, 200 agents, minimum near 1.5 m/s), at
/// reduced size: 100 agents of radius 0.3 m (Helbing's 0.25–0.35 m) through a 1 m door, the
/// mean over four seeds of the time the last one leaves. Walking faster empties the room
/// sooner up to 3 m/s, but at 5 m/s the agents press into the door and clog it. One run is
/// chaotic (a change in the last bits of the goals moved seed 0 at 5 m/s from 74.8 to 69.9 s),
/// so the test holds the mean (measured, seeds 0–3: 97.7, 93.3, 89.0, 97.8 s at 1.5 m/s; 68.8,
/// 68.0, 69.1, 63.5 at 3; 69.9, 77.0, 81.6, 71.1 at 5: means 94.5, 67.4, 74.9). Full size
/// (200 agents, 0.6–5 m/s) in `bench/bench_bottleneck.py`.
#[test]
fn faster_is_slower_at_a_narrow_door() {
    let mean_last = |speed: f64| {
        const SEEDS: u64 = 4;
        (0..SEEDS)
            .map(|seed| {
                let c = evacuate(1.0, 100, 0.3, speed, seed, 200.0, 0.0);
                assert_eq!(c.len(), 100, "seed {seed}, {speed} m/s: {} out", c.len());
                c[99]
            })
            .sum::<f64>()
            / SEEDS as f64
    };
    let (calm, fast, panic) = (mean_last(1.5), mean_last(3.0), mean_last(5.0));
    eprintln!("mean time all out: {calm:.1} s at 1.5 m/s, {fast:.1} s at 3, {panic:.1} s at 5");
    assert!(fast < 0.9 * calm, "{fast} against {calm}");
    assert!(panic > 1.05 * fast, "{panic} against {fast}");
}

/// With the time gap 0.065 s that gives Weidmann's fundamental diagram (docs/crowd.md), the
/// specific flow is constant above one lane, as Seyfried et al. 2009 and Kretz et al. 2006
/// find: within 10 % of its mean over 1.2–2.4 m, the mean within 20 % of Seyfried's 1.9
/// /(m s) (measured: 1.50, 1.66, 1.67, 1.68, mean 1.63; as published, 1.96–2.49, fails).
#[test]
fn with_the_time_gap_the_specific_flow_is_constant() {
    let specific: Vec<f64> = [1.2, 1.6, 2.0, 2.4]
        .iter()
        .map(|&w| steady_flow(&evacuate(w, 100, 0.25, 1.34, 0, 60.0, 0.065)) / w)
        .collect();
    let mean = specific.iter().sum::<f64>() / specific.len() as f64;
    eprintln!("specific flows {specific:?} /(m s), mean {mean}");
    assert!(specific.iter().all(|j| (j / mean - 1.0).abs() < 0.1), "{specific:?}");
    assert!((mean / 1.9 - 1.0).abs() < 0.2, "{mean}");
}
