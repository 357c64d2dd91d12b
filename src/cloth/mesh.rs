//! Cloth meshes: a regular grid builder, meshes from arrays, Wavefront OBJ read/write, and the
//! topology the material models need (edges, interior edges with their two opposite
//! vertices).

use crate::error::{reserve, Error, Result};
use std::collections::HashMap;

/// How each quad of a grid is split into two triangles.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Triangulation {
    /// Every quad split along the same diagonal (from its lower-left to its upper-right corner).
    Regular,
    /// Diagonals alternate in a checkerboard pattern, which avoids a preferred shear direction.
    Alternating,
}

/// A triangle mesh with rest-state texture coordinates per triangle corner.
///
/// `uv[t][c]` are the material coordinates (m) of corner `c` of triangle `t`; per-corner
/// storage lets a seam give one vertex different coordinates in different triangles.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct Mesh {
    /// Vertex positions (m).
    pub positions: Vec<[f64; 3]>,
    /// Triangles as vertex indices (counter-clockwise seen from the front).
    pub triangles: Vec<[usize; 3]>,
    /// Rest coordinates `(u, v)` (m) of each triangle corner.
    pub uv: Vec<[[f64; 2]; 3]>,
}

/// Rest (u, v) of each corner when a mesh has none: a 2D frame in the triangle's plane with
/// `u` along its first edge, so lengths and angles are those of the initial shape.
pub fn uv_from_shape(positions: &[[f64; 3]], triangles: &[[usize; 3]]) -> Vec<[[f64; 2]; 3]> {
    triangles
        .iter()
        .map(|&[a, b, c]| {
            let p = |i: usize| glam::DVec3::from_array(positions[i]);
            let e1 = p(b) - p(a);
            let e2 = p(c) - p(a);
            let u_axis = e1.normalize_or_zero();
            let n = e1.cross(e2);
            let v_axis = n.cross(e1).normalize_or_zero();
            [[0.0, 0.0], [e1.length(), 0.0], [e2.dot(u_axis), e2.dot(v_axis)]]
        })
        .collect()
}

