//! The rod model: what every step reads and no step changes — the rest shape (edge lengths,
//! Voronoi lengths, material curvatures and twists of the given points, their reference
//! frames), the cross-section and material, the lumped masses and twist inertias, gravity,
//! the solver settings and the boundary conditions (pinned vertices, locked twist angles).

use super::contact::{validate_settings, Collider};
use super::frames::{curvature_binormal, directors, perpendicular, reference_twist, transport};
use crate::error::{Error, Result};
use glam::DVec3;
use std::f64::consts::PI;

/// The rod's material and cross-section.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Young's modulus `E` (Pa).
    pub youngs_modulus: f64,
    /// Shear modulus `G` (Pa); `E / (2 (1 + ν))` for Poisson's ratio `ν`.
    pub shear_modulus: f64,
    /// Density `ρ` (kg/m³).
    pub density: f64,
    /// Semi-axes `(a, b)` of the elliptic cross-section (m): `a` along the material director
    /// `m1`, `b` along `m2`; equal for a round rod of radius `a`.
    pub radius: [f64; 2],
}

/// How [`super::Solver::step`] integrates in time.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integrator {
    /// Implicit (backward) Euler: each step minimises the incremental potential by Newton's
    /// method on the banded Hessian with a backtracking line search (the default; stable at
    /// any step, first order, damps).
    ImplicitEuler,
    /// Symplectic (semi-implicit) Euler: explicit, first order, stable only below the rod's
    /// fastest period over `π` (for comparison).
    SymplecticEuler,
}

/// Settings of the solver and the world.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Gravity (m/s², default `(0, -9.81, 0)`).
    pub gravity: DVec3,
    /// The time integrator (default implicit Euler).
    pub integrator: Integrator,
    /// Newton stops when a step moves no vertex more than `tolerance` times the rod's length
    /// and turns no twist angle more than `tolerance` rad (default 1e-10).
    pub tolerance: f64,
    /// The most Newton iterations of one step or static solve (default 100).
    pub max_iterations: usize,
    /// Stiffness `k` of the contact penalty (N/m, default 1e4): a resting vertex sinks by
    /// its load over `k` (see `contact.rs`).
    pub contact_stiffness: f64,
    /// Friction's sliding-speed threshold `ε_v` (m/s, default 1e-3): below it friction is a
    /// stiff spring (a held contact creeps slower than `ε_v`), above it Coulomb's `μ λ`.
    pub friction_velocity: f64,
    /// Whether the edges keep their rest lengths exactly (default false: stiff stretching
    /// alone). Each step is followed by a fast projection onto the edge-length constraints
    /// (Goldenthal, Harmon, Fattal, Bercovier & Grinspun 2007, "Efficient simulation of
    /// inextensible cloth", sec. 4), the velocities taking the correction over the step.
    pub inextensible: bool,
    /// Whether the twist angles are quasi-static (default false: they have their inertia):
    /// each implicit step minimises the energy over the free twists given the centreline
    /// (Bergou et al. 2008, sec. 6: the twist's inertia is negligible), done by giving them
    /// no inertia in the step's minimisation. Only with implicit Euler.
    pub quasistatic_twist: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            gravity: DVec3::new(0.0, -9.81, 0.0),
            integrator: Integrator::ImplicitEuler,
            tolerance: 1e-10,
            max_iterations: 100,
            contact_stiffness: 1e4,
            friction_velocity: 1e-3,
            inextensible: false,
            quasistatic_twist: false,
        }
    }
}

