//! Moving colliders under the SIMBICON walkers (`Walker::set_collider`,
//! `Walker3d::set_collider`): a walk on a ground that moves at a constant velocity is the walk
//! on still ground carried along, bad colliders are named, and a failed step on a moving
//! ground leaves the walker and the collider as they were.

use glam::DVec3;
use kinema::character::{Collider, Coronal, Gait, Settings, Walker, Walker3d, TORSO, TORSO_3D};
use kinema::geometry::{Plane, Shape, Sphere};

/// The walkers' settings: stiff feet, as in `tests/biped.rs` and `tests/biped3d.rs`; the
/// ground plane y = 0 on or off.
fn settings(ground: bool) -> Settings {
    Settings { contact_frequency: 200.0, ground, ..Settings::default() }
}

const DT: f64 = 1e-3;

/// The plane y = 0 as a collider translating at `velocity` (m/s) from time 0.
fn moving_ground(velocity: DVec3) -> Collider {
    let shape = Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::Y });
    Collider { shape, friction: None, velocity, angular_velocity: DVec3::ZERO, since: 0.0 }
}

/// Walk `still` (on the ground) and `moving` (on a ground moving at `v`) for 6 s, comparing
/// their centres of mass every 0.1 s less `v t`; returns the largest gap (m).
fn gap(mut still: impl FnMut() -> DVec3, mut moving: impl FnMut() -> DVec3, v: DVec3) -> f64 {
    let mut apart = 0.0f64;
    for k in 1..=60 {
        let gap = moving() - v * (k as f64 * 0.1) - still();
        apart = apart.max(gap.length());
    }
    apart
}

/// The planar walk from 0.3 m/s on still ground against the same walk on a ground plane
/// moving at `V` = 0.5 m/s along x (the walker starting at 0.3 + V m/s), 6 s: the moving
/// walk less `V t` stays on the still walk within 1 cm (measured 3.9e-14 m: SIMBICON's
/// balance feedback takes the centre of mass's velocity relative to the stance foot's
/// ground, so the two are one walk in two inertial frames, to rounding). With the world
/// velocity in the feedback (`ground_velocity` left out) the two walks end 1.03 m apart
/// (the 3-D ones, below, 2.46 m).
#[test]
fn a_planar_walk_on_a_moving_ground_is_the_walk_carried_along() {
    let v = DVec3::new(0.5, 0.0, 0.0);
    let mut still = Walker::new(settings(true), Gait::default(), 0.3).unwrap();
    let mut moving = Walker::new(settings(false), Gait::default(), 0.3 + v.x).unwrap();
    let i = moving.add_collider(moving_ground(DVec3::ZERO).shape, None).unwrap();
    moving.set_collider(i, moving_ground(v)).unwrap();
    let apart = gap(
        || {
            still.step(DT, 100).unwrap();
            still.com()
        },
        || {
            moving.step(DT, 100).unwrap();
            moving.com()
        },
        v,
    );
    println!("planar: {apart:.3e} m apart");
    assert!(apart < 0.01, "{apart} m apart");
    assert!(moving.state().q()[1] > 0.8, "fell");
}

/// The 3-D walk, likewise, on a ground moving at 0.5 m/s forward and 0.2 m/s to the right
/// (+z): within 1 cm of the still walk carried along (measured 2.6e-14 m). The moving ground
/// is the plane y = 0, where the 3-D controller's grip looks for the stance foot's contacts.
#[test]
fn a_3d_walk_on_a_moving_ground_is_the_walk_carried_along() {
    let v = DVec3::new(0.5, 0.0, 0.2);
    let new = |ground| Walker3d::new(settings(ground), Gait::default_3d(), Coronal::default(), 0.3);
    let (mut still, mut moving) = (new(true).unwrap(), new(false).unwrap());
    let i = moving.add_collider(moving_ground(DVec3::ZERO).shape, None).unwrap();
    moving.set_collider(i, moving_ground(v)).unwrap();
    let (_, state) = moving.parts_mut();
    let mut qd = state.qd().to_vec();
    qd[3] += v.x; // the free root's rates: [ω (body axes); v (world)]
    qd[5] += v.z;
    state.set_qd(&qd).unwrap();
    let apart = gap(
        || {
            still.step(DT, 100).unwrap();
            still.com()
        },
        || {
            moving.step(DT, 100).unwrap();
            moving.com()
        },
        v,
    );
    println!("3-D: {apart:.3e} m apart");
    assert!(apart < 0.01, "{apart} m apart");
    assert!(moving.state().q()[1] > 0.8, "fell");
}

