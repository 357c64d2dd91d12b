//! Cloth snapshots: what a decoded [`Cloth`] must satisfy before it is stepped.
//!
//! The derived structure (the matrix pattern and every element's slots in it) is rebuilt from
//! the elements' vertices exactly as [`Cloth::new`] builds it and compared, so a damaged pattern
//! cannot send the assembly or the PCG out of bounds.

use super::{BlockMatrix, Cloth, ContactState, Model, VertexConstraint};
use crate::error::Result;
use crate::snapshot::{check, finite, Snapshot};
use glam::DVec3;

impl Snapshot for Cloth {
    const TAG: &'static str = "Cloth";

    fn validate(&self) -> Result<()> {
        let n = self.x.len();
        let vec3 = |v: &[DVec3]| finite(v.iter().flat_map(|p| p.to_array()));
        check(n > 0 && !self.triangles.is_empty(), "x", || "a cloth needs vertices".into())?;
        let same = |field: &str, len: usize| {
            check(len == n, field, || format!("{len} entries for {n} vertices"))
        };
        same("v", self.v.len())?;
        same("mass", self.mass.len())?;
        same("constraints", self.constraints.len())?;
        same("contact", self.contact.len())?;
        check(vec3(&self.x) && vec3(&self.v), "x", || "non-finite positions or velocities".into())?;
        check(self.mass.iter().all(|m| m.is_finite() && *m > 0.0), "mass", || {
            "masses must be finite and positive".into()
        })?;
        if let Some((xp, vp, h)) = &self.history {
            same("history", xp.len())?;
            same("history", vp.len())?;
            check(vec3(xp) && vec3(vp), "history", || "non-finite values".into())?;
            check(h.is_finite() && *h > 0.0, "history", || {
                "previous step not finite and > 0".into()
            })?;
        }
        let m = &self.material;
        check(
            finite([m.density, m.stretch, m.shear, m.bend, m.damping, m.air_damping])
                && [m.density, m.stretch].iter().all(|&v| v > 0.0)
                && [m.shear, m.bend, m.damping, m.air_damping].iter().all(|&v| v >= 0.0),
            "material",
            || "material parameters out of range".into(),
        )?;
        check(
            self.gravity.is_finite() && self.thickness.is_finite() && self.thickness >= 0.0,
            "gravity",
            || "gravity and thickness must be finite".into(),
        )?;
        check(self.time.is_finite(), "time", || "non-finite".into())?;
        let constraint_ok = |c: &VertexConstraint| match *c {
            VertexConstraint::Pinned(p) | VertexConstraint::Velocity(p) => p.is_finite(),
            VertexConstraint::Plane(d) | VertexConstraint::Line(d) => {
                d.is_finite() && (d.length() - 1.0).abs() < 1e-6
            }
        };
        check(self.constraints.iter().flatten().all(constraint_ok), "constraints", || {
            "non-finite or non-unit constraint vectors".into()
        })?;
        check(
            self.contact.iter().all(|c| match c {
                ContactState::Touching(j) => j.is_finite(),
                _ => true,
            }),
            "contact",
            || "non-finite contact impulses".into(),
        )?;
        for c in &self.colliders {
            c.checked()?;
        }
        self.check_elements(n)?;
        self.check_scratch(n)?;
        if let Some(s) = &self.stepper {
            s.validate()?;
            check(s.dimension() == 6 * n, "stepper", || "dimension is not 6 x vertices".into())?;
        }
        Ok(())
    }
}

impl Cloth {
    /// Elements, hinges and springs index existing vertices, carry finite parameters, and their
    /// matrix pattern and slots are the ones [`Cloth::new`] builds from their vertices.
    fn check_elements(&self, n: usize) -> Result<()> {
        let inside = |verts: &[usize]| verts.iter().all(|&v| v < n);
        check(self.triangles.iter().all(|t| inside(t)), "triangles", || {
            format!("vertex index out of range ({n} vertices)")
        })?;
        check(
            self.elements.len() == self.triangles.len()
                && self.elements.iter().zip(&self.triangles).all(|(e, t)| e.verts == *t),
            "elements",
            || "do not match the triangles".into(),
        )?;
        check(
            self.elements.iter().all(|e| {
                finite(e.du.iter().chain(&e.dv).copied())
                    && e.area.is_finite()
                    && e.area > 0.0
                    && e.mass_share.is_finite()
            }),
            "elements",
            || "non-finite rest shape or zero area".into(),
        )?;
        check(
            self.hinges.iter().all(|h| inside(&h.verts) && finite([h.rest_angle, h.k])),
            "hinges",
            || "vertex out of range or non-finite parameters".into(),
        )?;
        check(
            self.springs.iter().all(|s| inside(&s.verts) && finite([s.rest, s.k, s.mass_share])),
            "springs",
            || "vertex out of range or non-finite parameters".into(),
        )?;
        let bending = self.model == Model::BaraffWitkin;
        check(
            if bending { self.springs.is_empty() } else { self.hinges.is_empty() },
            "springs",
            || "elements of another model".into(),
        )?;
        let pattern = if bending {
            BlockMatrix::from_elements(
                n,
                self.elements
                    .iter()
                    .map(|t| &t.verts[..])
                    .chain(self.hinges.iter().map(|h| &h.verts[..])),
            )
        } else {
            BlockMatrix::from_elements(n, self.springs.iter().map(|s| &s.verts[..]))
        };
        let m = &self.matrix;
        check(
            m.row_ptr == pattern.row_ptr
                && m.cols == pattern.cols
                && m.blocks.len() == pattern.blocks.len(),
            "matrix",
            || "the pattern is not the one of the elements".into(),
        )?;
        check(finite(m.blocks.iter().flat_map(|b| b.to_cols_array())), "matrix", || {
            "non-finite blocks".into()
        })?;
        let slots = |verts: &[usize], k: usize| {
            let w = verts.len();
            pattern.slot(verts[k / w], verts[k % w])
        };
        let triangles_ok = self
            .elements
            .iter()
            .all(|t| (0..9).all(|k| t.slots[k] == if bending { slots(&t.verts, k) } else { 0 }));
        let hinges_ok =
            self.hinges.iter().all(|h| (0..16).all(|k| h.slots[k] == slots(&h.verts, k)));
        let springs_ok =
            self.springs.iter().all(|s| (0..4).all(|k| s.slots[k] == slots(&s.verts, k)));
        check(triangles_ok && hinges_ok && springs_ok, "slots", || {
            "element slots do not match the matrix pattern".into()
        })
    }

    /// The step's workspaces have one entry per vertex (those that grow hold vertex indices).
    fn check_scratch(&self, n: usize) -> Result<()> {
        let s = &self.scratch;
        let per_vertex = [
            &s.f, &s.ku, &s.u, &s.b, &s.dv, &s.q, &s.z, &s.y, &s.x_new, &s.v_new, &s.hx, &s.hv,
            &s.ex, &s.ev,
        ];
        check(
            per_vertex.iter().all(|v| v.len() == n) && s.filter.len() == n && s.states.len() == n,
            "scratch",
            || format!("workspaces not of {n} vertices"),
        )?;
        check(
            s.constrained.iter().all(|&i| i < n) && s.contact_normal.iter().all(|c| c.0 < n),
            "scratch",
            || "vertex index out of range".into(),
        )
    }
}
