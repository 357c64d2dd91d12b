//! Hair: many strands of one rod [`Model`] stepped together in parallel, their roots clamped
//! to a rigid head that moves, and kept apart by a rod–rod repulsion.
//!
//! Every strand is the model's rest shape (the *template*: a strand growing from the origin
//! along `+z`) placed on the head by a rigid motion `(R_s, t_s)`; elastic energies are
//! invariant under rigid motions, so the strands share the model and differ only in their
//! [`State`]s. The head's pose `(R_h, t_h)` (a unit quaternion and a translation, m) is set
//! per call; over the `m` steps of a call it moves from the last pose to the new one
//! (rotation by slerp, translation linearly), and in each step the clamped root edge of
//! strand `s` goes to the template's rotated by `R_h R_s` and shifted by `R_h t_s + t_h`
//! ([`State::move_clamp`]), so the roots stay exactly on the head.
//!
//! **Repulsion** (hair volume; `contact.rs`): at the start of every step the edges of all
//! strands are put in the shared uniform grid by their midpoints (cell size the longest edge
//! plus twice the thickness, so that every pair of edges closer than twice the thickness is
//! found), and each pair of edges of two strands closer than that becomes an obstacle of each
//! strand: a linearised penalty keeping their centrelines [`Repulsion::thickness`] apart,
//! implicit in the strand stepped and lagged in the other.
//!
//! **The head as a collider** ([`Hair::set_head_collider`]): a ball in the head's frame,
//! one of the model's colliders, moved to the head's pose of every step before the strands
//! are stepped (so it is implicit in the step, like the roots).
//!
//! Strands are stepped in parallel (rayon) in fixed tasks of [`STRANDS_PER_TASK`] strands, one
//! [`Solver`] per task; a strand's step reads only its own state and its obstacles, so the
//! result is bitwise the same on any number of threads. Nothing is allocated once the first
//! step has sized the buffers. A failed step (any strand) leaves every strand as it was.

use super::contact::{Obstacle, Repulsion};
use super::model::Integrator;
use super::{End, Material, Model, Settings, Solver, State, Stats};
use crate::error::{Error, Result};
use crate::geometry::grid::Grid;
use crate::geometry::segment::closest_points_of_segments;
use crate::geometry::{Shape, Sphere};
use glam::{DQuat, DVec3};
use rayon::prelude::*;

/// Strands per parallel task (one solver each).
pub const STRANDS_PER_TASK: usize = 16;

/// A rigid pose: rotation, then translation (m).
pub type Pose = (DQuat, DVec3);

/// The template strand of [`Hair::groom`]: `segments + 1` points from the origin over the arc
/// length `length` (m), straight along `+z` when `curl` is 0, else a helix of radius `curl`
/// (m) about the `z` axis with pitch angle 45° (it turns once per `2π √2 curl` of arc; its
/// curvature, the strand's natural curvature, is `1 / (2 curl)`).
pub fn template(length: f64, segments: usize, curl: f64) -> Vec<DVec3> {
    let root = std::f64::consts::FRAC_1_SQRT_2;
    (0..=segments)
        .map(|i| {
            let u = length * i as f64 / segments as f64;
            if curl == 0.0 {
                return DVec3::new(0.0, 0.0, u);
            }
            let w = u * root / curl;
            DVec3::new(curl * (1.0 - w.cos()), curl * w.sin(), u * root)
        })
        .collect()
}

/// The buffers of a step (sized by the first).
#[derive(Clone, Debug, Default)]
struct Work {
    tasks: Vec<Task>,
    backup: Vec<State>,
    grid: Grid,
    midpoints: Vec<DVec3>,
}

/// One parallel task: its solver and the obstacles of its strands.
#[derive(Clone, Debug, Default)]
struct Task {
    solver: Solver,
    /// The obstacles of the task's strands, concatenated; strand `k` of the task owns
    /// `obstacles[offsets[k]..offsets[k + 1]]`.
    obstacles: Vec<Obstacle>,
    offsets: Vec<usize>,
    stats: Stats,
    error: Option<Error>,
}

