//! The finite rotation groups of 3D space (cyclic `Cn`, dihedral `Dn`, tetrahedral `T`,
//! octahedral `O`, icosahedral `I`; e.g. Conway & Smith 2003, "On Quaternions and Octonions",
//! ch. 3) as unit quaternions, and the reduction of rotations by a group (the element of the
//! coset `L p R` with the smallest angle, as scipy's `Rotation.reduce`).

use crate::error::{Error, Result};
use glam::DQuat;

/// The golden ratio `(1 + √5) / 2`.
const PHI: f64 = 1.618_033_988_749_895;

/// The elements of group `name` as scalar-first unit quaternions `(w, x, y, z)`, one per
/// rotation (one sign of each), the identity first.
///
/// `name` is `"I"` (60 elements), `"O"` (24), `"T"` (12), `"Cn"` (`n`: rotations by
/// `2πk/n` about `axis`) or `"Dn"` (`2n`: `Cn` and the `n` half turns about the axes at
/// angles `πk/n` in the plane normal to `axis`, from the next axis in cyclic order), `n >= 1`.
/// `axis` is `'X'`, `'Y'` or `'Z'` (either case); `I`, `O`, `T` do not use it. The
/// polyhedral groups are the symmetries of the tetrahedron with vertex `(1, 1, 1)`, the
/// octahedron with vertices `±e_i` and the icosahedron with vertices the cyclic shifts of
/// `(0, ±1, ±φ)`.
///
/// # Errors
/// [`Error::InvalidInput`] naming `group` or `axis`.
pub fn create_group(name: &str, axis: &str) -> Result<Vec<[f64; 4]>> {
    let a = match axis {
        "x" | "X" => 0,
        "y" | "Y" => 1,
        "z" | "Z" => 2,
        _ => return Err(Error::invalid("axis", "must be one of 'X', 'Y', 'Z'")),
    };
    let bad = || Error::invalid("group", "must be one of 'I', 'O', 'T', 'Dn', 'Cn' (n >= 1)");
    match name {
        "I" => Ok(icosahedral()),
        "O" => Ok(octahedral()),
        "T" => Ok(tetrahedral()),
        _ if name.len() >= 2 && name.is_char_boundary(1) => {
            let digits = &name[1..];
            if !digits.bytes().all(|b| b.is_ascii_digit()) {
                return Err(bad());
            }
            let n: usize = digits.parse().map_err(|_| bad())?;
            if n == 0 || n > 1 << 24 {
                return Err(bad());
            }
            match &name[..1] {
                "C" => Ok(cyclic(n, a)),
                "D" => Ok(dihedral(n, a)),
                _ => Err(bad()),
            }
        }
        _ => Err(bad()),
    }
}

fn cyclic(n: usize, axis: usize) -> Vec<[f64; 4]> {
    (0..n)
        .map(|k| {
            let (s, c) = (std::f64::consts::PI * k as f64 / n as f64).sin_cos();
            let mut q = [c, 0.0, 0.0, 0.0];
            q[1 + axis] = s;
            q
        })
        .collect()
}

fn dihedral(n: usize, axis: usize) -> Vec<[f64; 4]> {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let half_turns = (0..n).map(|k| {
        let (s, c) = (std::f64::consts::PI * k as f64 / n as f64).sin_cos();
        let mut q = [0.0; 4];
        q[1 + u] = c;
        q[1 + v] = s;
        q
    });
    cyclic(n, axis).into_iter().chain(half_turns).collect()
}

