//! Cyclic coordinate descent (Wang & Chen 1991): one dof at a time turned (or shifted) to
//! bring the effectors closest to their targets.

use super::super::model::Kind;
use super::super::{Report, Target};
use super::Solver;
use glam::{DQuat, DVec3};

impl Solver<'_> {
    pub(super) fn ccd(&mut self, q: &mut [f64], targets: &[Target]) -> Report {
        let tol = self.options.tol;
        let n = self.vars.len();
        self.forward(q);
        let mut err = std::mem::take(&mut self.err);
        let (mut f, mut ep, mut eo) = self.errors(targets, &mut err);
        let mut iterations = 0;
        while iterations < self.options.max_iters && !(ep <= tol && eo <= tol) && n > 0 {
            for (e, t) in targets.iter().enumerate() {
                self.eff_p[e] = self.pos[t.joint];
                self.eff_r[e] = self.rot[t.joint];
            }
            for c in 0..n {
                match self.vars[c].kind {
                    Kind::Rotation => self.ccd_turn(c, q, targets),
                    Kind::Translation => self.ccd_shift(c, q, targets),
                }
            }
            iterations += 1;
            self.forward(q);
            let (f2, ep2, eo2) = self.errors(targets, &mut err);
            let stalled = f2 >= f;
            (f, ep, eo) = (f2, ep2, eo2);
            if stalled {
                break;
            }
        }
        self.err = err;
        self.report(ep, eo, iterations)
    }

    /// One CCD update of rotational variable `c`: the angle about its axis that best turns
    /// the effectors it moves towards their targets (positions, and orientations weighted by
    /// the squared reach), within its limits; the effectors are turned with it.
    fn ccd_turn(&mut self, c: usize, q: &mut [f64], targets: &[Target]) {
        let n = self.vars.len();
        let v = self.vars[c];
        let w = self.axis[v.index];
        let centre = self.pivot[v.index];
        let (mut k1, mut k2, mut k3) = (0.0, 0.0, 0.0);
        for (e, t) in targets.iter().enumerate() {
            if !self.affects[e * n + c] {
                continue;
            }
            let (r, s) = (self.eff_p[e] - centre, t.position - centre);
            k1 += s.dot(w) * r.dot(w);
            k2 += s.dot(r);
            k3 += w.dot(r.cross(s));
            if let Some(qt) = t.orientation {
                let wt = self.reach[e] * self.reach[e];
                for axis in DVec3::AXES {
                    let (u, d) = (self.eff_r[e] * axis, qt * axis);
                    k1 += wt * u.dot(w) * d.dot(w);
                    k2 += wt * u.dot(d);
                    k3 += wt * w.dot(u.cross(d));
                }
            }
        }
        // Maximise (k2 - k1) cos θ + k3 sin θ over θ within the limits.
        let gain = |th: f64| (k2 - k1) * th.cos() + k3 * th.sin();
        let (lo, hi) = (v.lo - q[v.index], v.hi - q[v.index]);
        let best = k3.atan2(k2 - k1);
        let theta = [best, best - std::f64::consts::TAU, best + std::f64::consts::TAU]
            .into_iter()
            .find(|th| *th >= lo && *th <= hi)
            .unwrap_or_else(|| if gain(lo) >= gain(hi) { lo } else { hi });
        // Clamp again: q + (hi - q) can round past hi.
        let next = (q[v.index] + theta).clamp(v.lo, v.hi);
        let theta = next - q[v.index];
        if theta == 0.0 || !theta.is_finite() {
            return;
        }
        q[v.index] = next;
        let turn = DQuat::from_axis_angle(w, theta);
        for e in 0..targets.len() {
            if self.affects[e * n + c] {
                self.eff_p[e] = centre + turn * (self.eff_p[e] - centre);
                self.eff_r[e] = (turn * self.eff_r[e]).normalize();
            }
        }
    }

    /// One CCD update of translational variable `c`: the mean shift along its axis towards
    /// the targets of the effectors it moves; the effectors are shifted with it.
    fn ccd_shift(&mut self, c: usize, q: &mut [f64], targets: &[Target]) {
        let n = self.vars.len();
        let v = self.vars[c];
        let w = self.axis[v.index];
        let (mut sum, mut count) = (0.0, 0.0);
        for (e, t) in targets.iter().enumerate() {
            if self.affects[e * n + c] {
                sum += w.dot(t.position - self.eff_p[e]);
                count += 1.0;
            }
        }
        let shift = sum / count;
        q[v.index] += shift;
        for e in 0..targets.len() {
            if self.affects[e * n + c] {
                self.eff_p[e] += w * shift;
            }
        }
    }
}
