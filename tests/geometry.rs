//! The shared collision shapes: distances against closed forms, closest points on the surface,
//! and one message per mistake naming the argument.

use glam::{DQuat, DVec3};
use kinema::geometry::{Capsule, Cuboid, Material, Plane, Shape, Sphere};
use kinema::Error;

fn arg_of(e: Error) -> String {
    match e {
        Error::InvalidInput { arg, .. } => arg,
        other => panic!("expected InvalidInput, got {other:?}"),
    }
}

#[test]
fn distances_match_the_closed_forms() {
    let p = DVec3::new(1.0, 2.0, -0.5);
    let plane = Shape::Plane(Plane { point: DVec3::new(0.0, 0.5, 0.0), normal: DVec3::Y });
    assert_eq!(plane.distance(p), (1.5, DVec3::Y));
    let sphere = Shape::Sphere(Sphere { center: DVec3::new(1.0, 0.0, -0.5), radius: 0.5 });
    assert_eq!(sphere.distance(p), (1.5, DVec3::Y));
    // Inside: negative, normal towards the nearest surface point.
    let (d, n) = sphere.distance(DVec3::new(1.3, 0.0, -0.5));
    assert!((d + 0.2).abs() < 1e-15 && (n - DVec3::X).length() < 1e-15, "{d} {n}");
    // The centre, where every direction is nearest: +Y.
    assert_eq!(sphere.distance(DVec3::new(1.0, 0.0, -0.5)), (-0.5, DVec3::Y));
    // A capsule: the ball around the nearest axis point, clamped to the ends.
    let capsule =
        Shape::Capsule(Capsule { a: DVec3::ZERO, b: DVec3::new(2.0, 0.0, 0.0), radius: 0.25 });
    assert_eq!(capsule.distance(DVec3::new(1.0, 1.0, 0.0)), (0.75, DVec3::Y));
    assert_eq!(capsule.distance(DVec3::new(3.0, 0.0, 0.0)), (0.75, DVec3::X));
    let ball = Shape::Capsule(Capsule { a: DVec3::ONE, b: DVec3::ONE, radius: 1.0 });
    assert_eq!(ball.distance(DVec3::new(1.0, 1.0, 3.0)), (1.0, DVec3::Z));
    // A box turned by 90° about Y: its x half extent lies along world z.
    let turn = DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2);
    let cuboid = Shape::Box(Cuboid {
        center: DVec3::ZERO,
        rotation: turn,
        half: DVec3::new(2.0, 0.5, 0.25),
    });
    let (d, n) = cuboid.distance(DVec3::new(0.0, 0.0, 3.0));
    assert!((d - 1.0).abs() < 1e-12 && (n - DVec3::Z).length() < 1e-12, "{d} {n}");
    // Beyond a corner: the distance to the corner.
    let (d, _) = cuboid.distance(DVec3::new(1.25, 1.5, 3.0));
    assert!((d - 3f64.sqrt()).abs() < 1e-12, "{d}");
    // Inside: the nearest face.
    let (d, n) = cuboid.distance(DVec3::new(0.0, 0.4, 0.0));
    assert!((d + 0.1).abs() < 1e-12 && (n - DVec3::Y).length() < 1e-12, "{d} {n}");
}

#[test]
fn closest_points_lie_on_the_surface() {
    let shapes = [
        Shape::Plane(Plane {
            point: DVec3::new(0.1, -0.2, 0.3),
            normal: DVec3::new(0.2, 1.0, -0.1),
        })
        .checked()
        .unwrap(),
        Shape::Sphere(Sphere { center: DVec3::new(0.5, 0.2, -0.1), radius: 0.7 }),
        Shape::Capsule(Capsule { a: DVec3::new(-1.0, 0.0, 0.2), b: DVec3::Y, radius: 0.3 }),
        Shape::Box(Cuboid {
            center: DVec3::new(0.2, 0.1, 0.0),
            rotation: DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1),
            half: DVec3::new(0.3, 0.6, 0.2),
        }),
    ];
    for shape in shapes {
        let mut inside = 0;
        for k in 0..100 {
            let t = k as f64;
            // From well inside every solid (a tenth of the scale) to well outside.
            let scale = 0.15 * (k % 10 + 1) as f64;
            let p = DVec3::new((1.7 * t).sin(), (2.3 * t).cos(), (0.9 * t).sin()) * scale;
            let (d, n) = shape.distance(p);
            assert!((n.length() - 1.0).abs() < 1e-12, "{shape:?} {p}");
            let q = shape.closest_point(p);
            assert!(shape.distance(q).0.abs() < 1e-12, "{shape:?} {p}: {q}");
            assert!(((p - q).length() - d.abs()).abs() < 1e-12, "{shape:?} {p}");
            inside += usize::from(d < 0.0);
        }
        assert!(inside >= 5, "{shape:?}: {inside} points inside");
    }
}

#[test]
fn translation_moves_the_distance_field() {
    let d = DVec3::new(0.3, -1.0, 2.0);
    let shapes = [
        Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::Y }),
        Shape::Sphere(Sphere { center: DVec3::ONE, radius: 0.5 }),
        Shape::Capsule(Capsule { a: DVec3::ZERO, b: DVec3::X, radius: 0.2 }),
        Shape::Box(Cuboid { center: DVec3::ZERO, rotation: DQuat::IDENTITY, half: DVec3::ONE }),
    ];
    let p = DVec3::new(0.7, 0.4, -0.3);
    for s in shapes {
        let (a, na) = s.distance(p);
        let (b, nb) = s.translated(d).distance(p + d);
        assert!((a - b).abs() < 1e-12 && (na - nb).length() < 1e-12, "{s:?}");
    }
}