/// What changes in a [`Hair`] (its strands' states, the head's pose and goal, the stats): an
/// undo point ([`Hair::save`], [`Hair::restore`]; no allocation once sized).
#[derive(Clone, Debug, Default)]
pub struct Motion {
    states: Vec<State>,
    head: Option<Pose>,
    goal: Option<Pose>,
    stats: Stats,
}

/// Many strands of one model on a moving head (see the module docs).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Hair {
    model: Model,
    placements: Vec<Pose>,
    states: Vec<State>,
    head: Pose,
    goal: Option<Pose>,
    repulsion: Repulsion,
    /// The head as a moving collider: a ball in the head's frame and its slot in the
    /// model's colliders (which it occupies at the head's pose of the step).
    head_ball: Option<(usize, Sphere)>,
    #[serde(skip)]
    work: Work,
    /// What the last step did, summed over the strands.
    pub stats: Stats,
}

impl Hair {
    /// Strands of `model` (its rest shape the template, its first end clamped here) placed by
    /// `placements`, at rest, the head at the identity pose.
    ///
    /// # Errors
    /// No strand (`points`); a placement not a finite unit quaternion and finite translation
    /// (`points`, with index); an integrator other than implicit Euler (`integrator`); a bad
    /// repulsion ([`Repulsion::checked`]).
    pub fn new(mut model: Model, placements: &[Pose], repulsion: Repulsion) -> Result<Self> {
        if placements.is_empty() {
            return Err(Error::invalid("points", "expected at least one root"));
        }
        if let Some(s) = placements.iter().position(|p| !pose_ok(p)) {
            return Err(Error::invalid("points", "a non-finite root or normal").at(s));
        }
        if model.settings().integrator != Integrator::ImplicitEuler {
            return Err(Error::invalid("integrator", "hair is stepped by implicit Euler only"));
        }
        model.clamp(End::First);
        let states = placements.iter().map(|p| placed(&model, p)).collect();
        Ok(Hair {
            model,
            placements: placements.to_vec(),
            states,
            head: (DQuat::IDENTITY, DVec3::ZERO),
            goal: None,
            repulsion: repulsion.checked()?,
            head_ball: None,
            work: Work::default(),
            stats: Stats::default(),
        })
    }

    /// Grow one strand from each of the scalp `points` (m, on the head at the identity pose)
    /// along its unit `normals`: the [`template`] of `length`, `segments` and `curl` turned
    /// from `+z` onto the normal (the shortest arc) and moved to the point.
    ///
    /// # Errors
    /// `points` and `normals` of different lengths (`normals`), a zero or non-finite normal
    /// (`normals`, with index), `length` not finite and > 0, `segments` 0, `curl` not finite
    /// and ≥ 0 (named); those of [`Model::new`] and [`Hair::new`].
    #[allow(clippy::too_many_arguments)]
    pub fn groom(
        points: &[DVec3],
        normals: &[DVec3],
        length: f64,
        segments: usize,
        curl: f64,
        material: Material,
        settings: Settings,
        repulsion: Repulsion,
    ) -> Result<Self> {
        if normals.len() != points.len() {
            return Err(Error::invalid("normals", "expected one per point"));
        }
        if let Some(i) = normals.iter().position(|n| !(n.is_finite() && n.length() > 0.0)) {
            return Err(Error::invalid("normals", "zero or non-finite").at(i));
        }
        if !(length.is_finite() && length > 0.0) {
            return Err(Error::invalid("length", "must be finite and > 0"));
        }
        if segments == 0 {
            return Err(Error::invalid("segments", "must be at least 1"));
        }
        if !(curl.is_finite() && curl >= 0.0) {
            return Err(Error::invalid("curl", "must be finite and >= 0"));
        }
        let model = Model::new(&template(length, segments, curl), material, settings)?;
        let placements: Vec<Pose> = points
            .iter()
            .zip(normals)
            .map(|(p, n)| (DQuat::from_rotation_arc(DVec3::Z, n.normalize()), *p))
            .collect();
        Hair::new(model, &placements, repulsion)
    }

