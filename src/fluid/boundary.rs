//! Solid walls as boundary particles (Akinci et al. 2012, "Versatile rigid-fluid coupling for
//! incompressible SPH", sec. 3): a wall's surface is sampled by one layer of particles about
//! one fluid spacing apart; each gets the volume `V_b = 1 / Σ_k W(x_b - x_k)` over the
//! boundary particles `k` near it (itself included; their eq. 4, `ψ_b = ρ₀ V_b`), so densely or
//! unevenly sampled walls push no harder than evenly sampled ones.
//!
//! One such layer adds `P(d) / P(0)` to the density ratio of a fluid particle at distance `d`,
//! with `P(d)` the sum of `W` over a plane lattice at distance `d`. Fluid on a lattice whose
//! first layer is half a spacing from the wall misses only the layers a lattice continued
//! behind the wall would give (`V (P(s) + P(2s))`, 0.15 for the cubic spline): a layer on the
//! wall itself gives 0.70 and would push that fluid hard. So the layer is put a distance `o`
//! behind the wall's surface ([`offset`], bisected once per model: 0.6 spacing for the cubic
//! spline) such that fluid at rest against the wall has the rest density.
//!
//! Each wall also keeps the fluid on its side as a last resort: a fluid particle that a step
//! carries through it is put back on the inner side and loses its velocity into the wall
//! ([`Wall::confine`]). The pressure of the boundary particles normally keeps the fluid half a
//! spacing away, so this acts only on particles the pressure solve could not stop.

use super::Kernel;
use crate::error::{Error, Result};
use crate::geometry::grid::Grid;
use glam::DVec3;

/// A wall that bounds the fluid.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub enum Wall {
    /// The inside of the axis-aligned box `[lower, upper]` (m): a closed tank.
    Box {
        /// Lowest corner (m).
        lower: DVec3,
        /// Highest corner (m).
        upper: DVec3,
    },
    /// The square `|t| ≤ half_extent` about `point` in the plane of unit `normal`; the fluid
    /// stays on the side the normal points to.
    Plane {
        /// A point of the plane, the square's centre (m).
        point: DVec3,
        /// Unit normal towards the fluid.
        normal: DVec3,
        /// Half the side of the square (m).
        half_extent: f64,
    },
}

impl Wall {
    /// Sample the wall with particles about `spacing` apart (m), `offset` (m) behind its
    /// surface, appending them to `out`.
    pub(super) fn sample(&self, spacing: f64, offset: f64, out: &mut Vec<DVec3>) {
        match *self {
            Wall::Box { lower, upper } => shell(lower - offset, upper + offset, spacing, out),
            Wall::Plane { point, normal, half_extent } => {
                let t1 = normal.any_orthonormal_vector();
                let t2 = normal.cross(t1);
                let n = (2.0 * half_extent / spacing).ceil().max(1.0) as usize;
                let step = 2.0 * half_extent / n as f64;
                let point = point - normal * offset;
                for j in 0..=n {
                    for i in 0..=n {
                        let (a, b) = (i as f64 * step - half_extent, j as f64 * step - half_extent);
                        out.push(point + t1 * a + t2 * b);
                    }
                }
            }
        }
    }

    /// Whether `p` is on the fluid's side of the wall, at least `margin` (m) inside.
    pub(super) fn contains(&self, p: DVec3, margin: f64) -> bool {
        match *self {
            Wall::Box { lower, upper } => {
                p.cmpge(lower + margin).all() && p.cmple(upper - margin).all()
            }
            Wall::Plane { point, normal, .. } => (p - point).dot(normal) >= margin,
        }
    }

    /// Put `x` back `margin` (m) inside the wall if it is not, removing the velocity `v`'s
    /// component into the wall (a box: per axis; a plane: only within its square and up to
    /// `8 margin` behind it, so fluid that fell past the square's edge is left alone).
    pub(super) fn confine(&self, x: &mut DVec3, v: &mut DVec3, margin: f64) {
        match *self {
            Wall::Box { lower, upper } => {
                let (lo, hi) = ((lower + margin).to_array(), (upper - margin).to_array());
                let (mut xa, mut va) = (x.to_array(), v.to_array());
                for a in 0..3 {
                    if xa[a] < lo[a] {
                        xa[a] = lo[a];
                        va[a] = va[a].max(0.0);
                    } else if xa[a] > hi[a] {
                        xa[a] = hi[a];
                        va[a] = va[a].min(0.0);
                    }
                }
                (*x, *v) = (DVec3::from_array(xa), DVec3::from_array(va));
            }
            Wall::Plane { point, normal, half_extent } => {
                let d = *x - point;
                let depth = d.dot(normal);
                let tangent = d - normal * depth;
                if depth < margin
                    && depth > -8.0 * margin
                    && tangent.abs().max_element() <= half_extent
                {
                    *x += normal * (margin - depth);
                    *v -= normal * v.dot(normal).min(0.0);
                }
            }
        }
    }