/// A rod model (see the module docs): read-only during a step (`&Model`); several
/// [`super::State`]s may share it. An open rod of `n` edges has `V = n + 1` vertices and
/// `n − 1` interior vertices (stencils); a closed rod (a ring, [`Model::closed`]) has
/// `V = n` vertices, edge `j` joining vertex `j` to `(j + 1) mod n`, and `n` stencils.
/// Stencil `k` is the vertex `(k + 1) mod V` between edges `k` and `(k + 1) mod n`.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct Model {
    pub(super) material: Material,
    pub(super) settings: Settings,
    /// Whether the last vertex joins the first by an edge (a ring).
    pub(super) closed: bool,
    /// Whether the rod is naturally straight and untwisted ([`Model::straighten`]).
    pub(super) straight: bool,
    /// The rest positions (m), `V`: the shape the rod was built from.
    pub(super) rest_positions: Vec<DVec3>,
    /// The reference directors `d1` of the rest shape (space-parallel transported from the
    /// first edge's), `n`.
    pub(super) rest_reference: Vec<DVec3>,
    /// Rest edge lengths `l̄_j` (m), `n`.
    pub(super) rest_lengths: Vec<f64>,
    /// Voronoi lengths `(l̄_k + l̄_{k+1}) / 2` of the stencils (m).
    pub(super) voronoi: Vec<f64>,
    /// Rest material curvatures `(κ̄1, κ̄2)` of the stencils (natural curvature: those of
    /// the rest shape at zero twist; zero when straightened).
    pub(super) rest_curvatures: Vec<[f64; 2]>,
    /// Rest twists `m̄` of the stencils (rad): the rest shape's reference twist (zero for
    /// its space-parallel frames, but for a ring's holonomy at its last stencil; zero when
    /// straightened).
    pub(super) rest_twists: Vec<f64>,
    /// Lumped vertex masses `ρ A (l̄_{i−1} + l̄_i)/2` (kg), `V`.
    pub(super) masses: Vec<f64>,
    /// Twist inertias `ρ (I1 + I2) l̄_j` (kg m²) of the edges, `n`.
    pub(super) inertias: Vec<f64>,
    /// Pinned vertices (position held), `V`.
    pub(super) pinned: Vec<bool>,
    /// Edges whose twist angle is held, `n`.
    pub(super) locked: Vec<bool>,
    /// Static collision shapes with their friction.
    pub(super) colliders: Vec<Collider>,
}

/// An end of a rod.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum End {
    /// Vertex 0 and edge 0.
    First,
    /// The last vertex and edge.
    Last,
}

impl Material {
    fn validate(&self) -> Result<()> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        for (arg, v) in [
            ("youngs_modulus", self.youngs_modulus),
            ("shear_modulus", self.shear_modulus),
            ("density", self.density),
            ("radius", self.radius[0]),
            ("radius", self.radius[1]),
        ] {
            if !positive(v) {
                return Err(Error::invalid(arg, "must be finite and > 0"));
            }
        }
        Ok(())
    }

    /// Cross-section area `A = π a b` (m²).
    pub fn area(&self) -> f64 {
        PI * self.radius[0] * self.radius[1]
    }

    /// Second moments of area `(I1, I2) = (π a³ b / 4, π a b³ / 4)` (m⁴): resisting bending
    /// towards `m1` and towards `m2`.
    pub fn second_moments(&self) -> [f64; 2] {
        let [a, b] = self.radius;
        [PI * a * a * a * b / 4.0, PI * a * b * b * b / 4.0]
    }

    /// Torsion constant of the ellipse `J = π a³ b³ / (a² + b²)` (m⁴; `π r⁴ / 2` when round).
    pub fn torsion_constant(&self) -> f64 {
        let [a, b] = self.radius;
        PI * (a * b).powi(3) / (a * a + b * b)
    }
}

impl Settings {
    fn validate(&self) -> Result<()> {
        if !self.gravity.is_finite() {
            return Err(Error::invalid("gravity", "must be finite"));
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return Err(Error::invalid("tolerance", "must be finite and > 0"));
        }
        if self.max_iterations == 0 {
            return Err(Error::invalid("max_iterations", "must be at least 1"));
        }
        if self.quasistatic_twist && self.integrator != Integrator::ImplicitEuler {
            return Err(Error::invalid(
                "quasistatic_twist",
                "needs the implicit integrator (symplectic Euler cannot step a twist without inertia)",
            ));
        }
        validate_settings(self.contact_stiffness, self.friction_velocity)
    }
}

impl Model {
    /// The model of an open rod whose rest shape is `points` (m, at least 2, consecutive
    /// points distinct, no turn of 170° or more at a vertex), free (nothing pinned).
    ///
    /// # Errors
    /// Fewer than 2 points, non-finite or coincident points, a near half turn (`points`, with
    /// index); a material or setting out of range (named).
    pub fn new(points: &[DVec3], material: Material, settings: Settings) -> Result<Self> {
        Model::build(points, material, settings, false)
    }

    /// The model of a closed rod (a ring) through `points` (m, at least 3; the last joins
    /// the first by an edge), its rest shape: its natural curvature is the loop's (an O-ring)
    /// unless [`Model::straighten`]ed (a ring bent from a straight wire).
    ///
    /// # Errors
    /// As [`Model::new`], and fewer than 3 points (`points`).
    pub fn closed(points: &[DVec3], material: Material, settings: Settings) -> Result<Self> {
        if points.len() < 3 {
            return Err(Error::invalid("points", "a closed rod needs at least 3 points"));
        }
        Model::build(points, material, settings, true)
    }