impl Mesh {
    /// An `nx` by `ny` grid of vertices in the x–z plane at height 0, centred on the origin,
    /// `width` (m) along x and `height` (m) along z. Vertex `i + nx * j` sits at
    /// `x = -width/2 + i width/(nx-1)`, `z = -height/2 + j height/(ny-1)`; the rest coordinates
    /// are `(u, v) = (x, z)`. Triangles face +Y.
    ///
    /// # Errors
    /// `nx` or `ny` below 2, more than `2^32 - 1` vertices or more than the allocator grants
    /// (named `nx, ny`), or a non-positive / non-finite size.
    pub fn grid(
        nx: usize,
        ny: usize,
        width: f64,
        height: f64,
        triangulation: Triangulation,
    ) -> Result<Mesh> {
        if nx < 2 || ny < 2 {
            return Err(Error::invalid(
                "nx, ny",
                format!("need at least 2 x 2 vertices, got {nx} x {ny}"),
            ));
        }
        for (name, value) in [("width", width), ("height", height)] {
            if !value.is_finite() || value <= 0.0 {
                return Err(Error::invalid(
                    name,
                    format!("must be positive and finite, got {value}"),
                ));
            }
        }
        // The block matrix numbers vertices with 32 bits; the buffers are allocated or
        // reported, never aborted on.
        let vertices = nx.checked_mul(ny).filter(|&n| n <= u32::MAX as usize).ok_or_else(|| {
            Error::invalid("nx, ny", format!("{nx} x {ny} vertices, more than 2^32 - 1"))
        })?;
        let mut positions = Vec::new();
        reserve("nx, ny", &mut positions, vertices)?;
        for j in 0..ny {
            for i in 0..nx {
                let x = -0.5 * width + width * i as f64 / (nx - 1) as f64;
                let z = -0.5 * height + height * j as f64 / (ny - 1) as f64;
                positions.push([x, 0.0, z]);
            }
        }
        let mut triangles = Vec::new();
        reserve("nx, ny", &mut triangles, 2 * (nx - 1) * (ny - 1))?;
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let (a, b, c, d) =
                    (i + nx * j, i + 1 + nx * j, i + nx * (j + 1), i + 1 + nx * (j + 1));
                // Counter-clockwise seen from +Y in the x–z plane: a -> c -> b.
                let flip = triangulation == Triangulation::Alternating && (i + j) % 2 == 1;
                if flip {
                    triangles.push([a, c, b]);
                    triangles.push([b, c, d]);
                } else {
                    triangles.push([a, c, d]);
                    triangles.push([a, d, b]);
                }
            }
        }
        let uv = triangles.iter().map(|t| t.map(|v| [positions[v][0], positions[v][2]])).collect();
        Ok(Mesh { positions, triangles, uv })
    }

    /// A mesh from vertex positions and triangles; `uv` (per corner) defaults to the initial
    /// shape ([`uv_from_shape`]). The mesh is checked with [`Mesh::validate`].
    ///
    /// # Errors
    /// See [`Mesh::validate`].
    pub fn new(
        positions: Vec<[f64; 3]>,
        triangles: Vec<[usize; 3]>,
        uv: Option<Vec<[[f64; 2]; 3]>>,
    ) -> Result<Mesh> {
        for (i, p) in positions.iter().enumerate() {
            crate::error::ensure_finite("vertices", p).map_err(|e| e.at(i))?;
        }
        for (t, tri) in triangles.iter().enumerate() {
            if let Some(&v) = tri.iter().find(|&&v| v >= positions.len()) {
                return Err(Error::invalid(
                    "triangles",
                    format!("vertex index {v} is out of range for {} vertices", positions.len()),
                )
                .at(t));
            }
        }
        let uv = match uv {
            Some(uv) => {
                if uv.len() != triangles.len() {
                    return Err(Error::Shape {
                        arg: "uv".into(),
                        expected: format!("({}, 3, 2)", triangles.len()),
                        got: vec![uv.len(), 3, 2],
                    });
                }
                uv
            }
            None => uv_from_shape(&positions, &triangles),
        };
        let mesh = Mesh { positions, triangles, uv };
        mesh.validate()?;
        Ok(mesh)
    }

    /// Check what the material models need: at least one triangle, three distinct vertices per
    /// triangle, a positive rest area and a positive 3D area for every triangle, every edge in
    /// at most two triangles (manifold), every vertex used, finite coordinates.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] naming the triangle, edge or vertex at fault.
    pub fn validate(&self) -> Result<()> {
        if self.triangles.is_empty() {
            return Err(Error::invalid("triangles", "a cloth needs at least one triangle"));
        }
        let mut used = vec![false; self.positions.len()];
        for (t, &[a, b, c]) in self.triangles.iter().enumerate() {
            if a == b || b == c || a == c {
                return Err(Error::invalid(
                    "triangles",
                    format!("repeats a vertex: {:?}", [a, b, c]),
                )
                .at(t));
            }
            let p = |i: usize| glam::DVec3::from_array(self.positions[i]);
            let area3 = 0.5 * (p(b) - p(a)).cross(p(c) - p(a)).length();
            let [ua, ub, uc] = self.uv[t];
            if ua.iter().chain(&ub).chain(&uc).any(|x| !x.is_finite()) {
                return Err(Error::invalid("uv", "must be finite").at(t));
            }
            let area_uv =
                0.5 * ((ub[0] - ua[0]) * (uc[1] - ua[1]) - (uc[0] - ua[0]) * (ub[1] - ua[1])).abs();
            let scale = [p(b) - p(a), p(c) - p(a), p(c) - p(b)]
                .iter()
                .map(|e| e.length_squared())
                .fold(0.0, f64::max);
            if area3 <= 1e-12 * scale || area_uv <= 1e-12 * scale {
                return Err(Error::invalid(
                    "triangles",
                    format!("has zero area (degenerate triangle {:?})", [a, b, c]),
                )
                .at(t));
            }
            for v in [a, b, c] {
                used[v] = true;
            }
        }
        if let Some(v) = used.iter().position(|u| !u) {
            return Err(Error::invalid(
                "vertices",
                "is not used by any triangle (it would have no mass)",
            )
            .at(v));
        }
        let topology = Topology::new(&self.triangles);
        if let Some(&(edge, count)) = topology.non_manifold.first() {
            return Err(Error::invalid(
                "triangles",
                format!("edge {edge:?} is shared by {count} triangles; cloth needs a manifold mesh (at most two per edge)"),
            ));
        }
        Ok(())
    }
}