    /// Check the wall's description against the fluid's `spacing` (m).
    pub(super) fn validate(&self, spacing: f64) -> Result<()> {
        match *self {
            Wall::Box { lower, upper } => {
                if !lower.is_finite() || !upper.is_finite() {
                    return Err(Error::invalid("lower", "the box corners must be finite"));
                }
                if (upper - lower).min_element() < 2.0 * spacing {
                    return Err(Error::invalid(
                        "upper",
                        "the box must be at least two spacings wide along every axis",
                    ));
                }
            }
            Wall::Plane { point, normal, half_extent } => {
                if !point.is_finite() {
                    return Err(Error::invalid("point", "must be finite"));
                }
                if !normal.is_finite() || (normal.length() - 1.0).abs() > 1e-9 {
                    return Err(Error::invalid("normal", "must be a finite unit vector"));
                }
                if !(half_extent.is_finite() && half_extent >= spacing) {
                    return Err(Error::invalid(
                        "half_extent",
                        "must be finite and at least the particle spacing",
                    ));
                }
            }
        }
        Ok(())
    }
}

/// Sample the surface of the box `[lower, upper]` (m) on a lattice about `spacing` apart
/// (m), every face's points and the edges' once, appending them to `out`.
pub(super) fn shell(lower: DVec3, upper: DVec3, spacing: f64, out: &mut Vec<DVec3>) {
    let size = upper - lower;
    let count = |l: f64| (l / spacing).ceil().max(1.0) as usize;
    let n = [count(size.x), count(size.y), count(size.z)];
    let step = size / DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
    for k in 0..=n[2] {
        for j in 0..=n[1] {
            // Inner lattice points only on the two x faces.
            let on_yz = k == 0 || k == n[2] || j == 0 || j == n[1];
            let stride = if on_yz { 1 } else { n[0].max(1) };
            let mut i = 0;
            while i <= n[0] {
                out.push(lower + DVec3::new(i as f64, j as f64, k as f64) * step);
                i += stride;
            }
        }
    }
}

/// Akinci's volumes `V_b = 1 / Σ_k W(x_b - x_k)` (m³) of the boundary particles `points`, for
/// `kernel` of support `h` (m), written into `volumes`.
pub(super) fn volumes(points: &[DVec3], kernel: Kernel, h: f64, volumes: &mut Vec<f64>) {
    let mut grid = Grid::default();
    grid.build(points, points.len(), h);
    volumes.clear();
    volumes.extend((0..points.len()).map(|b| {
        let sum: f64 = kernel.value(0.0, h)
            + grid
                .neighbours(b)
                .iter()
                .map(|&k| kernel.value((points[b] - points[k as usize]).length(), h))
                .sum::<f64>();
        1.0 / sum
    }));
}

/// The distance (m) behind a wall's surface at which one layer of boundary particles gives
/// fluid at rest against the wall (first layer half a `spacing` inside) the rest density:
/// the root of `P(s/2 + o) / P(0) = V (P(s) + P(2s))` (module docs), by bisection on
/// `[0, 2s]`; `volume` is the fluid particle's (m³), `h` the support (m).
pub(super) fn offset(kernel: Kernel, spacing: f64, h: f64, volume: f64) -> f64 {
    let plane = |d: f64| {
        let mut sum = 0.0;
        for j in -2i32..=2 {
            for i in -2i32..=2 {
                let t = spacing * f64::from(i * i + j * j).sqrt();
                sum += kernel.value((t * t + d * d).sqrt(), h);
            }
        }
        sum
    };
    let missing = volume * (plane(spacing) + plane(2.0 * spacing));
    let (mut lo, mut hi) = (0.0, 2.0 * spacing);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if plane(0.5 * spacing + mid) / plane(0.0) > missing {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}
