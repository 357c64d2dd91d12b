//! The coupled step of a rigid world, stage by stage: joint forces (penalty springs, Lagrange
//! multipliers), velocities, contacts, sequential impulses (Catto 2005) over contacts and
//! impulse joints, positions, Lagrange post-stabilisation (Cline & Pai 2003), the position
//! pass, and the XPBD projection (Müller et al. 2020).

use super::super::contact::{self, Bodies, Contact};
use super::super::integrate::{exp_map, rotate};
use super::super::joint::{JointKind, JointMethod, Kinematics, Row, SLOTS};
use super::super::joint_solver::{self as js, Mass};
use super::super::narrow::Placed;
use super::super::{Model, State};
use super::Solver;
use crate::error::Result;
use glam::DVec3;

/// Sweeps of the XPBD velocity pass over a hinge with limits or a motor.
const XPBD_VELOCITY_SWEEPS: usize = 8;

/// Alternations of a Lagrange velocity projection and a contact sweep when both are present.
const LAGRANGE_CONTACT_ROUNDS: usize = 4;

/// Contact sweeps of an island (in a world without joints) stop early once no contact's
/// speed changes by more than this in a sweep (m/s): at rest, warm-started contacts converge
/// in a few sweeps, and the rest would be paid for nothing. (With joints the sweeps are
/// shared with them and always all run.)
const CONVERGED: f64 = 1e-12;

/// Which joint formulations the model uses.
#[derive(Clone, Copy)]
struct Methods {
    penalty: bool,
    lagrange: bool,
    impulse: bool,
    xpbd: bool,
}

impl Methods {
    fn of(model: &Model) -> Self {
        let has = |m: JointMethod| model.joints.iter().any(|j| j.method == m);
        Methods {
            penalty: has(JointMethod::Penalty),
            lagrange: has(JointMethod::Lagrange),
            impulse: has(JointMethod::Impulse),
            xpbd: has(JointMethod::Xpbd),
        }
    }
}

/// The inverse masses of `model`'s bodies, as the joint solver reads them.
fn mass_of(model: &Model) -> Mass<'_> {
    Mass { inv_mass: &model.inv_mass, inv_moments: &model.inv_moments }
}

/// Sweeps of the velocity solve and of the position pass: the contact iterations when
/// there are `contacts`, at least the joint iterations with impulse joints.
fn sweeps(contacts: &[Contact], model: &Model, impulse: bool) -> usize {
    let sweeps = if contacts.is_empty() { 0 } else { model.contact_iterations };
    if impulse {
        sweeps.max(model.joint_iterations)
    } else {
        sweeps
    }
}

/// The impulse joints' rows at `s` and their effective masses, into `rows` and `row_mass`.
fn impulse_rows(model: &Model, s: &Kinematics<'_>, rows: &mut [Row], row_mass: &mut [f64]) {
    let mass = mass_of(model);
    for (ji, j) in model.joints.iter().enumerate() {
        if j.method == JointMethod::Impulse {
            let slots = ji * SLOTS..ji * SLOTS + j.slots();
            j.rows(s, &mut rows[ji * SLOTS..(ji + 1) * SLOTS]);
            js::effective_masses(j, &rows[slots.clone()], &mass, s.q, &mut row_mass[slots]);
        }
    }
}

/// Zero position corrections `dx` (m) and `dtheta` (rad) for `n` bodies.
fn clear_corrections(dx: &mut Vec<DVec3>, dtheta: &mut Vec<DVec3>, n: usize) {
    dx.clear();
    dx.resize(n, DVec3::ZERO);
    dtheta.clear();
    dtheta.resize(n, DVec3::ZERO);
}

impl Solver {
    /// One step (or substep number `substep`) of `h` seconds with contacts (when `detect`) and
    /// joints, on the scratch state; `state` gives the applied forces and, in the first
    /// substep, the warm starts (the previous substep's contacts give them after that).
    pub(super) fn coupled_step(
        &mut self,
        model: &Model,
        state: &State,
        h: f64,
        detect: bool,
        substep: usize,
    ) -> Result<()> {
        let methods = Methods::of(model);
        self.joint_forces(model, state, h, methods)?;
        self.kick(model, state, h, detect);
        if substep > 0 {
            std::mem::swap(&mut self.contacts, &mut self.previous);
        }
        self.contacts.clear();
        if detect {
            self.detect_contacts(model, h)?;
        }
        let previous = if substep == 0 { &state.contacts } else { &self.previous };
        contact::warm_start(&mut self.contacts, previous);
        self.solve_velocities(model, h, methods)?;
        self.drift(model, h);
        if methods.lagrange {
            self.post_stabilize(model)?;
        }
        self.position_pass(model, methods.impulse);
        if methods.xpbd {
            self.xpbd_step(model, h);
        }
        Ok(())
    }

