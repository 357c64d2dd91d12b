//! `kinema.particles`: a compiled particle system whose state numpy views without a copy.

use super::args::Int;
use super::array::{compute, rows, zeroed};
use super::error::detached_on;
use super::pickle::{reduce, Reduced};
use super::view::view;
use crate::error::Error;
use crate::geometry::Material;
use crate::ode::Method;
use crate::particles::{
    Appearance, Collider, Emitter, Force, ParticleSystem, State, StepStats, SERIAL_CAPACITY,
};
use crate::snapshot::Snapshot;
use glam::DVec3;
use numpy::{PyArrayDyn, PyReadonlyArrayDyn};
use pyo3::prelude::*;
use pyo3::types::PyDict;

fn v3(p: &[f64], k: usize) -> DVec3 {
    DVec3::new(p[k], p[k + 1], p[k + 2])
}

fn params(p: &[f64], count: usize, what: &str) -> PyResult<()> {
    if p.len() == count {
        Ok(())
    } else {
        Err(Error::invalid(what, format!("expected {count} parameters, got {}", p.len())).into())
    }
}

/// A collider from its kind and parameters: the shape's ([`super::geometry::shape`]), then
/// restitution, friction, velocity 3 and inside (0 or 1).
fn collider(kind: &str, p: &[f64]) -> PyResult<Collider> {
    let (shape, t) = super::geometry::shape(kind, p, 6)?;
    let material = Material { restitution: t[0], friction: t[1] };
    Ok(Collider { shape, material, velocity: DVec3::new(t[2], t[3], t[4]), inside: t[5] != 0.0 })
}

/// A fixed-capacity particle system; see `kinema.particles.ParticleSystem` for the API.
#[pyclass(module = "kinema._kinema")]
pub struct Particles {
    pub(crate) system: ParticleSystem,
    /// The undo point of [`Particles::_mark`] (kept to reuse its buffers): the state, the
    /// colliders (a scene moves and adds them during a frame) and the counters.
    saved: Option<(State, Vec<Collider>, StepStats)>,
}

