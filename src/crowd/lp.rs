//! The low-dimensional linear programs of ORCA (van den Berg, Guy, Lin & Manocha 2011,
//! "Reciprocal n-body collision avoidance", §5.2): the velocity closest to the preferred one
//! inside the disc `|v| ≤ max_speed` and on the permitted side of every half-plane, found
//! incrementally (Seidel 1991: each violated constraint re-solves a 1-D program on its
//! line); and, when that is infeasible, the 3-D program of §5.3, the velocity that minimises
//! the largest distance by which it violates an agent half-plane, the hard (obstacle)
//! half-planes kept.
//!
//! Constraints are taken in the fixed order given (hard half-planes first, then agents by
//! distance), so the result is deterministic.

use glam::DVec2;

/// Lines closer to parallel than this (the cross product of their unit directions) are
/// treated as parallel.
const PARALLEL: f64 = 1e-9;

/// A directed line bounding a half-plane of velocities (m/s): the permitted velocities lie
/// on its left, `det(direction, point - v) ≤ 0` (the paper's `ORCA = {v | (v - (v_A +
/// u/2)) · n ≥ 0}` with `n` the direction turned a quarter anticlockwise).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line {
    /// A point on the line (m/s).
    pub point: DVec2,
    /// Unit direction.
    pub direction: DVec2,
}

impl Line {
    /// By how much `v` lies on the forbidden side (m/s; `≤ 0` when permitted).
    pub fn violation(&self, v: DVec2) -> f64 {
        det(self.direction, self.point - v)
    }
}

/// `a × b`, the z component of the cross product.
pub(crate) fn det(a: DVec2, b: DVec2) -> f64 {
    a.perp_dot(b)
}

/// The best point on line `k` inside the disc of `radius` and permitted by lines `..k`:
/// closest to `opt`, or the farthest along `opt` when `direction` is set. `None` if no point
/// of the line is permitted.
fn program1(lines: &[Line], k: usize, radius: f64, opt: DVec2, direction: bool) -> Option<DVec2> {
    let line = lines[k];
    let dot = line.point.dot(line.direction);
    let disc = dot * dot + radius * radius - line.point.length_squared();
    if disc < 0.0 {
        return None; // the disc lies wholly on the forbidden side
    }
    let root = disc.sqrt();
    let (mut left, mut right) = (-dot - root, -dot + root);
    for other in &lines[..k] {
        let denominator = det(line.direction, other.direction);
        let numerator = det(other.direction, line.point - other.point);
        if denominator.abs() <= PARALLEL {
            if numerator < 0.0 {
                return None; // parallel, and line k lies on the forbidden side of `other`
            }
            continue;
        }
        let t = numerator / denominator;
        if denominator >= 0.0 {
            right = right.min(t);
        } else {
            left = left.max(t);
        }
        if left > right {
            return None;
        }
    }
    let t = if direction {
        if opt.dot(line.direction) > 0.0 {
            right
        } else {
            left
        }
    } else {
        line.direction.dot(opt - line.point).clamp(left, right)
    };
    Some(line.point + t * line.direction)
}

/// The 2-D program: the velocity of the disc of `radius` permitted by every line closest to
/// `opt` (or, with `direction`, farthest along the unit `opt`), written into `result`.
/// Returns `lines.len()` when feasible, else the index of the first line that could not be
/// met (`result` then holds the optimum of the lines before it).
pub fn program2(
    lines: &[Line],
    radius: f64,
    opt: DVec2,
    direction: bool,
    result: &mut DVec2,
) -> usize {
    *result = if direction {
        opt * radius
    } else if opt.length_squared() > radius * radius {
        opt.normalize() * radius
    } else {
        opt
    };
    for k in 0..lines.len() {
        if lines[k].violation(*result) > 0.0 {
            match program1(lines, k, radius, opt, direction) {
                Some(v) => *result = v,
                None => return k,
            }
        }
    }
    lines.len()
}

/// The 3-D program (§5.3) for when [`program2`] failed at line `first`: starting from its
/// partial `result`, minimise the largest violation of the agent lines `hard..` while the
/// hard (obstacle) lines `..hard` stay satisfied. For each line `i` still violated by more than the
/// current worst, the optimum lies on the bisectors of `i` with the lines before it, found as
/// a 2-D program in the direction normal to `i`. `projected` is scratch.
pub fn program3(
    lines: &[Line],
    hard: usize,
    first: usize,
    radius: f64,
    result: &mut DVec2,
    projected: &mut Vec<Line>,
) {
    let mut distance = 0.0;
    for i in first..lines.len() {
        let li = lines[i];
        if li.violation(*result) <= distance {
            continue;
        }
        projected.clear();
        projected.extend_from_slice(&lines[..hard]);
        // When a hard line itself failed (`i < hard`) there is nothing to bisect.
        for lj in &lines[hard.min(i)..i] {
            let determinant = det(li.direction, lj.direction);
            let point = if determinant.abs() <= PARALLEL {
                if li.direction.dot(lj.direction) > 0.0 {
                    continue; // same direction: line j is implied
                }
                0.5 * (li.point + lj.point)
            } else {
                li.point + (det(lj.direction, li.point - lj.point) / determinant) * li.direction
            };
            let direction = (lj.direction - li.direction).normalize();
            projected.push(Line { point, direction });
        }
        let before = *result;
        let normal = DVec2::new(-li.direction.y, li.direction.x);
        if program2(projected, radius, normal, true, result) < projected.len() {
            // Only by rounding: the current result is feasible for the projected lines.
            *result = before;
        }
        distance = li.violation(*result);
    }
}