    /// Joint forces at the start of the step into `joint_force`/`joint_torque`: penalty
    /// springs, then the Lagrange multipliers for the accelerations of all other forces.
    fn joint_forces(&mut self, model: &Model, state: &State, h: f64, m: Methods) -> Result<()> {
        let (x, v, q, pi) = &*self.scratch;
        let n = model.len();
        let mass = mass_of(model);
        self.omega.clear();
        self.omega.extend((0..n).map(|i| q[i] * (pi[i] / model.moments[i])));
        self.joint_force.clear();
        self.joint_force.resize(n, DVec3::ZERO);
        self.joint_torque.clear();
        self.joint_torque.resize(n, DVec3::ZERO);
        if !(m.penalty || m.lagrange) {
            return Ok(());
        }
        let s = Kinematics { x, q, v, w: &self.omega };
        for (ji, j) in model.joints.iter().enumerate() {
            if matches!(j.method, JointMethod::Penalty | JointMethod::Lagrange) {
                j.rows(&s, &mut self.rows[ji * SLOTS..(ji + 1) * SLOTS]);
            }
            if j.method == JointMethod::Penalty {
                let rows = &self.rows[ji * SLOTS..ji * SLOTS + j.slots()];
                js::penalty(j, rows, &mass, &s, h, &mut self.joint_force, &mut self.joint_torque);
            }
        }
        if !m.lagrange {
            return Ok(());
        }
        self.acc_free.clear();
        self.alpha_free.clear();
        for i in 0..n {
            if model.fixed[i] {
                self.acc_free.push(DVec3::ZERO);
                self.alpha_free.push(DVec3::ZERO);
                continue;
            }
            let force = state.force[i] + self.joint_force[i];
            let torque = state.torque[i] + self.joint_torque[i];
            let l = q[i] * pi[i]; // world angular momentum I ω
            self.acc_free.push(model.gravity + force / model.mass[i]);
            self.alpha_free.push(mass.inv_inertia(i, q[i], torque - self.omega[i].cross(l)));
        }
        self.multipliers.solve(
            &model.joints,
            &self.rows,
            &mass,
            &s,
            &self.acc_free,
            &self.alpha_free,
            h,
            model.baumgarte,
            &mut self.joint_force,
            &mut self.joint_torque,
        )
    }

    /// Velocities from all forces (`v += h a`, `Π += h τ`) and damping; the angular
    /// velocities; the shapes placed at the current pose when contacts are `detect`ed.
    fn kick(&mut self, model: &Model, state: &State, h: f64, detect: bool) {
        let (x, v, q, pi) = &mut *self.scratch;
        self.placed.clear();
        for i in 0..model.len() {
            if !model.fixed[i] {
                let force = state.force[i] + self.joint_force[i];
                v[i] += h * (model.gravity + force / model.mass[i]);
                pi[i] += h * (q[i].conjugate() * (state.torque[i] + self.joint_torque[i]));
                // Damping (`set_damping`): e^{−0} = 1 exactly, so none changes nothing.
                v[i] *= (-h * model.linear_damping[i]).exp();
                pi[i] *= (-h * model.angular_damping[i]).exp();
            }
            self.omega[i] = q[i] * (pi[i] / model.moments[i]);
            if detect {
                let orient = q[i] * model.principal[i].conjugate();
                self.placed.push(Placed::new(
                    &model.shape[i],
                    x[i] - orient * model.com_body[i],
                    orient,
                ));
            }
        }
    }

