//! The geometry of cloth self-collision: the exact triangle–triangle test on hand-built
//! intersecting, touching and separate pairs, and continuous collision detection of a vertex
//! and a triangle and of two edges, with times of impact computed by hand.

use glam::DVec3;
use kinema::geometry::ccd::{edge_edge, vertex_triangle};
use kinema::geometry::triangle::{
    closest_point_on_triangle, intersecting_triangles, segment_meets_triangle, triangles_intersect,
};

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// The unit right triangle in the z = 0 plane.
fn base() -> [DVec3; 3] {
    [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)]
}

#[test]
fn crossing_triangles_intersect_and_separate_ones_do_not() {
    // A vertical triangle piercing the base through its interior.
    let pierce = [v(0.2, 0.2, -0.5), v(0.3, 0.2, 0.5), v(0.2, 0.3, 0.5)];
    assert!(triangles_intersect(base(), pierce));
    assert!(triangles_intersect(pierce, base()));
    // The same lifted by 0.6: entirely above.
    let above = pierce.map(|p| p + v(0.0, 0.0, 0.6));
    assert!(!triangles_intersect(base(), above));
    // Straddling the plane but outside the triangle (beyond the hypotenuse).
    let beside = pierce.map(|p| p + v(0.6, 0.6, 0.0));
    assert!(!triangles_intersect(base(), beside));
    // An edge through the base's interior, the triangle's body outside it on both sides.
    let edge_through = [v(0.25, 0.25, -1.0), v(0.25, 0.25, 1.0), v(3.0, 3.0, 0.0)];
    assert!(triangles_intersect(base(), edge_through));
}

#[test]
fn touching_triangles_intersect_exactly_and_a_hair_apart_do_not() {
    // A vertex of one exactly on the other's interior.
    let touch = [v(0.25, 0.25, 0.0), v(0.5, 0.5, 1.0), v(0.0, 0.5, 1.0)];
    assert!(triangles_intersect(base(), touch));
    // The same lifted by the smallest step above 0: apart (an approximate test says either).
    let lifted = touch.map(|p| v(p.x, p.y, if p.z == 0.0 { f64::MIN_POSITIVE } else { p.z }));
    assert!(!triangles_intersect(base(), lifted));
    // Edge on edge: the second triangle's edge lies along the first's hypotenuse.
    let along = [v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(1.0, 1.0, 1.0)];
    assert!(triangles_intersect(base(), along));
    // Vertex on a vertex.
    let corner = [v(1.0, 0.0, 0.0), v(2.0, 0.0, 1.0), v(2.0, 1.0, 0.0)];
    assert!(triangles_intersect(base(), corner));
}

#[test]
fn coplanar_triangles_overlap_contain_or_stay_apart() {
    let inner = [v(0.1, 0.1, 0.0), v(0.3, 0.1, 0.0), v(0.1, 0.3, 0.0)];
    assert!(triangles_intersect(base(), inner), "contained");
    assert!(triangles_intersect(inner, base()), "containing");
    let overlap = [v(0.5, 0.5, 0.0), v(-0.5, 0.5, 0.0), v(0.5, -0.5, 0.0)];
    assert!(triangles_intersect(base(), overlap), "overlapping");
    let apart = [v(0.6, 0.6, 0.0), v(1.6, 0.6, 0.0), v(0.6, 1.6, 0.0)];
    assert!(!triangles_intersect(base(), apart), "beyond the hypotenuse");
    // Sharing the hypotenuse's midpoint only.
    let kiss = [v(0.5, 0.5, 0.0), v(1.5, 0.5, 0.0), v(0.5, 1.5, 0.0)];
    assert!(triangles_intersect(base(), kiss), "touching at a point");
    // A tilted plane where rounding matters: coplanar points built from 0.1-steps.
    let (a, b, c) = (v(0.1, 0.2, 0.3), v(1.1, 0.7, 0.3), v(0.3, 1.3, 0.9));
    let mid = (a + b) * 0.5;
    assert!(segment_meets_triangle(mid + (c - mid) * 0.5, c, [a, b, c]));
}

