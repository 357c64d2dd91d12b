//! The explicit path of the cloth, for comparison with the implicit step: the cloth as a
//! first-order system `y = [x; v]` stepped by any explicit method of [`crate::ode`].

use super::*;

impl Cloth {
    /// One explicit step: the shared integrator on `y = [x; v]`, then pins and collisions.
    pub(super) fn step_explicit(&mut self, h: f64, method: Method) -> Result<()> {
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
                let (d, normal) = col.shape.distance(self.x[i]);
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
