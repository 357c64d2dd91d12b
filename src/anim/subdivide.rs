//! Subdivision curves: corner cutting (Chaikin 1974), uniform cubic B-spline subdivision
//! (Lane & Riesenfeld 1980) and the interpolating 4-point scheme (Dyn, Levin & Gregory 1987,
//! weight 1/16), open or closed.

use crate::error::{reserve, too_large, Error, Result};

/// A subdivision rule.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scheme {
    /// `q = 3/4 p_i + 1/4 p_{i+1}`, `r = 1/4 p_i + 3/4 p_{i+1}`; limit: quadratic B-spline.
    Chaikin,
    /// New vertices `(p_{i-1} + 6 p_i + p_{i+1})/8`, edge points `(p_i + p_{i+1})/2`; limit:
    /// cubic B-spline.
    BSpline,
    /// Keeps the points and inserts `(-p_{i-1} + 9 p_i + 9 p_{i+1} - p_{i+2})/16`; interpolating,
    /// C1 limit.
    FourPoint,
}

impl Scheme {
    /// Parse `"chaikin" | "bspline" | "four_point"`.
    ///
    /// # Errors
    /// Any other name.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "chaikin" => Ok(Scheme::Chaikin),
            "bspline" => Ok(Scheme::BSpline),
            "four_point" => Ok(Scheme::FourPoint),
            _ => Err(Error::invalid(
                "scheme",
                format!("{name:?} is not one of chaikin, bspline, four_point"),
            )),
        }
    }
}

/// Apply `iterations` rounds of `scheme` to the polygon `points` (`n x dim`, row-major);
/// `closed` treats it as a loop. Open curves keep their end points (the end rules of each
/// scheme: Chaikin and B-spline keep the ends, the 4-point scheme mirrors the missing
/// neighbour). Returns the refined points, row-major.
///
/// Each round at most doubles the points, so both working buffers are allocated once with
/// room for `n 2^iterations` points before any work is done.
///
/// # Errors
/// Fewer than 2 points (3 when closed), non-finite coordinates, more points than the
/// allocator grants (named `iterations`).
pub fn subdivide(
    points: &[f64],
    dim: usize,
    scheme: Scheme,
    iterations: usize,
    closed: bool,
) -> Result<Vec<f64>> {
    let n = check_points(points, dim, closed)?;
    let room = (iterations < usize::BITS as usize)
        .then(|| points.len().checked_mul(1 << iterations))
        .flatten()
        .ok_or_else(|| too_large("iterations", format!("{n} x 2^{iterations} points"), 8 * dim))?;
    let (mut cur, mut next) = (Vec::new(), Vec::new());
    reserve("iterations", &mut cur, room)?;
    reserve("iterations", &mut next, room)?;
    cur.extend_from_slice(points);
    for _ in 0..iterations {
        next.clear();
        let m = cur.len() / dim;
        let p = |i: isize| -> &[f64] {
            let j = if closed {
                i.rem_euclid(m as isize) as usize
            } else {
                i.clamp(0, m as isize - 1) as usize
            };
            &cur[j * dim..(j + 1) * dim]
        };
        let mut push = |w: &[(f64, isize)]| {
            for c in 0..dim {
                next.push(w.iter().map(|&(wt, i)| wt * p(i)[c]).sum());
            }
        };
        match scheme {
            Scheme::Chaikin => chaikin(m as isize, closed, &mut push),
            Scheme::BSpline => bspline(m as isize, closed, &mut push),
            Scheme::FourPoint => four_point(m as isize, closed, &mut push),
        }
        std::mem::swap(&mut cur, &mut next);
    }
    Ok(cur)
}

/// The number of points of `points` (`n x dim`, row-major), after checking the shape, the
/// count (2 at least, 3 when closed) and that every coordinate is finite.
fn check_points(points: &[f64], dim: usize, closed: bool) -> Result<usize> {
    if dim == 0 || !points.len().is_multiple_of(dim) {
        return Err(Error::invalid("points", "must be an (n, dim) array"));
    }
    let n = points.len() / dim;
    if n < if closed { 3 } else { 2 } {
        return Err(Error::invalid(
            "points",
            format!("need at least {} points, got {n}", if closed { 3 } else { 2 }),
        ));
    }
    if let Some(i) = points.iter().position(|v| !v.is_finite()) {
        return Err(Error::InvalidInput {
            arg: "points".into(),
            index: Some(i / dim),
            reason: "contains NaN or infinity".into(),
        });
    }
    Ok(n)
}

/// One round of Chaikin's corner cutting on `m` points: `push` receives each new point as
/// weights on the old ones (indices wrap when `closed`, clamp otherwise).
fn chaikin(m: isize, closed: bool, push: &mut impl FnMut(&[(f64, isize)])) {
    let edges = if closed { m } else { m - 1 };
    if !closed {
        push(&[(1.0, 0)]);
    }
    for i in 0..edges {
        push(&[(0.75, i), (0.25, i + 1)]);
        push(&[(0.25, i), (0.75, i + 1)]);
    }
    if !closed {
        push(&[(1.0, m - 1)]);
    }
}

/// One round of cubic B-spline subdivision (see [`chaikin`] for `push`).
fn bspline(m: isize, closed: bool, push: &mut impl FnMut(&[(f64, isize)])) {
    for i in 0..m {
        if !closed && (i == 0 || i == m - 1) {
            push(&[(1.0, i)]);
        } else {
            push(&[(0.125, i - 1), (0.75, i), (0.125, i + 1)]);
        }
        if closed || i < m - 1 {
            push(&[(0.5, i), (0.5, i + 1)]);
        }
    }
}

/// One round of the interpolating four-point scheme (see [`chaikin`] for `push`); an open
/// curve mirrors the missing neighbour at each end (`p_{-1} = 2 p_0 - p_1`).
fn four_point(m: isize, closed: bool, push: &mut impl FnMut(&[(f64, isize)])) {
    for i in 0..m {
        push(&[(1.0, i)]);
        if !closed && i == m - 1 {
            continue;
        }
        if closed || (i > 0 && i + 2 < m) {
            push(&[
                (-1.0 / 16.0, i - 1),
                (9.0 / 16.0, i),
                (9.0 / 16.0, i + 1),
                (-1.0 / 16.0, i + 2),
            ]);
        } else if i == 0 && m > 2 {
            push(&[
                (-2.0 / 16.0, 0),
                (1.0 / 16.0, 1),
                (9.0 / 16.0, 0),
                (9.0 / 16.0, 1),
                (-1.0 / 16.0, 2),
            ]);
        } else if i + 2 == m && m > 2 {
            let (a, b) = (i, i + 1);
            push(&[
                (-1.0 / 16.0, a - 1),
                (9.0 / 16.0, a),
                (9.0 / 16.0, b),
                (-2.0 / 16.0, b),
                (1.0 / 16.0, a),
            ]);
        } else {
            push(&[(0.5, i), (0.5, i + 1)]);
        }
    }
}
