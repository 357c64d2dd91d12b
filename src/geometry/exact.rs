//! Exact orientation predicates: the sign of `orient2d` and `orient3d` for any finite `f64`
//! input, by a floating-point filter with Shewchuk's error bounds and, where the filter cannot
//! decide, exact evaluation in floating-point expansions (Shewchuk 1997, "Adaptive precision
//! floating-point arithmetic and fast robust geometric predicates", §2 and §4: Two-Sum,
//! Two-Product, Grow-Expansion, Scale-Expansion). Used by the exact triangle–triangle
//! intersection test of [`super::triangle`].

use glam::{DVec2, DVec3};
use std::cmp::Ordering;

/// Unit roundoff of `f64` (2⁻⁵³).
const EPS: f64 = f64::EPSILON * 0.5;

/// `a + b` as the exact pair `(sum, error)` (Knuth's Two-Sum).
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let x = a + b;
    let bv = x - a;
    let av = x - bv;
    (x, (a - av) + (b - bv))
}

/// `a · b` as the exact pair `(product, error)` (the error by a fused multiply-add).
fn two_product(a: f64, b: f64) -> (f64, f64) {
    let x = a * b;
    (x, a.mul_add(b, -x))
}

/// The most components an expansion of these predicates needs (orient3d's sum of three
/// products of a 2-component difference and a 32-component minor).
const CAP: usize = 192;

/// A floating-point expansion: a sum of non-overlapping components in increasing magnitude,
/// zeros dropped, held on the stack.
#[derive(Clone, Copy)]
struct Expansion {
    c: [f64; CAP],
    n: usize,
}

impl Expansion {
    /// The expansion of the components `parts`, small first (zeros dropped).
    fn of(parts: &[f64]) -> Expansion {
        let mut e = Expansion { c: [0.0; CAP], n: 0 };
        parts.iter().for_each(|&p| e.push(p));
        e
    }

    fn push(&mut self, x: f64) {
        if x != 0.0 {
            self.c[self.n] = x;
            self.n += 1;
        }
    }

    fn parts(&self) -> &[f64] {
        &self.c[..self.n]
    }

    /// `a − b` exactly.
    fn diff(a: f64, b: f64) -> Expansion {
        let (x, y) = two_sum(a, -b);
        Expansion::of(&[y, x])
    }

    /// The sum with `f` (Grow-Expansion of each component of `f` into this one).
    fn add(&self, f: &Expansion) -> Expansion {
        let mut h = *self;
        for &b in f.parts() {
            let mut q = b;
            let mut out = Expansion { c: [0.0; CAP], n: 0 };
            for &hi in h.parts() {
                let (s, err) = two_sum(q, hi);
                out.push(err);
                q = s;
            }
            out.push(q);
            h = out;
        }
        h
    }

    /// This expansion times the number `b` (Scale-Expansion).
    fn scale(&self, b: f64) -> Expansion {
        let mut h = Expansion { c: [0.0; CAP], n: 0 };
        let Some((&first, rest)) = self.parts().split_first() else {
            return h;
        };
        let (mut q, low) = two_product(first, b);
        h.push(low);
        for &ei in rest {
            let (t_hi, t_lo) = two_product(ei, b);
            let (s, err) = two_sum(q, t_lo);
            h.push(err);
            let (s2, err2) = two_sum(t_hi, s);
            h.push(err2);
            q = s2;
        }
        h.push(q);
        h
    }

    /// The product with `f`.
    fn mul(&self, f: &Expansion) -> Expansion {
        f.parts().iter().fold(Expansion::of(&[]), |acc, &b| acc.add(&self.scale(b)))
    }

    fn neg(mut self) -> Expansion {
        self.c[..self.n].iter_mut().for_each(|c| *c = -*c);
        self
    }

    /// The sign: that of the largest component (the last; the components do not overlap).
    fn sign(&self) -> Ordering {
        self.parts().last().map_or(Ordering::Equal, |c| c.total_cmp(&0.0))
    }
}

/// `e · f − g · h` of expansions, exactly.
fn cross_term(e: &Expansion, f: &Expansion, g: &Expansion, h: &Expansion) -> Expansion {
    e.mul(f).add(&g.mul(h).neg())
}

