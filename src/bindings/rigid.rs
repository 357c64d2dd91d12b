//! `kinema.rigid`: a compiled world of free rigid bodies.

use super::args::{Int, MAX_ITERATIONS};
use super::array::{compute, zeroed};
use super::error::detached;
use super::pickle::{reduce, Reduced};
use crate::error::Error;
use crate::geometry::Solid;
use crate::rigid::{
    BodyDesc, JointDesc, JointKind, JointMethod, Motor, RotationIntegrator, State, World,
};
use crate::snapshot::Snapshot;
use glam::{DQuat, DVec3};
use numpy::{PyArrayDyn, PyReadonlyArrayDyn};
use pyo3::prelude::*;

type Array<'py> = Bound<'py, PyArrayDyn<f64>>;

fn vec3(v: [f64; 3]) -> DVec3 {
    DVec3::from_array(v)
}

/// Free rigid bodies stepped together; see `kinema.rigid.World` for the documented API.
#[pyclass(module = "kinema._kinema")]
pub struct RigidWorld {
    world: World,
    /// The undo point of [`RigidWorld::_mark`]: the state only (the model does not change
    /// during a frame).
    saved: Option<State>,
}

#[pymethods]
impl RigidWorld {
    /// Pickle support: the object as a snapshot (model and state, see `kinema::snapshot`).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.world, vec![])
    }

    /// The object stored by `__reduce__`.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { world: World::from_snapshot(data)?, saved: None })
    }

    /// Remember the world's state as it is now (a scene's undo point before a frame), copied
    /// into a retained state (no allocation after the first mark of a world that has not
    /// grown).
    fn _mark(&mut self) {
        match &mut self.saved {
            Some(saved) => saved.clone_from(self.world.state()),
            None => self.saved = Some(self.world.state().clone()),
        }
    }

    /// Put the world's state back as it was at the last [`RigidWorld::_mark`].
    ///
    /// # Errors
    /// A world that gained bodies or joints since the mark (argument `"state"`).
    fn _rollback(&mut self) -> PyResult<()> {
        if let Some(saved) = &self.saved {
            self.world.set_state(saved)?;
        }
        Ok(())
    }

    /// An empty world with gravity (m/s², world frame), a rotation integrator name and
    /// whether bodies collide with each other.
    #[new]
    fn new(gravity: [f64; 3], integrator: &str, collisions: bool) -> PyResult<Self> {
        if !gravity.iter().all(|g| g.is_finite()) {
            return Err(Error::invalid("gravity", "contains NaN or infinity").into());
        }
        let mut world = World::new(vec3(gravity), RotationIntegrator::parse(integrator)?);
        world.model_mut().collisions = collisions;
        Ok(RigidWorld { world, saved: None })
    }

    /// Add a body; `kind` is sphere | box | capsule | cylinder | mesh with `dims` its
    /// dimensions (radius; half extents; radius, height; radius, height) or, for meshes,
    /// `vertices` (V, 3) and `triangles` (T, 3) as float indices. Returns the body index.
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (kind, dims, vertices, triangles, density, mass, position, orientation, velocity, angular_velocity, fixed, restitution, friction))]
    fn add_body(
        &mut self,
        kind: &str,
        dims: Vec<f64>,
        vertices: Option<PyReadonlyArrayDyn<'_, f64>>,
        triangles: Option<PyReadonlyArrayDyn<'_, f64>>,
        density: Option<f64>,
        mass: Option<f64>,
        position: [f64; 3],
        orientation: [f64; 4],
        velocity: [f64; 3],
        angular_velocity: [f64; 3],
        fixed: bool,
        restitution: f64,
        friction: f64,
    ) -> PyResult<usize> {
        let dim = |k: usize| {
            dims.get(k).copied().ok_or_else(|| Error::invalid("shape", "missing dimensions"))
        };
        let shape = match kind {
            "sphere" => Solid::Sphere { radius: dim(0)? },
            "box" => Solid::Box { half_extents: DVec3::new(dim(0)?, dim(1)?, dim(2)?) },
            "capsule" => Solid::Capsule { radius: dim(0)?, height: dim(1)? },
            "cylinder" => Solid::Cylinder { radius: dim(0)?, height: dim(1)? },
            "mesh" => {
                let (Some(v), Some(t)) = (vertices, triangles) else {
                    return Err(
                        Error::invalid("shape", "a mesh needs vertices and triangles").into()
                    );
                };
                let v = super::array::rows::<3>(&v, "vertices", &[3])?;
                let t_rows = super::array::rows::<3>(&t, "triangles", &[3])?;
                let mut tris = Vec::with_capacity(t_rows.len());
                for (i, row) in t_rows.iter().enumerate() {
                    if row.iter().any(|x| x.fract() != 0.0 || *x < 0.0 || !x.is_finite()) {
                        return Err(Error::InvalidInput {
                            arg: "triangles".into(),
                            index: Some(i),
                            reason: "indices must be non-negative integers".into(),
                        }
                        .into());
                    }
                    tris.push(row.map(|x| x as usize));
                }
                Solid::Mesh { vertices: v.iter().map(|&p| vec3(p)).collect(), triangles: tris }
            }
            other => {
                return Err(Error::invalid("shape", format!("unknown shape kind {other:?}")).into())
            }
        };
        let o = orientation;
        let desc = BodyDesc {
            shape,
            density,
            mass,
            position: vec3(position),
            orientation: DQuat::from_xyzw(o[1], o[2], o[3], o[0]),
            velocity: vec3(velocity),
            angular_velocity: vec3(angular_velocity),
            fixed,
            restitution,
            friction,
        };
        Ok(self.world.add_body(&desc)?)
    }

    /// Add the static plane `normal · x = offset` with its restitution and friction.
    fn add_plane(
        &mut self,
        normal: [f64; 3],
        offset: f64,
        restitution: f64,
        friction: f64,
    ) -> PyResult<()> {
        Ok(self.world.add_plane(vec3(normal), offset, restitution, friction)?)
    }

    /// Add a joint: `kind` is ball | hinge | slider | fixed between bodies `a` and `b` (None:
    /// the world), with the world `anchor` (m) and `axis` at creation, hinge `limits` (lo, hi)
    /// (rad), hinge `motor` (speed rad/s, max torque N m), the `method` (penalty | lagrange |
    /// impulse | xpbd) and the penalty `stiffness` (1/s²) and `damping` (1/s). Returns the
    /// joint index.
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (kind, a, b, anchor, axis, limits, motor, method, stiffness, damping))]
    fn add_joint(
        &mut self,
        kind: &str,
        a: Int,
        b: Option<Int>,
        anchor: [f64; 3],
        axis: [f64; 3],
        limits: Option<(f64, f64)>,
        motor: Option<(f64, f64)>,
        method: &str,
        stiffness: f64,
        damping: f64,
    ) -> PyResult<usize> {
        let kind = match kind {
            "ball" => JointKind::Ball,
            "hinge" => JointKind::Hinge {
                limits,
                motor: motor.map(|(speed, max_torque)| Motor { speed, max_torque }),
            },
            "slider" => JointKind::Slider,
            "fixed" => JointKind::Fixed,
            other => {
                return Err(Error::invalid("joint", format!("unknown joint kind {other:?}")).into())
            }
        };
        let desc = JointDesc {
            kind,
            method: JointMethod::parse(method)?,
            a: a.count("a")?,
            b: b.map(|b| b.count("b")).transpose()?,
            anchor: vec3(anchor),
            axis: vec3(axis),
            stiffness,
            damping,
        };
        Ok(self.world.add_joint(&desc)?)
    }

    /// Number of joints.
    fn joint_count(&self) -> usize {
        self.world.joint_count()
    }

    /// Position error per joint (J, 2): anchor distance (m), forbidden rotation angle (rad).
    fn joint_violations<'py>(&self, py: Python<'py>) -> PyResult<Array<'py>> {
        let w = &self.world;
        compute(py, w.joint_count(), &[2], |out| {
            let out = zeroed(out);
            for (j, o) in out.iter_mut().enumerate() {
                let (l, a) = w.joint_violation(j)?;
                *o = [l, a];
            }
            Ok(())
        })
    }

    /// Coordinate and rate per joint (J, 2): hinge angle (rad) and rate (rad/s), slider
    /// displacement (m) and rate (m/s), zeros for ball and fixed joints.
    fn joint_coordinates<'py>(&self, py: Python<'py>) -> PyResult<Array<'py>> {
        let w = &self.world;
        let c = w.joint_coordinates();
        compute(py, c.len(), &[2], |out| {
            let out = zeroed(out);
            out.iter_mut().zip(&c).for_each(|(o, &(x, v))| *o = [x, v]);
            Ok(())
        })
    }

    /// Sequential-impulse sweeps per step for contacts (velocities, then positions), at most
    /// `MAX_ITERATIONS` (10^6).
    #[getter]
    fn get_contact_iterations(&self) -> usize {
        self.world.model().contact_iterations
    }

    #[setter]
    fn set_contact_iterations(&mut self, n: Int) -> PyResult<()> {
        self.world.model_mut().contact_iterations =
            n.range("contact_iterations", 0, MAX_ITERATIONS)?;
        Ok(())
    }

    /// Sequential-impulse sweeps per step for impulse joints, at most `MAX_ITERATIONS` (10^6).
    #[getter]
    fn get_joint_iterations(&self) -> usize {
        self.world.model().joint_iterations
    }

    #[setter]
    fn set_joint_iterations(&mut self, n: Int) -> PyResult<()> {
        self.world.model_mut().joint_iterations = n.range("joint_iterations", 0, MAX_ITERATIONS)?;
        Ok(())
    }

    /// Substeps per step when a joint uses XPBD, 1 to `MAX_ITERATIONS` (10^6).
    #[getter]
    fn get_xpbd_substeps(&self) -> usize {
        self.world.model().xpbd_substeps
    }

    #[setter]
    fn set_xpbd_substeps(&mut self, n: Int) -> PyResult<()> {
        self.world.model_mut().xpbd_substeps = n.range("xpbd_substeps", 1, MAX_ITERATIONS)?;
        Ok(())
    }

    /// Baumgarte factor of the Lagrange formulation.
    #[getter]
    fn get_baumgarte(&self) -> f64 {
        self.world.model().baumgarte
    }

    #[setter]
    fn set_baumgarte(&mut self, beta: f64) -> PyResult<()> {
        if !(0.0..=1.0).contains(&beta) {
            return Err(
                Error::invalid("baumgarte", format!("must be in [0, 1], got {beta}")).into()
            );
        }
        self.world.model_mut().baumgarte = beta;
        Ok(())
    }

    /// Gravitational potential energy, zero at the origin (J).
    fn potential_energy(&self) -> f64 {
        self.world.potential_energy()
    }

    /// Number of bodies.
    fn __len__(&self) -> usize {
        self.world.len()
    }

    /// Mass (kg) of body `i`.
    fn mass(&self, i: Int) -> PyResult<f64> {
        let i = self.check(i)?;
        Ok(self.world.mass(i))
    }

    /// Inertia tensor about the centre of mass, body axes, row-major (9,) (kg m²).
    fn inertia(&self, i: Int) -> PyResult<Vec<f64>> {
        let i = self.check(i)?;
        Ok(self.world.inertia(i).transpose().to_cols_array().to_vec())
    }

    /// Centre of mass in the body frame (m).
    fn center_of_mass(&self, i: Int) -> PyResult<[f64; 3]> {
        let i = self.check(i)?;
        Ok(self.world.center_of_mass(i).to_array())
    }

    /// Coulomb friction coefficient of body `i`'s surface.
    fn friction(&self, i: Int) -> PyResult<f64> {
        let i = self.check(i)?;
        Ok(self.world.friction(i))
    }

    /// Linear and angular damping rates of body `i` (1/s).
    fn damping(&self, i: Int) -> PyResult<(f64, f64)> {
        let i = self.check(i)?;
        Ok(self.world.damping(i))
    }

    /// Set the linear and angular damping rates of body `i` (1/s, >= 0).
    fn set_damping(&mut self, i: Int, linear: f64, angular: f64) -> PyResult<()> {
        let i = self.check(i)?;
        Ok(self.world.set_damping(i, linear, angular)?)
    }

    /// Advance `steps` steps of `dt` seconds (GIL released).
    fn step(&mut self, py: Python<'_>, dt: f64, steps: Int) -> PyResult<()> {
        let steps = steps.count("steps")?;
        let world = &mut self.world;
        detached(py, || world.step(dt, steps))
    }

    /// Apply `force` (N) at world `point` (m) of body `i` during the next step.
    fn apply_force(&mut self, i: Int, force: [f64; 3], point: [f64; 3]) -> PyResult<()> {
        Ok(self.world.apply_force(i.count("body")?, vec3(force), vec3(point))?)
    }

    /// World positions of the body origins (N, 3) (m).
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Array<'py>> {
        let w = &self.world;
        compute(py, w.len(), &[3], |out| {
            let out = zeroed(out);
            out.iter_mut().enumerate().for_each(|(i, o)| *o = w.position(i).to_array());
            Ok(())
        })
    }

    /// Orientations (N, 4), scalar-first, body → world.
    fn orientations<'py>(&self, py: Python<'py>) -> PyResult<Array<'py>> {
        let w = &self.world;
        compute(py, w.len(), &[4], |out| {
            let out = zeroed(out);
            out.iter_mut()
                .enumerate()
                .for_each(|(i, o)| *o = crate::rotation::quat_to_wxyz(w.orientation(i)));
            Ok(())
        })
    }

    /// Centre-of-mass velocities (N, 3) (m/s).
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Array<'py>> {
        let w = &self.world;
        compute(py, w.len(), &[3], |out| {
            let out = zeroed(out);
            out.iter_mut().enumerate().for_each(|(i, o)| *o = w.velocity(i).to_array());
            Ok(())
        })
    }

    /// Angular velocities in the world frame (N, 3) (rad/s).
    fn angular_velocities<'py>(&self, py: Python<'py>) -> PyResult<Array<'py>> {
        let w = &self.world;
        compute(py, w.len(), &[3], |out| {
            let out = zeroed(out);
            out.iter_mut().enumerate().for_each(|(i, o)| *o = w.angular_velocity(i).to_array());
            Ok(())
        })
    }

    /// Total kinetic energy (J).
    fn kinetic_energy(&self) -> f64 {
        self.world.kinetic_energy()
    }

    /// Total linear momentum (kg m/s).
    fn linear_momentum(&self) -> [f64; 3] {
        self.world.linear_momentum().to_array()
    }

    /// Total angular momentum about the world origin (kg m²/s).
    fn angular_momentum(&self) -> [f64; 3] {
        self.world.angular_momentum().to_array()
    }
}

impl RigidWorld {
    /// Body index `i`, or a `ValueError` naming `body`.
    fn check(&self, i: Int) -> PyResult<usize> {
        let i = i.count("body")?;
        if i < self.world.len() {
            Ok(i)
        } else {
            Err(Error::invalid(
                "body",
                format!("index {i} out of range ({} bodies)", self.world.len()),
            )
            .into())
        }
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<RigidWorld>()
}
