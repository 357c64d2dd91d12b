//! The stages of building a cloth's model from its mesh ([`super::Model::new`]): the material checked, lumped
//! vertex masses, the bending hinges of the triangle model (Baraff & Witkin 1998, §4.3, with
//! the discrete-shells stiffness scaling of Grinspun et al. 2003) or the springs of the
//! mass-spring model (Provot 1995: structural, shear and bend springs), the mass shares that
//! bound the indefinite curvature terms, the block pattern of the implicit matrix and each
//! element's slots in it.

use super::elements::{Hinge, Spring, Triangle};
use super::{dihedral_angle, BlockMatrix, Elasticity, Material, Topology};
use crate::error::{Error, Result};
use glam::DVec3;

impl Material {
    /// Check every parameter: finite, `density` and `stretch` positive, the others `>= 0`.
    ///
    /// # Errors
    /// The first parameter out of range, named.
    pub(super) fn check(&self) -> Result<()> {
        for (name, value, positive) in [
            ("density", self.density, true),
            ("stretch", self.stretch, true),
            ("shear", self.shear, false),
            ("bend", self.bend, false),
            ("damping", self.damping, false),
            ("air_damping", self.air_damping, false),
        ] {
            if !value.is_finite() || value < 0.0 || (positive && value == 0.0) {
                let need = if positive { "positive" } else { ">= 0" };
                return Err(Error::invalid(
                    name,
                    format!("must be finite and {need}, got {value}"),
                ));
            }
        }
        Ok(())
    }
}

/// Lumped masses (kg): each triangle gives a third of `density · area` to each of its vertices.
pub(super) fn lumped_masses(n: usize, elements: &[Triangle], density: f64) -> Vec<f64> {
    let mut mass = vec![0.0; n];
    for t in elements {
        for &v in &t.verts {
            mass[v] += density * t.area / 3.0;
        }
    }
    mass
}

/// The bending hinges of the triangle model: rest angle the dihedral angle at `x`, stiffness
/// `bend · 3|e|²/(A₁ + A₂)`.
pub(super) fn hinges(topology: &Topology, x: &[DVec3], bend: f64) -> Vec<Hinge> {
    let area3 = |a: usize, b: usize, c: usize| 0.5 * (x[b] - x[a]).cross(x[c] - x[a]).length();
    topology
        .hinges
        .iter()
        .map(|&[a, b, p, q]| {
            let (theta, _) = dihedral_angle(x[a], x[b], x[p], x[q]);
            let e2 = (x[b] - x[a]).length_squared();
            let k = bend * 3.0 * e2 / (area3(a, b, p) + area3(a, b, q));
            Hinge { verts: [a, b, p, q], rest_angle: theta, k, slots: [0; 16] }
        })
        .collect()
}

/// The springs of the mass-spring model at rest at `x`: along every edge (shear stiffness on
/// the diagonals of quads, stretch otherwise), and across every hinge (shear across a quad's
/// diagonal, bend `bend / L²` otherwise).
pub(super) fn springs(topology: &Topology, x: &[DVec3], material: &Material) -> Vec<Spring> {
    let is_quad_diagonal = |[a, b, p, q]: [usize; 4]| {
        let mid_edge = 0.5 * (x[a] + x[b]);
        let mid_cross = 0.5 * (x[p] + x[q]);
        (mid_edge - mid_cross).length() < 0.25 * (x[b] - x[a]).length()
    };
    let mut springs = Vec::new();
    let mut spring = |a: usize, b: usize, k: f64| {
        springs.push(Spring {
            verts: [a, b],
            rest: (x[b] - x[a]).length(),
            k,
            mass_share: 0.0,
            slots: [0; 4],
        });
    };
    let diagonal_edges: std::collections::HashSet<[usize; 2]> = topology
        .hinges
        .iter()
        .filter(|h| is_quad_diagonal(**h))
        .map(|h| [h[0].min(h[1]), h[0].max(h[1])])
        .collect();
    for &[a, b] in &topology.edges {
        let k = if diagonal_edges.contains(&[a, b]) { material.shear } else { material.stretch };
        spring(a, b, k);
    }
    for &h in &topology.hinges {
        let [_, _, p, q] = h;
        if is_quad_diagonal(h) {
            spring(p, q, material.shear);
        } else {
            let l2 = (x[q] - x[p]).length_squared();
            spring(p, q, material.bend / l2);
        }
    }
    springs
}

/// The block pattern coupling the vertices of every element: triangles and hinges in the
/// triangle model, springs in the mass-spring model.
pub(super) fn pattern(
    n: usize,
    model: Elasticity,
    elements: &[Triangle],
    hinges: &[Hinge],
    springs: &[Spring],
) -> BlockMatrix {
    match model {
        Elasticity::BaraffWitkin => BlockMatrix::from_elements(
            n,
            elements.iter().map(|t| &t.verts[..]).chain(hinges.iter().map(|h| &h.verts[..])),
        ),
        Elasticity::MassSpring => {
            BlockMatrix::from_elements(n, springs.iter().map(|s| &s.verts[..]))
        }
    }
}

/// Mass shares for the indefinite curvature terms: half of `mᵢ / (conditions at i)`, the least
/// over an element's vertices.
pub(super) fn mass_shares(
    model: Elasticity,
    mass: &[f64],
    elements: &mut [Triangle],
    springs: &mut [Spring],
) {
    let mut count = vec![0usize; mass.len()];
    match model {
        Elasticity::BaraffWitkin => {
            elements.iter().flat_map(|t| t.verts).for_each(|v| count[v] += 3)
        }
        Elasticity::MassSpring => springs.iter().flat_map(|s| s.verts).for_each(|v| count[v] += 1),
    }
    let share = |v: usize| 0.5 * mass[v] / count[v].max(1) as f64;
    for t in elements {
        t.mass_share = t.verts.iter().map(|&v| share(v)).fold(f64::INFINITY, f64::min);
    }
    for s in springs {
        s.mass_share = s.verts.iter().map(|&v| share(v)).fold(f64::INFINITY, f64::min);
    }
}

/// Each element's slots in `matrix`: the block of every pair of its vertices (a triangle's
/// only in the triangle model, where it is in the pattern).
pub(super) fn slots(
    model: Elasticity,
    matrix: &BlockMatrix,
    elements: &mut [Triangle],
    hinges: &mut [Hinge],
    springs: &mut [Spring],
) {
    for t in elements {
        t.slots = std::array::from_fn(|k| {
            if model == Elasticity::BaraffWitkin {
                matrix.slot(t.verts[k / 3], t.verts[k % 3])
            } else {
                0
            }
        });
    }
    for h in hinges {
        h.slots = std::array::from_fn(|k| matrix.slot(h.verts[k / 4], h.verts[k % 4]));
    }
    for s in springs {
        s.slots = std::array::from_fn(|k| matrix.slot(s.verts[k / 2], s.verts[k % 2]));
    }
}