/// Edges and bending hinges of a triangle mesh.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, Default)]
pub struct Topology {
    /// Every edge once, as `(min, max)` vertex indices, in order of first appearance.
    pub edges: Vec<[usize; 2]>,
    /// Interior edges: `[a, b, p, q]` with `(a, b)` the shared edge and `p`, `q` the vertices
    /// opposite it in its two triangles.
    pub hinges: Vec<[usize; 4]>,
    /// Edges in more than two triangles, with their triangle count.
    pub non_manifold: Vec<([usize; 2], usize)>,
}

impl Topology {
    /// Build the topology of `triangles`.
    pub fn new(triangles: &[[usize; 3]]) -> Topology {
        let mut first: HashMap<[usize; 2], (usize, usize, usize)> = HashMap::new();
        let mut order = Vec::new();
        let mut hinges = Vec::new();
        let mut non_manifold = Vec::new();
        for tri in triangles {
            for k in 0..3 {
                let (a, b, opposite) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                let key = [a.min(b), a.max(b)];
                match first.get_mut(&key) {
                    None => {
                        first.insert(key, (opposite, 1, order.len()));
                        order.push(key);
                    }
                    Some(entry) => {
                        entry.1 += 1;
                        if entry.1 == 2 {
                            hinges.push([a, b, entry.0, opposite]);
                        } else if entry.1 == 3 {
                            non_manifold.push((key, 3));
                        } else if let Some(e) = non_manifold.iter_mut().find(|e| e.0 == key) {
                            e.1 = entry.1;
                        }
                    }
                }
            }
        }
        Topology { edges: order, hinges, non_manifold }
    }
}

/// Parse a Wavefront OBJ: `v` positions, optional `vt` texture coordinates, `f` faces (`v`,
/// `v/vt`, `v//vn`, `v/vt/vn`, negative indices, polygons split into triangle fans). Other
/// statements are ignored. Returns positions, triangles and per-corner uv when every face
/// corner has a texture coordinate.
///
/// # Errors
/// [`Error::Parse`] with the line and what was expected.
pub fn parse_obj(text: &str, file: &str) -> Result<Mesh> {
    const FINITE_V: &str = "three finite numbers after 'v'";
    let mut obj = Obj { file, ..Obj::default() };
    for (number, raw) in text.lines().enumerate() {
        let line = number + 1;
        let content = raw.split('#').next().unwrap_or("").trim();
        let mut words = content.split_whitespace();
        match words.next() {
            Some("v") => {
                let [x, y, z] = obj.numbers(words, line, "three numbers after 'v'", FINITE_V)?;
                if ![x, y, z].iter().all(|x| x.is_finite()) {
                    return Err(obj.err(line, FINITE_V));
                }
                obj.positions.push([x, y, z]);
            }
            Some("vt") => {
                let uv =
                    obj.numbers(words, line, "two numbers after 'vt'", "two numbers after 'vt'")?;
                obj.texcoords.push(uv);
            }
            Some("f") => obj.face(words, line)?,
            _ => {}
        }
    }
    let Obj { positions, triangles, corner_uv, .. } = obj;
    let uv = if !corner_uv.is_empty() && corner_uv.iter().all(Option::is_some) {
        Some(corner_uv.into_iter().flatten().collect())
    } else {
        None
    };
    Mesh::new(positions, triangles, uv)
}