#[test]
fn closest_points_on_a_triangle_by_region() {
    let [a, b, c] = base();
    let (q, w) = closest_point_on_triangle(v(0.2, 0.3, 2.0), a, b, c);
    assert!((q - v(0.2, 0.3, 0.0)).length() < 1e-15 && (w[0] - 0.5).abs() < 1e-15);
    let (q, _) = closest_point_on_triangle(v(-1.0, -1.0, 0.5), a, b, c);
    assert_eq!(q, a);
    let (q, w) = closest_point_on_triangle(v(1.0, 1.0, 0.0), a, b, c);
    assert!((q - v(0.5, 0.5, 0.0)).length() < 1e-15 && w[0].abs() < 1e-15);
}

#[test]
fn all_pairs_search_finds_a_folded_strip_crossing_itself() {
    // Two quads of a strip, the second folded back through the first.
    let x = vec![
        v(0.0, 0.0, 0.0),
        v(1.0, 0.0, 0.0),
        v(0.0, 1.0, 0.0),
        v(1.0, 1.0, 0.0),
        v(0.5, -0.5, 0.5),
        v(0.5, 1.5, 0.5),
        v(0.5, -0.5, -0.5),
        v(0.5, 1.5, -0.5),
    ];
    let t = vec![[0, 1, 2], [1, 3, 2], [4, 5, 6], [5, 7, 6]];
    let found = intersecting_triangles(&x, &t);
    assert!(!found.is_empty());
    assert!(found.iter().all(|&(i, j)| i < 2 && j >= 2), "{found:?}");
    // Adjacent triangles (sharing an edge) are never reported.
    assert!(intersecting_triangles(&x[..4], &t[..2]).is_empty());
}

#[test]
fn a_vertex_crossing_a_triangle_is_found_at_the_time_it_crosses() {
    let [a, b, c] = base();
    // From z = 0.3 to z = -0.1 over the step: crosses at t = 0.75.
    let x0 = [v(0.2, 0.2, 0.3), a, b, c];
    let x1 = [v(0.2, 0.2, -0.1), a, b, c];
    let hit = vertex_triangle(x0, x1, 1e-9).expect("crossing");
    assert!((hit.time - 0.75).abs() < 1e-12, "{}", hit.time);
    assert!(hit.distance < 1e-9);
    // The normal points to where the vertex came from, the weights are the barycentrics.
    assert!((hit.normal - DVec3::Z).length() < 1e-12);
    let w = hit.weights;
    assert!((w[1] + 0.6).abs() < 1e-9 && (w[2] + 0.2).abs() < 1e-9 && (w[3] + 0.2).abs() < 1e-9);
    // The triangle moving up through a resting vertex: same time, and the normal still points
    // up, to the side of the plane the vertex started on.
    let up = |p: DVec3, t: f64| p + v(0.0, 0.0, t);
    let y0 = [v(0.2, 0.2, 0.0), up(a, -0.3), up(b, -0.3), up(c, -0.3)];
    let y1 = [v(0.2, 0.2, 0.0), up(a, 0.1), up(b, 0.1), up(c, 0.1)];
    let hit = vertex_triangle(y0, y1, 1e-9).expect("crossing");
    assert!((hit.time - 0.75).abs() < 1e-12 && (hit.normal - DVec3::Z).length() < 1e-12, "{hit:?}");
    // Missing the triangle (beyond the hypotenuse), or stopping short of it: no collision.
    let miss = [v(0.8, 0.8, 0.3), a, b, c];
    assert!(vertex_triangle(miss, [v(0.8, 0.8, -0.1), a, b, c], 1e-9).is_none());
    assert!(vertex_triangle(x0, [v(0.2, 0.2, 0.01), a, b, c], 1e-9).is_none());
}

