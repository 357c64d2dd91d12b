//! Narrow phases of rigid contacts: the points of a body that can touch a plane first, and
//! the contacts between two placed shapes — sphere–sphere, sphere–box (closest point),
//! box–box (separating axes of Gottschalk et al. 1996, the incident face clipped against the
//! reference face as Box2D and ODE do, reduced to four points after Gregorius 2015; edge on
//! edge by closest points), capsules as swept spheres (the closest points of their segments,
//! [`crate::geometry::segment`], and the segment ends and middle against a box). Cylinders
//! and meshes collide with planes only.

use crate::geometry::segment::{closest_point_on_segment, closest_points_of_segments};
use crate::geometry::Solid;
use glam::{DQuat, DVec3};

/// The points of `shape` (body frame, about the body origin) that can touch a plane of
/// normal `n` first, in world coordinates for a body at `origin` turned by `orient`.
///
/// Spheres and capsules give their lowest surface point(s); boxes their corners; meshes their
/// vertices; a cylinder the lowest point of each rim, and three more rim points per cap when
/// the cap lies within 5° of the plane (so it can stand on it).
pub(crate) fn candidate_points(
    shape: &Solid,
    origin: DVec3,
    orient: DQuat,
    n: DVec3,
    out: &mut Vec<DVec3>,
) {
    let world = |p: DVec3| origin + orient * p;
    match shape {
        Solid::Sphere { radius } => out.push(origin - *radius * n),
        Solid::Capsule { radius, height } => {
            for s in [-0.5, 0.5] {
                out.push(world(DVec3::new(0.0, s * height, 0.0)) - *radius * n);
            }
        }
        Solid::Box { half_extents } => out.extend(corners(origin, orient, *half_extents)),
        Solid::Cylinder { radius, height } => {
            let axis = orient * DVec3::Y;
            let radial = n - n.dot(axis) * axis;
            let u = if radial.length() > 1e-9 {
                -radial.normalize()
            } else {
                axis.any_orthonormal_vector()
            };
            let flat = n.dot(axis).abs() > 5f64.to_radians().cos();
            for s in [-0.5, 0.5] {
                let c = world(DVec3::new(0.0, s * height, 0.0));
                out.push(c + *radius * u);
                if flat {
                    let v = axis.cross(u);
                    out.extend([c + *radius * v, c - *radius * u, c - *radius * v]);
                }
            }
        }
        Solid::Mesh { vertices, .. } => out.extend(vertices.iter().map(|&p| world(p))),
    }
}

/// A shape placed in the world, as the narrow phase sees it.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug)]
pub(crate) enum Placed {
    Sphere {
        c: DVec3,
        r: f64,
    },
    Capsule {
        p0: DVec3,
        p1: DVec3,
        r: f64,
    },
    Box {
        c: DVec3,
        q: DQuat,
        h: DVec3,
    },
    /// Cylinders and meshes: no body–body contacts.
    Other,
}

impl Placed {
    /// `shape` (body frame about the body origin) at `origin`, turned by `orient`.
    pub fn new(shape: &Solid, origin: DVec3, orient: DQuat) -> Self {
        match shape {
            Solid::Sphere { radius } => Placed::Sphere { c: origin, r: *radius },
            Solid::Capsule { radius, height } => {
                let a = orient * DVec3::new(0.0, 0.5 * height, 0.0);
                Placed::Capsule { p0: origin - a, p1: origin + a, r: *radius }
            }
            Solid::Box { half_extents } => Placed::Box { c: origin, q: orient, h: *half_extents },
            _ => Placed::Other,
        }
    }
}

/// A contact found by a narrow phase: world point, unit normal from the second shape towards
/// the first, and signed gap (negative when they overlap).
pub(crate) type Touch = (DVec3, DVec3, f64);

