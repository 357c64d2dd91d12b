//! `kinema.crowd`: a compiled crowd (ORCA or social forces) whose positions, velocities and
//! goals numpy views without a copy.

use super::args::Int;
use super::array::{compute, rows, zeroed};
use super::error::detached;
use super::pickle::{reduce, Reduced};
use super::view::view;
use crate::crowd::{Crowd as Core, Kind, Settings, SocialForce, State, Stats};
use crate::error::Error;
use crate::snapshot::Snapshot;
use glam::DVec2;
use numpy::{PyArrayDyn, PyReadonlyArrayDyn};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A crowd; see `kinema.crowd.Crowd` for the API.
#[pyclass(module = "kinema._kinema")]
pub struct Crowd {
    crowd: Core,
    /// Whether a view of the agents' arrays was handed out: their buffers must then never be
    /// reallocated, so no agent may be added.
    viewed: bool,
    /// The scene's undo point (`_mark`).
    saved: Option<(State, Stats)>,
}

fn points(arr: &PyReadonlyArrayDyn<'_, f64>, arg: &str) -> PyResult<Vec<DVec2>> {
    points_shaped(arr, arg, &[2])
}

fn out1<'py>(py: Python<'py>, values: &[f64]) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    compute::<1>(py, values.len(), &[], |out| {
        let out = zeroed(out);
        out.iter_mut().zip(values).for_each(|(o, v)| o[0] = *v);
        Ok(())
    })
}

