//! The collision shapes, placed in the world (metres), and their validation.
//!
//! A shape is only geometry; what a contact with it does (restitution, friction) is its
//! [`Material`](super::Material), and how it moves is up to the system that holds it. Every
//! shape is checked once, when a system takes it ([`Shape::checked`]), with one message per
//! mistake naming the argument.

use crate::error::{Error, Result};
use glam::{DQuat, DVec3};

/// The plane through `point` with unit `normal`; the side `normal` points to is free, the
/// other side is solid.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// A point of the plane (m).
    pub point: DVec3,
    /// Normal towards the free side (made unit by [`Shape::checked`]).
    pub normal: DVec3,
}

/// A solid ball.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre (m).
    pub center: DVec3,
    /// Radius (m) > 0.
    pub radius: f64,
}

/// A solid capsule: the points within `radius` of the segment `a`–`b`.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Capsule {
    /// One end of the axis (m).
    pub a: DVec3,
    /// The other end of the axis (m); may equal `a` (a ball).
    pub b: DVec3,
    /// Radius (m) > 0.
    pub radius: f64,
}

/// A solid box (rectangular cuboid).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Cuboid {
    /// Centre (m).
    pub center: DVec3,
    /// Orientation (body → world, unit quaternion).
    pub rotation: DQuat,
    /// Half extents along the box's own axes (m), each > 0.
    pub half: DVec3,
}

/// One of the collision shapes.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A plane (half-space).
    Plane(Plane),
    /// A ball.
    Sphere(Sphere),
    /// A capsule.
    Capsule(Capsule),
    /// A box.
    Box(Cuboid),
}

fn finite(arg: &str, shape: &str, v: DVec3) -> Result<()> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(Error::invalid(arg, format!("a {shape} collider needs finite coordinates")))
    }
}

fn radius(shape: &str, r: f64) -> Result<()> {
    if r.is_finite() && r > 0.0 {
        Ok(())
    } else {
        Err(Error::invalid(
            "radius",
            format!("a {shape} collider needs a positive, finite radius, got {r}"),
        ))
    }
}

impl Shape {
    /// The shape, checked, with a plane's normal made unit.
    ///
    /// # Errors
    /// Each mistake named by its argument: a non-finite `point`, `center`, `a` or `b`; a zero
    /// or non-finite `normal`; a non-positive or non-finite `radius` or `half_extents`; an
    /// `orientation` that is not a unit quaternion.
    pub fn checked(self) -> Result<Shape> {
        match self {
            Shape::Plane(Plane { point, normal }) => {
                finite("point", "plane", point)?;
                if !(normal.is_finite() && normal.length() > 0.0) {
                    return Err(Error::invalid(
                        "normal",
                        "a plane collider needs a finite, non-zero normal",
                    ));
                }
                Ok(Shape::Plane(Plane { point, normal: normal.normalize() }))
            }
            Shape::Sphere(Sphere { center, radius: r }) => {
                finite("center", "sphere", center)?;
                radius("sphere", r)?;
                Ok(self)
            }
            Shape::Capsule(Capsule { a, b, radius: r }) => {
                finite("a", "capsule", a)?;
                finite("b", "capsule", b)?;
                radius("capsule", r)?;
                Ok(self)
            }
            Shape::Box(Cuboid { center, rotation, half }) => {
                finite("center", "box", center)?;
                if !(half.is_finite() && half.min_element() > 0.0) {
                    return Err(Error::invalid(
                        "half_extents",
                        "a box collider needs positive, finite half extents",
                    ));
                }
                if !(rotation.is_finite() && (rotation.length() - 1.0).abs() < 1e-9) {
                    return Err(Error::invalid("orientation", "must be a unit quaternion"));
                }
                Ok(self)
            }
        }
    }

    /// The point a shape turns about: a plane's point, a sphere's or a box's centre, a
    /// capsule's axis midpoint (m).
    pub fn centre(&self) -> DVec3 {
        match *self {
            Shape::Plane(p) => p.point,
            Shape::Sphere(s) => s.center,
            Shape::Capsule(c) => 0.5 * (c.a + c.b),
            Shape::Box(b) => b.center,
        }
    }

    /// The shape turned by the unit quaternion `q` about [`Shape::centre`].
    pub fn turned(&self, q: DQuat) -> Shape {
        let c = self.centre();
        match *self {
            Shape::Plane(p) => Shape::Plane(Plane { normal: q * p.normal, ..p }),
            Shape::Sphere(_) => *self,
            Shape::Capsule(k) => {
                Shape::Capsule(Capsule { a: c + q * (k.a - c), b: c + q * (k.b - c), ..k })
            }
            Shape::Box(b) => Shape::Box(Cuboid { rotation: (q * b.rotation).normalize(), ..b }),
        }
    }

    /// The shape translated by `d` (m).
    pub fn translated(&self, d: DVec3) -> Shape {
        match *self {
            Shape::Plane(p) => Shape::Plane(Plane { point: p.point + d, ..p }),
            Shape::Sphere(s) => Shape::Sphere(Sphere { center: s.center + d, ..s }),
            Shape::Capsule(c) => Shape::Capsule(Capsule { a: c.a + d, b: c.b + d, ..c }),
            Shape::Box(b) => Shape::Box(Cuboid { center: b.center + d, ..b }),
        }
    }
}

impl From<Plane> for Shape {
    fn from(p: Plane) -> Shape {
        Shape::Plane(p)
    }
}

impl From<Sphere> for Shape {
    fn from(s: Sphere) -> Shape {
        Shape::Sphere(s)
    }
}

impl From<Capsule> for Shape {
    fn from(c: Capsule) -> Shape {
        Shape::Capsule(c)
    }
}

impl From<Cuboid> for Shape {
    fn from(b: Cuboid) -> Shape {
        Shape::Box(b)
    }
}