fn spheres(ca: DVec3, ra: f64, cb: DVec3, rb: f64) -> Touch {
    let d = ca - cb;
    let dist = d.length();
    let n = if dist > 1e-12 { d / dist } else { DVec3::Y };
    (cb + n * rb, n, dist - ra - rb)
}

/// A sphere (centre `c`, radius `r`) against a box: the box's closest point, or the face of
/// least penetration when the centre is inside.
fn sphere_box(c: DVec3, r: f64, bc: DVec3, bq: DQuat, h: DVec3) -> Touch {
    let local = bq.conjugate() * (c - bc);
    let clamped = local.clamp(-h, h);
    if clamped != local {
        let d = local - clamped;
        let dist = d.length();
        let n = bq * (d / dist);
        (bc + bq * clamped, n, dist - r)
    } else {
        let depth = h - local.abs();
        let axis = if depth.x <= depth.y && depth.x <= depth.z {
            0
        } else if depth.y <= depth.z {
            1
        } else {
            2
        };
        let sign = if local[axis] >= 0.0 { 1.0 } else { -1.0 };
        let mut face = local;
        face[axis] = sign * h[axis];
        let n = bq * (DVec3::AXES[axis] * sign);
        (bc + bq * face, n, -depth[axis] - r)
    }
}

/// The corners of box `(c, q, h)`, corner `i` at `(±h.x, ±h.y, ±h.z)` with `+` where bit 0,
/// 1, 2 of `i` is set. Opposite corners `i` and `7 − i` share one rotation: `q (−p) = −(q p)`
/// exactly (every term of the rotation is odd in `p`), so four rotations give all eight.
fn corners(c: DVec3, q: DQuat, h: DVec3) -> [DVec3; 8] {
    let lower: [DVec3; 4] = std::array::from_fn(|i| {
        let sign = |b: usize| if i & b == 0 { -1.0 } else { 1.0 };
        q * DVec3::new(sign(1) * h.x, sign(2) * h.y, -h.z)
    });
    std::array::from_fn(|i| if i < 4 { c + lower[i] } else { c + -lower[7 - i] })
}

type PlacedBox = (DVec3, DQuat, DVec3);

/// The face of box `(c, q, h)` whose outward normal is closest to `n`: its axis index and sign.
fn face_towards(q: DQuat, n: DVec3) -> (usize, f64) {
    let local = q.conjugate() * n;
    let k = local.abs().max_position();
    (k, local[k].signum())
}