/// The 12 rotations of the tetrahedron: the Hurwitz units up to sign (identity, half turns
/// about the axes, `(±1, ±1, ±1, ±1)/2` with `w > 0`).
fn tetrahedral() -> Vec<[f64; 4]> {
    let mut g = vec![[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
    g.push([0.0, 0.0, 0.0, 1.0]);
    for signs in 0..8 {
        let s = |bit: usize| if signs >> bit & 1 == 1 { -0.5 } else { 0.5 };
        g.push([0.5, s(0), s(1), s(2)]);
    }
    g
}

/// The 24 rotations of the octahedron: the tetrahedral group and the 12 quaternions with
/// two components `±1/√2` (one sign of each).
fn octahedral() -> Vec<[f64; 4]> {
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let mut g = tetrahedral();
    for i in 0..4 {
        for j in i + 1..4 {
            for sign in [1.0, -1.0] {
                let mut q = [0.0; 4];
                q[i] = h;
                q[j] = sign * h;
                g.push(q);
            }
        }
    }
    g
}

/// The 60 rotations of the icosahedron: the tetrahedral group and the 48 quaternions
/// `(0, ±1, ±1/φ, ±φ)/2` with their components permuted evenly (one sign of each).
fn icosahedral() -> Vec<[f64; 4]> {
    const EVEN: [[usize; 4]; 12] = [
        [0, 1, 2, 3],
        [0, 2, 3, 1],
        [0, 3, 1, 2],
        [1, 0, 3, 2],
        [1, 2, 0, 3],
        [1, 3, 2, 0],
        [2, 0, 1, 3],
        [2, 1, 3, 0],
        [2, 3, 0, 1],
        [3, 0, 2, 1],
        [3, 1, 0, 2],
        [3, 2, 1, 0],
    ];
    let base = [0.0, 0.5, 0.5 / PHI, 0.5 * PHI];
    let mut g = tetrahedral();
    for p in EVEN {
        for signs in 0..8 {
            let s = |bit: usize| if signs >> bit & 1 == 1 { -1.0 } else { 1.0 };
            let v = [base[0], s(0) * base[1], s(1) * base[2], s(2) * base[3]];
            let mut q = [0.0; 4];
            for (slot, &from) in p.iter().enumerate() {
                q[slot] = v[from];
            }
            // One of q, -q: the first non-zero component positive.
            if q.iter().find(|c| **c != 0.0).is_some_and(|c| *c < 0.0) {
                continue;
            }
            g.push(q);
        }
    }
    g
}

/// The element `l p r` (`l` from `left`, `r` from `right`; an empty list stands for the
/// identity alone) with the smallest rotation angle, i.e. the largest `|w|`, and the indices
/// of `l` and `r` (`-1` for an empty list). Ties go to the first pair in the order
/// `(l, r)` row-major.
pub fn reduce(p: DQuat, left: &[DQuat], right: &[DQuat]) -> (DQuat, i64, i64) {
    let identity = [DQuat::IDENTITY];
    let ls = if left.is_empty() { &identity[..] } else { left };
    let rs = if right.is_empty() { &identity[..] } else { right };
    let mut best = (-1.0, 0, 0);
    for (i, l) in ls.iter().enumerate() {
        let lp = *l * p;
        for (j, r) in rs.iter().enumerate() {
            // w of (l p) r = (l p) · conj(r) component-wise.
            let w = (lp.w * r.w - lp.x * r.x - lp.y * r.y - lp.z * r.z).abs();
            if w > best.0 {
                best = (w, i, j);
            }
        }
    }
    let (_, i, j) = best;
    let index = |k: usize, list: &[DQuat]| if list.is_empty() { -1 } else { k as i64 };
    (ls[i] * p * rs[j], index(i, left), index(j, right))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quat(q: &[f64; 4]) -> DQuat {
        DQuat::from_xyzw(q[1], q[2], q[3], q[0])
    }

    /// Closed under products, no element twice (up to sign), of the right order.
    #[test]
    fn groups_are_closed_and_distinct() {
        for (name, order) in [("I", 60), ("O", 24), ("T", 12), ("C5", 5), ("D7", 14), ("C1", 1)] {
            let g: Vec<DQuat> = create_group(name, "Y").unwrap().iter().map(quat).collect();
            assert_eq!(g.len(), order, "{name}");
            let find = |q: DQuat| g.iter().filter(|e| e.dot(q).abs() > 1.0 - 1e-12).count();
            for a in &g {
                assert!((a.length() - 1.0).abs() < 1e-15, "{name}");
                assert_eq!(find(*a), 1, "{name}: duplicate");
                for b in &g {
                    assert_eq!(find(*a * *b), 1, "{name}: not closed");
                }
            }
        }
        for bad in ["", "C0", "D", "Q", "C-1", "I2", "Cx", "é1"] {
            assert!(create_group(bad, "Z").is_err(), "{bad}");
        }
        assert!(create_group("C3", "W").is_err());
    }

    #[test]
    fn reduction_by_the_group_itself_gives_the_identity() {
        let g: Vec<DQuat> = create_group("O", "Z").unwrap().iter().map(quat).collect();
        for p in &g {
            let (q, i, j) = reduce(*p, &g, &g);
            assert!(q.w.abs() > 1.0 - 1e-15 && i >= 0 && j >= 0);
            let (q, _, j) = reduce(*p, &[], &g);
            assert!(q.w.abs() > 1.0 - 1e-15 && j >= 0);
            let (q, i, j) = reduce(*p, &g, &[]);
            assert!(q.w.abs() > 1.0 - 1e-15 && i >= 0 && j == -1);
        }
        let p = DQuat::from_rotation_z(0.3);
        assert_eq!(reduce(p, &[], &[]), (p, -1, -1));
    }
}