    /// The model shared by the strands (the template at rest).
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The strands' states.
    pub fn states(&self) -> &[State] {
        &self.states
    }

    /// The strands' states, to change them (forces, velocities).
    pub fn states_mut(&mut self) -> &mut [State] {
        &mut self.states
    }

    /// The placement of each strand on the head (template → head frame).
    pub fn placements(&self) -> &[Pose] {
        &self.placements
    }

    /// The head's pose (after the last step).
    pub fn head(&self) -> Pose {
        self.head
    }

    /// The repulsion.
    pub fn repulsion(&self) -> Repulsion {
        self.repulsion
    }

    /// Copy what changes into `into`.
    pub fn save(&self, into: &mut Motion) {
        if into.states.len() != self.states.len() {
            into.states.clone_from(&self.states);
        }
        for (a, b) in into.states.iter_mut().zip(&self.states) {
            a.clone_from(b);
        }
        (into.head, into.goal, into.stats) = (Some(self.head), self.goal, self.stats);
    }

    /// Put back what [`Hair::save`] copied into `from` (nothing if it holds no save).
    pub fn restore(&mut self, from: &Motion) {
        let Some(head) = from.head else { return };
        for (a, b) in self.states.iter_mut().zip(&from.states) {
            a.clone_from(b);
        }
        (self.head, self.goal, self.stats) = (head, from.goal, from.stats);
        self.place_head_ball(head);
    }

    /// Add a static collision shape for every strand ([`Model::add_collider`]).
    ///
    /// # Errors
    /// Those of [`Model::add_collider`].
    pub fn add_collider(&mut self, collider: super::Collider) -> Result<()> {
        self.model.add_collider(collider)
    }

    /// Make the head a frictionless moving collider for every strand: the ball `ball` (m, in
    /// the head's frame, i.e. where it is at the identity pose) moves with the head, and each
    /// step keeps the strands' vertices out of it by their radius as a static collider does
    /// (`contact.rs`: the penalty of the model's `contact_stiffness`), with the ball where the
    /// head is at the end of the step (implicit). The root edges are clamped and exempt.
    /// Replaces the head ball set before.
    ///
    /// # Errors
    /// A bad ball (`center`, `radius`: [`Shape::checked`]).
    pub fn set_head_collider(&mut self, ball: Sphere) -> Result<()> {
        let collider = super::Collider { shape: Shape::Sphere(ball), friction: 0.0 }.checked()?;
        let slot = match self.head_ball {
            Some((slot, _)) => slot,
            None => {
                self.model.add_collider(collider)?;
                self.model.colliders.len() - 1
            }
        };
        self.head_ball = Some((slot, ball));
        self.place_head_ball(self.head);
        Ok(())
    }

    /// Put the head ball (if any) where the head is at `pose`.
    fn place_head_ball(&mut self, pose: Pose) {
        if let Some((slot, ball)) = self.head_ball {
            let center = pose.0 * ball.center + pose.1;
            self.model.colliders[slot].shape = Shape::Sphere(Sphere { center, ..ball });
        }
    }

    /// Set the repulsion for the later steps.
    ///
    /// # Errors
    /// Those of [`Repulsion::checked`].
    pub fn set_repulsion(&mut self, repulsion: Repulsion) -> Result<()> {
        self.repulsion = repulsion.checked()?;
        Ok(())
    }

    /// Move the head to `pose` (rotation about the origin, then translation, m) by the end of
    /// the next [`Hair::step`] call, linearly over its steps (slerp for the rotation).
    ///
    /// # Errors
    /// A rotation not a finite unit quaternion (`rotation`), a non-finite translation
    /// (`translation`).
    pub fn set_head(&mut self, rotation: DQuat, translation: DVec3) -> Result<()> {
        if !(rotation.is_finite() && (rotation.length() - 1.0).abs() < 1e-9) {
            return Err(Error::invalid("rotation", "must be a finite unit quaternion"));
        }
        if !translation.is_finite() {
            return Err(Error::invalid("translation", "must be finite"));
        }
        self.goal = Some((rotation, translation));
        Ok(())
    }