/// What [`parse_obj`] has read so far.
#[derive(Default)]
struct Obj<'a> {
    file: &'a str,
    positions: Vec<[f64; 3]>,
    texcoords: Vec<[f64; 2]>,
    triangles: Vec<[usize; 3]>,
    /// Per triangle, its corners' texture coordinates when all three have one.
    corner_uv: Vec<Option<[[f64; 2]; 3]>>,
}

impl Obj<'_> {
    /// The parse error at `line`.
    fn err(&self, line: usize, expected: &str) -> Error {
        Error::Parse { file: self.file.to_string(), line, expected: expected.to_string() }
    }

    /// The first `K` words as numbers: the error `expected` when one is not a number,
    /// `too_few` when there are fewer than `K`.
    fn numbers<'w, const K: usize>(
        &self,
        words: impl Iterator<Item = &'w str>,
        line: usize,
        expected: &str,
        too_few: &str,
    ) -> Result<[f64; K]> {
        let xs: Vec<f64> = words
            .take(K)
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|_| self.err(line, expected))?;
        xs.try_into().map_err(|_| self.err(line, too_few))
    }

    /// A 1-based (or negative, counted back from the last) index into `count` items, `None`
    /// when absent.
    fn index(&self, s: Option<&str>, count: usize, line: usize) -> Result<Option<usize>> {
        match s {
            None | Some("") => Ok(None),
            Some(s) => {
                let i: i64 = s.parse().map_err(|_| self.err(line, "integer indices in 'f'"))?;
                let idx = if i > 0 { i - 1 } else { count as i64 + i };
                if i == 0 || idx < 0 || idx >= count as i64 {
                    return Err(self.err(line, "indices that refer to earlier 'v'/'vt' lines"));
                }
                Ok(Some(idx as usize))
            }
        }
    }

    /// An `f` statement: its corners `v[/vt[/vn]]`, split into a triangle fan.
    fn face<'w>(&mut self, words: impl Iterator<Item = &'w str>, line: usize) -> Result<()> {
        let mut corners = Vec::new();
        for word in words {
            let mut parts = word.split('/');
            let v = self
                .index(parts.next(), self.positions.len(), line)?
                .ok_or_else(|| self.err(line, "a vertex index"))?;
            let vt = self.index(parts.next(), self.texcoords.len(), line)?;
            corners.push((v, vt));
        }
        if corners.len() < 3 {
            return Err(self.err(line, "at least three vertices per face"));
        }
        for k in 1..corners.len() - 1 {
            let tri = [corners[0], corners[k], corners[k + 1]];
            self.triangles.push(tri.map(|c| c.0));
            let uv = &self.texcoords;
            self.corner_uv.push(match (tri[0].1, tri[1].1, tri[2].1) {
                (Some(a), Some(b), Some(c)) => Some([uv[a], uv[b], uv[c]]),
                _ => None,
            });
        }
        Ok(())
    }
}

/// Write positions and triangles (and the per-corner uv as `vt`, one per corner) as OBJ text.
pub fn write_obj(
    positions: &[[f64; 3]],
    triangles: &[[usize; 3]],
    uv: Option<&[[[f64; 2]; 3]]>,
) -> String {
    use std::fmt::Write;
    let mut out = String::from("# written by kinema\n");
    for p in positions {
        let _ = writeln!(out, "v {:?} {:?} {:?}", p[0], p[1], p[2]);
    }
    if let Some(uv) = uv {
        for corners in uv {
            for c in corners {
                let _ = writeln!(out, "vt {:?} {:?}", c[0], c[1]);
            }
        }
    }
    for (t, tri) in triangles.iter().enumerate() {
        if uv.is_some() {
            let _ = writeln!(
                out,
                "f {}/{} {}/{} {}/{}",
                tri[0] + 1,
                3 * t + 1,
                tri[1] + 1,
                3 * t + 2,
                tri[2] + 1,
                3 * t + 3
            );
        } else {
            let _ = writeln!(out, "f {} {} {}", tri[0] + 1, tri[1] + 1, tri[2] + 1);
        }
    }
    out
}