#[pymethods]
impl Crowd {
    /// Pickle support: the crowd as a snapshot (model and state).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.crowd, vec![])
    }

    /// The object stored by `__reduce__`.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { crowd: Core::from_snapshot(data)?, viewed: false, saved: None })
    }

    /// An empty crowd: `model` ("orca" or "social_force"), agent `radius` (m), `max_speed`
    /// and `preferred_speed` (m/s), `neighbour_distance` (m), `max_neighbours`, ORCA's
    /// `time_horizon` and `obstacle_time_horizon` (s), `goal_tolerance` (m), and the social
    /// forces' `mass` (kg), `relaxation_time` (s), `strength` (N), `range` (m), `body`
    /// (kg/s²), `friction` (kg/(m s)), `max_substep` (s), `anisotropy` (λ, in [0, 1]) and
    /// `time_gap` (s; Seyfried's `d = a + b v`); ORCA's preferred-velocity
    /// `perturbation` (m/s) and its `seed`; ORCA's `planning_margin` (the agents plan with the
    /// radius `r (1 + planning_margin)`).
    #[new]
    #[allow(clippy::too_many_arguments)]
    fn new(
        model: &str,
        radius: f64,
        max_speed: f64,
        preferred_speed: f64,
        neighbour_distance: f64,
        max_neighbours: Int,
        time_horizon: f64,
        obstacle_time_horizon: f64,
        goal_tolerance: f64,
        mass: f64,
        relaxation_time: f64,
        strength: f64,
        range: f64,
        body: f64,
        friction: f64,
        max_substep: f64,
        anisotropy: f64,
        time_gap: f64,
        perturbation: f64,
        seed: Int,
        planning_margin: f64,
    ) -> PyResult<Self> {
        let kind = match model {
            "orca" => Kind::Orca,
            "social_force" => Kind::SocialForce(SocialForce {
                mass,
                relaxation_time,
                strength,
                range,
                body,
                friction,
                max_substep,
                anisotropy,
                time_gap,
            }),
            _ => return Err(Error::invalid("model", "expected 'orca' or 'social_force'").into()),
        };
        let settings = Settings {
            radius,
            max_speed,
            preferred_speed,
            neighbour_distance,
            max_neighbours: max_neighbours.range("max_neighbours", 0, 1024)?,
            time_horizon,
            obstacle_time_horizon,
            goal_tolerance,
            perturbation,
            seed: seed.count("seed")? as u64,
            planning_margin,
            kind,
        };
        Ok(Crowd { crowd: Core::new(settings)?, viewed: false, saved: None })
    }

    /// Add agents at `positions` (N, 2) in m walking to `goals` (N, 2) in m.
    fn add_agents(
        &mut self,
        positions: PyReadonlyArrayDyn<'_, f64>,
        goals: PyReadonlyArrayDyn<'_, f64>,
    ) -> PyResult<()> {
        if self.viewed {
            return Err(Error::invalid(
                "positions",
                "add agents before reading positions, velocities or goals (their views must stay valid)",
            )
            .into());
        }
        let (p, g) = (points(&positions, "positions")?, points(&goals, "goals")?);
        Ok(self.crowd.add_agents(&p, &g)?)
    }

    /// Give the agents new goals (N, 2) in m, one per agent (views stay valid).
    fn set_goals(&mut self, goals: PyReadonlyArrayDyn<'_, f64>) -> PyResult<()> {
        Ok(self.crowd.state_mut().set_goals(&points(&goals, "goals")?)?)
    }

    /// Add a static obstacle polygon (K, 2) in m (counterclockwise; two points: a wall).
    fn add_obstacle(&mut self, polygon: PyReadonlyArrayDyn<'_, f64>) -> PyResult<()> {
        Ok(self.crowd.add_obstacle(&points(&polygon, "polygon")?)?)
    }

    /// Turn the navigation layer on with paths keeping `clearance` (m) from the obstacles,
    /// or off (`None`).
    fn set_navigation(&mut self, clearance: Option<f64>) -> PyResult<()> {
        Ok(self.crowd.set_navigation(clearance)?)
    }

    /// Keep a copy of the state and stats to go back to (`_rollback`; the scene's undo
    /// point).
    fn _mark(&mut self) {
        let crowd = &self.crowd;
        let saved = self.saved.get_or_insert_with(|| (crowd.state().clone(), crowd.stats));
        saved.0.clone_from(crowd.state());
        saved.1 = crowd.stats;
    }

    /// Put the state and stats back as they were at the last `_mark`, in place (views stay
    /// valid: agents are never added by a step).
    fn _rollback(&mut self) {
        if let Some((state, stats)) = &self.saved {
            self.crowd.state_mut().clone_from(state);
            self.crowd.stats = *stats;
        }
    }

    /// Advance `steps` steps of `dt` seconds (GIL released).
    fn step(&mut self, py: Python<'_>, dt: f64, steps: Int) -> PyResult<()> {
        let steps = steps.count("steps")?;
        let crowd = &mut self.crowd;
        detached(py, || crowd.step(dt, steps))
    }

    /// Number of agents.
    fn __len__(&self) -> usize {
        self.crowd.state().len()
    }

    /// Read-only view (N, 2) of the positions (m), updated in place by `step`.
    #[getter]
    fn positions<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        slf.borrow_mut().viewed = true;
        let n = slf.borrow().crowd.state().len();
        view(slf, &[n, 2], |c| bytemuck::cast_slice(c.crowd.state().positions()))
    }

    /// Read-only view (N, 2) of the velocities (m/s), updated in place by `step`.
    #[getter]
    fn velocities<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        slf.borrow_mut().viewed = true;
        let n = slf.borrow().crowd.state().len();
        view(slf, &[n, 2], |c| bytemuck::cast_slice(c.crowd.state().velocities()))
    }

    /// Read-only view (N, 2) of the goals (m).
    #[getter]
    fn goals<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        slf.borrow_mut().viewed = true;
        let n = slf.borrow().crowd.state().len();
        view(slf, &[n, 2], |c| bytemuck::cast_slice(c.crowd.state().goals()))
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.crowd.state().time()
    }

    /// The measurements so far: collision tallies, arrival times (N,) and path lengths (N,)
    /// in s and m, straight-line distances (N,) from start to goal in m.
    fn metrics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.crowd.state();
        let t = s.tally();
        let d = PyDict::new(py);
        d.set_item("steps", t.steps)?;
        d.set_item("agent_collisions", t.agent_collisions)?;
        d.set_item("obstacle_collisions", t.obstacle_collisions)?;
        d.set_item("steps_with_collisions", t.steps_with_collisions)?;
        d.set_item("max_overlap", t.max_overlap)?;
        d.set_item("max_penetration", t.max_penetration)?;
        d.set_item("arrival_times", out1(py, s.arrival_times())?)?;
        d.set_item("path_lengths", out1(py, s.path_lengths())?)?;
        let straight: Vec<f64> =
            s.starts().iter().zip(s.goals()).map(|(a, b)| (*b - *a).length()).collect();
        d.set_item("straight_lengths", out1(py, &straight)?)?;
        Ok(d)
    }

    /// What the last `step` call did.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.crowd.stats;
        let d = PyDict::new(py);
        d.set_item("steps", s.steps)?;
        d.set_item("substeps", s.substeps)?;
        d.set_item("fallbacks", s.fallbacks)?;
        Ok(d)
    }
}

/// The times (s, sorted) at which agents of `frames` (F, N, 2) in m at `times` (F,) in s
/// cross the segment `a`–`b` (m) from its right to its left.
#[pyfunction]
fn crowd_crossings<'py>(
    py: Python<'py>,
    frames: PyReadonlyArrayDyn<'py, f64>,
    times: PyReadonlyArrayDyn<'py, f64>,
    a: [f64; 2],
    b: [f64; 2],
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    use numpy::PyUntypedArrayMethods;
    let n = frames.shape().get(1).copied().unwrap_or(0);
    let flat: Vec<DVec2> = points_shaped(&frames, "frames", &[n, 2])?;
    let t = rows::<1>(&times, "times", &[1])?;
    let t: Vec<f64> = t.iter().map(|x| x[0]).collect();
    let refs: Vec<&[DVec2]> = if n == 0 { vec![&[]; t.len()] } else { flat.chunks(n).collect() };
    let found = detached(py, || {
        crate::crowd::metrics::crossings(&refs, &t, DVec2::from_array(a), DVec2::from_array(b))
    })?;
    out1(py, &found)
}