/// ORCA's velocity: the permitted velocity of speed at most `max_speed` closest to
/// `preferred`, or, if there is none, the one of least largest violation of the agent lines
/// (`lines[hard..]`; the hard lines `lines[..hard]` are kept). Returns it and whether the
/// fallback was needed.
pub fn solve(
    lines: &[Line],
    hard: usize,
    max_speed: f64,
    preferred: DVec2,
    projected: &mut Vec<Line>,
) -> (DVec2, bool) {
    let mut v = DVec2::ZERO;
    let failed = program2(lines, max_speed, preferred, false, &mut v);
    if failed < lines.len() {
        program3(lines, hard, failed, max_speed, &mut v, projected);
        return (v, true);
    }
    (v, false)
}

/// Uniform numbers in `[0, 1)` from a 64-bit LCG (Knuth's MMIX constants), for tests.
#[cfg(test)]
pub(crate) fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The half-plane `n · v ≥ c` (unit `n`) as a line.
    fn half(n: DVec2, c: f64) -> Line {
        Line { point: n * c, direction: DVec2::new(n.y, -n.x) }
    }

    #[test]
    fn line_convention_permits_the_left() {
        let l = half(DVec2::X, 1.0); // v.x ≥ 1
        assert!(l.violation(DVec2::new(2.0, 5.0)) < 0.0);
        assert!(l.violation(DVec2::new(0.5, 0.0)) > 0.0);
        assert!((l.violation(DVec2::new(0.0, 3.0)) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn unconstrained_is_the_preferred_velocity_clipped_to_the_disc() {
        let mut scratch = Vec::new();
        let (v, fell) = solve(&[], 0, 2.0, DVec2::new(1.0, 0.5), &mut scratch);
        assert_eq!((v, fell), (DVec2::new(1.0, 0.5), false));
        let (v, _) = solve(&[], 0, 2.0, DVec2::new(30.0, 40.0), &mut scratch);
        assert!((v - DVec2::new(1.2, 1.6)).length() < 1e-15);
    }

    #[test]
    fn feasible_program_is_the_projection_onto_the_corner() {
        // Preferred (2, 2) with v.x ≤ 1 and v.y ≤ 0.5: the optimum is the corner (1, 0.5).
        let lines = [half(-DVec2::X, -1.0), half(-DVec2::Y, -0.5)];
        let mut scratch = Vec::new();
        let (v, fell) = solve(&lines, 0, 10.0, DVec2::new(2.0, 2.0), &mut scratch);
        assert!(!fell);
        assert!((v - DVec2::new(1.0, 0.5)).length() < 1e-12, "{v}");
        // One active constraint: the projection onto it.
        let (v, _) = solve(&lines[..1], 0, 10.0, DVec2::new(2.0, 2.0), &mut scratch);
        assert!((v - DVec2::new(1.0, 2.0)).length() < 1e-12, "{v}");
        // Against the speed limit as well: (1, sqrt(3)) on the circle of radius 2.
        let (v, _) = solve(&lines[..1], 0, 2.0, DVec2::new(5.0, 2.0), &mut scratch);
        assert!((v - DVec2::new(1.0, 3f64.sqrt())).length() < 1e-12, "{v}");
    }

    #[test]
    fn random_feasible_programs_match_a_brute_force_optimum() {
        // Lines tangent to circles around the origin keep 0 feasible; the optimum found must
        // be feasible and no worse than any feasible point of a fine polar grid.
        let mut rnd = uniform(12345);
        let mut scratch = Vec::new();
        for _ in 0..200 {
            let lines: Vec<Line> = (0..6)
                .map(|_| {
                    let a = rnd() * std::f64::consts::TAU;
                    half(DVec2::new(a.cos(), a.sin()), -0.2 - rnd())
                })
                .collect();
            let opt = DVec2::new(rnd() * 6.0 - 3.0, rnd() * 6.0 - 3.0);
            let (v, fell) = solve(&lines, 0, 2.0, opt, &mut scratch);
            assert!(!fell);
            assert!(lines.iter().all(|l| l.violation(v) < 1e-9) && v.length() < 2.0 + 1e-9);
            let best = (v - opt).length();
            for r in 0..=40 {
                for k in 0..256 {
                    let a = k as f64 / 256.0 * std::f64::consts::TAU;
                    let p = DVec2::new(a.cos(), a.sin()) * (2.0 * r as f64 / 40.0);
                    if lines.iter().all(|l| l.violation(p) <= 0.0) {
                        assert!((p - opt).length() >= best - 1e-9, "{p} beats {v}");
                    }
                }
            }
        }
    }

    #[test]
    fn infeasible_program_falls_back_to_least_largest_violation() {
        // v.x ≥ 1 and v.x ≤ -1 cannot both hold: the least largest violation is 1, at v.x = 0.
        let lines = [half(DVec2::X, 1.0), half(-DVec2::X, 1.0)];
        let mut scratch = Vec::new();
        let (v, fell) = solve(&lines, 0, 5.0, DVec2::new(3.0, 0.7), &mut scratch);
        assert!(fell);
        assert!(v.x.abs() < 1e-12, "{v}");
        let worst = lines.iter().map(|l| l.violation(v)).fold(f64::MIN, f64::max);
        assert!((worst - 1.0).abs() < 1e-12, "{worst}");
        // Three constraints pointing at a triangle's inside from outside: the optimum is the
        // incentre, equally violated by all three (violation = inradius of the offsets).
        let ns: Vec<DVec2> = (0..3)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 3.0;
                DVec2::new(a.cos(), a.sin())
            })
            .collect();
        // n_k · v ≥ 1 for all k is impossible (the n_k sum to 0); the best is v = 0, violation 1.
        let lines: Vec<Line> = ns.iter().map(|&n| half(n, 1.0)).collect();
        let (v, fell) = solve(&lines, 0, 5.0, DVec2::new(0.3, -2.0), &mut scratch);
        assert!(fell);
        assert!(v.length() < 1e-9, "{v}");
    }

    #[test]
    fn fallback_keeps_obstacle_lines_hard() {
        // Hard: v.x ≥ 0.5. Soft: v.x ≤ -1. Least violation of the soft line under the hard
        // one: v.x = 0.5 (violation 1.5).
        let lines = [half(DVec2::X, 0.5), half(-DVec2::X, 1.0)];
        let mut scratch = Vec::new();
        let (v, fell) = solve(&lines, 1, 5.0, DVec2::new(-3.0, 0.0), &mut scratch);
        assert!(fell);
        assert!((v.x - 0.5).abs() < 1e-12, "{v}");
    }

    #[test]
    fn infeasible_hard_lines_fall_back_without_panicking() {
        // Two contradictory hard lines (v.x ≥ 1 and v.x ≤ -1) and one agent line: the 2-D
        // program fails inside the hard prefix, and the fallback keeps a finite velocity.
        let lines = [half(DVec2::X, 1.0), half(-DVec2::X, 1.0), half(DVec2::Y, 0.5)];
        let mut scratch = Vec::new();
        let (v, fell) = solve(&lines, 2, 5.0, DVec2::new(0.0, 3.0), &mut scratch);
        assert!(fell && v.is_finite() && v.length() <= 5.0 + 1e-12, "{v}");
    }

    #[test]
    fn random_infeasible_programs_match_a_brute_force_minimax() {
        let mut rnd = uniform(777);
        let mut scratch = Vec::new();
        let mut checked = 0;
        for _ in 0..300 {
            let lines: Vec<Line> = (0..5)
                .map(|_| {
                    let a = rnd() * std::f64::consts::TAU;
                    let n = DVec2::new(a.cos(), a.sin());
                    Line { point: n * (rnd() * 3.0), direction: DVec2::new(n.y, -n.x) }
                })
                .collect();
            let opt = DVec2::new(rnd() - 0.5, rnd() - 0.5);
            let (v, fell) = solve(&lines, 0, 2.0, opt, &mut scratch);
            if !fell {
                continue;
            }
            checked += 1;
            let worst = |p: DVec2| lines.iter().map(|l| l.violation(p)).fold(f64::MIN, f64::max);
            let mut best = f64::INFINITY;
            for r in 0..=100 {
                for k in 0..512 {
                    let a = k as f64 / 512.0 * std::f64::consts::TAU;
                    best = best.min(worst(DVec2::new(a.cos(), a.sin()) * (2.0 * r as f64 / 100.0)));
                }
            }
            assert!(v.length() <= 2.0 + 1e-9);
            assert!(worst(v) <= best + 1e-9, "fallback {} vs grid {best}", worst(v));
            assert!(worst(v) >= best - 0.05, "fallback {} vs grid {best}", worst(v));
        }
        assert!(checked > 30, "{checked}");
    }
}