    /// Sequential impulses: the contacts (warm-started in [`Solver::coupled_step`]), the impulse
    /// joints from their accumulated impulses, then the sweeps (island by island without
    /// joints, shared with the impulse joints otherwise) and the alternation with the
    /// Lagrange joints' velocity projection.
    fn solve_velocities(&mut self, model: &Model, h: f64, m: Methods) -> Result<()> {
        let (x, v, q, _) = &mut *self.scratch;
        let mass = mass_of(model);
        contact::world_inverse_inertias(q, &model.inv_moments, &mut self.inv_inertia);
        let bodies = Bodies { inv_mass: &model.inv_mass, inv_inertia: &self.inv_inertia };
        for c in self.contacts.iter_mut() {
            bodies.prepare(c);
        }
        contact::apply_impulses(&self.contacts, &bodies, v, &mut self.omega);
        let sweeps = sweeps(&self.contacts, model, m.impulse);
        if m.impulse {
            let s = Kinematics { x, q, v, w: &self.omega };
            impulse_rows(model, &s, &mut self.rows, &mut self.row_mass);
            for (ji, j) in model.joints.iter().enumerate() {
                if j.method == JointMethod::Impulse {
                    for k in ji * SLOTS..ji * SLOTS + j.slots() {
                        let l = self.joint_impulse[k];
                        js::apply(&mass, j, &self.rows[k], l, q, v, &mut self.omega);
                    }
                }
            }
        }
        if model.joints.is_empty() {
            let fixed = &model.fixed;
            self.islands.build(&self.contacts, |i| !fixed[i], model.len());
            self.islands.solve(&mut self.contacts, &bodies, sweeps, CONVERGED, v, &mut self.omega);
        }
        // With joints the contacts share the sweeps with the impulse joints, all of them.
        let shared = if model.joints.is_empty() { 0 } else { sweeps };
        for _ in 0..shared {
            for (ji, j) in model.joints.iter().enumerate() {
                if j.method == JointMethod::Impulse {
                    let slots = ji * SLOTS..ji * SLOTS + j.slots();
                    js::sweep(
                        j,
                        &self.rows[slots.clone()],
                        &self.row_mass[slots.clone()],
                        &mut self.joint_impulse[slots],
                        &mass,
                        q,
                        h,
                        v,
                        &mut self.omega,
                    );
                }
            }
            contact::sweep(&mut self.contacts, &bodies, v, &mut self.omega);
        }
        if m.lagrange && !self.contacts.is_empty() {
            // The contacts changed the velocities after the multipliers: alternate a velocity
            // projection onto the Lagrange joints with contact sweeps so both hold.
            for _ in 0..LAGRANGE_CONTACT_ROUNDS {
                let (joints, rows) = (&model.joints, &self.rows);
                self.multipliers.project_velocities(joints, rows, &mass, q, v, &mut self.omega)?;
                contact::sweep(&mut self.contacts, &bodies, v, &mut self.omega);
            }
        }
        Ok(())
    }

    /// Positions from the new velocities (`x += h v`) and the rotation by the model's
    /// integrator; the contacts' gaps advanced with them.
    fn drift(&mut self, model: &Model, h: f64) {
        let (x, v, q, pi) = &mut *self.scratch;
        contact::advance_gaps(&mut self.contacts, h, v, &self.omega);
        for i in (0..model.len()).filter(|&i| !model.fixed[i]) {
            pi[i] = (q[i].conjugate() * self.omega[i]) * model.moments[i];
            x[i] += h * v[i];
            let (qi, pii) = rotate(model.integrator, q[i], pi[i], model.moments[i], DVec3::ZERO, h);
            q[i] = qi;
            pi[i] = pii;
        }
    }

    /// Post-stabilisation of the Lagrange joints at the end-of-step pose.
    fn post_stabilize(&mut self, model: &Model) -> Result<()> {
        let (x, _, q, _) = &mut *self.scratch;
        let n = model.len();
        clear_corrections(&mut self.dx, &mut self.dtheta, n);
        let s = Kinematics { x, q, v: &[], w: &[] };
        for (ji, j) in model.joints.iter().enumerate() {
            if j.method == JointMethod::Lagrange {
                j.rows(&s, &mut self.rows[ji * SLOTS..(ji + 1) * SLOTS]);
            }
        }
        let mass = mass_of(model);
        let (joints, rows) = (&model.joints, &self.rows);
        self.multipliers.project(joints, rows, &mass, q, &mut self.dx, &mut self.dtheta)?;
        for i in (0..n).filter(|&i| !model.fixed[i]) {
            x[i] += self.dx[i];
            q[i] = (exp_map(self.dtheta[i]) * q[i]).normalize();
        }
        Ok(())
    }

