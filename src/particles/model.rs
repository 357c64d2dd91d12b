//! The particle model: what every step reads and no step changes — the capacity, the forces
//! (gravity among them), the colliders and the emitters' descriptions. Built by
//! [`Model::new`] and the `add_*` methods, each of which validates what it adds.

use super::{Collider, Emitter, Force};
use crate::error::{Error, Result};
use glam::DVec3;

/// A particle model (see the module docs): read-only during a step (`&Model`); several
/// [`super::State`]s may share it.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Model {
    /// Number of slots (live and dead) of every state of this model.
    pub(super) n: usize,
    pub(super) forces: Vec<Force>,
    pub(super) colliders: Vec<Collider>,
    pub(super) emitters: Vec<Emitter>,
    /// A key of the capacity and the forces ([`crate::ode::fresh_key`]), new whenever they
    /// change: what a solver's kept factorisation was built for. Copied by a clone (the same
    /// forces); not part of the model's value or of its serialised form.
    #[serde(skip, default = "crate::ode::fresh_key")]
    pub(super) forces_key: u64,
}

impl PartialEq for Model {
    fn eq(&self, other: &Self) -> bool {
        // Destructured so that a new field cannot be forgotten here.
        let Model { n, forces, colliders, emitters, forces_key: _ } = self;
        (n, forces, colliders, emitters)
            == (&other.n, &other.forces, &other.colliders, &other.emitters)
    }
}

impl Model {
    /// A model of `capacity` slots without forces, colliders or emitters.
    pub fn new(capacity: usize) -> Self {
        Model {
            n: capacity,
            forces: Vec::new(),
            colliders: Vec::new(),
            emitters: Vec::new(),
            forces_key: crate::ode::fresh_key(),
        }
    }

    /// Number of slots (live and dead) of the states of this model.
    pub fn capacity(&self) -> usize {
        self.n
    }

    /// The forces, in the order added.
    pub fn forces(&self) -> &[Force] {
        &self.forces
    }

    /// The colliders, in the order added.
    pub fn colliders(&self) -> &[Collider] {
        &self.colliders
    }

    /// The emitters' descriptions, in the order added (their accumulators and random states
    /// are in each [`super::State`]).
    pub fn emitters(&self) -> &[Emitter] {
        &self.emitters
    }

    /// Add a force (a vortex's axis is made unit).
    ///
    /// # Errors
    /// Invalid parameters ([`Force::validate`]).
    pub fn add_force(&mut self, force: Force) -> Result<()> {
        force.validate(self.n)?;
        self.forces.push(match force {
            Force::Vortex { center, axis, strength, core } => {
                Force::Vortex { center, axis: axis.normalize(), strength, core }
            }
            f => f,
        });
        self.forces_key = crate::ode::fresh_key();
        Ok(())
    }

    /// Add a collider.
    ///
    /// # Errors
    /// Those of [`Collider::checked`].
    pub fn add_collider(&mut self, collider: Collider) -> Result<()> {
        self.colliders.push(collider.checked()?);
        Ok(())
    }

    /// Replace collider `index` (move a collider between steps, e.g. one that follows an
    /// animated or rigid body).
    ///
    /// # Errors
    /// `index` out of range, or those of [`Collider::checked`].
    pub fn set_collider(&mut self, index: usize, collider: Collider) -> Result<()> {
        if index >= self.colliders.len() {
            return Err(Error::invalid(
                "index",
                format!("no collider {index}: there are {}", self.colliders.len()),
            ));
        }
        self.colliders[index] = collider.checked()?;
        Ok(())
    }

    /// Put back the colliders `saved` (an earlier copy of [`Model::colliders`]), reusing the
    /// list's room: a scene's undo of a frame that moved or added colliders.
    pub fn restore_colliders(&mut self, saved: &[Collider]) {
        self.colliders.truncate(saved.len());
        let kept = self.colliders.len();
        self.colliders.clone_from_slice(&saved[..kept]);
        self.colliders.extend_from_slice(&saved[kept..]);
    }

    /// Add an emitter; states of this model take it on with [`super::State::fit`].
    ///
    /// # Errors
    /// Negative or non-finite rate, spreads, lifespan or mass, non-finite position or
    /// velocity (each named).
    pub fn add_emitter(&mut self, emitter: Emitter) -> Result<()> {
        emitter.validate()?;
        self.emitters.push(emitter);
        Ok(())
    }

    /// A deterministic 64-bit hash of the model ([`crate::snapshot::fingerprint`]), recorded
    /// by state snapshots so that a state is not restored onto another model.
    pub fn fingerprint(&self) -> u64 {
        crate::snapshot::fingerprint(self)
    }

    /// The sum of the gravity forces' accelerations (m/s²).
    pub(super) fn gravity(&self) -> DVec3 {
        self.forces
            .iter()
            .map(|f| if let Force::Gravity { g } = f { *g } else { DVec3::ZERO })
            .sum()
    }

    /// Whether every force is affine in the state with a Jacobian that depends on nothing
    /// but the model, the masses and the live slots: gravity, damping, linear drag and springs
    /// of rest length 0 without damping (`-k d`).
    pub(super) fn linear(&self) -> bool {
        self.forces.iter().all(|f| match f {
            Force::Gravity { .. } | Force::Damping { .. } => true,
            Force::Drag { quadratic, .. } => *quadratic == 0.0,
            Force::Springs { rest, damping, .. } => {
                *damping == 0.0 && rest.iter().all(|l| *l == 0.0)
            }
            _ => false,
        })
    }

    /// Whether a force acts between particles (springs, repulsion, all-pairs gravity).
    pub(super) fn pairwise(&self) -> bool {
        self.forces.iter().any(|f| !f.acts_alone())
    }
}
