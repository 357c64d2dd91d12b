//! Contact detection of a rigid step: each free body's candidate points against the planes,
//! a sweep-and-prune broad phase over bounding spheres grown by the motion, and the narrow
//! phases of [`crate::rigid::contact`] between the pairs; each contact gets its target normal
//! velocity (speculative contacts close their gap exactly, fast ones bounce).

use super::super::contact::{self, Contact};
use super::super::narrow::{self, Placed, Touch};
use super::super::Model;
use super::Solver;
use crate::error::{Error, Result};
use glam::DVec3;

/// What a new contact reads of the bodies: centres of mass, velocities, angular velocities,
/// the step `h` and the speed below which a touching contact does not bounce (`2 |g| h`).
struct Approach<'a> {
    x: &'a [DVec3],
    v: &'a [DVec3],
    w: &'a [DVec3],
    h: f64,
    resting_speed: f64,
}

/// A point of body `a` at which it may touch `b` (or a plane): the lever arms from the centres
/// of mass (m) and the normal velocity of `a` relative to `b` there (m/s).
struct Approaching {
    a: usize,
    b: Option<usize>,
    ra: DVec3,
    rb: DVec3,
    vn: f64,
}

impl Approach<'_> {
    /// How body `a` approaches `b` (or a plane) at point `p` along the normal `nrm`: read
    /// before a contact is made, so that points that will not touch within the step cost no
    /// more.
    fn approaching(&self, a: usize, b: Option<usize>, p: DVec3, nrm: DVec3) -> Approaching {
        let (x, v, w) = (self.x, self.v, self.w);
        let (ra, rb) = (p - x[a], b.map_or(DVec3::ZERO, |b| p - x[b]));
        let vel = v[a] + w[a].cross(ra) - b.map_or(DVec3::ZERO, |b| v[b] + w[b].cross(rb));
        Approaching { a, b, ra, rb, vn: vel.dot(nrm) }
    }

    /// The contact of the approach `at` with `touch`, restitution `e` and friction `mu`.
    fn contact(
        &self,
        key: (usize, usize, usize),
        at: &Approaching,
        touch: Touch,
        e: f64,
        mu: f64,
    ) -> Contact {
        let (_, nrm, gap) = touch;
        let vn = at.vn;
        // Bounce when approaching fast (landing within this step or touching); otherwise
        // close any gap exactly and stop (overlaps are undone by the position pass).
        let target =
            if vn < -self.resting_speed && e > 0.0 { -e * vn } else { -gap.max(0.0) / self.h };
        let t1 = nrm.any_orthonormal_vector();
        Contact {
            key,
            a: at.a,
            b: at.b,
            ra: at.ra,
            rb: at.rb,
            n: nrm,
            t1,
            t2: nrm.cross(t1),
            mass: [0.0; 3],
            compliance: [0.0; 3],
            spin: [[DVec3::ZERO; 3]; 2],
            coupling: [0.0; 2],
            target,
            gap,
            mu,
            impulse: [0.0; 3],
        }
    }
}

impl Solver {
    /// Find the contacts of the scratch state (planes, then body pairs by sweep and prune)
    /// into `self.contacts`, in the order of [`contact::warm_start`]; velocities already
    /// include this step's forces.
    ///
    /// # Errors
    /// A step too large for a speculative contact ([`resolvable`]).
    pub(super) fn detect_contacts(&mut self, model: &Model, h: f64) -> Result<()> {
        self.plane_contacts(model, h)?;
        self.broad_phase(model, h);
        self.pair_contacts(model, h)
    }

    /// The contacts of every free body's candidate points with the planes.
    fn plane_contacts(&mut self, model: &Model, h: f64) -> Result<()> {
        let (x, v, q, _) = &*self.scratch;
        let resting_speed = 2.0 * model.gravity.length() * h;
        let approach = Approach { x, v, w: &self.omega, h, resting_speed };
        for i in (0..model.len()).filter(|&i| !model.fixed[i]) {
            let orient = q[i] * model.principal[i].conjugate();
            let origin = x[i] - orient * model.com_body[i];
            for (k, (plane, material)) in model.planes.iter().enumerate() {
                self.points.clear();
                let shape = &model.shape[i];
                narrow::candidate_points(shape, origin, orient, plane.normal, &mut self.points);
                let e = model.restitution[i].max(material.restitution);
                let mu = (model.friction[i] * material.friction).sqrt();
                for (j, &p) in self.points.iter().enumerate() {
                    let (gap, _) = plane.distance(p);
                    let at = approach.approaching(i, None, p, plane.normal);
                    if gap <= (-at.vn * h).max(0.0) + 1e-9 {
                        resolvable(at.vn, gap, h, resting_speed, i)?;
                        let touch = (p, plane.normal, gap);
                        self.contacts.push(approach.contact((i, k, j), &at, touch, e, mu));
                    }
                }
            }
        }
        Ok(())
    }

