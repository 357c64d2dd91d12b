//! The rod state: what changes in time and what a later step reads — vertex positions and
//! velocities, edge twist angles and their rates, the reference frames carried in time (the
//! time-parallel transport of Bergou et al. 2010 starts each step from the last step's
//! frames, so they are state, as is the reference twist whose branch they continue), the
//! external forces and clamp motions applied during the next steps, and the time.

use super::frames::{directors, Frames};
use super::{End, Model};
use crate::error::{Error, Result};
use glam::{DQuat, DVec3};

/// Where a clamped end goes by the end of the next call to [`super::Solver::step`] or
/// [`super::Solver::solve_static`] (prescribed motion, an input like the forces).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub(super) struct ClampGoal {
    /// The end's clamped edge.
    pub(super) edge: usize,
    /// The positions of its two vertices (m).
    pub(super) positions: [DVec3; 2],
    /// Its material director `m1` (unit, perpendicular to the edge).
    pub(super) director: DVec3,
}

/// The state of a rod of a [`Model`] of `n` edges and `V` vertices. `clone_from` reuses
/// every buffer.
#[derive(serde::Serialize, serde::Deserialize, Debug, PartialEq)]
pub struct State {
    /// Vertex positions (m), `V`.
    pub(super) positions: Vec<DVec3>,
    /// Vertex velocities (m/s), `V`.
    pub(super) velocities: Vec<DVec3>,
    /// Twist angles `θ` of the material frames from the reference frames (rad), `n`.
    pub(super) twists: Vec<f64>,
    /// Their rates (rad/s), `n`.
    pub(super) twist_rates: Vec<f64>,
    /// Reference directors `d1` (unit, perpendicular to the edges), `n`.
    pub(super) reference: Vec<DVec3>,
    /// Reference twist at the stencils (rad), [`Model::stencils`] (a ring's last with its
    /// seam twist).
    pub(super) reference_twist: Vec<f64>,
    /// A closed rod's seam twist (rad): the turn of the material frame across the seam
    /// between its last edge and its first beyond what its twist angles give — the twist
    /// put into the ring ([`State::twist_ring`]; 0 for an open rod).
    pub(super) seam: f64,
    /// External forces on the vertices (N), `V`, applied during every later step until
    /// changed (gravity comes from the model).
    pub(super) forces: Vec<DVec3>,
    /// The prescribed motions of the first and last clamped ends, reached at the end of the
    /// next call and then cleared (the end stays there).
    pub(super) clamp_goals: [Option<ClampGoal>; 2],
    /// Simulated time (s).
    pub(super) time: f64,
}

impl Clone for State {
    fn clone(&self) -> Self {
        let mut s = State {
            positions: Vec::new(),
            velocities: Vec::new(),
            twists: Vec::new(),
            twist_rates: Vec::new(),
            reference: Vec::new(),
            reference_twist: Vec::new(),
            seam: 0.0,
            forces: Vec::new(),
            clamp_goals: [None; 2],
            time: 0.0,
        };
        s.clone_from(self);
        s
    }

    /// Field by field, reusing every buffer (no allocation once the sizes match).
    fn clone_from(&mut self, source: &Self) {
        self.positions.clone_from(&source.positions);
        self.velocities.clone_from(&source.velocities);
        self.twists.clone_from(&source.twists);
        self.twist_rates.clone_from(&source.twist_rates);
        self.reference.clone_from(&source.reference);
        self.reference_twist.clone_from(&source.reference_twist);
        self.seam = source.seam;
        self.forces.clone_from(&source.forces);
        self.clamp_goals = source.clamp_goals;
        self.time = source.time;
    }
}

impl State {
    /// The rod at rest in its rest shape, untwisted, at time 0.
    pub fn new(model: &Model) -> Self {
        let (n, v) = (model.edges(), model.vertices());
        let mut state = State {
            positions: model.rest_positions.clone(),
            velocities: vec![DVec3::ZERO; v],
            twists: vec![0.0; n],
            twist_rates: vec![0.0; n],
            reference: model.rest_reference.clone(),
            reference_twist: model.rest_twists.clone(),
            seam: 0.0,
            forces: vec![DVec3::ZERO; v],
            clamp_goals: [None; 2],
            time: 0.0,
        };
        if model.straight {
            // The rest shape's reference twists (the model's rest twists are zero).
            let mut frames = Frames::default();
            state.frames_into(&mut frames, &mut Vec::new());
            state.reference_twist.clone_from(&frames.reference_twist);
        }
        state
    }

    /// Vertex positions (m), `V`.
    pub fn positions(&self) -> &[DVec3] {
        &self.positions
    }

    /// Vertex velocities (m/s), `V`.
    pub fn velocities(&self) -> &[DVec3] {
        &self.velocities
    }

    /// Twist angles (rad), `n`.
    pub fn twists(&self) -> &[f64] {
        &self.twists
    }

