//! The cloth's model: what is built once from the mesh and read by every step — topology,
//! lumped masses, the elements with their rest shapes (Baraff & Witkin 1998, §4), the
//! material, gravity, the collision thickness — and the checks a decoded model must pass.
//! The block pattern of the implicit matrix is a function of the elements
//! ([`Model::pattern`]); the slots of every element in it are stored with the element.

use super::elements::{Hinge, Spring, Triangle};
use super::{build, BlockMatrix, Elasticity, Material, Mesh, SelfCollision, State, Topology};
use crate::error::{Error, Result};
use crate::snapshot::{check, fingerprint, finite};
use glam::DVec3;

/// A cloth's model (see the module documentation); [`Model::state`] gives its initial
/// [`State`], [`super::Solver::new`] a solver for it.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Model {
    /// The triangles (vertex indices), `(M, 3)`.
    pub(super) triangles: Vec<[usize; 3]>,
    pub(super) elasticity: Elasticity,
    pub(super) material: Material,
    /// Gravity (m/s²).
    pub(super) gravity: DVec3,
    /// Collision thickness (m).
    pub(super) thickness: f64,
    /// Self-collision, when on.
    pub(super) self_collision: Option<SelfCollision>,
    /// The mesh's positions (m), `(N, 3)`: the initial positions of [`Model::state`].
    pub(super) initial: Vec<DVec3>,
    /// Lumped vertex masses (kg), `(N,)`.
    pub(super) mass: Vec<f64>,
    pub(super) elements: Vec<Triangle>,
    pub(super) hinges: Vec<Hinge>,
    pub(super) springs: Vec<Spring>,
}

impl Model {
    /// The model of a cloth on `mesh` (rest state: the mesh's uv for stretch and shear, its
    /// initial shape for bending), with vertex masses `density × area / 3` from the rest areas
    /// of the triangles around each vertex, and a collision thickness of 1 mm.
    ///
    /// # Errors
    /// An invalid mesh ([`Mesh::validate`]) or material (negative, non-finite, or zero density
    /// or stretch), or non-finite gravity.
    pub fn new(
        mesh: Mesh,
        elasticity: Elasticity,
        material: Material,
        gravity: DVec3,
    ) -> Result<Model> {
        mesh.validate()?;
        material.check()?;
        if !gravity.is_finite() {
            return Err(Error::invalid("gravity", "must be finite"));
        }
        let n = mesh.positions.len();
        let x: Vec<DVec3> = mesh.positions.iter().map(|p| DVec3::from_array(*p)).collect();
        let topology = Topology::new(&mesh.triangles);
        let mut elements: Vec<Triangle> =
            mesh.triangles.iter().zip(&mesh.uv).map(|(t, uv)| Triangle::new(*t, *uv)).collect();
        let mass = build::lumped_masses(n, &elements, material.density);
        let (mut hinges, mut springs) = match elasticity {
            Elasticity::BaraffWitkin => (build::hinges(&topology, &x, material.bend), Vec::new()),
            Elasticity::MassSpring => (Vec::new(), build::springs(&topology, &x, &material)),
        };
        let pattern = build::pattern(n, elasticity, &elements, &hinges, &springs);
        build::mass_shares(elasticity, &mass, &mut elements, &mut springs);
        build::slots(elasticity, &pattern, &mut elements, &mut hinges, &mut springs);
        Ok(Model {
            triangles: mesh.triangles,
            elasticity,
            material,
            gravity,
            thickness: 1e-3,
            self_collision: None,
            initial: x,
            mass,
            elements,
            hinges,
            springs,
        })
    }

    /// The initial state: the mesh's positions, at rest, at time 0, free, without colliders.
    pub fn state(&self) -> State {
        State::new(self)
    }

    /// Number of vertices `N`.
    pub fn len(&self) -> usize {
        self.mass.len()
    }

    /// Whether the model has no vertices (never: a cloth has at least one triangle).
    pub fn is_empty(&self) -> bool {
        self.mass.is_empty()
    }

    /// The triangles, `(M, 3)` vertex indices.
    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    /// The elastic model.
    pub fn elasticity(&self) -> Elasticity {
        self.elasticity
    }

    /// The material.
    pub fn material(&self) -> Material {
        self.material
    }

    /// Gravity (m/s²).
    pub fn gravity(&self) -> DVec3 {
        self.gravity
    }

    /// Vertex masses (kg), `(N,)`.
    pub fn masses(&self) -> &[f64] {
        &self.mass
    }

    /// Collision thickness (m): contacts keep vertices this far from collider surfaces.
    pub fn thickness(&self) -> f64 {
        self.thickness
    }

    /// Set the collision thickness (m, >= 0).
    ///
    /// # Errors
    /// A negative or non-finite value; the model is then unchanged.
    pub fn set_thickness(&mut self, thickness: f64) -> Result<()> {
        if !thickness.is_finite() || thickness < 0.0 {
            return Err(Error::invalid(
                "thickness",
                format!("must be finite and >= 0, got {thickness}"),
            ));
        }
        self.thickness = thickness;
        Ok(())
    }

    /// Self-collision settings, `None` when off (the default).
    pub fn self_collision(&self) -> Option<SelfCollision> {
        self.self_collision
    }

    /// Turn self-collision on (Bridson, Fedkiw & Anderson 2002; see the `self_collide`
    /// module docs of the cloth) with `settings`, or off with `None`. It uses the model's
    /// thickness ([`Model::set_thickness`]).
    ///
    /// # Errors
    /// A negative or non-finite friction; the model is then unchanged.
    pub fn set_self_collision(&mut self, settings: Option<SelfCollision>) -> Result<()> {
        if let Some(s) = settings {
            crate::geometry::material::friction(s.friction)?;
        }
        self.self_collision = settings;
        Ok(())
    }