    /// Position pass: penetration and the impulse joints' drift removed by moving positions
    /// only (nonlinear Gauss–Seidel, as Box2D v2).
    fn position_pass(&mut self, model: &Model, impulse: bool) {
        let (x, _, q, _) = &mut *self.scratch;
        let n = model.len();
        clear_corrections(&mut self.dx, &mut self.dtheta, n);
        if !impulse && self.contacts.is_empty() {
            return;
        }
        let sweeps = sweeps(&self.contacts, model, impulse);
        let mass = mass_of(model);
        contact::world_inverse_inertias(q, &model.inv_moments, &mut self.inv_inertia);
        let bodies = Bodies { inv_mass: &model.inv_mass, inv_inertia: &self.inv_inertia };
        let s = Kinematics { x, q, v: &[], w: &[] };
        impulse_rows(model, &s, &mut self.rows, &mut self.row_mass);
        for _ in 0..sweeps {
            for (ji, j) in model.joints.iter().enumerate() {
                if j.method == JointMethod::Impulse {
                    let slots = ji * SLOTS..ji * SLOTS + j.slots();
                    let (rows, row_mass) = (&self.rows[slots.clone()], &self.row_mass[slots]);
                    js::correct_positions(
                        j,
                        rows,
                        row_mass,
                        &mass,
                        q,
                        &mut self.dx,
                        &mut self.dtheta,
                    );
                }
            }
            let pushed = contact::correct_positions(
                &self.contacts,
                1,
                &bodies,
                &mut self.dx,
                &mut self.dtheta,
            );
            if model.joints.is_empty() && !pushed {
                break; // nothing overlaps beyond the slop any more
            }
        }
        for i in (0..n).filter(|&i| !model.fixed[i]) {
            x[i] += self.dx[i];
            q[i] = (exp_map(self.dtheta[i]) * q[i]).normalize();
        }
    }

    /// The XPBD part of a substep: project the positions onto the XPBD joints once, take the
    /// corrections into the velocities (`v += Δx/h`, `ω += Δθ/h`), then run the motors of
    /// those joints as a velocity pass (Müller et al. 2020, Alg. 2).
    fn xpbd_step(&mut self, model: &Model, h: f64) {
        let (x, v, q, pi) = &mut *self.scratch;
        let n = model.len();
        let mass = mass_of(model);
        clear_corrections(&mut self.xpbd_dx, &mut self.xpbd_dtheta, n);
        for i in 0..n {
            self.omega[i] = q[i] * (pi[i] / model.moments[i]);
        }
        for j in model.joints.iter().filter(|j| j.method == JointMethod::Xpbd) {
            js::project(j, &mass, x, q, &mut self.xpbd_dx, &mut self.xpbd_dtheta);
        }
        for i in (0..n).filter(|&i| !model.fixed[i]) {
            v[i] += self.xpbd_dx[i] / h;
            self.omega[i] += self.xpbd_dtheta[i] / h;
        }
        // Velocity pass of hinges with limits or a motor: a few sweeps over all their rows
        // (equalities, limits as λ ≥ 0, the motor within its torque bound), so that a limit
        // stops the whole body (not only its turning about the centre of mass) and a motor
        // turns it about the hinge.
        let s = Kinematics { x, q, v: &[], w: &[] };
        for (ji, j) in model.joints.iter().enumerate() {
            let driven = matches!(j.kind, JointKind::Hinge { limits: Some(_), .. })
                || matches!(j.kind, JointKind::Hinge { motor: Some(_), .. });
            if j.method != JointMethod::Xpbd || !driven {
                continue;
            }
            let slots = ji * SLOTS..(ji + 1) * SLOTS;
            j.rows(&s, &mut self.rows[slots.clone()]);
            js::effective_masses(
                j,
                &self.rows[slots.clone()],
                &mass,
                q,
                &mut self.row_mass[slots.clone()],
            );
            let mut impulse = [0.0; SLOTS];
            for _ in 0..XPBD_VELOCITY_SWEEPS {
                let (rows, row_mass) = (&self.rows[slots.clone()], &self.row_mass[slots.clone()]);
                js::sweep(j, rows, row_mass, &mut impulse, &mass, q, h, v, &mut self.omega);
            }
        }
        for i in (0..n).filter(|&i| !model.fixed[i]) {
            pi[i] = (q[i].conjugate() * self.omega[i]) * model.moments[i];
        }
    }
}
