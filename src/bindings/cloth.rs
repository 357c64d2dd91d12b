//! `kinema.cloth`: the compiled cloth, whose positions and velocities numpy views without a
//! copy.

use super::args::{counts, Int, MAX_ITERATIONS};
use super::array::{compute, rows, zeroed};
use super::error::detached;
use super::pickle::{reduce, Reduced};
use super::view::view;
use crate::cloth::{
    parse_obj, write_obj, Cloth, Collider, Elasticity, LinearSolver, Material, Mesh, MeshCollider,
    SelfCollision, SolveOptions, State, Triangulation, VertexConstraint,
};
use crate::error::Error;
use crate::geometry::triangle::intersecting_triangles;
use crate::ode::Method;
use crate::snapshot::Snapshot;
use glam::DVec3;
use numpy::{PyArrayDyn, PyReadonlyArrayDyn};
use pyo3::prelude::*;
use pyo3::types::PyDict;

fn vectors(arr: &PyReadonlyArrayDyn<'_, f64>, arg: &str) -> PyResult<Vec<DVec3>> {
    Ok(rows::<3>(arr, arg, &[3])?.iter().map(|p| DVec3::from_array(*p)).collect())
}

/// Triangles `(M, 3)` given as float64 vertex indices, checked to be non-negative integers
/// (argument `triangles`).
fn indices(triangles: &PyReadonlyArrayDyn<'_, f64>) -> PyResult<Vec<[usize; 3]>> {
    let mut tris = Vec::new();
    for (k, t) in rows::<3>(triangles, "triangles", &[3])?.iter().enumerate() {
        if t.iter().any(|x| x.fract() != 0.0 || *x < 0.0 || !x.is_finite()) {
            return Err(Error::invalid("triangles", "indices must be non-negative integers")
                .at(k)
                .into());
        }
        tris.push(t.map(|x| x as usize));
    }
    Ok(tris)
}

/// A collider from its kind and parameters: the shape's ([`super::geometry::shape`]), then
/// velocity 3 and friction.
fn collider(kind: &str, p: &[f64]) -> PyResult<Collider> {
    let (shape, t) = super::geometry::shape(kind, p, 4)?;
    Ok(Collider { shape, velocity: DVec3::new(t[0], t[1], t[2]), friction: t[3] })
}

/// A piece of cloth; see `kinema.cloth.Cloth` for the API.
#[pyclass(module = "kinema._kinema")]
pub struct ClothCore {
    cloth: Cloth,
    /// The undo point of [`ClothCore::_mark`], a copy of the state (none before the first).
    saved: Option<State>,
}

