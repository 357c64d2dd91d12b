//! Constraint kinds and their rows: each constraint's value `C`, Jacobian blocks `∂C/∂x` per
//! particle and `J̇ q̇` (Witkin, "Constrained dynamics"), evaluated into [`Rows`]; user
//! constraints through [`ConstraintFunction`] (`J̇ q̇` by central differences).

use super::Curve;
use crate::error::{Error, Result};
use glam::DVec3;
use std::sync::Arc;

/// A user constraint `C(x) = 0` of `m` scalar rows on `k` particles, given by its value and
/// gradient (for teaching; e.g. Python callables). `J̇ q̇` is obtained by central differences
/// of the gradient along the velocity (see [`Constraint::Custom`]).
pub trait ConstraintFunction: Send + Sync + std::fmt::Debug {
    /// Number of scalar rows `m` >= 1.
    fn rows(&self) -> usize;
    /// Write `C` (`m` values) at the positions `x` (`k x 3` values, the constraint's particles
    /// in order, m) into `value`.
    ///
    /// # Errors
    /// Whatever the function reports (a Python exception, a wrong shape).
    fn value(&self, x: &[f64], value: &mut [f64]) -> Result<()>;
    /// Write `∂C/∂x` (`m x 3k`, row-major: row `r` holds `∂C_r/∂x₀, ∂C_r/∂y₀, ∂C_r/∂z₀,
    /// ∂C_r/∂x₁...`) at `x` into `gradient`.
    ///
    /// # Errors
    /// Whatever the function reports.
    fn gradient(&self, x: &[f64], gradient: &mut [f64]) -> Result<()>;
}

/// A holonomic constraint on particles.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub enum Constraint {
    /// `|x_i - x_j| - length = 0` (a rod).
    Distance {
        /// First particle.
        i: usize,
        /// Second particle.
        j: usize,
        /// Rod length (m) > 0.
        length: f64,
    },
    /// `|x_i - center| - radius = 0` (a bead on a sphere, or on a circle in a plane).
    OnSphere {
        /// Particle.
        i: usize,
        /// Centre (m).
        center: DVec3,
        /// Radius (m) > 0.
        radius: f64,
    },
    /// `n · (x_i - point) = 0`.
    OnPlane {
        /// Particle.
        i: usize,
        /// A point of the plane (m).
        point: DVec3,
        /// Normal (normalised here).
        normal: DVec3,
    },
    /// `x_i - point = 0` (three rows).
    Fixed {
        /// Particle.
        i: usize,
        /// Position (m).
        point: DVec3,
    },
    /// `x_i` on a parametric curve (a bead on a wire), as two rows
    /// `C_k = n_k · (x_i - x(u*))`, `k = 1, 2`, where `u*` is the parameter of the closest
    /// point (tracked from step to step, refined by Newton's method at every evaluation) and
    /// `n₁ = â × t̂ / |â × t̂|`, `n₂ = t̂ × n₁` span the plane normal to the tangent `t̂` (`â` a
    /// reference axis held per step: the circle's normal, else a world axis far from `t̂`).
    /// `C = 0` exactly when the particle is on the curve. `J` is exact
    /// (`J_k = n_k + (d · ∂n_k/∂u) ∇u*`, `d = x_i - x(u*)`, `∇u* = x'/(|x'|² - x''·d)`);
    /// `J̇ q̇` is exact on the curve and drops the terms proportional to `|d|` that would need
    /// the curve's third derivative (they only change how a drift is corrected).
    OnCurve {
        /// Particle.
        i: usize,
        /// The wire.
        curve: Curve,
    },
    /// A user constraint of `function.rows()` rows on `particles` (distinct indices).
    /// `J̇ q̇ = d/dε [∇C(x + ε q̇)] q̇` is taken by central differences with
    /// `ε |q̇|_max = ∛(machine ε) · max(1, |x|_max)` (error ~1e-11 relative, two extra gradient
    /// evaluations per row evaluation).
    #[serde(skip)] // holds a user function: a system with one cannot be saved
    Custom {
        /// The particles the function reads, in order.
        particles: Vec<usize>,
        /// Value and gradient.
        function: Arc<dyn ConstraintFunction>,
    },
}

impl Constraint {
    pub(super) fn rows(&self) -> usize {
        match self {
            Constraint::Fixed { .. } => 3,
            Constraint::OnCurve { .. } => 2,
            Constraint::Custom { function, .. } => function.rows(),
            _ => 1,
        }
    }

    pub(super) fn particles(&self) -> Vec<usize> {
        match self {
            Constraint::Distance { i, j, .. } => vec![*i, *j],
            Constraint::OnSphere { i, .. }
            | Constraint::OnPlane { i, .. }
            | Constraint::Fixed { i, .. }
            | Constraint::OnCurve { i, .. } => vec![*i],
            Constraint::Custom { particles, .. } => particles.clone(),
        }
    }
}

