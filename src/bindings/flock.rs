//! `kinema.flock`: a compiled flock of boids whose positions and velocities numpy views
//! without a copy.

use super::args::Int;
use super::array::rows;
use super::error::detached;
use super::pickle::{reduce, Reduced};
use super::view::view;
use crate::error::Error;
use crate::flock::{Behaviour, Flock as Core, Settings, State, Steering};
use crate::snapshot::Snapshot;
use glam::DVec3;
use numpy::{PyArrayDyn, PyReadonlyArrayDyn};
use pyo3::prelude::*;

/// A flock; see `kinema.flock.Flock` for the API.
#[pyclass(module = "kinema._kinema")]
pub struct Flock {
    flock: Core,
    /// The scene's undo point (`_mark`).
    saved: Option<State>,
}

fn points(arr: &PyReadonlyArrayDyn<'_, f64>, arg: &str) -> PyResult<Vec<DVec3>> {
    Ok(rows::<3>(arr, arg, &[3])?.iter().map(|x| DVec3::from_array(*x)).collect())
}

#[pymethods]
impl Flock {
    /// Pickle support: the flock as a snapshot (model and state).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.flock, vec![])
    }

    /// The object stored by `__reduce__`.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { flock: Core::from_snapshot(data)?, saved: None })
    }

    /// A flock of boids at `positions` (N, 3) in m with `velocities` (N, 3) in m/s; the
    /// weights `separation`, `alignment`, `cohesion`, `neighbour_radius` and
    /// `separation_distance` (m), `field_of_view` (rad), `max_speed` (m/s), `max_force`
    /// (m/s²).
    #[new]
    #[allow(clippy::too_many_arguments)]
    fn new(
        positions: PyReadonlyArrayDyn<'_, f64>,
        velocities: PyReadonlyArrayDyn<'_, f64>,
        separation: f64,
        alignment: f64,
        cohesion: f64,
        neighbour_radius: f64,
        separation_distance: f64,
        field_of_view: f64,
        max_speed: f64,
        max_force: f64,
    ) -> PyResult<Self> {
        let settings = Settings {
            separation,
            alignment,
            cohesion,
            neighbour_radius,
            separation_distance,
            field_of_view,
            max_speed,
            max_force,
        };
        let (p, v) = (points(&positions, "positions")?, points(&velocities, "velocities")?);
        Ok(Flock { flock: Core::new(settings, &p, &v)?, saved: None })
    }

    /// Keep a copy of the state to go back to (`_rollback`; the scene's undo point).
    fn _mark(&mut self) {
        let flock = &self.flock;
        self.saved.get_or_insert_with(|| flock.state().clone()).clone_from(flock.state());
    }

    /// Put the state back as it was at the last `_mark`, in place (views stay valid).
    fn _rollback(&mut self) {
        if let Some(state) = &self.saved {
            self.flock.state_mut().clone_from(state);
        }
    }

    /// Add a steering behaviour of `kind` — "seek", "flee" (`values`: target 3, m),
    /// "arrive" (target 3, slow radius, m), "pursue", "evade" (`boid`), "wander" (distance,
    /// radius in m, `seed`, `planar`), "avoid" (`shape` and its parameters, then horizon in
    /// s and clearance in m), "follow" (the path's points, 3 numbers each, then radius in m
    /// and lookahead in s) — with `weight`, acting on boids `first..end`.
    #[allow(clippy::too_many_arguments)]
    fn add_steering(
        &mut self,
        kind: &str,
        weight: f64,
        first: Int,
        end: Int,
        values: Vec<f64>,
        boid: Int,
        seed: Int,
        planar: bool,
        shape: &str,
    ) -> PyResult<()> {
        let need = |n: usize| {
            if values.len() == n {
                Ok(())
            } else {
                Err(Error::invalid("values", format!("expected {n} numbers")))
            }
        };
        let v3 = |k: usize| DVec3::new(values[k], values[k + 1], values[k + 2]);
        let max = u32::MAX as usize;
        let behaviour = match kind {
            "seek" | "flee" => {
                need(3)?;
                if kind == "seek" {
                    Behaviour::Seek(v3(0))
                } else {
                    Behaviour::Flee(v3(0))
                }
            }
            "arrive" => {
                need(4)?;
                Behaviour::Arrive { target: v3(0), slow_radius: values[3] }
            }
            "pursue" => Behaviour::Pursue(boid.range("boid", 0, max)? as u32),
            "evade" => Behaviour::Evade(boid.range("boid", 0, max)? as u32),
            "wander" => {
                need(2)?;
                let seed = seed.count("seed")? as u64;
                Behaviour::Wander { distance: values[0], radius: values[1], seed, planar }
            }
            "avoid" => {
                let (shape, tail) = super::geometry::shape(shape, &values, 2)?;
                Behaviour::Avoid { shape, horizon: tail[0], clearance: tail[1] }
            }
            "follow" => {
                if values.len() < 2 || !(values.len() - 2).is_multiple_of(3) {
                    return Err(
                        Error::invalid("values", "expected 3 numbers a point, then 2").into()
                    );
                }
                let (points, tail) = values.split_at(values.len() - 2);
                let path = points.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2])).collect();
                Behaviour::Follow { path, radius: tail[0], lookahead: tail[1] }
            }
            _ => return Err(Error::invalid("kind", "unknown steering behaviour").into()),
        };
        let boids = [first.range("boids", 0, max)? as u32, end.range("boids", 0, max)? as u32];
        Ok(self.flock.add_steering(Steering { behaviour, weight, boids })?)
    }

    /// Advance `steps` steps of `dt` seconds (GIL released).
    fn step(&mut self, py: Python<'_>, dt: f64, steps: Int) -> PyResult<()> {
        let steps = steps.count("steps")?;
        let flock = &mut self.flock;
        detached(py, || flock.step(dt, steps))
    }

    /// Number of boids.
    fn __len__(&self) -> usize {
        self.flock.state().len()
    }

    /// Read-only view (N, 3) of the positions (m), updated in place by `step`.
    #[getter]
    fn positions<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().flock.state().len();
        view(slf, &[n, 3], |c| bytemuck::cast_slice(c.flock.state().positions()))
    }

    /// Read-only view (N, 3) of the velocities (m/s), updated in place by `step`.
    #[getter]
    fn velocities<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().flock.state().len();
        view(slf, &[n, 3], |c| bytemuck::cast_slice(c.flock.state().velocities()))
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.flock.state().time()
    }

    /// The polarisation order parameter of the velocities (Vicsek et al. 1995), in [0, 1].
    fn polarisation(&self) -> f64 {
        crate::flock::polarisation(self.flock.state().velocities())
    }

    /// The fraction of boids in the largest cluster of boids closer than `radius` (m; default
    /// the neighbour radius) (Grégoire & Chaté 2004), in (0, 1].
    #[pyo3(signature = (radius=None))]
    fn cohesion(&self, py: Python<'_>, radius: Option<f64>) -> PyResult<f64> {
        let positions = self.flock.state().positions();
        let radius = radius.unwrap_or(self.flock.model().settings().neighbour_radius);
        detached(py, || crate::flock::cohesion(positions, radius))
    }
}

/// Register the class.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Flock>()
}