    /// Broad phase: sweep and prune along x over bounding spheres grown by the motion, into
    /// `self.pairs` (sorted, so the contacts come out sorted for warm starting).
    fn broad_phase(&mut self, model: &Model, h: f64) {
        let (x, v, _, _) = &*self.scratch;
        let n = model.len();
        let bound = &model.bound;
        self.reach.clear();
        self.reach.extend(
            (0..n).map(|i| bound[i] + h * (v[i].length() + self.omega[i].length() * bound[i])),
        );
        let reach = &self.reach;
        self.order.clear();
        if model.collisions {
            self.order.extend(
                (0..n)
                    .filter(|&i| !matches!(self.placed[i], Placed::Other))
                    .map(|i| (x[i].x - reach[i], i)),
            );
        }
        self.order.sort_unstable_by(|p, q| p.0.total_cmp(&q.0).then(p.1.cmp(&q.1)));
        self.pairs.clear();
        for (k, &(_, i)) in self.order.iter().enumerate() {
            for &(low, j) in &self.order[k + 1..] {
                if low > x[i].x + reach[i] {
                    break;
                }
                let (a, b) = (i.min(j), i.max(j));
                if (model.fixed[i] && model.fixed[j])
                    || (x[i] - x[j]).length() > reach[i] + reach[j]
                    || model.jointed.binary_search(&(a, b)).is_ok()
                {
                    continue;
                }
                self.pairs.push((a, b));
            }
        }
        self.pairs.sort_unstable();
    }

    /// The contacts of the broad phase's pairs by their narrow phases.
    fn pair_contacts(&mut self, model: &Model, h: f64) -> Result<()> {
        let (x, v, _, _) = &*self.scratch;
        let resting_speed = 2.0 * model.gravity.length() * h;
        let approach = Approach { x, v, w: &self.omega, h, resting_speed };
        let np = model.planes.len();
        for &(a, b) in &self.pairs {
            let margin = h * (v[a] - v[b]).length().max(resting_speed) + contact::SLOP;
            self.touches.clear();
            narrow::touches(&self.placed[a], &self.placed[b], margin, &mut self.touches);
            let e = model.restitution[a].max(model.restitution[b]);
            let mu = (model.friction[a] * model.friction[b]).sqrt();
            for &(f, touch) in &self.touches {
                let (p, nrm, gap) = touch;
                let at = approach.approaching(a, Some(b), p, nrm);
                if gap <= (-at.vn * h).max(0.0) + contact::SLOP {
                    resolvable(at.vn, gap, h, resting_speed, a)?;
                    self.contacts.push(approach.contact((a, np + b, f), &at, touch, e, mu));
                }
            }
        }
        Ok(())
    }
}

/// Whether a speculative contact of `body` apart by `gap` (m), approaching at normal speed
/// `-vn` (m/s), can be honoured in a step of `h` (s): its target speed `gap / h` must stand
/// above the rounding of the speeds the impulse cancels (16 ulp of `|vn|`). Otherwise (e.g. a
/// body 2.5 m above the ground at dt = 1e9 s, which gravity moves at 1e10 m/s) the target is
/// lost in the cancellation and the body would stop in mid-air. Only an approach the step's
/// gravity accounts for (`|vn| <= resting_speed = 2 |g| h`) is blamed on `dt`; a faster one is
/// a diverging state, reported as divergence after the step.
///
/// # Errors
/// [`Error::InvalidInput`] (argument `"dt"`) naming the body.
fn resolvable(vn: f64, gap: f64, h: f64, resting_speed: f64, body: usize) -> Result<()> {
    if gap > contact::SLOP && vn.abs() <= resting_speed && gap / h < 16.0 * f64::EPSILON * vn.abs()
    {
        return Err(Error::invalid(
            "dt",
            format!(
                "{h} s is too large for the contacts of body {body}: closing its gap of {gap:.3e} \
                 m within the step needs {:.3e} m/s, below the rounding of its approach speed \
                 {:.3e} m/s; take smaller steps",
                gap / h,
                vn.abs()
            ),
        ));
    }
    Ok(())
}