/// One row of `J` (its particle blocks are `Rows::blocks[start..start + count]`), with `C`,
/// `Ċ = J q̇` and `J̇ q̇`.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, Default)]
pub(super) struct Row {
    pub(super) start: usize,
    pub(super) count: usize,
    pub(super) c: f64,
    pub(super) cdot: f64,
    pub(super) jdot_qdot: f64,
}

/// The evaluated rows of `J` and their particle blocks.
#[derive(serde::Serialize, serde::Deserialize, Debug, Default)]
pub(super) struct Rows {
    pub(super) rows: Vec<Row>,
    pub(super) blocks: Vec<(usize, DVec3)>,
    /// Custom constraints: positions, value, gradient and the two shifted gradients.
    pub(super) scratch: Vec<f64>,
}

impl Rows {
    pub(super) fn clear(&mut self) {
        self.rows.clear();
        self.blocks.clear();
    }

    pub(super) fn blocks(&self, r: usize) -> &[(usize, DVec3)] {
        let row = &self.rows[r];
        &self.blocks[row.start..row.start + row.count]
    }

    /// Append a row; `Ċ` is computed as `J q̇` from the velocities `v`.
    pub(super) fn push(
        &mut self,
        blocks: impl IntoIterator<Item = (usize, DVec3)>,
        c: f64,
        jdot_qdot: f64,
        v: impl Fn(usize) -> DVec3,
    ) {
        let start = self.blocks.len();
        self.blocks.extend(blocks);
        let count = self.blocks.len() - start;
        let cdot = self.blocks[start..].iter().map(|&(p, g)| g.dot(v(p))).sum();
        self.rows.push(Row { start, count, c, cdot, jdot_qdot });
    }
}

/// Attribute an error of a curve search to particle `i`.
pub(super) fn at_particle(e: Error, i: usize) -> Error {
    match e {
        Error::SolverFailed { reason } => {
            Error::SolverFailed { reason: format!("particle {i} on its curve: {reason}") }
        }
        other => other,
    }
}

/// Evaluate every constraint row at `y = [x; v]`, with the curves' tracked parameters as
/// starting guesses.
pub(super) fn evaluate(
    constraints: &[Constraint],
    curves: &[(f64, DVec3)],
    y: &[f64],
    n: usize,
    rows: &mut Rows,
) -> Result<()> {
    rows.clear();
    let x = |i: usize| DVec3::from_slice(&y[3 * i..]);
    let v = |i: usize| DVec3::from_slice(&y[3 * n + 3 * i..]);
    for (c, &tracked) in constraints.iter().zip(curves) {
        match c {
            &Constraint::Distance { i, j, length } => {
                let (c, dir, jdot) = radial(x(i) - x(j), v(i) - v(j), length);
                rows.push([(i, dir), (j, -dir)], c, jdot, v);
            }
            &Constraint::OnSphere { i, center, radius } => {
                let (c, dir, jdot) = radial(x(i) - center, v(i), radius);
                rows.push([(i, dir)], c, jdot, v);
            }
            &Constraint::OnPlane { i, point, normal } => {
                rows.push([(i, normal)], normal.dot(x(i) - point), 0.0, v);
            }
            &Constraint::Fixed { i, point } => {
                for k in 0..3 {
                    rows.push([(i, DVec3::AXES[k])], x(i)[k] - point[k], 0.0, v);
                }
            }
            Constraint::OnCurve { i, curve } => curve_rows(*i, curve, tracked, &x, &v, rows)?,
            Constraint::Custom { particles, function } => {
                custom(particles, function.as_ref(), &x, &v, rows)?;
            }
        }
    }
    Ok(())
}

/// The row `|d| - length` of a rod or sphere with separation `d` and relative velocity `w`:
/// its value, unit direction (`+X` when `d = 0`) and `J̇ q̇ = (|w|² - (d̂·w)²) / |d|`.
fn radial(d: DVec3, w: DVec3, length: f64) -> (f64, DVec3, f64) {
    let len = d.length();
    let dir = if len > 0.0 { d / len } else { DVec3::X };
    let along = dir.dot(w);
    let jdot = if len > 0.0 { (w.length_squared() - along * along) / len } else { 0.0 };
    (len - length, dir, jdot)
}

