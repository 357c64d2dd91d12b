//! The collision shapes from Python: a kind and a flat list of parameters, as every
//! `kinema.geometry` class gives them (`Shape._params`).

use crate::error::Error;
use crate::geometry::{Capsule, Cuboid, Plane, Shape, Sphere};
use glam::{DQuat, DVec3};
use pyo3::prelude::*;

/// The shape of `kind` from the head of `p` — `plane` (point 3, normal 3), `sphere` (centre 3,
/// radius), `capsule` (a 3, b 3, radius) or `box` (centre 3, orientation w x y z, half extents
/// 3) — and the `tail` parameters after it (the system's own: material, velocity...).
pub(crate) fn shape<'a>(kind: &str, p: &'a [f64], tail: usize) -> PyResult<(Shape, &'a [f64])> {
    let need = match kind {
        "plane" => 6,
        "sphere" => 4,
        "capsule" => 7,
        "box" => 10,
        _ => return Err(Error::invalid("collider", "unknown kind of collider").into()),
    };
    if p.len() != need + tail {
        let reason = format!("expected {} parameters, got {}", need + tail, p.len());
        return Err(Error::invalid("collider", reason).into());
    }
    let v = |k: usize| DVec3::new(p[k], p[k + 1], p[k + 2]);
    let shape = match kind {
        "plane" => Shape::Plane(Plane { point: v(0), normal: v(3) }),
        "sphere" => Shape::Sphere(Sphere { center: v(0), radius: p[3] }),
        "capsule" => Shape::Capsule(Capsule { a: v(0), b: v(3), radius: p[6] }),
        _ => Shape::Box(Cuboid {
            center: v(0),
            rotation: DQuat::from_xyzw(p[4], p[5], p[6], p[3]),
            half: v(7),
        }),
    };
    Ok((shape, &p[need..]))
}

/// The kind and parameters of `shape`, laid out as [`shape`] reads them.
pub(crate) fn params(shape: &Shape) -> (&'static str, Vec<f64>) {
    match *shape {
        Shape::Plane(p) => ("plane", [p.point.to_array(), p.normal.to_array()].concat()),
        Shape::Sphere(s) => ("sphere", [&s.center.to_array()[..], &[s.radius]].concat()),
        Shape::Capsule(c) => {
            ("capsule", [&c.a.to_array()[..], &c.b.to_array(), &[c.radius]].concat())
        }
        Shape::Box(b) => {
            let r = b.rotation;
            let q = [r.w, r.x, r.y, r.z];
            ("box", [&b.center.to_array()[..], &q, &b.half.to_array()].concat())
        }
    }
}