    fn build(
        points: &[DVec3],
        material: Material,
        settings: Settings,
        closed: bool,
    ) -> Result<Self> {
        material.validate()?;
        settings.validate()?;
        if points.len() < 2 {
            return Err(Error::invalid("points", "a rod needs at least 2 points"));
        }
        if let Some(i) = points.iter().position(|p| !p.is_finite()) {
            return Err(Error::invalid("points", "contains NaN or infinity").at(i));
        }
        let v = points.len();
        let n = if closed { v } else { v - 1 };
        let edges: Vec<DVec3> = (0..n).map(|j| points[(j + 1) % v] - points[j]).collect();
        let scale = edges.iter().map(|e| e.length()).fold(0.0, f64::max);
        if let Some(j) =
            edges.iter().position(|e| e.length() <= 1e-9 * scale || !e.length().is_finite())
        {
            return Err(Error::invalid("points", "coincides with the next point").at(j));
        }
        let tangents: Vec<DVec3> = edges.iter().map(|e| e.normalize()).collect();
        let stencils = if closed { n } else { n - 1 };
        let pair = |k: usize| (k, (k + 1) % n);
        if let Some(k) = (0..stencils).position(|k| {
            let (a, b) = pair(k);
            tangents[a].dot(tangents[b]) < (170f64).to_radians().cos()
        }) {
            return Err(Error::invalid("points", "turns by 170 degrees or more").at((k + 1) % v));
        }
        let mut reference = vec![perpendicular(tangents[0])];
        for j in 1..n {
            let d = transport(reference[j - 1], tangents[j - 1], tangents[j]);
            reference.push((d - d.dot(tangents[j]) * tangents[j]).normalize());
        }
        let rest_lengths: Vec<f64> = edges.iter().map(|e| e.length()).collect();
        let mut voronoi = Vec::with_capacity(stencils);
        let mut rest_curvatures = Vec::with_capacity(stencils);
        let mut rest_twists = Vec::with_capacity(stencils);
        for k in 0..stencils {
            let (a, b) = pair(k);
            voronoi.push(0.5 * (rest_lengths[a] + rest_lengths[b]));
            let kb = curvature_binormal(edges[a], edges[b]);
            let (m1e, m2e) = directors(tangents[a], reference[a], 0.0);
            let (m1f, m2f) = directors(tangents[b], reference[b], 0.0);
            rest_curvatures.push([0.5 * kb.dot(m2e + m2f), -0.5 * kb.dot(m1e + m1f)]);
            let (t0, t1) = (tangents[a], tangents[b]);
            rest_twists.push(reference_twist(t0, reference[a], t1, reference[b], 0.0));
        }
        let rho_a = material.density * material.area();
        let mut masses = vec![0.0; v];
        for (j, l) in rest_lengths.iter().enumerate() {
            masses[j] += 0.5 * rho_a * l;
            masses[(j + 1) % v] += 0.5 * rho_a * l;
        }
        let [i1, i2] = material.second_moments();
        let inertias = rest_lengths.iter().map(|l| material.density * (i1 + i2) * l).collect();
        Ok(Model {
            material,
            settings,
            closed,
            straight: false,
            rest_positions: points.to_vec(),
            rest_reference: reference,
            rest_lengths,
            voronoi,
            rest_curvatures,
            rest_twists,
            masses,
            inertias,
            pinned: vec![false; v],
            locked: vec![false; n],
            colliders: Vec::new(),
        })
    }

    /// Make the rod naturally straight and untwisted: rest curvatures and twists zero, the
    /// points only its initial shape (a straight wire bent into it, as Michell's ring).
    pub fn straighten(&mut self) {
        self.straight = true;
        self.rest_curvatures.fill([0.0; 2]);
        self.rest_twists.fill(0.0);
    }

    /// Whether the rod is closed (a ring).
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// Number of vertices `V` (`n + 1` open, `n` closed).
    pub fn vertices(&self) -> usize {
        self.masses.len()
    }

    /// Number of degrees of freedom, `3 V` positions and `n` twist angles interleaved.
    pub fn dofs(&self) -> usize {
        3 * self.vertices() + self.edges()
    }

    /// Number of stencils (bending and twisting vertices): `n − 1` open, `n` closed.
    pub fn stencils(&self) -> usize {
        self.voronoi.len()
    }