/// The two rows of particle `i` on `curve` (see [`Constraint::OnCurve`]), from the tracked
/// `(parameter, reference axis)`.
fn curve_rows(
    i: usize,
    curve: &Curve,
    (guess, reference): (f64, DVec3),
    x: &impl Fn(usize) -> DVec3,
    v: &impl Fn(usize) -> DVec3,
    rows: &mut Rows,
) -> Result<()> {
    let u = curve.closest(x(i), guess).map_err(|e| at_particle(e, i))?;
    let [p, dp, ddp] = curve.eval(u);
    let d = x(i) - p;
    let speed2 = dp.length_squared();
    let denom = speed2 - ddp.dot(d);
    if !(denom.is_finite() && denom > 0.0) {
        return Err(Error::SolverFailed {
            reason: format!(
                "particle {i} is farther from its curve than the radius of \
                 curvature; the closest point is not unique"
            ),
        });
    }
    let speed = speed2.sqrt();
    let t = dp / speed;
    let t_u = (ddp - t.dot(ddp) * t) / speed; // dt̂/du
    let m = reference.cross(t);
    let m_len = m.length();
    let n1 = m / m_len;
    let w = reference.cross(t_u) / m_len;
    let n1_u = w - n1.dot(w) * n1;
    let n2 = t.cross(n1);
    let n2_u = t_u.cross(n1) + t.cross(n1_u);
    let grad_u = dp / denom;
    let u_dot = grad_u.dot(v(i));
    let d_dot = v(i) - u_dot * dp;
    for (nk, nk_u) in [(n1, n1_u), (n2, n2_u)] {
        let g = nk + d.dot(nk_u) * grad_u;
        rows.push([(i, g)], nk.dot(d), u_dot * nk_u.dot(v(i) + d_dot), v);
    }
    Ok(())
}

/// The rows of a custom constraint on `particles` (see [`Constraint::Custom`]), through the
/// scratch buffer of `rows`.
fn custom(
    particles: &[usize],
    function: &dyn ConstraintFunction,
    x: &impl Fn(usize) -> DVec3,
    v: &impl Fn(usize) -> DVec3,
    rows: &mut Rows,
) -> Result<()> {
    let (k, m) = (particles.len(), function.rows());
    let mut scratch = std::mem::take(&mut rows.scratch);
    scratch.resize(3 * k * (1 + 3 * m) + m, 0.0);
    let (xs, rest) = scratch.split_at_mut(3 * k);
    let (value, rest) = rest.split_at_mut(m);
    let (grad, rest) = rest.split_at_mut(3 * k * m);
    let (grad_plus, grad_minus) = rest.split_at_mut(3 * k * m);
    let mut scale = 1.0_f64;
    let mut speed = 0.0_f64;
    for (a, &p) in particles.iter().enumerate() {
        xs[3 * a..3 * a + 3].copy_from_slice(&x(p).to_array());
        scale = scale.max(x(p).abs().max_element());
        speed = speed.max(v(p).abs().max_element());
    }
    let result =
        custom_rows(function, particles, [xs, value, grad, grad_plus, grad_minus], scale, speed, v);
    if result.is_ok() {
        for r in 0..m {
            let blocks = particles
                .iter()
                .enumerate()
                .map(|(a, &p)| (p, DVec3::from_slice(&grad[3 * k * r + 3 * a..])));
            let jdot: f64 = particles
                .iter()
                .enumerate()
                .map(|(a, &p)| {
                    let o = 3 * k * r + 3 * a;
                    (DVec3::from_slice(&grad_plus[o..]) - DVec3::from_slice(&grad_minus[o..]))
                        .dot(v(p))
                })
                .sum();
            rows.push(blocks, value[r], jdot, v);
        }
    }
    rows.scratch = scratch;
    result
}

/// Value and gradient of a custom constraint at `xs`, and `grad_plus`, `grad_minus` =
/// `∇C(x ± εv) / (2ε)`, so that `(grad_plus - grad_minus) · v` is the central difference of
/// `J̇ q̇` (both zero when nothing moves). `xs` is left shifted.
pub(super) fn custom_rows(
    function: &dyn ConstraintFunction,
    particles: &[usize],
    [xs, value, grad, grad_plus, grad_minus]: [&mut [f64]; 5],
    scale: f64,
    speed: f64,
    v: &impl Fn(usize) -> DVec3,
) -> Result<()> {
    function.value(xs, value)?;
    function.gradient(xs, grad)?;
    if speed > 0.0 {
        let eps = f64::EPSILON.cbrt() * scale / speed;
        let shift = |xs: &mut [f64], by: f64| {
            for (a, &p) in particles.iter().enumerate() {
                for (c, vc) in v(p).to_array().iter().enumerate() {
                    xs[3 * a + c] += by * vc;
                }
            }
        };
        shift(xs, eps);
        function.gradient(xs, grad_plus)?;
        shift(xs, -2.0 * eps);
        function.gradient(xs, grad_minus)?;
        for g in grad_plus.iter_mut().chain(grad_minus.iter_mut()) {
            *g /= 2.0 * eps;
        }
    } else {
        grad_plus.fill(0.0);
        grad_minus.fill(0.0);
    }
    if [&*value, &*grad, &*grad_plus, &*grad_minus].iter().any(|s| s.iter().any(|g| !g.is_finite()))
    {
        return Err(Error::invalid("value", "a custom constraint returned NaN or infinity"));
    }
    Ok(())
}

