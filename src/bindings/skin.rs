//! `kinema.skin`: skinning of a bind-pose surface by a skeleton's joint frames.

use super::args::Int;
use super::array::{compute, rows};
use super::error::detached;
use super::pickle::{reduce, Reduced};
use crate::error::Error;
use crate::skin::{capsule_union, heat_weights, proximity_weights, Method, Skin};
use crate::snapshot::Snapshot;
use numpy::{PyArray1, PyArray2, PyArrayDyn, PyArrayMethods, PyReadonlyArray1, PyReadonlyArrayDyn};
use pyo3::prelude::*;

/// Vertices in a bind pose bound to a skeleton's bones; see `kinema.skin.Skin`.
#[pyclass(module = "kinema._kinema", name = "Skin", frozen)]
pub struct PySkin {
    skin: Skin,
}

fn method(name: &str) -> PyResult<Method> {
    match name {
        "lbs" => Ok(Method::Linear),
        "dqs" => Ok(Method::DualQuaternion),
        _ => Err(Error::invalid("method", "must be \"dqs\" or \"lbs\"").into()),
    }
}

#[pymethods]
impl PySkin {
    /// A skin of `vertices` (V, 3) with `k` influences per vertex, `bones` and `weights`
    /// (V k values each, flat), bone `b` having its origin at joint `origins[b]`, bound at
    /// the pose `bind_positions` (J, 3) and `bind_orientations` (J, 4).
    #[new]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        vertices: PyReadonlyArrayDyn<'_, f64>,
        k: Int,
        bones: PyReadonlyArray1<'_, u32>,
        weights: PyReadonlyArray1<'_, f64>,
        origins: Vec<usize>,
        bind_positions: PyReadonlyArrayDyn<'_, f64>,
        bind_orientations: PyReadonlyArrayDyn<'_, f64>,
    ) -> PyResult<Self> {
        let rest = rows::<3>(&vertices, "vertices", &[3])?;
        let k = k.range("influences", 1, 64)?;
        let bones = bones.as_slice().map_err(|_| Error::invalid("bones", "must be contiguous"))?;
        let weights =
            weights.as_slice().map_err(|_| Error::invalid("weights", "must be contiguous"))?;
        let p = rows::<3>(&bind_positions, "bind_positions", &[3])?;
        let q = rows::<4>(&bind_orientations, "bind_orientations", &[4])?;
        let skin = detached(py, || Skin::new(rest, k, bones, weights, &origins, p, q))?;
        Ok(Self { skin })
    }

    /// Pickle support: the skin as a snapshot.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.skin, vec![])
    }

    /// The skin stored by `__reduce__`, validated.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { skin: Skin::from_snapshot(data)? })
    }

    /// The normalised weights (V k values, flat).
    #[getter]
    fn weights<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.skin.weights())
    }

    /// The skinned vertices (P V, 3) of `P` poses given as joint `positions` (P J, 3) and
    /// `orientations` (P J, 4), blended by `method` ("dqs" or "lbs").
    fn deform<'py>(
        &self,
        py: Python<'py>,
        positions: PyReadonlyArrayDyn<'py, f64>,
        orientations: PyReadonlyArrayDyn<'py, f64>,
        method: &str,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let m = self::method(method)?;
        let p = rows::<3>(&positions, "positions", &[3])?;
        let q = rows::<4>(&orientations, "orientations", &[4])?;
        let poses = p.len() / self.skin.bones().max(1);
        let skin = &self.skin;
        compute(py, poses * skin.vertices(), &[3], |out| skin.deform(p, q, m, out))
    }
}

/// The segments (S, 2, 3) as (start, end) pairs.
fn segment_pairs(segments: &PyReadonlyArrayDyn<'_, f64>) -> PyResult<Vec<([f64; 3], [f64; 3])>> {
    let s = rows::<6>(segments, "segments", &[2, 3])?;
    Ok(s.iter().map(|r| ([r[0], r[1], r[2]], [r[3], r[4], r[5]])).collect())
}

/// Bones and weights of the influences, `k` per vertex, flat.
type Influences<'py> = (Bound<'py, PyArray1<u32>>, Bound<'py, PyArray1<f64>>);

/// The `k` nearest bones of every vertex (V, 3) and their weights by inverse distance to
/// the power `falloff` to the bones' segments (S, 2, 3), segment `s` owned by bone
/// `owners[s]` of `bones`: `(bones (V k,), weights (V k,))`.
#[pyfunction]
fn skin_proximity_weights<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArrayDyn<'py, f64>,
    segments: PyReadonlyArrayDyn<'py, f64>,
    owners: Vec<u32>,
    bones: usize,
    k: Int,
    falloff: f64,
) -> PyResult<Influences<'py>> {
    let v = rows::<3>(&vertices, "vertices", &[3])?;
    let pairs = segment_pairs(&segments)?;
    let k = k.range("influences", 1, 64)?;
    let (b, w) = detached(py, || proximity_weights(v, &pairs, &owners, bones, k, falloff))?;
    Ok((PyArray1::from_vec(py, b), PyArray1::from_vec(py, w)))
}

/// The `k` largest heat-diffusion weights (Baran & Popović 2007) of every vertex (V, 3) of
/// the surface with `triangles` (M, 3), for the bones owning `segments` (S, 2, 3), segment
/// `s` owned by bone `owners[s]` of `bones`: `(bones (V k,), weights (V k,))`.
#[pyfunction]
fn skin_heat_weights<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArrayDyn<'py, f64>,
    triangles: Vec<[u32; 3]>,
    segments: PyReadonlyArrayDyn<'py, f64>,
    owners: Vec<u32>,
    bones: usize,
    k: Int,
) -> PyResult<Influences<'py>> {
    let v = rows::<3>(&vertices, "vertices", &[3])?;
    let pairs = segment_pairs(&segments)?;
    let k = k.range("influences", 1, 64)?;
    let (b, w) = detached(py, || heat_weights(v, &triangles, &pairs, &owners, bones, k))?;
    Ok((PyArray1::from_vec(py, b), PyArray1::from_vec(py, w)))
}

/// Vertices (V, 3) and triangles (M, 3) of a surface.
type SurfaceMesh<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<u32>>);

/// Vertices (V, 3) and outward triangles (M, 3) of the smooth union of capsules around
/// `segments` (S, 2, 3) of `radii` (S values), filleted over `blend`, sampled every `cell`.
#[pyfunction]
fn skin_capsule_union<'py>(
    py: Python<'py>,
    segments: PyReadonlyArrayDyn<'py, f64>,
    radii: Vec<f64>,
    blend: f64,
    cell: f64,
) -> PyResult<SurfaceMesh<'py>> {
    let pairs = segment_pairs(&segments)?;
    let (v, t) = detached(py, || capsule_union(&pairs, &radii, blend, cell))?;
    let (nv, nt) = (v.len(), t.len());
    let v = PyArray1::from_vec(py, v.into_flattened()).reshape([nv, 3])?;
    let t = PyArray1::from_vec(py, t.into_flattened()).reshape([nt, 3])?;
    Ok((v, t))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySkin>()?;
    m.add_function(wrap_pyfunction!(skin_proximity_weights, m)?)?;
    m.add_function(wrap_pyfunction!(skin_heat_weights, m)?)?;
    m.add_function(wrap_pyfunction!(skin_capsule_union, m)?)?;
    Ok(())
}
