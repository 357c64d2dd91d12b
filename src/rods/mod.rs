//! Discrete elastic rods (Bergou, Wardetzky, Robinson, Audoly & Grinspun 2008, "Discrete
//! elastic rods"; Bergou, Audoly, Vouga, Wardetzky & Grinspun 2010, "Discrete viscous
//! threads"): hair, ropes, cables and stems as a polyline of `n + 1` vertices with one twist
//! angle per edge.
//!
//! - `frames.rs`: parallel transport, reference frames carried in time (time-parallel
//!   transport), reference twist, material frames, curvature binormals.
//! - `energy.rs`: stretching, bending (with natural curvature, anisotropic cross-sections)
//!   and twisting energies with analytic gradients and Hessians (Kaufman et al. 2014).
//! - `contact.rs`: contacts with the shared collision shapes: a normal penalty and lagged
//!   Coulomb friction as potentials of the implicit step (Li et al. 2020).
//! - `hair.rs`: [`Hair`], many strands of one model on a moving head, stepped in parallel
//!   and kept apart by a rod–rod repulsion; `groom` grows them from a scalp.
//! - `band.rs`: the banded `L D Lᵀ` solve of the Newton system, linear in `n`.
//! - `solver.rs`: implicit Euler by Newton with a line search on the incremental potential,
//!   symplectic Euler, and the static equilibrium.
//!
//! The rod is split as every system of kinema is: a [`Model`] (rest shape, material,
//! masses, boundary conditions, settings), a [`State`] (positions, velocities, twists,
//! reference frames, external forces, time) and a [`Solver`] (workspaces), so one model and
//! one solver can advance several states. [`Rod`] is the three together.

mod band;
mod contact;
mod energy;
mod frames;
mod hair;
mod inextensible;
mod model;
mod snapshot;
mod solver;
mod state;

pub use band::Band;
pub use contact::{Collider, Repulsion};
pub use energy::{curvature, elastic, elastic_energy, stretch, twist, Local, Stencil, STENCIL};
pub use frames::{curvature_binormal, directors, reference_twist, transport, Frames};
pub use hair::{template, Hair, Motion, Pose, STRANDS_PER_TASK};
pub use model::{End, Integrator, Material, Model, Settings};
pub use solver::Solver;
pub use state::State;

use crate::error::Result;
use glam::{DQuat, DVec3};

/// What the last call to [`Solver::step`] or [`Solver::solve_static`] did.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Steps taken.
    pub steps: usize,
    /// Newton iterations, summed over the steps.
    pub iterations: usize,
    /// Halvings of the line searches, summed over the steps.
    pub halvings: usize,
}

/// A rod: a [`Model`] with one [`State`] and a [`Solver`], its methods delegating to them.
/// A snapshot holds the model and the state.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Rod {
    model: Model,
    state: State,
    #[serde(skip)]
    solver: Solver,
    /// What the last step or static solve did.
    pub stats: Stats,
}

impl Rod {
    /// A rod at rest in the shape of `points` ([`Model::new`]), twisted by `twists` (rad per
    /// edge) if given.
    ///
    /// # Errors
    /// Those of [`Model::new`] and [`State::set_twists`].
    pub fn new(
        points: &[DVec3],
        material: Material,
        settings: Settings,
        twists: Option<&[f64]>,
    ) -> Result<Self> {
        Rod::from_model(Model::new(points, material, settings)?, twists)
    }

    /// A rod of `model` (open or closed, [`Model::closed`]) at rest, twisted by `twists`
    /// (rad per edge) if given.
    ///
    /// # Errors
    /// Those of [`State::set_twists`].
    pub fn from_model(model: Model, twists: Option<&[f64]>) -> Result<Self> {
        let mut state = State::new(&model);
        if let Some(t) = twists {
            state.set_twists(t)?;
        }
        let solver = Solver::new(&model);
        Ok(Rod { model, state, solver, stats: Stats::default() })
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The model, to change its boundary conditions or settings between steps.
    pub fn model_mut(&mut self) -> &mut Model {
        &mut self.model
    }

    /// The state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// The state, to change it (forces, velocities, twists).
    pub fn state_mut(&mut self) -> &mut State {
        &mut self.state
    }

    /// Move a clamped end to its rest pose rotated by `rotation` and shifted by
    /// `translation` (m) by the end of the next step or static solve
    /// ([`State::move_clamp`]).
    ///
    /// # Errors
    /// Those of [`State::move_clamp`].
    pub fn move_clamp(&mut self, end: End, rotation: DQuat, translation: DVec3) -> Result<()> {
        self.state.move_clamp(&self.model, end, rotation, translation)
    }

    /// Twist a closed rod by `angle` (rad) more, spread evenly ([`State::twist_ring`]).
    ///
    /// # Errors
    /// Those of [`State::twist_ring`].
    pub fn twist_ring(&mut self, angle: f64) -> Result<()> {
        self.state.twist_ring(&self.model, angle)
    }

    /// Advance `steps` steps of `dt` seconds ([`Solver::step`]).
    ///
    /// # Errors
    /// Those of [`Solver::step`]; the rod is then as it was.
    pub fn step(&mut self, dt: f64, steps: usize) -> Result<()> {
        self.stats = self.solver.step(&self.model, &mut self.state, dt, steps)?;
        Ok(())
    }

    /// Move to the static equilibrium nearest the current shape ([`Solver::solve_static`]).
    ///
    /// # Errors
    /// Those of [`Solver::solve_static`]; the rod is then as it was.
    pub fn solve_static(&mut self) -> Result<()> {
        self.stats = self.solver.solve_static(&self.model, &mut self.state)?;
        Ok(())
    }

    /// The elastic energy (J): stretching, bending and twisting.
    pub fn energy(&mut self) -> f64 {
        self.solver.energy(&self.model, &self.state)
    }

    /// The material frames of the edges, `n` rows `[t, m1, m2]` (unit vectors).
    pub fn material_frames(&mut self) -> Vec<[DVec3; 3]> {
        let mut frames = Frames::default();
        self.state.frames_into(&mut frames, &mut Vec::new());
        (0..self.model.edges()).map(|j| [frames.tangents[j], frames.m1[j], frames.m2[j]]).collect()
    }
}