/// Box–box contacts: the separating axis of least overlap among the six face normals
/// (Gottschalk et al. 1996, faces only) gives the normal `n` (from `b` towards `a`) and the
/// reference face; the incident face of the other box (the one facing it most) is clipped
/// against the reference face's four side planes (Sutherland–Hodgman), and every clipped
/// point within `margin` of the reference plane is a contact — the manifold of Box2D and ODE.
/// When an axis `A_i × B_j` of an edge of each box separates clearly better than every face
/// (two boxes crossing edge on edge), the contact is instead the single pair of closest points
/// of those two edges (feature `16 + 3i + j`), as in ODE's `dBoxBox`.
fn box_box(a: PlacedBox, b: PlacedBox, margin: f64, out: &mut Vec<(usize, Touch)>) {
    let (ca, qa, ha) = a;
    let (cb, qb, hb) = b;
    let d = ca - cb;
    let radius = |q: DQuat, h: DVec3, l: DVec3| (q.conjugate() * l).abs().dot(h);
    // Each box's axes in the world, turned once for the face and the edge axes.
    let (axes_a, axes_b) = (DVec3::AXES.map(|e| qa * e), DVec3::AXES.map(|e| qb * e));
    // Least overlap among each box's face axes; b's face is the reference only when clearly
    // better (Box2D's tolerances), so resting contacts keep their reference face and warm
    // starting finds them again.
    let least = |axes: [DVec3; 3]| {
        axes.into_iter()
            .map(|axis| {
                let gap = d.dot(axis).abs() - radius(qa, ha, axis) - radius(qb, hb, axis);
                (gap, if d.dot(axis) >= 0.0 { axis } else { -axis })
            })
            .fold((f64::NEG_INFINITY, DVec3::Y), |best, g| if g.0 > best.0 { g } else { best })
    };
    let (from_a, from_b) = (least(axes_a), least(axes_b));
    let best = if from_b.0 > 0.95 * from_a.0 + 0.01 * ha.min_element() {
        (from_b.0, from_b.1, false)
    } else {
        (from_a.0, from_a.1, true)
    };
    let (gap, n, reference_is_a) = best;
    if gap > margin {
        return;
    }
    // Edge–edge axes; preferred over the faces only when clearly better, like b's faces.
    let mut edge = (f64::NEG_INFINITY, DVec3::Y, 0, 0);
    for (i, axis_a) in axes_a.into_iter().enumerate() {
        for (j, axis_b) in axes_b.into_iter().enumerate() {
            let axis = axis_a.cross(axis_b);
            let len = axis.length();
            if len < 1e-6 {
                continue; // parallel edges: a face axis separates as well
            }
            let axis = axis / len;
            let g = d.dot(axis).abs() - radius(qa, ha, axis) - radius(qb, hb, axis);
            if g > edge.0 {
                edge = (g, if d.dot(axis) >= 0.0 { axis } else { -axis }, i, j);
            }
        }
    }
    if edge.0 > margin {
        return; // separated along an edge axis
    }
    if edge.0 > 0.95 * gap + 0.01 * ha.min_element().min(hb.min_element()) {
        out.push(edge_contact(a, b, edge));
    } else {
        face_contacts(a, b, n, reference_is_a, margin, out);
    }
}

/// The contact of two boxes crossing edge on edge along the separating axis `(gap, n, i, j)`
/// of box `a`'s axis `i` and box `b`'s axis `j`: the midpoint of the closest points of the
/// two supporting edges (feature `16 + 3i + j`).
fn edge_contact(a: PlacedBox, b: PlacedBox, edge: (f64, DVec3, usize, usize)) -> (usize, Touch) {
    let ((ca, qa, ha), (cb, qb, hb)) = (a, b);
    let (g, n, i, j) = edge;
    // Each box's edge along its axis i (j) that lies furthest towards the other box.
    let supporting = |c: DVec3, q: DQuat, h: DVec3, k: usize, toward: DVec3| {
        let mut mid = c;
        for m in (0..3).filter(|&m| m != k) {
            let axis = q * DVec3::AXES[m];
            mid += axis * (h[m] * axis.dot(toward).signum());
        }
        let half = q * DVec3::AXES[k] * h[k];
        (mid - half, mid + half)
    };
    let (a0, a1) = supporting(ca, qa, ha, i, -n);
    let (b0, b1) = supporting(cb, qb, hb, j, n);
    let (pa, pb) = closest_points_of_segments(a0, a1, b0, b1);
    (16 + 3 * i + j, (0.5 * (pa + pb), n, g))
}

