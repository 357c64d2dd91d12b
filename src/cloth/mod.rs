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
mod build;
mod collide;
mod explicit;
mod implicit;
mod mesh;
mod model;
mod pcg;
mod rollback;
mod snapshot;

pub use bsr::BlockMatrix;
pub use collide::Collider;
pub use mesh::{parse_obj, uv_from_shape, write_obj, Mesh, Topology, Triangulation};
pub use model::dihedral_angle;

use crate::error::{Error, Result};
use crate::geometry::{material, Shape};
use crate::linalg::SparseCholesky;
use crate::math::outer;
use crate::ode::{bdf2_weights, Method, OdeSystem, Stepper};
use collide::ContactState;
use glam::{DMat3, DVec3};
use implicit::CholeskyState;
use model::{Accumulator, Hinge, Spring, Triangle};
use rollback::Rollback;
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
        let (mut hinges, mut springs) = match model {
            Model::BaraffWitkin => (build::hinges(&topology, &x, material.bend), Vec::new()),
            Model::MassSpring => (Vec::new(), build::springs(&topology, &x, &material)),
        };
        let matrix = match model {
            Model::BaraffWitkin => BlockMatrix::from_elements(
                n,
                elements.iter().map(|t| &t.verts[..]).chain(hinges.iter().map(|h| &h.verts[..])),
            ),
            Model::MassSpring => {
                BlockMatrix::from_elements(n, springs.iter().map(|s| &s.verts[..]))
            }
        };
        build::mass_shares(model, &mass, &mut elements, &mut springs);
        build::slots(model, &matrix, &mut elements, &mut hinges, &mut springs);
        Ok(Cloth {
            triangles: mesh.triangles,
            model,
            material,
            gravity,
            thickness: 1e-3,
            v: vec![DVec3::ZERO; n],
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
            scratch: Scratch::new(n),
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
}