#[test]
fn each_mistake_is_named_and_planes_are_made_unit() {
    let bad = |s: Shape| arg_of(s.checked().unwrap_err());
    let nan = DVec3::new(f64::NAN, 0.0, 0.0);
    assert_eq!(bad(Shape::Plane(Plane { point: nan, normal: DVec3::Y })), "point");
    assert_eq!(bad(Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::ZERO })), "normal");
    assert_eq!(bad(Shape::Sphere(Sphere { center: nan, radius: 1.0 })), "center");
    assert_eq!(bad(Shape::Sphere(Sphere { center: DVec3::ZERO, radius: 0.0 })), "radius");
    assert_eq!(bad(Shape::Sphere(Sphere { center: DVec3::ZERO, radius: f64::INFINITY })), "radius");
    assert_eq!(bad(Shape::Capsule(Capsule { a: nan, b: DVec3::ZERO, radius: 1.0 })), "a");
    assert_eq!(bad(Shape::Capsule(Capsule { a: DVec3::ZERO, b: nan, radius: 1.0 })), "b");
    assert_eq!(
        bad(Shape::Capsule(Capsule { a: DVec3::ZERO, b: DVec3::X, radius: -1.0 })),
        "radius"
    );
    let unit = DQuat::IDENTITY;
    assert_eq!(bad(Shape::Box(Cuboid { center: nan, rotation: unit, half: DVec3::ONE })), "center");
    let flat = DVec3::new(1.0, 0.0, 1.0);
    assert_eq!(
        bad(Shape::Box(Cuboid { center: DVec3::ZERO, rotation: unit, half: flat })),
        "half_extents"
    );
    let long = DQuat::from_xyzw(0.0, 0.0, 0.0, 2.0);
    assert_eq!(
        bad(Shape::Box(Cuboid { center: DVec3::ZERO, rotation: long, half: DVec3::ONE })),
        "orientation"
    );
    let plane = Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::new(0.0, 3.0, 4.0) });
    let Shape::Plane(Plane { normal, .. }) = plane.checked().unwrap() else { panic!() };
    assert!((normal - DVec3::new(0.0, 0.6, 0.8)).length() < 1e-15, "{normal}");
    let material = |restitution, friction| Material { restitution, friction }.checked();
    assert_eq!(arg_of(material(1.5, 0.0).unwrap_err()), "restitution");
    assert_eq!(arg_of(material(f64::NAN, 0.0).unwrap_err()), "restitution");
    assert_eq!(arg_of(material(0.5, -0.1).unwrap_err()), "friction");
    assert_eq!(arg_of(material(0.5, f64::INFINITY).unwrap_err()), "friction");
    assert!(material(0.0, 0.0).is_ok() && material(1.0, 2.0).is_ok());
}

/// The deepest point of a segment in a shape is where the signed distance along it is least:
/// checked against 20,001 samples of the segment for every shape, on segments crossing a
/// box's edge and corner, lying in it, missing it, and crossing the other shapes.
#[test]
fn the_deepest_point_of_a_segment_is_the_least_distance_along_it() {
    let shapes = [
        Shape::Box(Cuboid {
            center: DVec3::new(0.1, -0.2, 0.3),
            rotation: DQuat::from_rotation_y(0.4) * DQuat::from_rotation_x(0.3),
            half: DVec3::new(0.5, 0.2, 0.3),
        }),
        Shape::Sphere(Sphere { center: DVec3::new(0.2, 0.1, 0.0), radius: 0.3 }),
        Shape::Capsule(Capsule { a: DVec3::new(-0.4, 0.0, 0.2), b: DVec3::Z, radius: 0.1 }),
        Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::new(0.3, 1.0, -0.2).normalize() }),
    ];
    let segments = [
        (DVec3::new(-1.0, 0.3, -0.2), DVec3::new(1.2, -0.1, 0.9)),
        (DVec3::new(0.7, 0.5, 0.6), DVec3::new(-0.2, -0.6, -0.4)),
        (DVec3::new(0.0, 0.9, 0.0), DVec3::new(0.3, 1.4, 0.1)),
        (DVec3::new(0.05, -0.2, 0.3), DVec3::new(0.15, -0.2, 0.3)),
        (DVec3::new(-2.0, -0.35, 0.0), DVec3::new(2.0, 0.2, 0.6)),
    ];
    for shape in shapes {
        for (a, b) in segments {
            let t = shape.deepest_on_segment(a, b);
            assert!((0.0..=1.0).contains(&t));
            let found = shape.distance(a.lerp(b, t)).0;
            let sampled = (0..=20_000)
                .map(|k| shape.distance(a.lerp(b, k as f64 / 20_000.0)).0)
                .fold(f64::INFINITY, f64::min);
            assert!(found <= sampled + 1e-12, "{shape:?} {a} {b}: {found} > {sampled}");
            assert!(found > sampled - 2.0 * a.distance(b) / 20_000.0, "{found} vs {sampled}");
        }
    }
}