    /// Advance every strand by `steps` implicit Euler steps of `dt` (s), the head moving to
    /// the pose set by [`Hair::set_head`].
    ///
    /// # Errors
    /// `dt` not finite and > 0 (`dt`); a strand's step failing (the error of the first such
    /// strand, [`Solver::step`]). Every strand and the head are then as they were.
    pub fn step(&mut self, dt: f64, steps: usize) -> Result<()> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid("dt", "must be finite and > 0"));
        }
        self.prepare();
        let mut stats = Stats::default();
        for k in 1..=steps {
            if let Err(e) = self.substep(dt, k as f64 / steps as f64, &mut stats) {
                for (s, b) in self.states.iter_mut().zip(&self.work.backup) {
                    s.clone_from(b);
                }
                self.place_head_ball(self.head);
                return Err(e);
            }
        }
        if steps > 0 {
            if let Some(goal) = self.goal.take() {
                self.head = goal;
            }
        }
        self.stats = stats;
        Ok(())
    }

    /// Size the tasks and back up the states.
    fn prepare(&mut self) {
        let tasks = self.states.len().div_ceil(STRANDS_PER_TASK);
        let work = &mut self.work;
        work.tasks
            .resize_with(tasks, || Task { solver: Solver::new(&self.model), ..Task::default() });
        if work.backup.len() != self.states.len() {
            work.backup.clone_from(&self.states);
        }
        for (b, s) in work.backup.iter_mut().zip(&self.states) {
            b.clone_from(s);
        }
    }

    /// One step of `dt`, the head at fraction `f` of its way to the goal at its end.
    fn substep(&mut self, dt: f64, f: f64, stats: &mut Stats) -> Result<()> {
        if let Some(goal) = self.goal {
            let head = (self.head.0.slerp(goal.0, f), self.head.1.lerp(goal.1, f));
            for (state, p) in self.states.iter_mut().zip(&self.placements) {
                let (rotation, translation) = (head.0 * p.0, head.0 * p.1 + head.1);
                state.move_clamp(&self.model, End::First, rotation, translation)?;
            }
            self.place_head_ball(head);
        }
        self.find_obstacles();
        let (model, repulsion) = (&self.model, self.repulsion);
        self.states.par_chunks_mut(STRANDS_PER_TASK).zip(self.work.tasks.par_iter_mut()).for_each(
            |(states, task)| {
                task.stats = Stats::default();
                task.error = None;
                for (k, state) in states.iter_mut().enumerate() {
                    let obstacles = &task.obstacles[task.offsets[k]..task.offsets[k + 1]];
                    match task.solver.step_among(model, state, dt, obstacles, repulsion) {
                        Ok(s) => {
                            task.stats.iterations += s.iterations;
                            task.stats.halvings += s.halvings;
                        }
                        Err(e) => {
                            task.error = Some(e);
                            return;
                        }
                    }
                }
            },
        );
        for task in &mut self.work.tasks {
            if let Some(e) = task.error.take() {
                return Err(e);
            }
            stats.iterations += task.stats.iterations;
            stats.halvings += task.stats.halvings;
        }
        stats.steps += 1;
        Ok(())
    }

    /// Each strand's obstacles: the edges of other strands closer than twice the thickness
    /// (found on the grid of the edges' midpoints).
    fn find_obstacles(&mut self) {
        let work = &mut self.work;
        let active = self.repulsion.stiffness > 0.0
            && self.repulsion.thickness > 0.0
            && self.states.len() > 1;
        let n = self.model.edges();
        if active {
            work.midpoints.clear();
            let mut longest: f64 = 0.0;
            for s in &self.states {
                for w in s.positions.windows(2) {
                    work.midpoints.push(0.5 * (w[0] + w[1]));
                    longest = longest.max((w[1] - w[0]).length());
                }
            }
            let reach = 2.0 * self.repulsion.thickness;
            work.grid.build(&work.midpoints, work.midpoints.len(), longest + reach);
        }
        let (states, grid, thickness) = (&self.states, &work.grid, self.repulsion.thickness);
        work.tasks.par_iter_mut().enumerate().for_each(|(t, task)| {
            task.obstacles.clear();
            task.offsets.clear();
            task.offsets.push(0);
            let first = t * STRANDS_PER_TASK;
            for s in first..(first + STRANDS_PER_TASK).min(states.len()) {
                if active {
                    near(states, grid, s, n, thickness, &mut task.obstacles);
                }
                task.offsets.push(task.obstacles.len());
            }
        });
    }
}