    /// External forces on the vertices (N), `V`.
    pub fn forces(&self) -> &[DVec3] {
        &self.forces
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Set the twist angles (rad), `n` (a rod twisted from its rest shape).
    ///
    /// # Errors
    /// A length other than the edge count or a non-finite value (`twist`, with index).
    pub fn set_twists(&mut self, twists: &[f64]) -> Result<()> {
        if twists.len() != self.twists.len() {
            return Err(Error::invalid("twist", "expected one angle per edge"));
        }
        if let Some(j) = twists.iter().position(|t| !t.is_finite()) {
            return Err(Error::invalid("twist", "contains NaN or infinity").at(j));
        }
        self.twists.copy_from_slice(twists);
        Ok(())
    }

    /// Set the vertex velocities (m/s), `n + 1`.
    ///
    /// # Errors
    /// A length other than the vertex count or a non-finite value (`velocities`, with index).
    pub fn set_velocities(&mut self, velocities: &[DVec3]) -> Result<()> {
        if velocities.len() != self.velocities.len() {
            return Err(Error::invalid("velocities", "expected one per vertex"));
        }
        if let Some(i) = velocities.iter().position(|v| !v.is_finite()) {
            return Err(Error::invalid("velocities", "contains NaN or infinity").at(i));
        }
        self.velocities.copy_from_slice(velocities);
        Ok(())
    }

    /// Set the external force (N) on vertex `index` for the later steps.
    ///
    /// # Errors
    /// `index` beyond the last vertex (`index`); a non-finite force (`force`).
    pub fn set_force(&mut self, index: usize, force: DVec3) -> Result<()> {
        if !force.is_finite() {
            return Err(Error::invalid("force", "must be finite"));
        }
        let Some(f) = self.forces.get_mut(index) else {
            return Err(Error::invalid("index", "beyond the last vertex"));
        };
        *f = force;
        Ok(())
    }

    /// Move a clamped end (prescribed motion, e.g. a hair root on a moving head): by the end
    /// of the next call to [`super::Solver::step`] (reached linearly over its steps) or
    /// [`super::Solver::solve_static`], the end's edge is its rest pose moved rigidly,
    /// `x = R x̄ + translation` for its two vertices (m), and its material director `m1` is
    /// `R` times the rest shape's untwisted one (so twisting the end by `φ` about its tangent
    /// twists the rod by `φ`). The twist angle goes to the branch nearest its current value,
    /// so one call turns the end by less than half a turn about its tangent.
    ///
    /// # Errors
    /// `end` not clamped (`end`); `rotation` not a finite unit quaternion (`rotation`);
    /// `translation` not finite (`translation`).
    pub fn move_clamp(
        &mut self,
        model: &Model,
        end: End,
        rotation: DQuat,
        translation: DVec3,
    ) -> Result<()> {
        let slot = usize::from(end == End::Last);
        let j = model.end_edge(end);
        let k = (j + 1) % model.vertices();
        if !(model.locked[j] && model.pinned[j] && model.pinned[k]) {
            return Err(Error::invalid("end", "is not clamped"));
        }
        if !(rotation.is_finite() && (rotation.length() - 1.0).abs() < 1e-9) {
            return Err(Error::invalid("rotation", "must be a finite unit quaternion"));
        }
        if !translation.is_finite() {
            return Err(Error::invalid("translation", "must be finite"));
        }
        let rest = &model.rest_positions;
        let tangent = (rest[k] - rest[j]).normalize();
        let (m1, _) = directors(tangent, model.rest_reference[j], 0.0);
        self.clamp_goals[slot] = Some(ClampGoal {
            edge: j,
            positions: [rotation * rest[j] + translation, rotation * rest[k] + translation],
            director: rotation * m1,
        });
        Ok(())
    }

    /// Twist a closed rod (a ring) by `angle` (rad) more, spread evenly: the seam twist
    /// grows by `angle` (the material cut at the seam, turned by `angle` about the tangent
    /// and joined again) and edge `j`'s twist angle by `j angle / n`, so the twist of every
    /// stencil grows by `angle / n` (Michell's twisted ring). The ring's link
    /// (Lk = Tw + Wr) grows by `angle / 2π`.
    ///
    /// # Errors
    /// An open rod (`model`); a non-finite angle (`angle`).
    pub fn twist_ring(&mut self, model: &Model, angle: f64) -> Result<()> {
        if !model.closed {
            return Err(Error::invalid("model", "is not a closed rod"));
        }
        if !angle.is_finite() {
            return Err(Error::invalid("angle", "must be finite"));
        }
        self.seam += angle;
        if let Some(last) = self.reference_twist.last_mut() {
            *last += angle;
        }
        let n = self.twists.len() as f64;
        for (j, t) in self.twists.iter_mut().enumerate() {
            *t += angle * j as f64 / n;
        }
        Ok(())
    }

    /// A closed rod's seam twist (rad; [`State::twist_ring`]).
    pub fn seam(&self) -> f64 {
        self.seam
    }

    /// The unit tangents of the edges into `tangents` (`n`; non-finite where an edge has
    /// collapsed).
    pub(super) fn tangents_into(&self, tangents: &mut Vec<DVec3>) {
        let (x, v) = (&self.positions, self.positions.len());
        tangents.clear();
        tangents.extend((0..self.twists.len()).map(|j| (x[(j + 1) % v] - x[j]).normalize()));
    }

    /// The frames of the state (edges, tangents, reference and material directors,
    /// reference twists) into `frames`; `false` if an edge has collapsed.
    pub(super) fn frames_into(&self, frames: &mut Frames, tangents: &mut Vec<DVec3>) -> bool {
        self.tangents_into(tangents);
        frames.update(
            &self.positions,
            &self.twists,
            tangents,
            &self.reference,
            &self.reference_twist,
            self.seam,
        )
    }
}