/// The face contacts of two boxes with normal `n` (from `b` towards `a`): the incident face
/// clipped against the side planes of the reference face (`a`'s when `reference_is_a`),
/// the clipped points within `margin` of it, reduced to four ([`reduce_manifold`]).
fn face_contacts(
    a: PlacedBox,
    b: PlacedBox,
    n: DVec3,
    reference_is_a: bool,
    margin: f64,
    out: &mut Vec<(usize, Touch)>,
) {
    // Reference box and its face's outward normal; the incident box.
    let ((cr, qr, hr), m, (ci, qi, hi)) = if reference_is_a { (a, -n, b) } else { (b, n, a) };
    let (k, sign) = face_towards(qr, m);
    let (j1, j2) = ((k + 1) % 3, (k + 2) % 3);
    let face_center = cr + m * hr[k];
    let (u, w) = (qr * DVec3::AXES[j1], qr * DVec3::AXES[j2]);
    debug_assert!((qr * DVec3::AXES[k] * sign - m).length() < 1e-9);
    // The incident face: the face of the other box facing the reference face most.
    let (ki, si) = face_towards(qi, -m);
    let (i1, i2) = ((ki + 1) % 3, (ki + 2) % 3);
    let fc = ci + qi * (DVec3::AXES[ki] * (si * hi[ki]));
    let (e1, e2) = (qi * DVec3::AXES[i1] * hi[i1], qi * DVec3::AXES[i2] * hi[i2]);
    let mut poly = [DVec3::ZERO; 8];
    poly[..4].copy_from_slice(&[fc - e1 - e2, fc + e1 - e2, fc + e1 + e2, fc - e1 + e2]);
    let mut len = 4;
    for (dir, extent) in [(u, hr[j1]), (-u, hr[j1]), (w, hr[j2]), (-w, hr[j2])] {
        let mut clipped = [DVec3::ZERO; 8];
        let mut count = 0;
        let dist = |p: DVec3| dir.dot(p - face_center) - extent;
        for i in 0..len {
            let (p, q) = (poly[i], poly[(i + 1) % len]);
            let (dp, dq) = (dist(p), dist(q));
            if dp <= 0.0 {
                clipped[count] = p;
                count += 1;
            }
            if ((dp < 0.0 && dq > 0.0) || (dp > 0.0 && dq < 0.0)) && count < 8 {
                clipped[count] = p + (q - p) * (dp / (dp - dq));
                count += 1;
            }
        }
        poly = clipped;
        len = count;
    }
    let first = if reference_is_a { 0 } else { 8 };
    let mut kept = [(0, DVec3::ZERO, 0.0); 8];
    let mut count = 0;
    for (i, &p) in poly[..len].iter().enumerate() {
        let g = m.dot(p - face_center);
        if g < margin {
            kept[count] = (first + i, p, g);
            count += 1;
        }
    }
    for &(k, p, g) in reduce_manifold(&mut kept[..count], m, 0.8 * u + 0.6 * w) {
        out.push((k, (p, n, g)));
    }
}

/// At most four of the clipped points `kept` (feature, point, gap) of a face manifold of
/// normal `m`, moved to the front and returned: the one furthest along `along` (a fixed
/// direction in the reference face), the one furthest from it, and the two spanning the
/// largest triangles with those on either side — the quadrilateral that holds the weight as
/// the whole polygon does, with fewer redundant contacts for the solver (Gregorius 2015,
/// "Robust contact creation for physics simulations", GDC). The first point is taken along a
/// fixed direction rather than as the deepest: depths of a resting face differ by rounding,
/// and a choice that flips between steps loses the warm start (boxes at rest in the benchmark
/// were kicked to 1e-3 m/s now and then).
fn reduce_manifold(
    kept: &mut [(usize, DVec3, f64)],
    m: DVec3,
    along: DVec3,
) -> &[(usize, DVec3, f64)] {
    if kept.len() <= 4 {
        return kept;
    }
    let argmax = |kept: &[(usize, DVec3, f64)], from: usize, f: &dyn Fn(DVec3, f64) -> f64| {
        (from..kept.len())
            .max_by(|&i, &j| f(kept[i].1, kept[i].2).total_cmp(&f(kept[j].1, kept[j].2)))
    };
    let first = argmax(kept, 0, &|p, _| p.dot(along)).unwrap_or(0);
    kept.swap(0, first);
    let p0 = kept[0].1;
    let far = argmax(kept, 1, &|p, _| (p - p0).length_squared()).unwrap_or(1);
    kept.swap(1, far);
    let edge = kept[1].1 - p0;
    let area = |p: DVec3| m.dot(edge.cross(p - p0));
    let left = argmax(kept, 2, &|p, _| area(p)).unwrap_or(2);
    kept.swap(2, left);
    let right = argmax(kept, 3, &|p, _| -area(p)).unwrap_or(3);
    kept.swap(3, right);
    &kept[..4]
}