/// Push the obstacles of strand `s` (`n` edges): for each of its edges, every edge of
/// another strand closer than twice the `thickness` (m) on `grid` (midpoints, strand-major).
fn near(
    states: &[State],
    grid: &Grid,
    s: usize,
    n: usize,
    thickness: f64,
    out: &mut Vec<Obstacle>,
) {
    let x = &states[s].positions;
    for a in 0..n {
        for &m in grid.neighbours(s * n + a) {
            let (other, b) = (m as usize / n, m as usize % n);
            if other == s {
                continue;
            }
            let y = &states[other].positions;
            let (p, q) = closest_points_of_segments(x[a], x[a + 1], y[b], y[b + 1]);
            let d = (p - q).length();
            if d >= 2.0 * thickness || d == 0.0 {
                continue;
            }
            let along = |from: DVec3, to: DVec3, at: DVec3| {
                let e = to - from;
                ((at - from).dot(e) / e.length_squared()).clamp(0.0, 1.0)
            };
            let (t, u) = (along(x[a], x[a + 1], p), along(y[b], y[b + 1], q));
            let v = &states[other].velocities;
            out.push(Obstacle {
                edge: a,
                s: t,
                point: q,
                normal: (p - q) / d,
                velocity: (1.0 - u) * v[b] + u * v[b + 1],
                gap: d - thickness,
            });
        }
    }
}

/// Check a decoded hair: the model, one placement per state, each state against the model.
pub(super) fn validate(hair: &Hair) -> Result<()> {
    use crate::snapshot::{check, Stamped};
    hair.model.validate()?;
    check(
        hair.placements.len() == hair.states.len() && !hair.states.is_empty(),
        "placements",
        || "one placement per strand, at least one".into(),
    )?;
    check(
        hair.placements.iter().chain([&hair.head]).chain(&hair.goal).all(pose_ok),
        "placements",
        || "non-finite or non-unit poses".into(),
    )?;
    check(hair.model.locked()[0] && hair.model.pinned()[0], "model", || {
        "the strands' first ends must be clamped".into()
    })?;
    hair.repulsion.checked()?;
    check(
        hair.head_ball.is_none_or(|(slot, _)| {
            matches!(hair.model.colliders.get(slot), Some(c) if matches!(c.shape, Shape::Sphere(_)))
        }),
        "head_ball",
        || "not a ball among the model's colliders".into(),
    )?;
    hair.states.iter().try_for_each(|s| s.validate(&hair.model))
}

/// Whether a pose is a finite unit quaternion and a finite translation.
fn pose_ok(p: &Pose) -> bool {
    p.0.is_finite() && (p.0.length() - 1.0).abs() < 1e-9 && p.1.is_finite()
}

/// The model's rest state moved rigidly by `pose` (positions and reference directors).
fn placed(model: &Model, pose: &Pose) -> State {
    let mut state = State::new(model);
    for x in &mut state.positions {
        *x = pose.0 * *x + pose.1;
    }
    for d in &mut state.reference {
        *d = (pose.0 * *d).normalize();
    }
    state
}
