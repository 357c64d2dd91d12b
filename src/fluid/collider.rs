//! Colliders: the shared collision shapes (`geometry::Shape`: sphere, capsule, box) as solid
//! obstacles in the fluid, fixed or moving with a rigid body (one-way coupling: the fluid
//! feels the body, the body not the fluid).
//!
//! A collider is sampled once, in its own frame, by one layer of boundary particles about one
//! spacing apart, the model's wall offset behind its surface (as the walls, see the
//! `boundary` module), each with Akinci et al. 2012's volume `V_b = 1 / Σ_k W(x_b - x_k)`
//! over the collider's own particles (their sec. 4: every rigid body's volumes over its own
//! particles, so they do not change as it moves). Frames: a sphere's is its centre (a ball
//! needs no orientation), a capsule's its axis' midpoint with `+Y` turned onto `b - a`, a
//! box's its centre and orientation.
//!
//! Its pose is state ([`super::State`]): [`super::State::set_collider`] puts it anywhere
//! between steps (a scene sets a rigid body's pose each frame), and each substep moves it by
//! its `velocity` times the substep. Its boundary particles carry that velocity into the
//! DFSPH solves (Akinci et al. 2012, eq. 10's `v_i - v_b`), so a moving body pushes the
//! fluid before it reaches it; as the walls, a collider puts fluid the pressure could not
//! stop back outside it, a quarter spacing from its surface, and removes the velocity into
//! it relative to the body ([`confine`]).

use super::boundary::shell;
use crate::error::{Error, Result};
use crate::geometry::Shape;
use glam::{DQuat, DVec3};

/// A collider in the fluid: a shape where it is now and the velocity it moves at.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Collider {
    /// The solid (m): a sphere, capsule or box (an unbounded plane cannot be sampled: use a
    /// [`super::Wall::Plane`]).
    pub shape: Shape,
    /// Its velocity (m/s): each substep moves it by `velocity · dt`, and its boundary
    /// particles carry it.
    pub velocity: DVec3,
}

/// What the model keeps of a collider: its shape as added (its size; the pose is state) and
/// its boundary particles in its own frame with their volumes.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub(super) struct Body {
    /// The shape as added (m).
    pub(super) shape: Shape,
    /// Boundary particles in the collider's frame (m).
    pub(super) points: Vec<DVec3>,
}

impl Collider {
    /// The collider checked ([`Shape::checked`]) and sized against the fluid's `spacing`
    /// (m): a sphere or capsule of radius at least the spacing, a box of half extents at
    /// least the spacing (the boundary layer lies `offset` < spacing behind the surface).
    ///
    /// # Errors
    /// Those of [`Shape::checked`]; a plane (`shape`); a size under the spacing (`radius`,
    /// `half_extents`); a non-finite velocity (`velocity`).
    pub(super) fn checked(self, spacing: f64) -> Result<Collider> {
        let shape = self.shape.checked()?;
        match shape {
            Shape::Plane(_) => {
                return Err(Error::invalid(
                    "shape",
                    "an unbounded plane cannot be sampled by particles: use \
                     add_boundary_plane(point, normal, half_extent)",
                ))
            }
            Shape::Sphere(s) if s.radius < spacing => {
                return Err(Error::invalid("radius", "must be at least the particle spacing"))
            }
            Shape::Capsule(c) if c.radius < spacing => {
                return Err(Error::invalid("radius", "must be at least the particle spacing"))
            }
            Shape::Box(b) if b.half.min_element() < spacing => {
                return Err(Error::invalid(
                    "half_extents",
                    "must each be at least the particle spacing",
                ))
            }
            _ => {}
        }
        if !self.velocity.is_finite() {
            return Err(Error::invalid("velocity", "must be finite"));
        }
        Ok(Collider { shape, velocity: self.velocity })
    }
}

/// The collider's frame: origin (m) and rotation (body → world).
fn frame(shape: &Shape) -> (DVec3, DQuat) {
    match *shape {
        Shape::Sphere(s) => (s.center, DQuat::IDENTITY),
        Shape::Capsule(c) => {
            let axis = c.b - c.a;
            let turn = if axis.length() > 0.0 {
                DQuat::from_rotation_arc(DVec3::Y, axis.normalize())
            } else {
                DQuat::IDENTITY
            };
            (0.5 * (c.a + c.b), turn)
        }
        Shape::Box(b) => (b.center, b.rotation),
        Shape::Plane(p) => (p.point, DQuat::IDENTITY),
    }
}