impl Constraint {
    /// This constraint with its parameters checked and a plane's normal made unit. Indices are
    /// checked by the caller; what depends on the particles' positions by
    /// [`Constraint::initial`].
    ///
    /// # Errors
    /// Those listed at [`super::Model::add`].
    pub(super) fn checked(self) -> Result<Constraint> {
        Ok(match self {
            Constraint::Distance { i, j, length } => {
                if i == j {
                    return Err(Error::invalid(
                        "j",
                        "a distance constraint needs two different particles",
                    ));
                }
                if !(length.is_finite() && length > 0.0) {
                    return Err(Error::invalid(
                        "length",
                        format!("must be positive and finite, got {length}"),
                    ));
                }
                self
            }
            Constraint::OnSphere { center, radius, .. } => {
                if !(center.is_finite() && radius.is_finite() && radius > 0.0) {
                    return Err(Error::invalid(
                        "radius",
                        format!("must be positive with a finite centre, got {radius}"),
                    ));
                }
                self
            }
            Constraint::OnPlane { i, point, normal } => {
                if !(point.is_finite() && normal.is_finite() && normal.length() > 0.0) {
                    return Err(Error::invalid("normal", "must be a finite non-zero vector"));
                }
                Constraint::OnPlane { i, point, normal: normal.normalize() }
            }
            Constraint::Fixed { point, .. } => {
                if !point.is_finite() {
                    return Err(Error::invalid("point", "contains NaN or infinity"));
                }
                self
            }
            Constraint::OnCurve { i, curve } => Constraint::OnCurve { i, curve: curve.checked()? },
            Constraint::Custom { particles, function } => {
                let (k, m) = (particles.len(), function.rows());
                if k == 0 || m == 0 {
                    return Err(Error::invalid(
                        "indices",
                        format!("a custom constraint needs particles and rows, got {k} and {m}"),
                    ));
                }
                if (1..k).any(|a| particles[..a].contains(&particles[a])) {
                    return Err(Error::invalid("indices", "must be distinct"));
                }
                Constraint::Custom { particles, function }
            }
        })
    }

    /// This (checked) constraint against the particles at `positions` (3 per particle, m;
    /// indices in range): the tracked state of a curve constraint (the closest point's
    /// parameter and the frame reference; zero for the other kinds).
    ///
    /// # Errors
    /// A rod between coincident particles (no direction; argument `j`), a curve whose closest
    /// point to its particle cannot be found (argument `curve`), a custom function that fails
    /// or is not finite at the positions.
    pub(super) fn initial(&self, positions: &[f64]) -> Result<(f64, DVec3)> {
        let pos = |i: usize| DVec3::from_slice(&positions[3 * i..]);
        match self {
            &Constraint::Distance { i, j, .. } if pos(i) == pos(j) => Err(Error::invalid(
                "j",
                format!("particles {i} and {j} coincide; the rod has no direction"),
            )),
            Constraint::OnCurve { i, curve } => {
                let x = pos(*i);
                let u = curve.closest(x, curve.initial_parameter(x)).map_err(|e| {
                    Error::invalid("curve", format!("no closest point to particle {i}: {e}"))
                })?;
                Ok((u, curve.reference(u)))
            }
            Constraint::Custom { particles, function } => {
                check_custom(particles, function.as_ref(), pos)?;
                Ok((0.0, DVec3::ZERO))
            }
            _ => Ok((0.0, DVec3::ZERO)),
        }
    }
}

/// Check that a custom constraint on particles `ids` has a finite value and gradient at `pos`.
fn check_custom(
    ids: &[usize],
    function: &dyn ConstraintFunction,
    pos: impl Fn(usize) -> DVec3,
) -> Result<()> {
    let (k, m) = (ids.len(), function.rows());
    let x: Vec<f64> = ids.iter().flat_map(|&p| pos(p).to_array()).collect();
    let mut value = vec![0.0; m];
    let mut gradient = vec![0.0; 3 * k * m];
    function.value(&x, &mut value)?;
    function.gradient(&x, &mut gradient)?;
    if value.iter().chain(&gradient).any(|v| !v.is_finite()) {
        return Err(Error::invalid(
            "value",
            "the constraint's value or gradient is not finite at the current positions",
        ));
    }
    Ok(())
}
