//! Cloth: the Baraff–Witkin (1998) "Large Steps in Cloth Simulation" triangle model and a
//! mass-spring model, stepped by implicit Euler with one Newton step (the paper's method),
//! BDF2 (Choi & Ko 2002), or any explicit method of [`crate::ode`] for comparison.
//!
//! An implicit step solves `A Δv = b` with
//! `A = M - h ∂f/∂v - h² ∂f/∂x`, `b = h (f₀ + ∂f/∂x (h v₀ + y))` (Baraff & Witkin 1998,
//! eqs. 15–18; `y` is the collision position correction of §6), assembled into a block-sparse
//! matrix ([`bsr::BlockMatrix`]) whose pattern is built once. BDF2 solves the same system
//! with `h` replaced by `2h/3` and the history terms of Choi & Ko (2002), eq. 12, at a
//! constant step, and with the variable-step coefficients of [`crate::ode::bdf2_weights`]
//! (`γh` and `c (x - x₋)`) after a change of step.
//!
//! Constraints are imposed by mass modification (§5.3): each vertex has a filter `S_i`
//! (identity when free, `I - n̂n̂ᵀ` on a plane, `d̂d̂ᵀ` on a line, 0 when pinned) and a
//! prescribed velocity change `z_i` in the constrained directions. The two solvers:
//! - [`Solver::Pcg`]: the paper's modified preconditioned conjugate gradient, which keeps
//!   every iterate in `z + range(S)`, with the stopping rule `δ < ε² δ₀` on the
//!   preconditioned residual; the preconditioner is block SSOR (over-relaxed symmetric
//!   Gauss–Seidel, `ω` growing with the mesh, applied by Eisenstat's trick) instead of the
//!   paper's block-Jacobi: a third of the iterations or fewer at about the same cost per
//!   iteration (the flops of one matrix product);
//! - [`Solver::Cholesky`]: faer's sparse Cholesky on the equivalent SPD system
//!   `(S A S + I - S) y = S (b - A z)`, `Δv = z + y`, whose symbolic factorisation is
//!   computed on first use and reused every step.
//!
//! Collisions with planes, spheres and capsules (which may move at constant velocity) become
//! constraints too (§6): a vertex whose predicted position comes within `2 thickness` of a
//! surface is held to end the step at `thickness` from it — a vertex above the surface gets
//! the normal velocity that lands it there, one below moves with the surface and the position
//! correction `y` lifts it out. Coulomb friction is an explicit force: the tangential impulse
//! that would bring the vertex to rest on the surface within the step (against its momentum
//! and gravity), limited to `μ jₙ` with `jₙ` the normal constraint impulse of the last step,
//! read from the residual `A Δv - b` (§5.3) — static friction when the limit is not reached,
//! sliding otherwise. A pulling normal
//! impulse releases the contact. Vertices dragged into a collider by their neighbours are
//! projected out after the step. Self-collision is not handled (yet).

mod bsr;
mod mesh;
mod model;
mod pcg;
mod snapshot;

pub use bsr::BlockMatrix;
pub use mesh::{parse_obj, uv_from_shape, write_obj, Mesh, Topology, Triangulation};
pub use model::dihedral_angle;

use crate::error::{Error, Result};
use crate::linalg::SparseCholesky;
use crate::ode::{bdf2_weights, Method, OdeSystem, Stepper};
use crate::sdf;
use glam::{DMat3, DQuat, DVec3};
use model::{Accumulator, Hinge, Spring, Triangle};
use std::time::Instant;

/// The material model.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    /// Baraff–Witkin triangle conditions (stretch, shear) and dihedral-angle bending.
    BaraffWitkin,
    /// Stretch and shear springs on edges and across quads, bend springs across the other
    /// interior edges, each with a damper.
    MassSpring,
}

/// Material parameters.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Areal density (kg/m²).
    pub density: f64,
    /// Stretch stiffness (N/m): membrane stiffness for the triangle model (energy
    /// `stretch/2 · a (‖w‖ - 1)²` per triangle), spring constant for stretch springs.
    pub stretch: f64,
    /// Shear stiffness (N/m), same meaning for the shear condition and shear springs.
    pub shear: f64,
    /// Bending stiffness (N m): hinge stiffness `bend · 3|e|²/(A₁ + A₂)` (the discrete-shells
    /// scaling, Grinspun et al. 2003) for the triangle model, `bend / L²` for bend springs.
    pub bend: f64,
    /// Stiffness-proportional damping (s): every condition gets `k_d = damping · k`.
    pub damping: f64,
    /// Mass-proportional (air) damping (1/s): a force `-air_damping · mᵢ vᵢ` on every vertex.
    /// With `damping` it makes Rayleigh damping `α M + β K`.
    pub air_damping: f64,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            density: 0.1,
            stretch: 1e3,
            shear: 1e2,
            bend: 1e-5,
            damping: 1e-3,
            air_damping: 0.0,
        }
    }
}

/// The linear solver of the implicit step.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Solver {
    /// Modified preconditioned conjugate gradient with the filter (Baraff & Witkin §5.3).
    Pcg,
    /// Sparse Cholesky (faer) of the filtered SPD system.
    Cholesky,
}

/// The surface of a collider.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// Free side: where `(x - point)·normal > 0`.
    Plane {
        /// A point of the plane (m).
        point: DVec3,
        /// Normal towards the free side (normalised on construction).
        normal: DVec3,
    },
    /// A solid sphere.
    Sphere {
        /// Centre (m).
        center: DVec3,
        /// Radius (m).
        radius: f64,
    },
    /// A solid capsule: all points within `radius` of the segment `a`–`b`.
    Capsule {
        /// First end of the axis (m).
        a: DVec3,
        /// Second end of the axis (m).
        b: DVec3,
        /// Radius (m).
        radius: f64,
    },
    /// A solid box.
    Box {
        /// Centre (m).
        center: DVec3,
        /// Orientation (body → world, unit).
        rotation: DQuat,
        /// Half extents along the box's axes (m).
        half: DVec3,
    },
}

/// A kinematic collider: a shape moving at a constant velocity, with Coulomb friction.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Collider {
    /// The shape at the cloth's current time.
    pub shape: Shape,
    /// Velocity (m/s); the shape is translated by `velocity · dt` each step.
    pub velocity: DVec3,
    /// Coulomb friction coefficient >= 0.
    pub friction: f64,
}

impl Collider {
    fn validate(&self) -> Result<()> {
        let finite = |v: DVec3| v.is_finite();
        let ok = match self.shape {
            Shape::Plane { point, normal } => {
                finite(point) && finite(normal) && normal.length() > 0.0
            }
            Shape::Sphere { center, radius } => {
                finite(center) && radius.is_finite() && radius > 0.0
            }
            Shape::Capsule { a, b, radius } => {
                finite(a) && finite(b) && radius.is_finite() && radius > 0.0
            }
            Shape::Box { center, rotation, half } => {
                finite(center)
                    && rotation.is_finite()
                    && (rotation.length() - 1.0).abs() < 1e-9
                    && finite(half)
                    && half.min_element() > 0.0
            }
        };
        if !ok {
            return Err(Error::invalid(
                "collider",
                "needs finite coordinates, a non-zero normal, a positive radius or half extents \
                 and a unit rotation",
            ));
        }
        if !finite(self.velocity) {
            return Err(Error::invalid("velocity", "must be finite"));
        }
        if self.friction.is_nan() || self.friction < 0.0 || self.friction.is_infinite() {
            return Err(Error::invalid(
                "friction",
                format!("must be finite and >= 0, got {}", self.friction),
            ));
        }
        Ok(())
    }

    /// The shape translated by `d`.
    fn translated(&self, d: DVec3) -> Shape {
        match self.shape {
            Shape::Plane { point, normal } => Shape::Plane { point: point + d, normal },
            Shape::Sphere { center, radius } => Shape::Sphere { center: center + d, radius },
            Shape::Capsule { a, b, radius } => Shape::Capsule { a: a + d, b: b + d, radius },
            Shape::Box { center, rotation, half } => {
                Shape::Box { center: center + d, rotation, half }
            }
        }
    }
}