/// Whether `b` is `a` moved: the same kind and size (within 1e-9 relative), any pose; a
/// capsule may change its length (a motion-captured bone's varies from frame to frame: see
/// [`place`]).
pub(super) fn same_body(a: &Shape, b: &Shape) -> bool {
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-9 * x.abs().max(y.abs());
    match (a, b) {
        (Shape::Sphere(a), Shape::Sphere(b)) => close(a.radius, b.radius),
        (Shape::Capsule(a), Shape::Capsule(b)) => close(a.radius, b.radius),
        (Shape::Box(a), Shape::Box(b)) => (0..3).all(|k| close(a.half[k], b.half[k])),
        _ => false,
    }
}

/// Points on the sphere of `radius` (m) about the origin, about `spacing` (m) apart: the
/// golden-angle spiral (Fibonacci lattice; González 2010, "Measurement of areas on a sphere
/// using Fibonacci and latitude-longitude lattices"), one point per `spacing²` of area.
fn fibonacci(radius: f64, spacing: f64, out: &mut Vec<DVec3>) {
    let area = 4.0 * std::f64::consts::PI * radius * radius;
    let n = (area / (spacing * spacing)).ceil().max(4.0) as usize;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for i in 0..n {
        let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let r = (1.0 - y * y).sqrt();
        let phi = golden * i as f64;
        out.push(DVec3::new(r * phi.cos(), y, r * phi.sin()) * radius);
    }
}

/// The boundary particles of `shape` (checked by [`Collider::checked`]) in its frame (m),
/// about `spacing` apart, `offset` (m) behind its surface.
pub(super) fn sample(shape: &Shape, spacing: f64, offset: f64) -> Vec<DVec3> {
    let mut out = Vec::new();
    match *shape {
        Shape::Sphere(s) => fibonacci(s.radius - offset, spacing, &mut out),
        Shape::Capsule(c) => {
            // The two half spheres at the ends, rings between them.
            let (r, half) = (c.radius - offset, 0.5 * (c.b - c.a).length());
            fibonacci(r, spacing, &mut out);
            for p in &mut out {
                p.y += if p.y >= 0.0 { half } else { -half };
            }
            let rings = (2.0 * half / spacing).ceil() as usize;
            let count = (std::f64::consts::TAU * r / spacing).ceil().max(3.0) as usize;
            for k in 1..rings {
                let y = -half + 2.0 * half * k as f64 / rings as f64;
                for i in 0..count {
                    let phi =
                        std::f64::consts::TAU * (i as f64 + 0.5 * (k % 2) as f64) / count as f64;
                    out.push(DVec3::new(r * phi.cos(), y, r * phi.sin()));
                }
            }
        }
        Shape::Box(b) => {
            let half = b.half - offset;
            shell(-half, half, spacing, &mut out);
        }
        Shape::Plane(_) => {}
    }
    out
}

/// `body`'s boundary particles at `collider`'s pose (m), appended to `out`. A capsule of
/// another length than sampled keeps its half spheres' particles at its ends and stretches
/// its rings' spacing (their volumes unchanged).
pub(super) fn place(body: &Body, collider: &Collider, out: &mut Vec<DVec3>) {
    let (origin, turn) = frame(&collider.shape);
    if let (Shape::Capsule(was), Shape::Capsule(now)) = (body.shape, collider.shape) {
        let (h0, h1) = (0.5 * (was.b - was.a).length(), 0.5 * (now.b - now.a).length());
        out.extend(body.points.iter().map(|&p| {
            // Half-sphere particles lie at |y| >= h0, ring particles strictly inside.
            let y = if p.y.abs() >= h0 { p.y + (h1 - h0).copysign(p.y) } else { p.y * h1 / h0 };
            origin + turn * DVec3::new(p.x, y, p.z)
        }));
        return;
    }
    out.extend(body.points.iter().map(|&p| origin + turn * p));
}

/// Put `x` back `margin` (m) outside the collider if it is closer to (or inside) it, removing
/// the velocity `v`'s component into it relative to the collider's velocity.
pub(super) fn confine(collider: &Collider, x: &mut DVec3, v: &mut DVec3, margin: f64) {
    let (d, n) = collider.shape.distance(*x);
    if d < margin {
        *x += n * (margin - d);
        let into = (*v - collider.velocity).dot(n);
        if into < 0.0 {
            *v -= n * into;
        }
    }
}
