//! The crowd's navigation layer: A* on the roadmap gives the analytic shortest paths around a
//! wall and out of a U, and agents in a room leave by its door to a goal behind the far wall,
//! which they do not do without it.

use glam::DVec2;
use kinema::crowd::{Crowd, Kind, Model, Settings, SocialForce};

fn length(from: DVec2, path: &[DVec2]) -> f64 {
    let mut at = from;
    let mut sum = 0.0;
    for &p in path {
        sum += (p - at).length();
        at = p;
    }
    sum
}

fn model_with(obstacles: &[&[DVec2]], clearance: f64) -> Model {
    let mut model = Model::new(Settings::rvo2_circle()).unwrap();
    model.set_navigation(Some(clearance)).unwrap();
    for o in obstacles {
        model.add_obstacle(o).unwrap();
    }
    model
}

#[test]
fn shortest_path_around_a_wall_is_the_analytic_one() {
    // A wall x = 0, |y| ≤ 5, inflated by c to a rectangle: the path from (-5, 0) to (5, 0)
    // runs to its corner (-c, 5 + c), along its end to (c, 5 + c) and down to the goal.
    let c = 0.3;
    let wall = [DVec2::new(0.0, -5.0), DVec2::new(0.0, 5.0)];
    let model = model_with(&[&wall], c);
    let (from, to) = (DVec2::new(-5.0, 0.0), DVec2::new(5.0, 0.0));
    let path = model.navigation().unwrap().path(&model, from, to).unwrap();
    let want = 2.0 * ((5.0 - c).powi(2) + (5.0 + c).powi(2)).sqrt() + 2.0 * c;
    assert!((length(from, &path) - want).abs() < 1e-12, "{path:?}");
    assert_eq!(path.len(), 3);
    // The goal in sight: the path is the straight line.
    let near = model.navigation().unwrap().path(&model, from, DVec2::new(-5.0, 7.0)).unwrap();
    assert_eq!(near, vec![DVec2::new(-5.0, 7.0)]);
}

#[test]
fn shortest_path_out_of_a_u_is_the_analytic_one() {
    // A U opening upwards (counterclockwise), its notch |x| < 1, -1 < y < 2. From the notch
    // to below the U: up to the inner tip's node (1 - c, 2 + c), across the arm's top to
    // (2 + c, 2 + c), down its outside to (2 + c, -2 - c), then to the goal.
    let c = 0.3;
    let u: Vec<DVec2> = [
        (-2.0, -2.0),
        (2.0, -2.0),
        (2.0, 2.0),
        (1.0, 2.0),
        (1.0, -1.0),
        (-1.0, -1.0),
        (-1.0, 2.0),
        (-2.0, 2.0),
    ]
    .iter()
    .map(|&(x, y)| DVec2::new(x, y))
    .collect();
    let model = model_with(&[&u], c);
    let (from, to) = (DVec2::ZERO, DVec2::new(0.0, -5.0));
    let path = model.navigation().unwrap().path(&model, from, to).unwrap();
    let want = DVec2::new(1.0 - c, 2.0 + c).length()
        + (1.0 + 2.0 * c)
        + (4.0 + 2.0 * c)
        + (DVec2::new(2.0 + c, -2.0 - c) - to).length();
    assert!((length(from, &path) - want).abs() < 1e-12, "{path:?}");
    // A goal inside the solid U is unreachable: no path.
    assert!(model.navigation().unwrap().path(&model, from, DVec2::new(1.5, 0.0)).is_none());
}

/// A room [0, 8]² of wall segments with a door `y ∈ [3.5, 4.5]` in its right wall.
fn room() -> Vec<[DVec2; 2]> {
    let p = |x: f64, y: f64| DVec2::new(x, y);
    vec![
        [p(0.0, 0.0), p(0.0, 8.0)],
        [p(0.0, 0.0), p(8.0, 0.0)],
        [p(0.0, 8.0), p(8.0, 8.0)],
        [p(8.0, 0.0), p(8.0, 3.5)],
        [p(8.0, 4.5), p(8.0, 8.0)],
    ]
}

/// Nine agents in a 3 × 3 block in the room walking for `seconds` to the same block 8 m to
/// the left, behind the room's left wall; the number arrived.
fn leave_room(kind: Kind, navigation: bool, seconds: f64) -> usize {
    let settings = Settings {
        radius: 0.25,
        max_speed: 2.0,
        preferred_speed: 1.34,
        neighbour_distance: 3.0,
        time_horizon: 2.0,
        obstacle_time_horizon: 1.0,
        goal_tolerance: 0.5,
        kind,
        ..Settings::rvo2_circle()
    };
    let mut crowd = Crowd::new(settings).unwrap();
    if navigation {
        crowd.set_navigation(Some(0.4)).unwrap();
    }
    for wall in room() {
        crowd.add_obstacle(&wall).unwrap();
    }
    let start: Vec<DVec2> =
        (0..9).map(|k| DVec2::new(3.0 + (k % 3) as f64, 3.0 + (k / 3) as f64)).collect();
    let goal: Vec<DVec2> = start.iter().map(|p| DVec2::new(-8.0, 0.0) + *p).collect();
    crowd.add_agents(&start, &goal).unwrap();
    crowd.step(0.1, (seconds / 0.1) as usize).unwrap();
    let s = crowd.state();
    assert_eq!(s.tally().obstacle_collisions, 0, "{kind:?}");
    s.arrival_times().iter().filter(|t| t.is_finite()).count()
}

#[test]
fn orca_agents_leave_a_room_by_its_door_only_with_navigation() {
    assert_eq!(leave_room(Kind::Orca, false, 60.0), 0);
    assert_eq!(leave_room(Kind::Orca, true, 60.0), 9);
}

#[test]
fn social_force_agents_leave_a_room_by_its_door_only_with_navigation() {
    let kind = Kind::SocialForce(SocialForce::default());
    // Social forces push through the door more slowly (the agents press into it).
    assert_eq!(leave_room(kind, false, 120.0), 0);
    assert_eq!(leave_room(kind, true, 120.0), 9);
}

#[test]
fn bad_clearance_is_named() {
    let mut model = Model::new(Settings::rvo2_circle()).unwrap();
    for bad in [0.0, -1.0, f64::NAN] {
        let e = model.set_navigation(Some(bad)).unwrap_err().to_string();
        assert!(e.contains("clearance"), "{e}");
    }
    assert!(model.navigation().is_none());
}