/// Signed distance from `p` to the surface of `shape` and the outward normal there.
fn distance(shape: &Shape, p: DVec3) -> (f64, DVec3) {
    match *shape {
        Shape::Plane { point, normal } => ((p - point).dot(normal), normal),
        Shape::Sphere { center, radius } => sdf::sphere(center, radius, p),
        Shape::Capsule { a, b, radius } => sdf::capsule(a, b, radius, p),
        Shape::Box { center, rotation, half } => sdf::oriented_box(center, rotation, half, p),
    }
}

/// What a vertex's contact did in the last step.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
enum ContactState {
    /// Not in contact.
    Free,
    /// The contact impulse pulled: the vertex may leave unless it would penetrate.
    Released,
    /// In contact, with the normal impulse (N s) of the last step.
    Touching(f64),
}

/// A user constraint on one vertex.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub enum VertexConstraint {
    /// Held at a position (m).
    Pinned(DVec3),
    /// Free to move in the plane through its position with this unit normal.
    Plane(DVec3),
    /// Free to move along the line through its position with this unit direction.
    Line(DVec3),
    /// Moving at a prescribed velocity (m/s).
    Velocity(DVec3),
}

/// Numbers of the last step.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, Default, PartialEq)]
pub struct StepStats {
    /// Conjugate-gradient iterations (0 for Cholesky and explicit steps).
    pub iterations: usize,
    /// Relative residual of the linear solve: `sqrt(δ/δ₀)` for PCG, `‖S(A Δv - b)‖/‖S b‖` for
    /// Cholesky.
    pub residual: f64,
    /// Whether the solve met its tolerance (PCG may stop at its iteration limit).
    pub converged: bool,
    /// Vertices in contact with a collider.
    pub contacts: usize,
    /// Implicit steps taken (more than one when the step was subdivided).
    pub substeps: usize,
    /// Seconds spent assembling forces and the matrix.
    pub assemble_seconds: f64,
    /// Seconds in the linear solve.
    pub solve_seconds: f64,
    /// Seconds in collision detection and response.
    pub collide_seconds: f64,
}

/// Options of an implicit step.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct SolveOptions {
    /// The linear solver.
    pub solver: Solver,
    /// PCG tolerance `ε` (relative, preconditioned norm).
    pub tol: f64,
    /// PCG iteration limit.
    pub max_iterations: usize,
    /// The largest change of any stretch ratio (`‖w_u‖`, `‖w_v‖`, or `l/L` of a spring) one
    /// step may make; a step that exceeds it is redone as two half steps (Baraff & Witkin §5:
    /// the step size is cut when a step stretches the cloth too much), down to `h / 32`.
    pub max_strain_change: f64,
}

impl Default for SolveOptions {
    fn default() -> Self {
        SolveOptions {
            solver: Solver::Pcg,
            tol: 1e-6,
            max_iterations: 1000,
            max_strain_change: 0.01,
        }
    }
}

/// The elements' contributions (`Cloth::add_elements`), compiled through
/// [`pulp::Arch::dispatch`] for the baseline instruction set, AVX2 and AVX-512, taken at run
/// time as the CPU has them. The AVX builds have three-operand instructions (no register
/// copies) and wider vectors: 64² assembly 1.07–1.09 ms with AVX2 instead of 1.29–1.37 ms,
/// about 0.98 ms with AVX-512. No fused multiply-add is introduced, so the results are bit
/// for bit the same on every build.
struct Elements<'a, 'b> {
    cloth: &'a Cloth,
    x: &'a [DVec3],
    acc: &'a mut Accumulator<'b>,
}

impl pulp::WithSimd for Elements<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let Elements { cloth, x, acc } = self;
        let Material { stretch, shear, damping, .. } = cloth.material;
        for t in cloth.elements.iter().filter(|_| cloth.model == Model::BaraffWitkin) {
            model::triangle(t, x, stretch, shear, damping, acc);
        }
        for h in &cloth.hinges {
            model::hinge(h, x, damping, acc);
        }
        for s in &cloth.springs {
            model::spring(s, x, damping, acc);
        }
    }
}

/// Relaxation factor `ω` of the SSOR preconditioner of PCG for `n` vertices. On model
/// problems the best `ω` of an SSOR preconditioner approaches 2 as `2 / (1 + c h)` with the mesh
/// spacing `h ∝ 1/√n` (Axelsson 1994, "Iterative Solution Methods"; cf. Young's
/// `2 / (1 + sin πh)` for SOR); here `2 / (1 + 25/√n)`, at least 1 (symmetric Gauss–Seidel).
/// The constant is fitted on the benchmark cloth, where the best `ω` measured was 1.0–1.2 at
/// 32², 1.4 at 64², 1.7 at 128² and 1.8 at 256² (the formula: 1.12, 1.44, 1.67, 1.82).
fn ssor_omega(n: usize) -> f64 {
    (2.0 / (1.0 + 25.0 / (n as f64).sqrt())).max(1.0)
}

/// Faer Cholesky state: the factorisation, where each scalar entry comes from, its values and
/// the filtered blocks.
struct CholeskyState {
    factor: SparseCholesky,
    source: Vec<(usize, usize)>,
    values: Vec<f64>,
    blocks: Vec<DMat3>,
    rhs: Vec<f64>,
}

/// Work vectors, allocated once.
#[derive(serde::Serialize, serde::Deserialize, Default)]
struct Scratch {
    f: Vec<DVec3>,
    ku: Vec<DVec3>,
    u: Vec<DVec3>,
    b: Vec<DVec3>,
    dv: Vec<DVec3>,
    q: Vec<DVec3>,
    filter: Vec<DMat3>,
    z: Vec<DVec3>,
    y: Vec<DVec3>,
    /// The PCG's four-lane vectors and preconditioner, rebuilt by each solve.
    #[serde(skip)]
    pcg: pcg::Work,
    constrained: Vec<usize>,
    /// Contacts of the step: vertex, normal, collider velocity, friction coefficient, normal
    /// impulse estimate (N s).
    contact_normal: Vec<(usize, DVec3, DVec3, f64, f64)>,
    states: Vec<ContactState>,
    x_new: Vec<DVec3>,
    v_new: Vec<DVec3>,
    /// BDF2 history terms `c (x - x₋)`, `c (v - v₋)` with `c` of [`crate::ode::bdf2_weights`]
    /// (`1/3` at a constant step; zero for implicit Euler).
    hx: Vec<DVec3>,
    hv: Vec<DVec3>,
    flat: Vec<f64>,
    ex: Vec<DVec3>,
    ev: Vec<DVec3>,
}

/// A piece of cloth.
#[derive(serde::Serialize, serde::Deserialize)]
pub struct Cloth {
    triangles: Vec<[usize; 3]>,
    model: Model,
    material: Material,
    gravity: DVec3,
    thickness: f64,
    x: Vec<DVec3>,
    v: Vec<DVec3>,
    mass: Vec<f64>,
    /// Positions, velocities and length (s) of the previous step (BDF2 history), if valid.
    history: History,
    time: f64,
    elements: Vec<Triangle>,
    hinges: Vec<Hinge>,
    springs: Vec<Spring>,
    matrix: BlockMatrix,
    constraints: Vec<Option<VertexConstraint>>,
    colliders: Vec<Collider>,
    contact: Vec<ContactState>,
    stats: StepStats,
    scratch: Scratch,
    #[serde(skip)] // rebuilt on the next Cholesky solve (same pattern, same factor)
    cholesky: Option<CholeskyState>,
    stepper: Option<Stepper>,
    #[serde(skip)] // refilled at the start of every step
    rollback: Rollback,
}

/// Everything a step may change that a later step reads, copied at the start of each step
/// and put back when the step fails (a subdivided step commits its substeps as it goes).
/// Positions, velocities and length (s) of the previous step: the BDF2 history.
type History = Option<(Vec<DVec3>, Vec<DVec3>, f64)>;