/// Goals (N, 2) in m that lead agents at `positions` (N, 2) out through the door `a`–`b`
/// (m); `crate::crowd::metrics::door_goals`.
#[pyfunction]
fn crowd_door_goals<'py>(
    py: Python<'py>,
    positions: PyReadonlyArrayDyn<'py, f64>,
    a: [f64; 2],
    b: [f64; 2],
    radius: f64,
    reach: f64,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let p = points(&positions, "positions")?;
    let (a, b) = (DVec2::from_array(a), DVec2::from_array(b));
    let mut goals = vec![DVec2::ZERO; p.len()];
    crate::crowd::metrics::door_goals(&p, a, b, radius, reach, &mut goals)?;
    compute::<2>(py, goals.len(), &[2], |out| {
        let out = zeroed(out);
        out.iter_mut().zip(&goals).for_each(|(o, g)| *o = g.to_array());
        Ok(())
    })
}

/// A density and a velocity field (`crowd_fields`).
type Fields<'py> = (Bound<'py, PyArrayDyn<f64>>, Bound<'py, PyArrayDyn<f64>>);

/// The density (agents/m², `(ny · nx,)`) and velocity (m/s, `(ny · nx, 2)`) fields of agents at
/// `positions` moving at `velocities` (N, 2) at the grid points `xs` × `ys` ((nx, 1), (ny, 1);
/// m), Gaussian radius `radius` (m); `crate::crowd::metrics::fields`.
#[pyfunction]
fn crowd_fields<'py>(
    py: Python<'py>,
    positions: PyReadonlyArrayDyn<'py, f64>,
    velocities: PyReadonlyArrayDyn<'py, f64>,
    xs: PyReadonlyArrayDyn<'py, f64>,
    ys: PyReadonlyArrayDyn<'py, f64>,
    radius: f64,
) -> PyResult<Fields<'py>> {
    let (p, v) = (points(&positions, "positions")?, points(&velocities, "velocities")?);
    let xs: Vec<f64> = rows::<1>(&xs, "xs", &[1])?.iter().map(|x| x[0]).collect();
    let ys: Vec<f64> = rows::<1>(&ys, "ys", &[1])?.iter().map(|y| y[0]).collect();
    let n = xs.len().saturating_mul(ys.len());
    let mut density = crate::error::filled("xs", n, 0.0)?;
    let mut velocity = crate::error::filled("xs", n, DVec2::ZERO)?;
    detached(py, || {
        crate::crowd::metrics::fields(&p, &v, &xs, &ys, radius, &mut density, &mut velocity)
    })?;
    let velocity = compute::<2>(py, n, &[2], |out| {
        let out = zeroed(out);
        out.iter_mut().zip(&velocity).for_each(|(o, u)| *o = u.to_array());
        Ok(())
    })?;
    Ok((out1(py, &density)?, velocity))
}

/// The settings of RVO2's circle-crossing example (`Settings::rvo2_circle`, the one place they
/// are written) as keyword arguments of `kinema.crowd.Crowd`: lengths in m, speeds in m/s,
/// horizons in s.
#[pyfunction]
fn crowd_rvo2_circle(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let s = Settings::rvo2_circle();
    let d = PyDict::new(py);
    d.set_item("radius", s.radius)?;
    d.set_item("max_speed", s.max_speed)?;
    d.set_item("preferred_speed", s.preferred_speed)?;
    d.set_item("neighbour_distance", s.neighbour_distance)?;
    d.set_item("max_neighbours", s.max_neighbours)?;
    d.set_item("time_horizon", s.time_horizon)?;
    d.set_item("obstacle_time_horizon", s.obstacle_time_horizon)?;
    d.set_item("goal_tolerance", s.goal_tolerance)?;
    d.set_item("perturbation", s.perturbation)?;
    d.set_item("seed", s.seed)?;
    d.set_item("planning_margin", s.planning_margin)?;
    Ok(d)
}

fn points_shaped(
    arr: &PyReadonlyArrayDyn<'_, f64>,
    arg: &str,
    shape: &[usize],
) -> PyResult<Vec<DVec2>> {
    let p = rows::<2>(arr, arg, shape)?;
    if let Some(i) = p.iter().position(|x| !x.iter().all(|v| v.is_finite())) {
        return Err(Error::invalid(arg, "contains NaN or infinity").at(i).into());
    }
    Ok(p.iter().map(|x| DVec2::from_array(*x)).collect())
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(crowd_crossings, m)?)?;
    m.add_function(wrap_pyfunction!(crowd_door_goals, m)?)?;
    m.add_function(wrap_pyfunction!(crowd_fields, m)?)?;
    m.add_function(wrap_pyfunction!(crowd_rvo2_circle, m)?)?;
    m.add_class::<Crowd>()
}