#[test]
fn a_rotating_triangle_sweeping_a_vertex_is_found_at_the_root_of_the_cubic() {
    // The triangle's far corner c goes from z = +1 to z = -1 while a, b stay: the plane
    // through a, b, c(t) contains p = (0.1, 0.1, 0.05) when 0.1 c_z(t) = 0.05 · 1 ...
    // with c(t) = (0, 1, 1 − 2t): the plane is z = c_z y, so p is in it when
    // 0.05 = (1 − 2t) 0.1, t = 0.25.
    let (a, b) = (v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0));
    let p = v(0.1, 0.1, 0.05);
    let x0 = [p, a, b, v(0.0, 1.0, 1.0)];
    let x1 = [p, a, b, v(0.0, 1.0, -1.0)];
    let hit = vertex_triangle(x0, x1, 1e-9).expect("swept");
    assert!((hit.time - 0.25).abs() < 1e-12, "{}", hit.time);
}

#[test]
fn crossing_edges_are_found_at_the_time_they_meet() {
    // Edge along x at z = 0.2 moving down to z = −0.2, edge along y at z = 0: meet at t = 0.5,
    // at parameters 0.5 and 0.5.
    let e = |z: f64| [v(-1.0, 0.0, z), v(1.0, 0.0, z)];
    let f = [v(0.0, -1.0, 0.0), v(0.0, 1.0, 0.0)];
    let x0 = [e(0.2)[0], e(0.2)[1], f[0], f[1]];
    let x1 = [e(-0.2)[0], e(-0.2)[1], f[0], f[1]];
    let hit = edge_edge(x0, x1, 1e-9).expect("crossing");
    assert!((hit.time - 0.5).abs() < 1e-12, "{}", hit.time);
    assert!((hit.normal - DVec3::Z).length() < 1e-12, "{:?}", hit.normal);
    assert!(hit.weights.iter().all(|w| (w.abs() - 0.5).abs() < 1e-12), "{:?}", hit.weights);
    // Passing beyond the end of the other edge: no collision.
    let shift = |x: [DVec3; 4]| [x[0] + v(0.0, 1.5, 0.0), x[1] + v(0.0, 1.5, 0.0), x[2], x[3]];
    assert!(edge_edge(shift(x0), shift(x1), 1e-9).is_none());
}

#[test]
fn parallel_and_degenerate_motion_is_handled() {
    let [a, b, c] = base();
    // Sliding parallel to the triangle, 0.1 above it: never coplanar.
    let x0 = [v(0.2, 0.2, 0.1), a, b, c];
    let x1 = [v(0.4, 0.3, 0.1), a, b, c];
    assert!(vertex_triangle(x0, x1, 1e-6).is_none());
    // Everything still: nothing.
    assert!(vertex_triangle(x0, x0, 1e-6).is_none());
    // All four coplanar throughout (a flat sheet moving in its plane), vertex far outside.
    let f0 = [v(2.0, 2.0, 0.0), a, b, c];
    let f1 = [v(2.5, 2.0, 0.0), a, b, c];
    assert!(vertex_triangle(f0, f1, 1e-6).is_none());
    // Parallel edges are coplanar all along (the cubic vanishes): checked at the start and the
    // end of the step. Closing in but stopping short: nothing.
    let x0 = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 0.5, 0.0), v(1.0, 0.5, 0.0)];
    let x1 = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
    let miss = edge_edge(x0, [x0[0], x0[1], v(0.0, 0.3, 0.0), v(1.0, 0.3, 0.0)], 1e-6);
    assert!(miss.is_none());
    // Parallel edges approaching face to face from above: coplanar only at the end.
    let y0 = [x0[0], x0[1], v(0.0, 0.0, 0.4), v(1.0, 0.0, 0.4)];
    let hit = edge_edge(y0, x1, 1e-6).expect("parallel edges meeting");
    assert!((hit.time - 1.0).abs() < 1e-9 && hit.normal.z.abs() > 0.99, "{hit:?}");
    // A zero-length edge (always coplanar with any edge): checked at the ends only, and a
    // finite, unit normal where found.
    let z0 = [v(0.5, 0.0, 0.2), v(0.5, 0.0, 0.2), f0[1], f0[2]];
    let z1 = [v(0.5, 0.0, 0.0), v(0.5, 0.0, 0.0), f0[1], f0[2]];
    let hit = edge_edge(z0, z1, 1e-6).expect("point landing on an edge");
    assert!((hit.normal.length() - 1.0).abs() < 1e-12 && hit.time == 1.0, "{hit:?}");
}