#[derive(Default)]
struct Rollback {
    x: Vec<DVec3>,
    v: Vec<DVec3>,
    history: History,
    /// The PCG's warm start `Δv` of the last step.
    dv: Vec<DVec3>,
    time: f64,
    contact: Vec<ContactState>,
    colliders: Vec<Collider>,
    stats: StepStats,
    /// The explicit stepper's evaluation counters.
    evaluations: Option<(usize, usize)>,
}

impl Rollback {
    /// Copy `what` into `into`, reusing its allocation.
    fn copy<T: Copy>(into: &mut Vec<T>, what: &[T]) {
        into.clear();
        into.extend_from_slice(what);
    }

    /// Copy a BDF2 history into another, reusing its buffers when it has them.
    fn copy_history(into: &mut History, what: &History) {
        match (what, into.as_mut()) {
            (None, _) => *into = None,
            (Some((wx, wv, wh)), Some((ix, iv, ih))) => {
                Rollback::copy(ix, wx);
                Rollback::copy(iv, wv);
                *ih = *wh;
            }
            (Some(h), None) => *into = Some(h.clone()),
        }
    }
}

impl std::fmt::Debug for Cloth {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Cloth({} vertices, {} triangles, {:?})",
            self.x.len(),
            self.triangles.len(),
            self.model
        )
    }
}