/// The sign of `(a − c) × (b − c)`: `Greater` when `a, b, c` turn counter-clockwise, `Less`
/// clockwise, `Equal` when they are collinear. Exact for finite input.
pub fn orient2d(a: DVec2, b: DVec2, c: DVec2) -> Ordering {
    let (l, r) = ((a.x - c.x) * (b.y - c.y), (a.y - c.y) * (b.x - c.x));
    let det = l - r;
    // Shewchuk's ccwerrboundA.
    if det.abs() > (3.0 + 16.0 * EPS) * EPS * (l.abs() + r.abs()) {
        return det.total_cmp(&0.0);
    }
    let d = Expansion::diff;
    let (acx, acy, bcx, bcy) = (d(a.x, c.x), d(a.y, c.y), d(b.x, c.x), d(b.y, c.y));
    cross_term(&acx, &bcy, &acy, &bcx).sign()
}

/// The sign of `det[a − d; b − d; c − d]` (the signed volume of the tetrahedron `abcd` times
/// six): `Equal` exactly when the four points are coplanar; the sign tells on which side of
/// the plane of `a, b, c` the point `d` lies (`Less` on the side `(b − a) × (c − a)` points
/// to). Exact for finite input.
pub fn orient3d(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> Ordering {
    let (ad, bd, cd) = (a - d, b - d, c - d);
    let terms = [
        (ad.x, bd.y * cd.z, bd.z * cd.y),
        (bd.x, cd.y * ad.z, cd.z * ad.y),
        (cd.x, ad.y * bd.z, ad.z * bd.y),
    ];
    let det: f64 = terms.iter().map(|(x, p, q)| x * (p - q)).sum();
    let permanent: f64 = terms.iter().map(|(x, p, q)| x.abs() * (p.abs() + q.abs())).sum();
    // Shewchuk's o3derrboundA.
    if det.abs() > (7.0 + 56.0 * EPS) * EPS * permanent {
        return det.total_cmp(&0.0);
    }
    let e = Expansion::diff;
    let (adx, ady, adz) = (e(a.x, d.x), e(a.y, d.y), e(a.z, d.z));
    let (bdx, bdy, bdz) = (e(b.x, d.x), e(b.y, d.y), e(b.z, d.z));
    let (cdx, cdy, cdz) = (e(c.x, d.x), e(c.y, d.y), e(c.z, d.z));
    let t1 = adx.mul(&cross_term(&bdy, &cdz, &bdz, &cdy));
    let t2 = bdx.mul(&cross_term(&cdy, &adz, &cdz, &ady));
    let t3 = cdx.mul(&cross_term(&ady, &bdz, &adz, &bdy));
    t1.add(&t2).add(&t3).sign()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orient3d_signs_of_a_unit_tetrahedron() {
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        // (b − a) × (c − a) = +z: a point above is on the `Less` side.
        assert_eq!(orient3d(a, b, c, DVec3::Z), Ordering::Less);
        assert_eq!(orient3d(a, b, c, -DVec3::Z), Ordering::Greater);
        assert_eq!(orient3d(a, b, c, DVec3::new(0.3, 0.7, 0.0)), Ordering::Equal);
    }

    #[test]
    fn near_degenerate_cases_are_decided_exactly() {
        // A point a fraction of an ulp off a plane through points whose differences round in
        // f64: the filter cannot decide, the expansions must.
        let (a, b, c) =
            (DVec3::new(0.1, 0.2, 0.3), DVec3::new(1.1, 0.2, 0.3), DVec3::new(0.1, 1.2, 0.3));
        assert_eq!(orient3d(a, b, c, DVec3::new(0.5, 0.5, 0.3)), Ordering::Equal);
        assert_eq!(
            orient3d(a, b, c, DVec3::new(0.5, 0.5, 0.3 + 0.3 * f64::EPSILON)),
            Ordering::Less
        );
        let p = DVec2::new(0.5, 0.5);
        assert_eq!(orient2d(DVec2::ZERO, DVec2::ONE, p), Ordering::Equal);
        // One ulp above 0.5 (2⁻⁵³) and one below (2⁻⁵⁴): the nearest points off the line.
        let above = DVec2::new(0.5, 0.5 + 2f64.powi(-53));
        let below = DVec2::new(0.5, 0.5 - 2f64.powi(-54));
        assert_eq!(orient2d(DVec2::ZERO, DVec2::ONE, above), Ordering::Greater);
        assert_eq!(orient2d(DVec2::ZERO, DVec2::ONE, below), Ordering::Less);
        // Points on the line y = 3x through values that are not exact in binary: the naive
        // cross product rounds, the exact sign is that of the binary values' products.
        let (q, r) = (DVec2::new(0.1, 0.3), DVec2::new(0.7, 2.1));
        let (l, lo) = two_product(q.x, r.y);
        let (m, mo) = two_product(q.y, r.x);
        let exact = Expansion::of(&[lo, l]).add(&Expansion::of(&[-mo, -m])).sign();
        assert_eq!(orient2d(q, r, DVec2::ZERO), exact);
    }
}