/// Contacts between two placed shapes within `margin` (normals from `b` towards `a`), pushed
/// to `out` with a feature index each.
pub(crate) fn touches(a: &Placed, b: &Placed, margin: f64, out: &mut Vec<(usize, Touch)>) {
    let mut push = |k: usize, t: Touch| {
        if t.2 < margin {
            out.push((k, t));
        }
    };
    let flip = |(p, n, g): Touch| (p, -n, g);
    match (*a, *b) {
        (Placed::Sphere { c: ca, r: ra }, Placed::Sphere { c: cb, r: rb }) => {
            push(0, spheres(ca, ra, cb, rb))
        }
        (Placed::Sphere { c, r }, Placed::Box { c: bc, q, h }) => {
            push(0, sphere_box(c, r, bc, q, h))
        }
        (Placed::Box { c: bc, q, h }, Placed::Sphere { c, r }) => {
            push(0, flip(sphere_box(c, r, bc, q, h)))
        }
        (Placed::Box { c: ca, q: qa, h: ha }, Placed::Box { c: cb, q: qb, h: hb }) => {
            box_box((ca, qa, ha), (cb, qb, hb), margin, out)
        }
        (Placed::Capsule { p0, p1, r }, Placed::Sphere { c, r: rs }) => {
            push(0, spheres(closest_point_on_segment(p0, p1, c), r, c, rs))
        }
        (Placed::Sphere { c, r: rs }, Placed::Capsule { p0, p1, r }) => {
            push(0, spheres(c, rs, closest_point_on_segment(p0, p1, c), r))
        }
        (Placed::Capsule { p0, p1, r: ra }, Placed::Capsule { p0: q0, p1: q1, r: rb }) => {
            let (x, y) = closest_points_of_segments(p0, p1, q0, q1);
            push(0, spheres(x, ra, y, rb));
            // The ends too, so capsules lying side by side rest on two points.
            push(1, spheres(p0, ra, closest_point_on_segment(q0, q1, p0), rb));
            push(2, spheres(p1, ra, closest_point_on_segment(q0, q1, p1), rb));
        }
        (Placed::Capsule { p0, p1, r }, Placed::Box { c, q, h }) => {
            for (k, p) in [p0, 0.5 * (p0 + p1), p1].into_iter().enumerate() {
                push(k, sphere_box(p, r, c, q, h));
            }
        }
        (Placed::Box { c, q, h }, Placed::Capsule { p0, p1, r }) => {
            for (k, p) in [p0, 0.5 * (p0 + p1), p1].into_iter().enumerate() {
                push(k, flip(sphere_box(p, r, c, q, h)));
            }
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The corners shared by opposite pairs are bit for bit those rotated one by one, for
    /// turned boxes away from the origin (a sign slip or a wrong pairing fails this).
    #[test]
    fn corners_are_bitwise_the_rotated_offsets() {
        for k in 0..50 {
            let t = k as f64;
            let axis = DVec3::new(t.sin(), (1.7 * t).cos(), 0.3 + (0.4 * t).sin()).normalize();
            let q = DQuat::from_axis_angle(axis, 0.37 * t + 0.1);
            let (c, h) = (DVec3::new(1.3, -0.2 * t, 7.0), DVec3::new(0.1, 0.27, 0.05 + 0.01 * t));
            for (i, p) in corners(c, q, h).into_iter().enumerate() {
                let sign = |b: usize| if i & b == 0 { -1.0 } else { 1.0 };
                let direct = c + q * DVec3::new(sign(1) * h.x, sign(2) * h.y, sign(4) * h.z);
                assert_eq!(p.to_array().map(f64::to_bits), direct.to_array().map(f64::to_bits));
            }
        }
    }

    #[test]
    fn boxes_crossing_edge_on_edge_touch_at_the_crossing_with_the_edges_normal() {
        // A unit box turned 45° about z (an edge along z on top) below a unit box turned 45°
        // about x (an edge along x at the bottom), overlapping by 1 cm at the crossing.
        let s = std::f64::consts::SQRT_2 * 0.5;
        let quarter = 0.25 * std::f64::consts::PI;
        let lower = (DVec3::ZERO, DQuat::from_rotation_z(quarter), DVec3::splat(0.5));
        let upper = (
            DVec3::new(0.0, 2.0 * s - 0.01, 0.0),
            DQuat::from_rotation_x(quarter),
            DVec3::splat(0.5),
        );
        let mut out = Vec::new();
        box_box(upper, lower, 0.0, &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        let (feature, (p, n, g)) = out[0];
        assert!(feature >= 16);
        assert!((n - DVec3::Y).length() < 1e-12, "normal {n}");
        assert!((g + 0.01).abs() < 1e-12, "gap {g}");
        assert!((p - DVec3::new(0.0, s - 0.005, 0.0)).length() < 1e-12, "point {p}");
        // Face on face still gives the clipped face manifold.
        let flat = (DVec3::new(0.0, 0.99, 0.0), DQuat::IDENTITY, DVec3::splat(0.5));
        out.clear();
        box_box(flat, (DVec3::ZERO, DQuat::IDENTITY, DVec3::splat(0.5)), 0.0, &mut out);
        assert_eq!(out.len(), 4);
        assert!(out.iter().all(|(k, _)| *k < 16));
    }

    #[test]
    fn a_turned_box_on_a_box_rests_on_four_points_spanning_most_of_the_overlap() {
        // A unit box turned 0.35 rad about y, 1 mm into another: the clipped face is an
        // octagon; the four kept points lie on it at the gap and span at least 80 % of it.
        let lower = (DVec3::ZERO, DQuat::IDENTITY, DVec3::splat(0.5));
        let upper = (DVec3::new(0.0, 0.999, 0.0), DQuat::from_rotation_y(0.35), DVec3::splat(0.5));
        let mut out = Vec::new();
        box_box(upper, lower, 0.0, &mut out);
        assert_eq!(out.len(), 4, "{out:?}");
        for (_, (p, n, g)) in &out {
            assert!((n - DVec3::Y).length() < 1e-12 && (g + 1e-3).abs() < 1e-12);
            assert!((p.y - 0.499).abs() < 1e-12 || (p.y - 0.5).abs() < 1e-12, "{p}");
        }
        // Area of the kept quadrilateral (in x–z, its corners in angular order).
        let mut hull: Vec<DVec3> = out.iter().map(|(_, (p, _, _))| *p).collect();
        let c = hull.iter().sum::<DVec3>() / 4.0;
        hull.sort_by(|a, b| (a.z - c.z).atan2(a.x - c.x).total_cmp(&(b.z - c.z).atan2(b.x - c.x)));
        let area = |ps: &[DVec3]| {
            (0..ps.len())
                .map(|i| {
                    let (a, b) = (ps[i], ps[(i + 1) % ps.len()]);
                    a.x * b.z - b.x * a.z
                })
                .sum::<f64>()
                .abs()
                * 0.5
        };
        // The octagon's area: the overlap of the two squares counted on a 400 × 400 grid.
        let inside = |x: f64, z: f64| {
            let (s, co) = 0.35f64.sin_cos();
            let (u, v) = (co * x - s * z, s * x + co * z);
            x.abs() <= 0.5 && z.abs() <= 0.5 && u.abs() <= 0.5 && v.abs() <= 0.5
        };
        let m = 400;
        let cells = (0..m * m)
            .filter(|k| {
                let x = ((k % m) as f64 + 0.5) / m as f64 - 0.5;
                let z = ((k / m) as f64 + 0.5) / m as f64 - 0.5;
                inside(x, z)
            })
            .count();
        let overlap = cells as f64 / (m * m) as f64;
        assert!(area(&hull) > 0.8 * overlap, "{} of {overlap}", area(&hull));
    }
}