impl Cloth {
    /// A cloth on `mesh` (rest state: the mesh's uv for stretch and shear, its initial shape
    /// for bending), with vertex masses `density × area / 3` from the rest areas of the
    /// triangles around each vertex.
    ///
    /// # Errors
    /// An invalid mesh ([`Mesh::validate`]) or material (negative, non-finite, or zero density
    /// or stretch).
    pub fn new(mesh: Mesh, model: Model, material: Material, gravity: DVec3) -> Result<Cloth> {
        mesh.validate()?;
        for (name, value, positive) in [
            ("density", material.density, true),
            ("stretch", material.stretch, true),
            ("shear", material.shear, false),
            ("bend", material.bend, false),
            ("damping", material.damping, false),
            ("air_damping", material.air_damping, false),
        ] {
            if !value.is_finite() || value < 0.0 || (positive && value == 0.0) {
                let need = if positive { "positive" } else { ">= 0" };
                return Err(Error::invalid(
                    name,
                    format!("must be finite and {need}, got {value}"),
                ));
            }
        }
        if !gravity.is_finite() {
            return Err(Error::invalid("gravity", "must be finite"));
        }
        let n = mesh.positions.len();
        let x: Vec<DVec3> = mesh.positions.iter().map(|p| DVec3::from_array(*p)).collect();
        let topology = Topology::new(&mesh.triangles);
        let mut elements: Vec<Triangle> =
            mesh.triangles.iter().zip(&mesh.uv).map(|(t, uv)| Triangle::new(*t, *uv)).collect();
        let mut mass = vec![0.0; n];
        for t in &elements {
            for &v in &t.verts {
                mass[v] += material.density * t.area / 3.0;
            }
        }
        let area3 = |a: usize, b: usize, c: usize| 0.5 * (x[b] - x[a]).cross(x[c] - x[a]).length();
        let mut hinges = Vec::new();
        let mut springs = Vec::new();
        match model {
            Model::BaraffWitkin => {
                for &[a, b, p, q] in &topology.hinges {
                    let (theta, _) = dihedral_angle(x[a], x[b], x[p], x[q]);
                    let e2 = (x[b] - x[a]).length_squared();
                    let k = material.bend * 3.0 * e2 / (area3(a, b, p) + area3(a, b, q));
                    hinges.push(Hinge {
                        verts: [a, b, p, q],
                        rest_angle: theta,
                        k,
                        slots: [0; 16],
                    });
                }
            }
            Model::MassSpring => {
                let is_quad_diagonal = |[a, b, p, q]: [usize; 4]| {
                    let mid_edge = 0.5 * (x[a] + x[b]);
                    let mid_cross = 0.5 * (x[p] + x[q]);
                    (mid_edge - mid_cross).length() < 0.25 * (x[b] - x[a]).length()
                };
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
                    let k = if diagonal_edges.contains(&[a, b]) {
                        material.shear
                    } else {
                        material.stretch
                    };
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
            }
        }
        let matrix = match model {
            Model::BaraffWitkin => BlockMatrix::from_elements(
                n,
                elements.iter().map(|t| &t.verts[..]).chain(hinges.iter().map(|h| &h.verts[..])),
            ),
            Model::MassSpring => {
                BlockMatrix::from_elements(n, springs.iter().map(|s| &s.verts[..]))
            }
        };
        // Mass shares for the indefinite curvature terms: half of m_i / (conditions at i).
        let mut count = vec![0usize; n];
        match model {
            Model::BaraffWitkin => {
                elements.iter().flat_map(|t| t.verts).for_each(|v| count[v] += 3)
            }
            Model::MassSpring => springs.iter().flat_map(|s| s.verts).for_each(|v| count[v] += 1),
        }
        let share = |v: usize| 0.5 * mass[v] / count[v].max(1) as f64;
        for t in &mut elements {
            t.mass_share = t.verts.iter().map(|&v| share(v)).fold(f64::INFINITY, f64::min);
        }
        for s in &mut springs {
            s.mass_share = s.verts.iter().map(|&v| share(v)).fold(f64::INFINITY, f64::min);
        }
        for t in &mut elements {
            t.slots = std::array::from_fn(|k| {
                if model == Model::BaraffWitkin {
                    matrix.slot(t.verts[k / 3], t.verts[k % 3])
                } else {
                    0
                }
            });
        }
        for h in &mut hinges {
            h.slots = std::array::from_fn(|k| matrix.slot(h.verts[k / 4], h.verts[k % 4]));
        }
        for s in &mut springs {
            s.slots = std::array::from_fn(|k| matrix.slot(s.verts[k / 2], s.verts[k % 2]));
        }
        let zero = vec![DVec3::ZERO; n];
        let scratch = Scratch {
            f: zero.clone(),
            ku: zero.clone(),
            u: zero.clone(),
            b: zero.clone(),
            dv: zero.clone(),
            q: zero.clone(),
            filter: vec![DMat3::IDENTITY; n],
            z: zero.clone(),
            y: zero.clone(),
            pcg: pcg::Work::default(),
            constrained: Vec::with_capacity(n),
            contact_normal: Vec::with_capacity(n),
            states: vec![ContactState::Free; n],
            x_new: zero.clone(),
            v_new: zero.clone(),
            hx: zero.clone(),
            hv: zero.clone(),
            flat: Vec::new(),
            ex: zero.clone(),
            ev: zero.clone(),
        };
        Ok(Cloth {
            triangles: mesh.triangles,
            model,
            material,
            gravity,
            thickness: 1e-3,
            v: zero,
            x,
            mass,
            history: None,
            time: 0.0,
            elements,
            hinges,
            springs,
            matrix,
            constraints: vec![None; n],
            colliders: Vec::new(),
            contact: vec![ContactState::Free; n],
            stats: StepStats::default(),
            scratch,
            cholesky: None,
            stepper: None,
            rollback: Rollback::default(),
        })
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Whether the cloth has no vertices (never: a cloth has at least one triangle).
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Vertex positions (m).
    pub fn positions(&self) -> &[DVec3] {
        &self.x
    }

    /// Vertex velocities (m/s).
    pub fn velocities(&self) -> &[DVec3] {
        &self.v
    }

    /// Vertex masses (kg).
    pub fn masses(&self) -> &[f64] {
        &self.mass
    }

    /// The triangles.
    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    /// The material model.
    pub fn model(&self) -> Model {
        self.model
    }

    /// The material.
    pub fn material(&self) -> Material {
        self.material
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Numbers of the last step.
    pub fn stats(&self) -> StepStats {
        self.stats
    }

    /// Stored blocks of the implicit matrix (its sparsity).
    pub fn matrix_blocks(&self) -> usize {
        self.matrix.blocks.len() - 1
    }

    /// Collision thickness (m): contacts keep vertices this far from collider surfaces.
    pub fn thickness(&self) -> f64 {
        self.thickness
    }

    /// Set the collision thickness (m, >= 0).
    ///
    /// # Errors
    /// A negative or non-finite value.
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

    /// Overwrite positions and velocities (clears the BDF2 history).
    ///
    /// # Errors
    /// Wrong lengths or non-finite values; the state is then unchanged.
    pub fn set_state(&mut self, positions: &[DVec3], velocities: &[DVec3]) -> Result<()> {
        for (name, values) in [("positions", positions), ("velocities", velocities)] {
            if values.len() != self.x.len() {
                return Err(Error::Shape {
                    arg: name.into(),
                    expected: format!("({}, 3)", self.x.len()),
                    got: vec![values.len(), 3],
                });
            }
            if let Some(i) = values.iter().position(|p| !p.is_finite()) {
                return Err(Error::invalid(name, "must be finite").at(i));
            }
        }
        self.x.copy_from_slice(positions);
        self.v.copy_from_slice(velocities);
        self.history = None;
        Ok(())
    }

    /// Set or clear (`None`) the constraint of vertices `indices`.
    ///
    /// # Errors
    /// An index out of range, or a zero / non-finite direction or position.
    pub fn constrain(
        &mut self,
        indices: &[usize],
        constraint: Option<VertexConstraint>,
    ) -> Result<()> {
        if let Some(&i) = indices.iter().find(|&&i| i >= self.x.len()) {
            return Err(Error::invalid(
                "indices",
                format!("vertex {i} is out of range for {} vertices", self.x.len()),
            ));
        }
        let constraint = match constraint {
            Some(VertexConstraint::Pinned(p)) if !p.is_finite() => {
                return Err(Error::invalid("positions", "must be finite"))
            }
            Some(VertexConstraint::Velocity(v)) if !v.is_finite() => {
                return Err(Error::invalid("velocities", "must be finite"))
            }
            Some(VertexConstraint::Plane(n)) | Some(VertexConstraint::Line(n))
                if !(n.is_finite() && n.length() > 0.0) =>
            {
                return Err(Error::invalid("direction", "must be finite and non-zero"))
            }
            Some(VertexConstraint::Plane(n)) => Some(VertexConstraint::Plane(n.normalize())),
            Some(VertexConstraint::Line(d)) => Some(VertexConstraint::Line(d.normalize())),
            other => other,
        };
        for &i in indices {
            self.constraints[i] = constraint;
        }
        Ok(())
    }

    /// Pin vertices `indices` at `positions` (their current positions when `None`).
    ///
    /// # Errors
    /// Out-of-range indices, a length mismatch, or non-finite positions.
    pub fn pin(&mut self, indices: &[usize], positions: Option<&[DVec3]>) -> Result<()> {
        if let Some(p) = positions {
            if p.len() != indices.len() {
                return Err(Error::Shape {
                    arg: "positions".into(),
                    expected: format!("({}, 3)", indices.len()),
                    got: vec![p.len(), 3],
                });
            }
        }
        self.constrain(indices, None)?;
        for (k, &i) in indices.iter().enumerate() {
            let target = positions.map_or(self.x[i], |p| p[k]);
            self.constrain(&[i], Some(VertexConstraint::Pinned(target)))?;
        }
        Ok(())
    }

    /// The constraint of each vertex.
    pub fn constraints(&self) -> &[Option<VertexConstraint>] {
        &self.constraints
    }

    /// Add a collider; returns its index.
    ///
    /// # Errors
    /// Invalid shape, velocity or friction.
    pub fn add_collider(&mut self, collider: Collider) -> Result<usize> {
        self.colliders.push(Self::checked(collider)?);
        Ok(self.colliders.len() - 1)
    }

    /// Replace collider `index` (to move it along a path of the user's choosing).
    ///
    /// # Errors
    /// A bad index or an invalid collider.
    pub fn set_collider(&mut self, index: usize, collider: Collider) -> Result<()> {
        let count = self.colliders.len();
        let slot = self.colliders.get_mut(index).ok_or_else(|| {
            Error::invalid("index", format!("no collider {index} (have {count})"))
        })?;
        *slot = Self::checked(collider)?;
        Ok(())
    }

    /// The colliders, at the cloth's current time.
    pub fn colliders(&self) -> &[Collider] {
        &self.colliders
    }

    fn checked(mut collider: Collider) -> Result<Collider> {
        collider.validate()?;
        if let Shape::Plane { normal, .. } = &mut collider.shape {
            *normal = normal.normalize();
        }
        Ok(collider)
    }

    /// Internal and external forces (N) at the current state, written into `out`; the
    /// elastic energy (J) is returned.
    fn forces_into(&self, x: &[DVec3], v: &[DVec3], out: &mut [DVec3]) -> f64 {
        let air = self.material.air_damping;
        for ((o, m), v) in out.iter_mut().zip(&self.mass).zip(v) {
            *o = (self.gravity - air * *v) * *m;
        }
        let mut acc = Accumulator { v, f: out, matrix: None, ku: None, energy: 0.0 };
        self.add_elements(x, &mut acc);
        acc.energy
    }

    fn add_elements(&self, x: &[DVec3], acc: &mut Accumulator) {
        pulp::Arch::new().dispatch(Elements { cloth: self, x, acc });
    }

    /// Total force on every vertex (N): gravity, elastic and damping forces (constraint and
    /// contact forces not included).
    pub fn forces(&self) -> Vec<DVec3> {
        let mut f = vec![DVec3::ZERO; self.x.len()];
        self.forces_into(&self.x, &self.v, &mut f);
        f
    }

    /// The fastest mode of small vibrations about the current shape, `(ω, c)`: the highest
    /// angular frequency `ω` (rad/s), `ω² = λ_max(M⁻¹ K)` with `K = -∂f/∂x`, and the highest
    /// damping rate `c` (1/s), `c = λ_max(M⁻¹ D)` with `D = -∂f/∂v` (stiffness-proportional and
    /// air damping), over the free vertices. Each by 60 power iterations with the products
    /// `K u`, `D u` from central differences of the forces (an estimate from below, within a
    /// few per cent). The mode `x'' + c x' + ω² x = 0` has the eigenvalues an explicit method
    /// must keep inside its stability region, which `kinema.Scene` checks before a run
    /// (`ode::max_stable_dt`). Allocates; not for a step.
    pub fn fastest_mode(&self) -> (f64, f64) {
        let n = self.x.len();
        let free: Vec<bool> = (0..n)
            .map(|i| {
                !matches!(self.constraints[i], Some(VertexConstraint::Pinned(_)))
                    && self.mass[i] > 0.0
            })
            .collect();
        let zero = vec![DVec3::ZERO; n];
        let mut plus = vec![DVec3::ZERO; n];
        let mut minus = vec![DVec3::ZERO; n];
        let (mut fp, mut fm) = (vec![DVec3::ZERO; n], vec![DVec3::ZERO; n]);
        // `-∂f/∂x u` (or `-∂f/∂v u`) by central differences with step `eps`.
        let mut derivative = |u: &[DVec3], eps: f64, in_velocity: bool, out: &mut [DVec3]| {
            let base = if in_velocity { &zero } else { &self.x };
            for i in 0..n {
                plus[i] = base[i] + eps * u[i];
                minus[i] = base[i] - eps * u[i];
            }
            if in_velocity {
                self.forces_into(&self.x, &plus, &mut fp);
                self.forces_into(&self.x, &minus, &mut fm);
            } else {
                self.forces_into(&plus, &zero, &mut fp);
                self.forces_into(&minus, &zero, &mut fm);
            }
            for i in 0..n {
                out[i] = if free[i] {
                    -(fp[i] - fm[i]) / (2.0 * eps * self.mass[i])
                } else {
                    DVec3::ZERO
                };
            }
        };
        let scale = self.x.iter().map(|p| p.abs().max_element()).fold(1.0, f64::max);
        let mut rates = [0.0; 2];
        for (k, in_velocity) in [false, true].into_iter().enumerate() {
            // A fixed start with every mode in it (no randomness: reproducible).
            let mut u: Vec<DVec3> = (0..n)
                .map(|i| {
                    let t = i as f64;
                    let s =
                        DVec3::new((1.3 * t).sin(), (2.1 * t + 0.5).cos(), (0.7 * t + 1.0).sin());
                    if free[i] {
                        s
                    } else {
                        DVec3::ZERO
                    }
                })
                .collect();
            let mut w = vec![DVec3::ZERO; n];
            let eps = if in_velocity { 1e-6 } else { 1e-7 * scale };
            for _ in 0..60 {
                let norm = u.iter().map(|v| v.length_squared()).sum::<f64>().sqrt();
                if !(norm > 0.0 && norm.is_finite()) {
                    break;
                }
                u.iter_mut().for_each(|v| *v /= norm);
                derivative(&u, eps, in_velocity, &mut w);
                // The Rayleigh quotient uᵀ w estimates the dominant eigenvalue.
                rates[k] = u.iter().zip(&w).map(|(a, b)| a.dot(*b)).sum::<f64>();
                std::mem::swap(&mut u, &mut w);
            }
        }
        (rates[0].abs().sqrt(), rates[1].max(0.0))
    }

    /// `(kinetic, gravitational potential, elastic)` energy (J); the potential is
    /// `-Σ m g·x`.
    pub fn energy(&self) -> (f64, f64, f64) {
        let kinetic =
            0.5 * self.v.iter().zip(&self.mass).map(|(v, m)| m * v.length_squared()).sum::<f64>();
        let potential =
            -self.x.iter().zip(&self.mass).map(|(x, m)| m * self.gravity.dot(*x)).sum::<f64>();
        let mut f = vec![DVec3::ZERO; self.x.len()];
        let elastic = self.forces_into(&self.x, &vec![DVec3::ZERO; self.x.len()], &mut f);
        (kinetic, potential, elastic)
    }

    /// Advance `steps` steps of `dt` seconds with `method`: [`Method::ImplicitEuler`] and
    /// [`Method::Bdf2`] take the linearised implicit step (one Newton step, `options` choose the
    /// solver); the explicit methods of [`crate::ode`] integrate `ẍ = M⁻¹ f` with the filter
    /// applied to accelerations and collisions resolved by projection after each step.
    ///
    /// # Errors
    /// A bad `dt` or options, [`Method::Trapezoidal`] (not offered for cloth), a failed
    /// Cholesky factorisation, or [`Error::Diverged`]. The cloth is left exactly at the end of
    /// the last good step (positions, velocities, time, BDF2 history, warm start, contact
    /// states, colliders and statistics; with `steps = 1`, as before the call), also when a
    /// subdivided step fails after committing some of its substeps.
    pub fn step(
        &mut self,
        dt: f64,
        steps: usize,
        method: Method,
        options: SolveOptions,
    ) -> Result<()> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid("dt", format!("must be positive and finite, got {dt}")));
        }
        if !(options.tol.is_finite() && options.tol > 0.0) || options.max_iterations == 0 {
            return Err(Error::invalid(
                "tol",
                "must be positive and finite, with max_iterations >= 1",
            ));
        }
        if options.max_strain_change.is_nan() || options.max_strain_change <= 0.0 {
            return Err(Error::invalid(
                "max_strain_change",
                "must be positive (inf turns the check off)",
            ));
        }
        for s in 0..steps {
            self.save_rollback();
            self.stats = StepStats { converged: true, ..StepStats::default() };
            let result = match method {
                Method::ImplicitEuler => self.step_adaptive(dt, false, options, 0),
                Method::Bdf2 => self.step_adaptive(dt, true, options, 0),
                Method::Trapezoidal => Err(Error::invalid(
                    "integrator",
                    "trapezoidal is not offered for cloth; use implicit_euler or bdf2",
                )),
                explicit => self.step_explicit(dt, explicit),
            };
            if let Err(e) = result {
                self.restore_rollback();
                return Err(match e {
                    Error::Diverged { index, reason, .. } => {
                        Error::Diverged { step: s, index, reason }
                    }
                    other => other,
                });
            }
        }
        Ok(())
    }

    /// Become `other` (e.g. an earlier [`crate::snapshot::Snapshot`] of this cloth), copying
    /// its positions and velocities into this cloth's buffers, which stay in place so views of
    /// them stay valid (a scene undoes a failed step this way).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"data"`) if `other` has another number of vertices.
    pub fn restore(&mut self, other: Cloth) -> Result<()> {
        if other.x.len() != self.x.len() || other.v.len() != self.v.len() {
            return Err(Error::invalid("data", "is a cloth with another number of vertices"));
        }
        let (mut x, mut v) = (std::mem::take(&mut self.x), std::mem::take(&mut self.v));
        x.copy_from_slice(&other.x);
        v.copy_from_slice(&other.v);
        *self = Cloth { x, v, ..other };
        Ok(())
    }

    /// Copy what a step may change into `self.rollback` (buffers reused: no allocation after
    /// the first step).
    fn save_rollback(&mut self) {
        let r = &mut self.rollback;
        Rollback::copy(&mut r.x, &self.x);
        Rollback::copy(&mut r.v, &self.v);
        Rollback::copy(&mut r.dv, &self.scratch.dv);
        Rollback::copy(&mut r.contact, &self.contact);
        Rollback::copy(&mut r.colliders, &self.colliders);
        Rollback::copy_history(&mut r.history, &self.history);
        r.time = self.time;
        r.stats = self.stats;
        r.evaluations = self.stepper.as_ref().map(|s| (s.nfev, s.njev));
    }

    /// Put back what [`Cloth::save_rollback`] copied (the state buffers are copied into, so
    /// Python views stay valid).
    fn restore_rollback(&mut self) {
        let r = &mut self.rollback;
        self.x.copy_from_slice(&r.x);
        self.v.copy_from_slice(&r.v);
        Rollback::copy(&mut self.scratch.dv, &r.dv);
        Rollback::copy(&mut self.contact, &r.contact);
        Rollback::copy(&mut self.colliders, &r.colliders);
        Rollback::copy_history(&mut self.history, &r.history);
        self.time = r.time;
        self.stats = r.stats;
        match (self.stepper.as_mut(), r.evaluations) {
            (Some(s), Some((nfev, njev))) => (s.nfev, s.njev) = (nfev, njev),
            (Some(_), None) => self.stepper = None,
            _ => {}
        }
    }

    /// Filter, prescribed velocity change and position correction of every vertex for a step
    /// to `t + h`, given the step's effective `h_eff` and BDF2 history displacement `cx`.
    fn build_constraints(&mut self, h: f64, h_eff: f64) {
        let Scratch { filter, z, y, constrained, contact_normal, hx, .. } = &mut self.scratch;
        constrained.clear();
        contact_normal.clear();
        for i in 0..self.x.len() {
            let (x, v) = (self.x[i], self.v[i]);
            let cx = hx[i];
            let (mut s, mut zi, mut yi) = (DMat3::IDENTITY, DVec3::ZERO, DVec3::ZERO);
            match self.constraints[i] {
                Some(VertexConstraint::Pinned(p)) => {
                    s = DMat3::ZERO;
                    zi = (p - x - cx) / h_eff - v;
                }
                Some(VertexConstraint::Plane(n)) => {
                    s = DMat3::IDENTITY - outer(n, n);
                    zi = -n * n.dot(v);
                }
                Some(VertexConstraint::Line(d)) => {
                    s = outer(d, d);
                    zi = -(v - d * d.dot(v));
                }
                Some(VertexConstraint::Velocity(target)) => {
                    s = DMat3::ZERO;
                    zi = target - v;
                }
                None => {
                    // The deepest contact wins.
                    let mut best: Option<(f64, DVec3, DVec3, f64)> = None;
                    for col in &self.colliders {
                        let shape = col.translated(col.velocity * h);
                        let (predicted, _) = distance(&shape, x + h * v);
                        // Contacts live in a band of two thicknesses so that a vertex resting
                        // at `thickness` stays in contact; released vertices leave freely
                        // unless they would penetrate.
                        if predicted >= 2.0 * self.thickness
                            || (self.contact[i] == ContactState::Released && predicted >= 0.0)
                        {
                            continue;
                        }
                        let (now, n) = distance(&shape, x);
                        if best.is_none_or(|b| now < b.0) {
                            best = Some((now, n, col.velocity, col.friction));
                        }
                    }
                    if let Some((now, n, vc, mu)) = best {
                        // End the step at `thickness` from the surface: a vertex still above
                        // it approaches at the speed that lands it there; one below moves
                        // with the surface and the position correction `y` lifts it out.
                        let gap = self.thickness - now - n.dot(cx) - h_eff * n.dot(vc);
                        let approach = if gap < 0.0 { gap / h_eff } else { 0.0 };
                        yi = n * gap.max(0.0);
                        s = DMat3::IDENTITY - outer(n, n);
                        zi = n * (n.dot(vc) + approach - n.dot(v));
                        // The normal impulse of the last step, or on a new contact the one
                        // that stops the approach (forces are added once assembled).
                        let jn = match self.contact[i] {
                            ContactState::Touching(jn) => jn,
                            _ => self.mass[i] * (-n.dot(v - vc)).max(0.0),
                        };
                        contact_normal.push((i, n, vc, mu, jn));
                    }
                }
            }
            if s != DMat3::IDENTITY {
                constrained.push(i);
            }
            filter[i] = s;
            z[i] = zi;
            y[i] = yi;
        }
    }

    /// An implicit step of `h`, redone as two half steps (recursively, at most five times)
    /// when it changes a stretch ratio by more than `options.max_strain_change`. BDF2 keeps its
    /// history through the halving: halving and the steps after it change the step by a ratio
    /// of 1/2 or 2, which the variable-step coefficients take.
    fn step_adaptive(
        &mut self,
        h: f64,
        bdf2: bool,
        options: SolveOptions,
        depth: u32,
    ) -> Result<()> {
        const MAX_HALVINGS: u32 = 5;
        if self.step_implicit(h, bdf2, options, depth < MAX_HALVINGS)? {
            return Ok(());
        }
        self.step_adaptive(0.5 * h, bdf2, options, depth + 1)?;
        self.step_adaptive(0.5 * h, bdf2, options, depth + 1)
    }

    /// The largest change of a stretch ratio between the current positions and `x_new`.
    fn strain_change(&self, x_new: &[DVec3]) -> f64 {
        let mut worst: f64 = 0.0;
        if self.model == Model::BaraffWitkin {
            for t in &self.elements {
                let (u0, v0) = t.warp(&self.x);
                let (u1, v1) = t.warp(x_new);
                worst = worst
                    .max((u1.length() - u0.length()).abs())
                    .max((v1.length() - v0.length()).abs());
            }
        }
        for sp in &self.springs {
            let [a, b] = sp.verts;
            let change =
                ((x_new[b] - x_new[a]).length() - (self.x[b] - self.x[a]).length()) / sp.rest;
            worst = worst.max(change.abs());
        }
        worst
    }

    /// One linearised implicit step; returns `false` (and changes nothing) when `check` is set
    /// and the step changes a stretch ratio by more than allowed.
    fn step_implicit(
        &mut self,
        h: f64,
        bdf2: bool,
        options: SolveOptions,
        check: bool,
    ) -> Result<bool> {
        let n = self.x.len();
        let t0 = Instant::now();
        let history = if bdf2 { self.history.take() } else { None };
        // Variable-step BDF2 (Choi & Ko 2002, eq. 12, at a constant step): with (c, γ) of
        // `bdf2_weights`, x₊ = x + c (x - x₋) + γh v₊, v₊ = v + c (v - v₋) + γh M⁻¹ f₊.
        let weights = history.as_ref().and_then(|&(_, _, hp)| bdf2_weights(h, Some(hp)));
        let h_eff = weights.map_or(h, |(_, gamma)| gamma * h);
        for i in 0..n {
            (self.scratch.hx[i], self.scratch.hv[i]) = match (&history, weights) {
                (Some((xp, vp, _)), Some((c, _))) => {
                    (c * (self.x[i] - xp[i]), c * (self.v[i] - vp[i]))
                }
                _ => (DVec3::ZERO, DVec3::ZERO),
            };
        }
        self.build_constraints(h, h_eff);
        let collide_time = t0.elapsed().as_secs_f64();

        // Assemble A = M - h ∂f/∂v - h² ∂f/∂x and b = M c_v + h (f + ∂f/∂x u), u = c_x + h v + y.
        let t1 = Instant::now();
        let mut scratch = std::mem::take(&mut self.scratch);
        for i in 0..n {
            scratch.u[i] = scratch.hx[i] + h_eff * self.v[i] + scratch.y[i];
            scratch.f[i] = (self.gravity - self.material.air_damping * self.v[i]) * self.mass[i];
            scratch.ku[i] = DVec3::ZERO;
        }
        self.matrix.blocks.iter_mut().for_each(|b| *b = DMat3::ZERO);
        let diagonal = 1.0 + h_eff * self.material.air_damping;
        for i in 0..n {
            self.matrix.blocks[i] = DMat3::from_diagonal(DVec3::splat(self.mass[i] * diagonal));
        }
        let mut blocks = std::mem::take(&mut self.matrix.blocks);
        {
            let mut acc = Accumulator {
                v: &self.v,
                f: &mut scratch.f,
                matrix: Some((&mut blocks, h_eff, h_eff * h_eff)),
                ku: Some((&scratch.u, &mut scratch.ku)),
                energy: 0.0,
            };
            self.add_elements(&self.x, &mut acc);
        }
        self.matrix.blocks = blocks;
        // Coulomb friction as an explicit force: the tangential impulse that would bring the
        // vertex to rest on the surface within the step against its momentum and gravity,
        // `p = m (v_rel + h g)` on the tangent plane, limited to `μ jₙ` — static when the limit
        // is not reached. (The stiff elastic forces stay out of it: an explicit force built
        // from them would be an explicit step of them.)
        for &(i, normal, vc, mu, jn) in &scratch.contact_normal {
            let p = self.mass[i] * (self.v[i] - vc + h_eff * self.gravity);
            let jn = jn.max(-normal.dot(p));
            let pt = p - normal * normal.dot(p);
            let len = pt.length();
            if len > 0.0 {
                scratch.f[i] -= pt * ((mu * jn).min(len) / (len * h_eff));
            }
        }
        for i in 0..n {
            scratch.b[i] = self.mass[i] * scratch.hv[i] + h_eff * (scratch.f[i] + scratch.ku[i]);
        }
        let assemble_time = t1.elapsed().as_secs_f64();
        // A step so large that `h² ∂f/∂x` or `h f` overflows has no meaningful solve (at
        // dt = 1e100 the PCG would stop at once and the step would silently do nothing).
        if !(scratch.b.iter().all(|b| b.is_finite())
            && self.matrix.blocks.iter().all(|b| b.is_finite()))
        {
            self.scratch = scratch;
            self.history = history;
            return Err(Error::invalid(
                "dt",
                format!("{h} s is too large for this cloth: the implicit system overflows"),
            ));
        }

        let t2 = Instant::now();
        let solved = match options.solver {
            Solver::Pcg => self.solve_pcg(&mut scratch, options),
            Solver::Cholesky => self.solve_cholesky(&mut scratch),
        };
        let solve_time = t2.elapsed().as_secs_f64();
        let (iterations, residual, converged) = match solved {
            Ok(r) => r,
            Err(e) => {
                self.scratch = scratch;
                self.history = history;
                return Err(e);
            }
        };
        self.stats.iterations += iterations;
        self.stats.assemble_seconds += assemble_time;
        self.stats.solve_seconds += solve_time;

        // New velocities and positions, friction at contacts.
        let t3 = Instant::now();
        for i in 0..n {
            scratch.v_new[i] = self.v[i] + scratch.dv[i];
        }
        // Contact states for the next step from the constraint impulse A Δv - b (Baraff &
        // Witkin §5.3): a pulling impulse releases the contact.
        scratch.states.iter_mut().for_each(|c| *c = ContactState::Free);
        if !scratch.contact_normal.is_empty() {
            self.matrix.mul(&scratch.dv, &mut scratch.q);
        }
        for &(i, normal, ..) in &scratch.contact_normal {
            let jn = (scratch.q[i] - scratch.b[i]).dot(normal);
            scratch.states[i] =
                if jn < 0.0 { ContactState::Released } else { ContactState::Touching(jn) };
        }
        for i in 0..n {
            scratch.x_new[i] = match self.constraints[i] {
                Some(VertexConstraint::Pinned(p)) => p,
                _ => self.x[i] + scratch.hx[i] + h_eff * scratch.v_new[i] + scratch.y[i],
            };
        }
        self.project_penetrating(&mut scratch, h);
        if check
            && options.max_strain_change.is_finite()
            && self.strain_change(&scratch.x_new) > options.max_strain_change
        {
            self.scratch = scratch;
            self.history = history;
            self.stats.collide_seconds += collide_time + t3.elapsed().as_secs_f64();
            return Ok(false);
        }
        if let Some(i) =
            (0..n).find(|&i| !(scratch.x_new[i].is_finite() && scratch.v_new[i].is_finite()))
        {
            self.scratch = scratch;
            self.history = history;
            return Err(Error::Diverged {
                step: 0,
                index: i,
                reason: "non-finite cloth state".into(),
            });
        }
        // The buffers of the history are reused (implicit Euler leaves them in place).
        let (mut xp, mut vp, _) = history
            .or_else(|| self.history.take())
            .unwrap_or_else(|| (vec![DVec3::ZERO; n], vec![DVec3::ZERO; n], h));
        xp.copy_from_slice(&self.x);
        vp.copy_from_slice(&self.v);
        self.history = Some((xp, vp, h));
        // Copies, not swaps: the state buffers never move, so Python views stay valid.
        self.x.copy_from_slice(&scratch.x_new);
        self.v.copy_from_slice(&scratch.v_new);
        std::mem::swap(&mut self.contact, &mut scratch.states);
        self.advance_colliders(h);
        self.stats.residual = residual;
        self.stats.converged &= converged;
        self.stats.contacts = scratch.contact_normal.len();
        self.stats.substeps += 1;
        self.stats.collide_seconds += collide_time + t3.elapsed().as_secs_f64();
        self.scratch = scratch;
        Ok(true)
    }

    /// The fallback for vertices that were not in contact at the start of the step but end it
    /// inside a collider (dragged in by their neighbours): put them back at `thickness` and
    /// remove their approaching normal velocity.
    fn project_penetrating(&self, scratch: &mut Scratch, h: f64) {
        for col in &self.colliders {
            let shape = col.translated(col.velocity * h);
            for i in 0..self.x.len() {
                if self.constraints[i].is_some() || scratch.filter[i] != DMat3::IDENTITY {
                    continue;
                }
                let (d, normal) = distance(&shape, scratch.x_new[i]);
                if d < 0.0 {
                    scratch.x_new[i] += normal * (self.thickness - d);
                    let vn = (scratch.v_new[i] - col.velocity).dot(normal);
                    if vn < 0.0 {
                        scratch.v_new[i] -= normal * vn;
                    }
                }
            }
        }
    }

    fn advance_colliders(&mut self, h: f64) {
        for c in &mut self.colliders {
            c.shape = c.translated(c.velocity * h);
        }
        self.time += h;
    }

    /// The modified PCG of Baraff & Witkin (1998, §5.3) on the filtered system: it solves
    /// `Â y = S (b - A Δv₀)` with `Â = S A S + I - S` and `Δv₀ = z + S Δv_last` (warm start), so
    /// every iterate stays in `z + range(S)`, and stops when `δ = rᵀ P⁻¹ r < ε² δ₀` with
    /// `δ₀ = (S b)ᵀ P⁻¹ S b` (the paper's rule).
    ///
    /// `P = (D/ω + L) (D/ω)⁻¹ (D/ω + U)` is the block SSOR preconditioner of `Â = L + D + U`
    /// (up to the constant factor `2 - ω`, which PCG does not see), with `ω` from
    /// [`ssor_omega`]; symmetric block Gauss–Seidel (`ω = 1`) needs about a third of the
    /// iterations of the paper's block-Jacobi `P = D` on cloth, and over-relaxation a further
    /// 2% (32²), 18% (64²), 40% (128²) and 53% (256²) fewer on the benchmark cloth.
    /// Eisenstat's trick (Eisenstat 1981, "Efficient implementation of a class of
    /// preconditioned conjugate gradient methods"; Saad, "Iterative Methods for Sparse Linear
    /// Systems", §9.2.2) makes an iteration cost one backward and one forward substitution,
    /// together one product with the matrix: with
    /// `p̂ = (D/ω + U) p` and `Â = (D/ω + L) + (D/ω + U) - (2/ω - 1) D`,
    /// `(D/ω + L)⁻¹ Â p = p + (D/ω + L)⁻¹ (U p + (1 - 1/ω) D p)`, and the iteration runs on
    /// `r̃ = (D/ω + L)⁻¹ r` (so `δ = r̃ᵀ (D/ω) r̃`) and `p̂`.
    ///
    /// The filter enters only through the diagonal: with `D̂ᵢ⁻¹ = Sᵢ (Sᵢ Aᵢᵢ Sᵢ + I - Sᵢ)⁻¹ Sᵢ`
    /// the substitutions on `A`'s blocks give those of `Â` for vectors in `range(S)` (`Â`'s
    /// off-diagonal blocks are `Sᵢ Aᵢⱼ Sⱼ`).
    ///
    /// The setup (diagonal inverses, warm start, right-hand sides) is here; the iterations run
    /// in [`pcg::solve`] on 3-vectors in four lanes (AVX2 where the CPU has it).
    fn solve_pcg(&self, s: &mut Scratch, options: SolveOptions) -> Result<(usize, f64, bool)> {
        let n = self.x.len();
        let a = &self.matrix;
        let omega = ssor_omega(n);
        let w = &mut s.pcg;
        w.resize(n);
        let (filter, b) = (&s.filter, &s.b);
        // Rounding floor: bᵀ D⁻¹ b of the unfiltered right-hand side.
        let mut delta_b = 0.0;
        w.precond.update(a, |i| {
            let (d, f) = (a.blocks[i], filter[i]);
            let inverse = d.inverse();
            delta_b += b[i].dot(inverse * b[i]);
            if f == DMat3::IDENTITY {
                (inverse * omega, d * (1.0 / omega))
            } else {
                (f * (f * d * f + DMat3::IDENTITY - f).inverse() * f * omega, f * d * (1.0 / omega))
            }
        });
        // Warm start Δv₀ = z + S Δv_last; the solve starts from r = S (b - A Δv₀) and, for
        // δ₀, from S b.
        for i in 0..n {
            s.dv[i] = s.z[i] + s.filter[i] * s.dv[i];
        }
        a.mul(&s.dv, &mut s.q);
        for i in 0..n {
            w.dv[i] = pcg::Lane::new(s.dv[i]);
            w.r[i] = pcg::Lane::new(s.filter[i] * (s.b[i] - s.q[i]));
            w.t[i] = pcg::Lane::new(s.filter[i] * s.b[i]);
        }
        // Stop at ε² δ₀, or at the rounding floor of the unfiltered right-hand side when the
        // filter cancels nearly all of it (e.g. a cloth held by friction).
        let floor = (1e3 * f64::EPSILON).powi(2) * delta_b;
        let outcome = pcg::solve(a, w, options.tol, options.max_iterations, floor, omega - 1.0)?;
        for i in 0..n {
            s.dv[i] = w.dv[i].vec3();
        }
        Ok(outcome)
    }

    /// Sparse Cholesky of `S A S + (I - S)` with right-hand side `S (b - A z)`.
    fn solve_cholesky(&mut self, s: &mut Scratch) -> Result<(usize, f64, bool)> {
        let n = self.x.len();
        if self.cholesky.is_none() {
            let (col_ptr, row_idx, source) = self.matrix.lower_scalar_pattern();
            let nnz = row_idx.len();
            let factor = SparseCholesky::new(3 * n, col_ptr, row_idx)?;
            self.cholesky = Some(CholeskyState {
                factor,
                source,
                values: vec![0.0; nnz],
                blocks: self.matrix.blocks.clone(),
                rhs: vec![0.0; 3 * n],
            });
        }
        let st = self.cholesky.as_mut().expect("created above");
        let a = &self.matrix;
        st.blocks.copy_from_slice(&a.blocks);
        if !s.constrained.is_empty() {
            for i in 0..n {
                for slot in std::iter::once(i).chain(a.row_ptr[i]..a.row_ptr[i + 1]) {
                    let j = a.cols[slot] as usize;
                    if s.filter[i] != DMat3::IDENTITY || s.filter[j] != DMat3::IDENTITY {
                        st.blocks[slot] = s.filter[i] * st.blocks[slot] * s.filter[j];
                    }
                }
            }
            for &i in &s.constrained {
                st.blocks[i] += DMat3::IDENTITY - s.filter[i];
            }
        }
        for (value, &(slot, k)) in st.values.iter_mut().zip(&st.source) {
            *value = bsr::entry(&st.blocks[slot], k);
        }
        st.factor.factorize(&st.values)?;
        a.mul(&s.z, &mut s.q);
        for i in 0..n {
            let rhs = s.filter[i] * (s.b[i] - s.q[i]);
            st.rhs[3 * i..3 * i + 3].copy_from_slice(&rhs.to_array());
        }
        st.factor.solve_in_place(&mut st.rhs);
        for i in 0..n {
            s.dv[i] = s.z[i] + DVec3::from_slice(&st.rhs[3 * i..3 * i + 3]);
        }
        // Relative residual of the filtered system.
        a.mul(&s.dv, &mut s.q);
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..n {
            num += (s.filter[i] * (s.q[i] - s.b[i])).length_squared();
            den += (s.filter[i] * s.b[i]).length_squared();
        }
        let residual = if den > 0.0 { (num / den).sqrt() } else { 0.0 };
        Ok((0, residual, true))
    }

    /// One explicit step: the shared integrator on `y = [x; v]`, then pins and collisions.
    fn step_explicit(&mut self, h: f64, method: Method) -> Result<()> {
        let n = self.x.len();
        let t0 = Instant::now();
        if self.stepper.as_ref().is_none_or(|s| s.method() != method) {
            self.stepper = Some(Stepper::new(method, 6 * n)?);
        }
        let mut stepper = self.stepper.take().expect("created above");
        let mut scratch = std::mem::take(&mut self.scratch);
        let mut flat = std::mem::take(&mut scratch.flat);
        flat.resize(6 * n, 0.0);
        for i in 0..n {
            flat[3 * i..3 * i + 3].copy_from_slice(&self.x[i].to_array());
            // Constrained velocities hold from the start of the step.
            let v = match self.constraints[i] {
                Some(VertexConstraint::Pinned(_)) => DVec3::ZERO,
                Some(VertexConstraint::Velocity(target)) => target,
                _ => self.v[i],
            };
            flat[3 * (n + i)..3 * (n + i) + 3].copy_from_slice(&v.to_array());
        }
        let result = {
            let mut system = ExplicitSystem {
                cloth: self,
                x: &mut scratch.ex,
                v: &mut scratch.ev,
                f: &mut scratch.f,
            };
            stepper.step(&mut system, self.time, &mut flat, h)
        };
        self.stepper = Some(stepper);
        scratch.flat = flat;
        self.scratch = scratch;
        let flat = &self.scratch.flat;
        if let Err(e) = result {
            return Err(match e {
                Error::Diverged { index, .. } => Error::Diverged {
                    step: 0,
                    index: (index % (3 * n)) / 3,
                    reason: "non-finite cloth state".into(),
                },
                other => other,
            });
        }
        for i in 0..n {
            self.x[i] = DVec3::from_slice(&flat[3 * i..3 * i + 3]);
            self.v[i] = DVec3::from_slice(&flat[3 * (n + i)..3 * (n + i) + 3]);
            match self.constraints[i] {
                Some(VertexConstraint::Pinned(p)) => {
                    self.x[i] = p;
                    self.v[i] = DVec3::ZERO;
                }
                Some(VertexConstraint::Velocity(target)) => self.v[i] = target,
                _ => {}
            }
        }
        self.advance_colliders(h);
        let mut contacts = 0;
        for i in 0..n {
            if self.constraints[i].is_some() {
                continue;
            }
            for col in &self.colliders {
                let (d, normal) = distance(&col.shape, self.x[i]);
                if d >= self.thickness {
                    continue;
                }
                contacts += 1;
                self.x[i] += normal * (self.thickness - d);
                let rel = self.v[i] - col.velocity;
                let vn = rel.dot(normal);
                if vn < 0.0 {
                    let tangential = rel - normal * vn;
                    let speed = tangential.length();
                    let reduce = (col.friction * -vn).min(speed);
                    let t = if speed > 0.0 { tangential * (reduce / speed) } else { DVec3::ZERO };
                    self.v[i] -= normal * vn + t;
                }
            }
        }
        self.history = None;
        self.stats = StepStats {
            contacts,
            converged: true,
            collide_seconds: t0.elapsed().as_secs_f64(),
            ..StepStats::default()
        };
        Ok(())
    }
}