    /// Number of edges `n`.
    pub fn edges(&self) -> usize {
        self.rest_lengths.len()
    }

    /// The material and cross-section.
    pub fn material(&self) -> &Material {
        &self.material
    }

    /// The settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The rest positions (m), `V`.
    pub fn rest_positions(&self) -> &[DVec3] {
        &self.rest_positions
    }

    /// The rest edge lengths (m), `n`.
    pub fn rest_lengths(&self) -> &[f64] {
        &self.rest_lengths
    }

    /// The lumped vertex masses (kg), `V`.
    pub fn masses(&self) -> &[f64] {
        &self.masses
    }

    /// Stretching stiffness `E A` (N).
    pub fn stretching_stiffness(&self) -> f64 {
        self.material.youngs_modulus * self.material.area()
    }

    /// Bending stiffnesses `(E I1, E I2)` (N m²).
    pub fn bending_stiffness(&self) -> [f64; 2] {
        self.material.second_moments().map(|i| self.material.youngs_modulus * i)
    }

    /// Twisting stiffness `G J` (N m²).
    pub fn twisting_stiffness(&self) -> f64 {
        self.material.shear_modulus * self.material.torsion_constant()
    }

    /// Pinned vertices, `V`.
    pub fn pinned(&self) -> &[bool] {
        &self.pinned
    }

    /// Edges whose twist angle is held, `n`.
    pub fn locked(&self) -> &[bool] {
        &self.locked
    }

    /// Hold vertex `i` where it is.
    ///
    /// # Errors
    /// `i` beyond the last vertex (`index`).
    pub fn pin(&mut self, i: usize) -> Result<()> {
        let Some(p) = self.pinned.get_mut(i) else {
            return Err(Error::invalid("index", "beyond the last vertex"));
        };
        *p = true;
        Ok(())
    }

    /// Clamp an end: hold its two vertices and its edge's twist angle, so its edge keeps its
    /// position and material frame (of a ring: its first or last edge).
    pub fn clamp(&mut self, end: End) {
        let (j, v) = (self.end_edge(end), self.vertices());
        self.pinned[j] = true;
        self.pinned[(j + 1) % v] = true;
        self.locked[j] = true;
    }

    /// The edge of an end: 0 or `n − 1`.
    pub(super) fn end_edge(&self, end: End) -> usize {
        match end {
            End::First => 0,
            End::Last => self.edges() - 1,
        }
    }

    /// The static collision shapes.
    pub fn colliders(&self) -> &[Collider] {
        &self.colliders
    }

    /// Add a static collision shape with its friction (see `contact.rs`).
    ///
    /// # Errors
    /// Those of [`Collider::checked`].
    pub fn add_collider(&mut self, collider: Collider) -> Result<()> {
        self.colliders.push(collider.checked()?);
        Ok(())
    }

    /// Change the settings (gravity, integrator, tolerances).
    ///
    /// # Errors
    /// A setting out of range (named).
    pub fn set_settings(&mut self, settings: Settings) -> Result<()> {
        settings.validate()?;
        self.settings = settings;
        Ok(())
    }

    /// A deterministic 64-bit hash of the model ([`crate::snapshot::fingerprint`]), recorded
    /// by state snapshots so that a state is not restored onto another model.
    pub fn fingerprint(&self) -> u64 {
        crate::snapshot::fingerprint(self)
    }

    /// Check a decoded model: lengths consistent, values finite and in range.
    pub(super) fn validate(&self) -> Result<()> {
        use crate::snapshot::check;
        let mut fresh =
            Model::build(&self.rest_positions, self.material, self.settings, self.closed)?;
        if self.straight {
            fresh.straighten();
        }
        check(
            fresh.rest_lengths == self.rest_lengths
                && fresh.voronoi == self.voronoi
                && fresh.rest_curvatures == self.rest_curvatures
                && fresh.rest_twists == self.rest_twists
                && fresh.masses == self.masses
                && fresh.inertias == self.inertias
                && fresh.rest_reference == self.rest_reference,
            "rest_positions",
            || "rest quantities do not match the rest shape".into(),
        )?;
        check(
            self.pinned.len() == self.masses.len() && self.locked.len() == self.rest_lengths.len(),
            "pinned",
            || "one flag per vertex and per edge".into(),
        )?;
        for c in &self.colliders {
            c.checked()?;
        }
        Ok(())
    }
}
