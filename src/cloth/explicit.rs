//! The explicit path of the cloth, for comparison with the implicit step: the cloth as a
//! first-order system `y = [x; v]` stepped by any explicit method of [`crate::ode`], then
//! pins and collisions resolved by projection.

use super::{Model, Solver, State, StepStats, VertexConstraint};
use crate::error::{Error, Result};
use crate::ode::{Method, OdeSystem, Stepper};
use glam::DVec3;
use std::time::Instant;

impl Solver {
    /// One explicit step: the shared integrator on `y = [x; v]`, then pins and collisions.
    pub(super) fn step_explicit(
        &mut self,
        model: &Model,
        state: &mut State,
        stats: &mut StepStats,
        h: f64,
        method: Method,
    ) -> Result<()> {
        let n = state.len();
        let t0 = Instant::now();
        if self.stepper.as_ref().is_none_or(|s| s.method() != method) {
            self.stepper = Some(Stepper::new(method, 6 * n)?);
        }
        let stepper = self.stepper.as_mut().expect("created above");
        let s = &mut self.scratch;
        s.flat.resize(6 * n, 0.0);
        for i in 0..n {
            s.flat[3 * i..3 * i + 3].copy_from_slice(&state.x[i].to_array());
            // Constrained velocities hold from the start of the step.
            let v = match state.constraints[i] {
                Some(VertexConstraint::Pinned(_)) => DVec3::ZERO,
                Some(VertexConstraint::Velocity(target)) => target,
                _ => state.v[i],
            };
            s.flat[3 * (n + i)..3 * (n + i) + 3].copy_from_slice(&v.to_array());
        }
        let mut system = ExplicitSystem { model, state, x: &mut s.ex, v: &mut s.ev, f: &mut s.f };
        if let Err(e) = stepper.step(&mut system, state.time, &mut s.flat, h) {
            return Err(match e {
                Error::Diverged { index, .. } => Error::Diverged {
                    step: 0,
                    index: (index % (3 * n)) / 3,
                    reason: "non-finite cloth state".into(),
                },
                other => other,
            });
        }
        take_explicit(state, &s.flat);
        state.advance_colliders(h);
        let contacts = project(model, state);
        state.previous_dt = None;
        *stats = StepStats {
            contacts,
            converged: true,
            collide_seconds: t0.elapsed().as_secs_f64(),
            ..StepStats::default()
        };
        Ok(())
    }
}

/// Copy `y = [x; v]` into the state, with pinned and prescribed vertices as constrained.
fn take_explicit(state: &mut State, flat: &[f64]) {
    let n = state.len();
    for i in 0..n {
        state.x[i] = DVec3::from_slice(&flat[3 * i..3 * i + 3]);
        state.v[i] = DVec3::from_slice(&flat[3 * (n + i)..3 * (n + i) + 3]);
        match state.constraints[i] {
            Some(VertexConstraint::Pinned(p)) => {
                state.x[i] = p;
                state.v[i] = DVec3::ZERO;
            }
            Some(VertexConstraint::Velocity(target)) => state.v[i] = target,
            _ => {}
        }
    }
}

/// Free vertices within `thickness` of a collider are put back at `thickness`, their
/// approaching normal velocity removed and their tangential velocity reduced by Coulomb
/// friction (`μ |vₙ|` at most); returns the number of such contacts.
fn project(model: &Model, state: &mut State) -> usize {
    let mut contacts = 0;
    let thickness = model.thickness;
    for i in 0..state.len() {
        if state.constraints[i].is_some() {
            continue;
        }
        for col in &state.colliders {
            let (d, normal) = col.shape.distance(state.x[i]);
            if d >= thickness {
                continue;
            }
            contacts += 1;
            state.x[i] += normal * (thickness - d);
            let rel = state.v[i] - col.velocity;
            let vn = rel.dot(normal);
            if vn < 0.0 {
                let tangential = rel - normal * vn;
                let speed = tangential.length();
                let reduce = (col.friction * -vn).min(speed);
                let t = if speed > 0.0 { tangential * (reduce / speed) } else { DVec3::ZERO };
                state.v[i] -= normal * vn + t;
            }
        }
    }
    contacts
}

/// The cloth as a first-order system `y = [x; v]`, `ẏ = [v; S M⁻¹ f]` for the explicit
/// integrators.
struct ExplicitSystem<'a> {
    model: &'a Model,
    state: &'a State,
    x: &'a mut [DVec3],
    v: &'a mut [DVec3],
    f: &'a mut [DVec3],
}

impl OdeSystem for ExplicitSystem<'_> {
    fn dim(&self) -> usize {
        6 * self.state.len()
    }

    fn rhs(&mut self, _t: f64, y: &[f64], dydt: &mut [f64]) -> Result<()> {
        let n = self.state.len();
        for i in 0..n {
            self.x[i] = DVec3::from_slice(&y[3 * i..3 * i + 3]);
            self.v[i] = DVec3::from_slice(&y[3 * (n + i)..3 * (n + i) + 3]);
        }
        self.model.forces_into(self.x, self.v, self.f);
        let mass = &self.model.mass;
        for i in 0..n {
            let (vel, acc) = match self.state.constraints[i] {
                Some(VertexConstraint::Pinned(_)) => (DVec3::ZERO, DVec3::ZERO),
                Some(VertexConstraint::Velocity(target)) => (target, DVec3::ZERO),
                Some(VertexConstraint::Plane(nrm)) => {
                    let a = self.f[i] / mass[i];
                    (self.v[i], a - nrm * nrm.dot(a))
                }
                Some(VertexConstraint::Line(d)) => (self.v[i], d * d.dot(self.f[i] / mass[i])),
                None => (self.v[i], self.f[i] / mass[i]),
            };
            dydt[3 * i..3 * i + 3].copy_from_slice(&vel.to_array());
            dydt[3 * (n + i)..3 * (n + i) + 3].copy_from_slice(&acc.to_array());
        }
        Ok(())
    }
}