/// `a bᵀ`.
fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// The cloth as a first-order system `y = [x; v]`, `ẏ = [v; S M⁻¹ f]` for the explicit
/// integrators.
struct ExplicitSystem<'a> {
    cloth: &'a Cloth,
    x: &'a mut [DVec3],
    v: &'a mut [DVec3],
    f: &'a mut [DVec3],
}

impl OdeSystem for ExplicitSystem<'_> {
    fn dim(&self) -> usize {
        6 * self.cloth.x.len()
    }

    fn rhs(&mut self, _t: f64, y: &[f64], dydt: &mut [f64]) -> Result<()> {
        let n = self.cloth.x.len();
        for i in 0..n {
            self.x[i] = DVec3::from_slice(&y[3 * i..3 * i + 3]);
            self.v[i] = DVec3::from_slice(&y[3 * (n + i)..3 * (n + i) + 3]);
        }
        self.cloth.forces_into(self.x, self.v, self.f);
        for i in 0..n {
            let (vel, acc) = match self.cloth.constraints[i] {
                Some(VertexConstraint::Pinned(_)) => (DVec3::ZERO, DVec3::ZERO),
                Some(VertexConstraint::Velocity(target)) => (target, DVec3::ZERO),
                Some(VertexConstraint::Plane(nrm)) => {
                    let a = self.f[i] / self.cloth.mass[i];
                    (self.v[i], a - nrm * nrm.dot(a))
                }
                Some(VertexConstraint::Line(d)) => {
                    (self.v[i], d * d.dot(self.f[i] / self.cloth.mass[i]))
                }
                None => (self.v[i], self.f[i] / self.cloth.mass[i]),
            };
            dydt[3 * i..3 * i + 3].copy_from_slice(&vel.to_array());
            dydt[3 * (n + i)..3 * (n + i) + 3].copy_from_slice(&acc.to_array());
        }
        Ok(())
    }
}