#[pymethods]
impl Particles {
    /// Pickle support: the object as a snapshot (model and state, see `kinema::snapshot`).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.system, vec![])
    }

    /// The object stored by `__reduce__`.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { system: ParticleSystem::from_snapshot(data)?, saved: None })
    }

    /// Remember the system's state, colliders and counters as they are now (a scene's undo
    /// point before a frame; no serialisation, and no allocation after the first time).
    fn _mark(&mut self) {
        let system = &self.system;
        let saved =
            self.saved.get_or_insert_with(|| (system.state().clone(), Vec::new(), system.stats));
        saved.0.clone_from(system.state());
        saved.1.clear();
        saved.1.extend_from_slice(system.model().colliders());
        saved.2 = system.stats;
    }

    /// Put the state, colliders and counters back as they were at the last
    /// [`Particles::_mark`], in place (views of the state stay valid).
    fn _rollback(&mut self) -> PyResult<()> {
        if let Some((state, colliders, stats)) = &self.saved {
            self.system.set_state(state)?;
            self.system.restore_colliders(colliders);
            self.system.stats = *stats;
        }
        Ok(())
    }

    /// `positions` (N, 3) m, `velocities` (N, 3) m/s, `masses` (N, 1) kg (inf pins), and room
    /// for `capacity` particles in all.
    #[new]
    fn new(
        positions: PyReadonlyArrayDyn<'_, f64>,
        velocities: PyReadonlyArrayDyn<'_, f64>,
        masses: PyReadonlyArrayDyn<'_, f64>,
        capacity: Int,
    ) -> PyResult<Self> {
        let capacity = capacity.count("capacity")?;
        let x: Vec<DVec3> = rows::<3>(&positions, "positions", &[3])?
            .iter()
            .map(|p| DVec3::from_array(*p))
            .collect();
        let v: Vec<DVec3> = rows::<3>(&velocities, "velocities", &[3])?
            .iter()
            .map(|p| DVec3::from_array(*p))
            .collect();
        let m: Vec<f64> = rows::<1>(&masses, "masses", &[1])?.iter().map(|p| p[0]).collect();
        Ok(Particles { system: ParticleSystem::new(&x, &v, &m, capacity)?, saved: None })
    }

    /// Add a force by kind with its parameters (see `kinema.particles` for each layout).
    #[pyo3(
        signature = (kind, p, pairs=None, rest=None, seed=Int::ZERO),
        text_signature = "($self, kind, p, pairs=None, rest=None, seed=0)"
    )]
    fn add_force(
        &mut self,
        kind: &str,
        p: Vec<f64>,
        pairs: Option<PyReadonlyArrayDyn<'_, f64>>,
        rest: Option<PyReadonlyArrayDyn<'_, f64>>,
        seed: Int,
    ) -> PyResult<()> {
        let seed = seed.seed("seed")?;
        let force = match kind {
            "gravity" => {
                params(&p, 3, "gravity")?;
                Force::Gravity { g: v3(&p, 0) }
            }
            "drag" => {
                params(&p, 5, "drag")?;
                Force::Drag { linear: p[0], quadratic: p[1], wind: v3(&p, 2) }
            }
            "damping" => {
                params(&p, 1, "damping")?;
                Force::Damping { rate: p[0] }
            }
            "springs" => {
                params(&p, 2, "springs")?;
                let (Some(pairs), Some(rest)) = (pairs, rest) else {
                    return Err(
                        Error::invalid("pairs", "springs need pairs and rest lengths").into()
                    );
                };
                let pr = rows::<2>(&pairs, "pairs", &[2])?;
                let mut ij = Vec::with_capacity(pr.len());
                for (k, q) in pr.iter().enumerate() {
                    if q.iter().any(|x| x.fract() != 0.0 || *x < 0.0 || !x.is_finite()) {
                        return Err(Error::InvalidInput {
                            arg: "pairs".into(),
                            index: Some(k),
                            reason: "indices must be non-negative integers".into(),
                        }
                        .into());
                    }
                    ij.push([q[0] as usize, q[1] as usize]);
                }
                let rest = rows::<1>(&rest, "rest", &[1])?.iter().map(|r| r[0]).collect();
                Force::Springs { pairs: ij, rest, stiffness: p[0], damping: p[1] }
            }
            "attractor" => {
                params(&p, 5, "attractor")?;
                Force::Attractor { center: v3(&p, 0), strength: p[3], softening: p[4] }
            }
            "vortex" => {
                params(&p, 8, "vortex")?;
                Force::Vortex { center: v3(&p, 0), axis: v3(&p, 3), strength: p[6], core: p[7] }
            }
            "turbulence" => {
                params(&p, 2, "turbulence")?;
                Force::Turbulence { strength: p[0], scale: p[1], seed }
            }
            "neighbor_repulsion" => {
                params(&p, 2, "neighbor_repulsion")?;
                Force::NeighborRepulsion { radius: p[0], stiffness: p[1] }
            }
            "nbody_gravity" => {
                params(&p, 2, "nbody_gravity")?;
                Force::NBodyGravity { constant: p[0], softening: p[1] }
            }
            other => return Err(Error::invalid("force", format!("unknown force {other:?}")).into()),
        };
        Ok(self.system.add_force(force)?)
    }

    /// Add a collider of `kind` with the shape's parameters (see [`super::geometry::shape`])
    /// followed by restitution, friction, velocity (3) and inside (0/1).
    fn add_collider(&mut self, kind: &str, p: Vec<f64>) -> PyResult<()> {
        Ok(self.system.add_collider(collider(kind, &p)?)?)
    }

    /// Replace collider `index` by one given as in `add_collider`.
    fn set_collider(&mut self, index: Int, kind: &str, p: Vec<f64>) -> PyResult<()> {
        Ok(self.system.set_collider(index.count("index")?, collider(kind, &p)?)?)
    }

    /// Add an emitter: (rate, position 3, position_spread, velocity 3, velocity_spread,
    /// lifespan, mass, color 4, color_spread, size, size_spread) and a seed.
    fn add_emitter(&mut self, p: Vec<f64>, seed: Int) -> PyResult<()> {
        params(&p, 18, "emitter")?;
        let seed = seed.seed("seed")?;
        Ok(self.system.add_emitter(Emitter {
            rate: p[0],
            position: v3(&p, 1),
            position_spread: p[4],
            velocity: v3(&p, 5),
            velocity_spread: p[8],
            lifespan: p[9],
            mass: p[10],
            seed,
            appearance: Appearance {
                color: [p[11], p[12], p[13], p[14]],
                color_spread: p[15],
                size: p[16],
                size_spread: p[17],
            },
        })?)
    }

    /// Advance `steps` steps of `dt` seconds with `method` (GIL released); the implicit
    /// methods factorise the sparse Newton matrix, or the dense one by differences when
    /// `sparse_jacobian` is false.
    #[pyo3(signature = (dt, steps, method, sparse_jacobian=true))]
    fn step(
        &mut self,
        py: Python<'_>,
        dt: f64,
        steps: Int,
        method: &str,
        sparse_jacobian: bool,
    ) -> PyResult<()> {
        let steps = steps.count("steps")?;
        let method = Method::parse(method)?;
        let system = &mut self.system;
        let parallel = system.capacity() > SERIAL_CAPACITY;
        detached_on(py, parallel, || system.step_with_jacobian(dt, steps, method, sparse_jacobian))
    }

    /// Read-only view (capacity, 3) of the positions (m), updated in place by `step`.
    #[getter]
    fn positions<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().system.capacity();
        view(slf, &[n, 3], |p| p.system.positions())
    }

    /// Read-only view (capacity, 3) of the velocities (m/s), updated in place by `step`.
    #[getter]
    fn velocities<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().system.capacity();
        view(slf, &[n, 3], |p| p.system.velocities())
    }

    /// Read-only view (capacity, 4) of the colours (linear RGBA in [0, 1]).
    #[getter]
    fn colors<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().system.capacity();
        view(slf, &[n, 4], |p| p.system.colors().as_flattened())
    }

    /// Read-only view (capacity,) of the sizes (diameters, m).
    #[getter]
    fn sizes<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().system.capacity();
        view(slf, &[n], |p| p.system.sizes())
    }

    /// Overwrite the colours (capacity, 4) and sizes (capacity, 1) of every slot.
    fn set_appearance(
        &mut self,
        colors: PyReadonlyArrayDyn<'_, f64>,
        sizes: PyReadonlyArrayDyn<'_, f64>,
    ) -> PyResult<()> {
        let c = rows::<4>(&colors, "colors", &[4])?;
        let s: Vec<f64> = rows::<1>(&sizes, "sizes", &[1])?.iter().map(|r| r[0]).collect();
        Ok(self.system.set_appearance(c, &s)?)
    }

    /// Overwrite positions and velocities (capacity, 3) of every slot.
    fn set_state(
        &mut self,
        positions: PyReadonlyArrayDyn<'_, f64>,
        velocities: PyReadonlyArrayDyn<'_, f64>,
    ) -> PyResult<()> {
        let n = self.system.capacity();
        let x = rows::<3>(&positions, "positions", &[3])?;
        let v = rows::<3>(&velocities, "velocities", &[3])?;
        if x.len() != n || v.len() != n {
            return Err(Error::invalid(
                "positions",
                format!("expected {n} rows (the capacity), got {} and {}", x.len(), v.len()),
            )
            .into());
        }
        if let Some(i) = x.iter().chain(v).position(|r| r.iter().any(|c| !c.is_finite())) {
            return Err(Error::InvalidInput {
                arg: if i < n { "positions".into() } else { "velocities".into() },
                index: Some(i % n),
                reason: "contains NaN or infinity".into(),
            }
            .into());
        }
        let y = self.system.state_mut();
        y[..3 * n].copy_from_slice(x.as_flattened());
        y[3 * n..].copy_from_slice(v.as_flattened());
        self.system.state_changed();
        Ok(())
    }

    /// Forces (capacity, 3) in N acting in the following steps (an empty array removes them).
    fn set_external_forces(&mut self, forces: PyReadonlyArrayDyn<'_, f64>) -> PyResult<()> {
        let f = rows::<3>(&forces, "forces", &[3])?;
        Ok(self.system.set_external_forces(f.as_flattened())?)
    }

    /// Live flags (capacity, 1) as 0.0 / 1.0.
    fn alive<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let a = self.system.alive();
        compute::<1>(py, a.len(), &[1], |out| {
            let out = zeroed(out);
            out.iter_mut().zip(a).for_each(|(o, l)| o[0] = f64::from(u8::from(*l)));
            Ok(())
        })
    }

    /// Ages (capacity, 1) in seconds.
    fn ages<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let a = self.system.ages();
        compute::<1>(py, a.len(), &[1], |out| {
            let out = zeroed(out);
            out.iter_mut().zip(a.iter()).for_each(|(o, v)| o[0] = *v);
            Ok(())
        })
    }

    /// Masses (capacity, 1) in kg (inf for pinned).
    fn masses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let a = self.system.masses();
        compute::<1>(py, a.len(), &[1], |out| {
            let out = zeroed(out);
            out.iter_mut().zip(a.iter()).for_each(|(o, v)| o[0] = *v);
            Ok(())
        })
    }

    /// Kinetic energy of the live particles (J).
    fn kinetic_energy(&self) -> f64 {
        self.system.kinetic_energy()
    }

    /// Potential energy of the conservative forces (J).
    fn potential_energy(&self) -> f64 {
        self.system.potential_energy()
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.system.time()
    }

    /// Counters of the last `step` call.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.system.stats;
        let d = PyDict::new(py);
        d.set_item("emitted", s.emitted)?;
        d.set_item("dropped", s.dropped)?;
        d.set_item("expired", s.expired)?;
        d.set_item("contacts", s.contacts)?;
        d.set_item("factorizations", s.factorizations)?;
        Ok(d)
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Particles>()
}