    /// Mean length (m) of the triangles' edges in the initial shape (each interior edge
    /// counted twice): the scale of a mesh, from which a self-collision thickness is chosen.
    pub fn mean_edge_length(&self) -> f64 {
        let x = &self.initial;
        let total: f64 = self
            .triangles
            .iter()
            .map(|t| (0..3).map(|k| (x[t[(k + 1) % 3]] - x[t[k]]).length()).sum::<f64>())
            .sum();
        total / (3 * self.triangles.len()) as f64
    }

    /// The block pattern of the implicit matrix (zero blocks): every pair of vertices that
    /// share an element of the model. Allocates.
    pub fn pattern(&self) -> BlockMatrix {
        build::pattern(self.len(), self.elasticity, &self.elements, &self.hinges, &self.springs)
    }

    /// A deterministic 64-bit hash of the model ([`crate::snapshot::fingerprint`] of its
    /// serialized bytes): state snapshots record it, and restoring one onto a model with
    /// another fingerprint is refused.
    pub fn fingerprint(&self) -> u64 {
        fingerprint(self)
    }

    /// Check a decoded model: lengths consistent, parameters finite and in range, every
    /// element's vertices in range and its slots those of [`Model::pattern`].
    ///
    /// # Errors
    /// [`Error::InvalidInput`] naming the first inconsistent field.
    pub(super) fn validate(&self) -> Result<()> {
        let n = self.mass.len();
        check(n > 0 && !self.triangles.is_empty(), "mass", || "a cloth needs vertices".into())?;
        check(self.initial.len() == n, "initial", || format!("not of {n} vertices"))?;
        check(finite(self.initial.iter().flat_map(|p| p.to_array())), "initial", || {
            "non-finite positions".into()
        })?;
        check(self.mass.iter().all(|m| m.is_finite() && *m > 0.0), "mass", || {
            "masses must be finite and positive".into()
        })?;
        let m = &self.material;
        check(
            finite([m.density, m.stretch, m.shear, m.bend, m.damping, m.air_damping])
                && [m.density, m.stretch].iter().all(|&v| v > 0.0)
                && [m.shear, m.bend, m.damping, m.air_damping].iter().all(|&v| v >= 0.0),
            "material",
            || "material parameters out of range".into(),
        )?;
        check(
            self.gravity.is_finite() && self.thickness.is_finite() && self.thickness >= 0.0,
            "gravity",
            || "gravity and thickness must be finite".into(),
        )?;
        check(
            self.self_collision.is_none_or(|s| s.friction.is_finite() && s.friction >= 0.0),
            "self_collision",
            || "friction must be finite and >= 0".into(),
        )?;
        self.check_elements(n)?;
        self.check_slots(n)
    }

    /// Elements, hinges and springs index existing vertices and carry finite parameters.
    fn check_elements(&self, n: usize) -> Result<()> {
        let inside = |verts: &[usize]| verts.iter().all(|&v| v < n);
        check(self.triangles.iter().all(|t| inside(t)), "triangles", || {
            format!("vertex index out of range ({n} vertices)")
        })?;
        check(
            self.elements.len() == self.triangles.len()
                && self.elements.iter().zip(&self.triangles).all(|(e, t)| e.verts == *t),
            "elements",
            || "do not match the triangles".into(),
        )?;
        check(
            self.elements.iter().all(|e| {
                finite(e.du.iter().chain(&e.dv).copied())
                    && e.area.is_finite()
                    && e.area > 0.0
                    && e.mass_share.is_finite()
            }),
            "elements",
            || "non-finite rest shape or zero area".into(),
        )?;
        check(
            self.hinges.iter().all(|h| inside(&h.verts) && finite([h.rest_angle, h.k])),
            "hinges",
            || "vertex out of range or non-finite parameters".into(),
        )?;
        check(
            self.springs.iter().all(|s| inside(&s.verts) && finite([s.rest, s.k, s.mass_share])),
            "springs",
            || "vertex out of range or non-finite parameters".into(),
        )?;
        let bending = self.elasticity == Elasticity::BaraffWitkin;
        check(
            if bending { self.springs.is_empty() } else { self.hinges.is_empty() },
            "springs",
            || "elements of another model".into(),
        )
    }

    /// Every element's slots are those [`Model::new`] gives it in [`Model::pattern`] (so a
    /// damaged slot cannot send the assembly out of bounds). Vertices checked in range first.
    fn check_slots(&self, n: usize) -> Result<()> {
        let pattern = self.pattern();
        check(pattern.n() == n, "slots", || "pattern of another size".into())?;
        let slots = |verts: &[usize], k: usize| {
            let w = verts.len();
            pattern.slot(verts[k / w], verts[k % w])
        };
        let bending = self.elasticity == Elasticity::BaraffWitkin;
        let triangles_ok = self
            .elements
            .iter()
            .all(|t| (0..9).all(|k| t.slots[k] == if bending { slots(&t.verts, k) } else { 0 }));
        let hinges_ok =
            self.hinges.iter().all(|h| (0..16).all(|k| h.slots[k] == slots(&h.verts, k)));
        let springs_ok =
            self.springs.iter().all(|s| (0..4).all(|k| s.slots[k] == slots(&s.verts, k)));
        check(triangles_ok && hinges_ok && springs_ok, "slots", || {
            "element slots do not match the matrix pattern".into()
        })
    }
}