/// A collider of another size, or an index beyond the colliders, is refused naming the
/// argument, and the walker keeps the collider it had.
#[test]
fn bad_colliders_are_named() {
    let mut w = Walker::new(settings(true), Gait::default(), 0.3).unwrap();
    let ball = |radius| Shape::Sphere(Sphere { center: DVec3::new(3.0, -0.5, 0.0), radius });
    let i = w.add_collider(ball(0.6), None).unwrap();
    let moved = Collider { shape: ball(0.7), ..moving_ground(DVec3::X) };
    let name = |e: kinema::Error| e.to_string();
    assert!(name(w.set_collider(i, moved).unwrap_err()).contains("shape"));
    let inf = Collider { shape: ball(0.6), ..moving_ground(DVec3::new(f64::NAN, 0.0, 0.0)) };
    assert!(name(w.set_collider(i, inf).unwrap_err()).contains("velocity"));
    let ok = Collider { shape: ball(0.6), ..moving_ground(DVec3::X) };
    assert!(name(w.set_collider(i + 1, ok).unwrap_err()).contains("index"));
    assert_eq!(w.model().colliders()[0].shape, ball(0.6));
    assert_eq!(w.model().colliders()[0].velocity, DVec3::ZERO);
}

/// A walker on a moving ground pushed with an absurd force diverges within a call: the call
/// fails, and the coordinates, rates, time, pushes and phase are bit for bit those before it, the
/// collider where it was (a function of the walker's time, which went back); both walkers.
#[test]
fn a_failed_step_on_a_moving_ground_leaves_the_walker_as_it_was() {
    let v = DVec3::new(0.5, 0.0, 0.0);
    let mut planar = Walker::new(settings(false), Gait::default(), 0.3 + v.x).unwrap();
    planar.add_collider(moving_ground(DVec3::ZERO).shape, None).unwrap();
    planar.set_collider(0, moving_ground(v)).unwrap();
    planar.step(DT, 500).unwrap();
    let (model, state) = planar.parts_mut();
    state.push(model, TORSO, DVec3::new(0.0, 1e12, 0.0), 1.0).unwrap();
    let before = (planar.state().clone(), planar.phase(), planar.model().colliders()[0]);
    assert!(planar.step(DT, 200).is_err(), "an absurd push did not diverge");
    let after = (planar.state().clone(), planar.phase(), planar.model().colliders()[0]);
    assert_eq!(format!("{before:?}"), format!("{after:?}"));

    let mut w =
        Walker3d::new(settings(false), Gait::default_3d(), Coronal::default(), 0.3).unwrap();
    w.add_collider(moving_ground(DVec3::ZERO).shape, None).unwrap();
    w.set_collider(0, moving_ground(v)).unwrap();
    w.step(DT, 500).unwrap();
    let (model, state) = w.parts_mut();
    state.push(model, TORSO_3D, DVec3::new(0.0, 1e12, 0.0), 1.0).unwrap();
    let before = (w.state().clone(), w.phase(), w.model().colliders()[0]);
    assert!(w.step(DT, 200).is_err(), "an absurd push did not diverge");
    let after = (w.state().clone(), w.phase(), w.model().colliders()[0]);
    assert_eq!(format!("{before:?}"), format!("{after:?}"));
}