#[pymethods]
impl ClothCore {
    /// Pickle support: the object as a snapshot (model and state, see `kinema::snapshot`).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.cloth, vec![])
    }

    /// The object stored by `__reduce__`.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { cloth: Cloth::from_snapshot(data)?, saved: None })
    }

    /// Remember the cloth's state as it is now (a scene's undo point before a frame): copied
    /// into a retained state (no allocation after the first mark). The model does not change
    /// during a frame.
    fn _mark(&mut self) {
        match &mut self.saved {
            Some(saved) => saved.clone_from(self.cloth.state()),
            None => self.saved = Some(self.cloth.state().clone()),
        }
    }

    /// Put the state back as it was at the last [`ClothCore::_mark`], in place: views of the
    /// positions and velocities stay valid.
    fn _rollback(&mut self) {
        if let Some(saved) = &self.saved {
            self.cloth.state_mut().clone_from(saved);
        }
    }

    /// A cloth from `vertices` (N, 3) m and `triangles` (M, 3) indices (as float64), with
    /// optional per-corner `uv` (M, 6) m, model `"baraff_witkin"` or `"mass_spring"` and
    /// material `[density, stretch, shear, bend, damping, air_damping]`, `gravity` (3,).
    #[new]
    #[pyo3(signature = (vertices, triangles, uv, model, material, gravity))]
    fn new(
        vertices: PyReadonlyArrayDyn<'_, f64>,
        triangles: PyReadonlyArrayDyn<'_, f64>,
        uv: Option<PyReadonlyArrayDyn<'_, f64>>,
        model: &str,
        material: [f64; 6],
        gravity: [f64; 3],
    ) -> PyResult<Self> {
        let positions = rows::<3>(&vertices, "vertices", &[3])?.to_vec();
        let tris = indices(&triangles)?;
        let uv = match uv {
            Some(a) => Some(
                rows::<6>(&a, "uv", &[6])?
                    .iter()
                    .map(|c| [[c[0], c[1]], [c[2], c[3]], [c[4], c[5]]])
                    .collect(),
            ),
            None => None,
        };
        let mesh = Mesh::new(positions, tris, uv)?;
        Self::build(mesh, model, material, gravity)
    }

    /// An `nx` x `ny` grid (see `kinema.cloth.Cloth.grid`).
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    fn grid(
        nx: Int,
        ny: Int,
        width: f64,
        height: f64,
        triangulation: &str,
        model: &str,
        material: [f64; 6],
        gravity: [f64; 3],
    ) -> PyResult<Self> {
        let triangulation = match triangulation {
            "regular" => Triangulation::Regular,
            "alternating" => Triangulation::Alternating,
            other => {
                return Err(Error::invalid(
                    "triangulation",
                    format!("{other:?} is not 'regular' or 'alternating'"),
                )
                .into())
            }
        };
        let (nx, ny) = (nx.count("nx")?, ny.count("ny")?);
        Self::build(Mesh::grid(nx, ny, width, height, triangulation)?, model, material, gravity)
    }

    /// A cloth from the text of an OBJ file (`file` names it in errors).
    #[staticmethod]
    fn from_obj(
        text: &str,
        file: &str,
        model: &str,
        material: [f64; 6],
        gravity: [f64; 3],
    ) -> PyResult<Self> {
        Self::build(parse_obj(text, file)?, model, material, gravity)
    }

    /// The cloth's current shape as OBJ text.
    fn to_obj(&self) -> String {
        let x: Vec<[f64; 3]> = self.cloth.positions().iter().map(|p| p.to_array()).collect();
        write_obj(&x, self.cloth.triangles(), None)
    }

    /// Pin `indices` at `positions` (K, 3), or where they are.
    #[pyo3(signature = (indices, positions=None))]
    fn pin(
        &mut self,
        indices: Vec<Int>,
        positions: Option<PyReadonlyArrayDyn<'_, f64>>,
    ) -> PyResult<()> {
        let idx = counts(&indices, "indices")?;
        let targets = positions.map(|p| vectors(&p, "positions")).transpose()?;
        Ok(self.cloth.pin(&idx, targets.as_deref())?)
    }

    /// Prescribe the velocities (K, 3) m/s of vertices `indices`.
    fn prescribe(
        &mut self,
        indices: Vec<Int>,
        velocities: PyReadonlyArrayDyn<'_, f64>,
    ) -> PyResult<()> {
        let idx = counts(&indices, "indices")?;
        let v = vectors(&velocities, "velocities")?;
        if v.len() != idx.len() {
            return Err(Error::Shape {
                arg: "velocities".into(),
                expected: format!("({}, 3)", idx.len()),
                got: vec![v.len(), 3],
            }
            .into());
        }
        for (i, v) in idx.iter().zip(v) {
            self.cloth.constrain(&[*i], Some(VertexConstraint::Velocity(v)))?;
        }
        Ok(())
    }

    /// Constrain `indices` to a plane (`kind="plane"`, `direction` its normal) or a line
    /// (`kind="line"`), or free them (`kind="free"`).
    fn constrain(&mut self, indices: Vec<Int>, kind: &str, direction: [f64; 3]) -> PyResult<()> {
        let idx = counts(&indices, "indices")?;
        let d = DVec3::from_array(direction);
        let constraint = match kind {
            "plane" => Some(VertexConstraint::Plane(d)),
            "line" => Some(VertexConstraint::Line(d)),
            "free" => None,
            other => {
                return Err(Error::invalid("kind", format!("unknown constraint {other:?}")).into())
            }
        };
        Ok(self.cloth.constrain(&idx, constraint)?)
    }

    /// Add a collider of `kind` with the shape's parameters (see [`super::geometry::shape`])
    /// followed by velocity (3) and friction; returns its index.
    fn add_collider(&mut self, kind: &str, p: Vec<f64>) -> PyResult<usize> {
        Ok(self.cloth.add_collider(collider(kind, &p)?)?)
    }

    /// Replace collider `index`.
    fn set_collider(&mut self, index: Int, kind: &str, p: Vec<f64>) -> PyResult<()> {
        Ok(self.cloth.set_collider(index.count("index")?, collider(kind, &p)?)?)
    }

    /// Add a triangle-mesh collider of `vertices` (V, 3) m, `triangles` (T, 3) float64
    /// indices, `velocities` (V, 3) m/s (at rest when `None`) and Coulomb `friction`; returns
    /// its index.
    #[pyo3(signature = (vertices, triangles, velocities, friction))]
    fn add_mesh_collider(
        &mut self,
        vertices: PyReadonlyArrayDyn<'_, f64>,
        triangles: PyReadonlyArrayDyn<'_, f64>,
        velocities: Option<PyReadonlyArrayDyn<'_, f64>>,
        friction: f64,
    ) -> PyResult<usize> {
        let x = vectors(&vertices, "vertices")?;
        let v = velocities.map(|v| vectors(&v, "velocities")).transpose()?;
        let mesh = MeshCollider::new(x, indices(&triangles)?, v, friction)?;
        Ok(self.cloth.add_mesh_collider(mesh))
    }

    /// Set the vertices (V, 3) m of mesh collider `index` at the current time and their
    /// velocities (V, 3) m/s (at rest when `None`).
    #[pyo3(signature = (index, vertices, velocities))]
    fn set_mesh_collider(
        &mut self,
        index: Int,
        vertices: PyReadonlyArrayDyn<'_, f64>,
        velocities: Option<PyReadonlyArrayDyn<'_, f64>>,
    ) -> PyResult<()> {
        let x = vectors(&vertices, "vertices")?;
        let v = match velocities {
            Some(v) => vectors(&v, "velocities")?,
            None => vec![DVec3::ZERO; x.len()],
        };
        Ok(self.cloth.set_mesh_collider(index.count("index")?, &x, &v)?)
    }

    /// Number of mesh colliders.
    #[getter]
    fn mesh_colliders(&self) -> usize {
        self.cloth.mesh_colliders().len()
    }

    /// Advance `steps` steps of `dt` s (GIL released); at most `MAX_ITERATIONS` (10^6) PCG
    /// iterations per solve.
    #[allow(clippy::too_many_arguments)]
    fn step(
        &mut self,
        py: Python<'_>,
        dt: f64,
        steps: Int,
        integrator: &str,
        solver: &str,
        tol: f64,
        max_iterations: Int,
        max_strain_change: f64,
        max_strain: f64,
    ) -> PyResult<()> {
        let steps = steps.count("steps")?;
        let max_iterations = max_iterations.range("max_iterations", 1, MAX_ITERATIONS)?;
        let method = Method::parse(integrator).map_err(|_| {
            Error::invalid("integrator", format!("{integrator:?} is not implicit_euler, bdf2 or an explicit method of kinema.ode"))
        })?;
        let solver = match solver {
            "multigrid" => LinearSolver::Multigrid,
            "block_ssor" => LinearSolver::BlockSsor,
            "cholesky" => LinearSolver::Cholesky,
            _ => {
                return Err(Error::invalid(
                    "solver",
                    "must be 'multigrid', 'block_ssor' or 'cholesky'",
                )
                .into())
            }
        };
        let options = SolveOptions { solver, tol, max_iterations, max_strain_change, max_strain };
        let cloth = &mut self.cloth;
        detached(py, || cloth.step(dt, steps, method, options))
    }

    /// Overwrite positions and velocities (N, 3).
    fn set_state(
        &mut self,
        positions: PyReadonlyArrayDyn<'_, f64>,
        velocities: PyReadonlyArrayDyn<'_, f64>,
    ) -> PyResult<()> {
        let x = vectors(&positions, "positions")?;
        let v = vectors(&velocities, "velocities")?;
        Ok(self.cloth.set_state(&x, &v)?)
    }

    /// Set the collision thickness (m).
    fn set_thickness(&mut self, thickness: f64) -> PyResult<()> {
        Ok(self.cloth.set_thickness(thickness)?)
    }

    /// Turn self-collision on (with Coulomb `friction` between layers and `iterations` passes
    /// of collision impulses before impact zones) or off.
    fn set_self_collision(&mut self, on: bool, friction: f64, iterations: Int) -> PyResult<()> {
        let iterations = iterations.range("self_iterations", 0, MAX_ITERATIONS)?;
        let settings = on.then_some(SelfCollision { friction, iterations });
        Ok(self.cloth.set_self_collision(settings)?)
    }

    /// Self-collision settings `(friction, iterations)`, or `None` when off.
    #[getter]
    fn self_collision(&self) -> Option<(f64, usize)> {
        self.cloth.model().self_collision().map(|s| (s.friction, s.iterations))
    }

    /// Mean edge length (m) of the initial shape.
    #[getter]
    fn mean_edge_length(&self) -> f64 {
        self.cloth.model().mean_edge_length()
    }

    /// Read-only view (N, 3) of the positions (m), updated in place by `step`.
    #[getter]
    fn positions<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().cloth.positions().len();
        view(slf, &[n, 3], |c| bytemuck::cast_slice(c.cloth.positions()))
    }

    /// Read-only view (N, 3) of the velocities (m/s), updated in place by `step`.
    #[getter]
    fn velocities<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().cloth.velocities().len();
        view(slf, &[n, 3], |c| bytemuck::cast_slice(c.cloth.velocities()))
    }

    /// Vertex masses (N,) kg.
    #[getter]
    fn masses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let m = self.cloth.masses();
        compute::<1>(py, m.len(), &[], |out| {
            let out = zeroed(out);
            out.iter_mut().zip(m).for_each(|(o, m)| o[0] = *m);
            Ok(())
        })
    }

    /// Triangles (M, 3) as float64 vertex indices.
    #[getter]
    fn triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let t = self.cloth.triangles();
        compute::<3>(py, t.len(), &[3], |out| {
            let out = zeroed(out);
            out.iter_mut().zip(t).for_each(|(o, t)| *o = t.map(|i| i as f64));
            Ok(())
        })
    }

    /// The pairs (K, 2) of triangles that share no vertex and intersect, as float64 triangle
    /// indices `i < j`: the exact all-pairs test of
    /// `geometry::triangle::intersecting_triangles` (Shewchuk's orientation predicates).
    fn self_intersections<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let pairs = intersecting_triangles(self.cloth.positions(), self.cloth.triangles());
        compute::<2>(py, pairs.len(), &[2], |out| {
            let out = zeroed(out);
            out.iter_mut().zip(&pairs).for_each(|(o, &(i, j))| *o = [i as f64, j as f64]);
            Ok(())
        })
    }

    /// Total force (N, 3) N: gravity, elastic, damping.
    fn forces<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let f = self.cloth.forces();
        compute::<3>(py, f.len(), &[3], |out| {
            let out = zeroed(out);
            out.iter_mut().zip(&f).for_each(|(o, f)| *o = f.to_array());
            Ok(())
        })
    }

    /// `[density, stretch, shear, bend, damping, air_damping]`, as given at construction.
    #[getter]
    fn material(&self) -> [f64; 6] {
        let m = self.cloth.material();
        [m.density, m.stretch, m.shear, m.bend, m.damping, m.air_damping]
    }

    /// The fastest mode `(ω rad/s, c 1/s)`, see `Cloth::fastest_mode`.
    fn fastest_mode(&self, py: Python<'_>) -> PyResult<(f64, f64)> {
        let cloth = &self.cloth;
        detached(py, || Ok(cloth.fastest_mode()))
    }

    /// (kinetic, potential, elastic) energy, J.
    fn energy(&self) -> (f64, f64, f64) {
        self.cloth.energy()
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.cloth.time()
    }

    /// Collision thickness (m).
    #[getter]
    fn thickness(&self) -> f64 {
        self.cloth.thickness()
    }

    /// Stored 3x3 blocks of the implicit matrix.
    #[getter]
    fn matrix_blocks(&self) -> usize {
        self.cloth.matrix_blocks()
    }

    /// Numbers of the last step as a dict.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.cloth.stats();
        let d = PyDict::new(py);
        d.set_item("iterations", s.iterations)?;
        d.set_item("residual", s.residual)?;
        d.set_item("converged", s.converged)?;
        d.set_item("contacts", s.contacts)?;
        d.set_item("substeps", s.substeps)?;
        d.set_item("newton_iterations", s.newton_iterations)?;
        d.set_item("assemble_seconds", s.assemble_seconds)?;
        d.set_item("solve_seconds", s.solve_seconds)?;
        d.set_item("collide_seconds", s.collide_seconds)?;
        d.set_item("proximities", s.proximities)?;
        d.set_item("ccd_iterations", s.ccd_iterations)?;
        d.set_item("impact_zones", s.impact_zones)?;
        d.set_item("self_collision_seconds", s.self_collision_seconds)?;
        Ok(d)
    }
}

impl ClothCore {
    fn build(mesh: Mesh, model: &str, m: [f64; 6], gravity: [f64; 3]) -> PyResult<Self> {
        let model = match model {
            "baraff_witkin" => Elasticity::BaraffWitkin,
            "mass_spring" => Elasticity::MassSpring,
            other => {
                return Err(Error::invalid(
                    "model",
                    format!("{other:?} is not 'baraff_witkin' or 'mass_spring'"),
                )
                .into())
            }
        };
        let material = Material {
            density: m[0],
            stretch: m[1],
            shear: m[2],
            bend: m[3],
            damping: m[4],
            air_damping: m[5],
        };
        let cloth = Cloth::new(mesh, model, material, DVec3::from_array(gravity))?;
        Ok(ClothCore { cloth, saved: None })
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<ClothCore>()
}
