//! Contacts between bodies and static planes and between bodies: the impulse response with
//! restitution and Coulomb friction.
//!
//! The response is sequential impulses (projected Gauss–Seidel on the contact velocities;
//! Catto 2005, "Iterative dynamics with temporal coherence", GDC; Mirtich 1996 for the
//! impulse law). Each contact `k` at lever arm `r` (from the centre of mass) with normal `n`
//! gets an accumulated normal impulse `λ_n ≥ 0` and a friction impulse in the tangent plane
//! clamped to the disc `|λ_t| ≤ μ λ_n` (isotropic Coulomb friction). The normal target is
//!
//! - `v_n ≥ -d/h` for a contact still apart by `d > 0` (a speculative contact: the body may
//!   close the gap within the step but not pass it, so it lands exactly on the plane), and
//! - `v_n ≥ -e v_n⁻` for a touching contact approaching faster than `2 |g| h` (restitution `e`
//!   of the approach speed `v_n⁻`), `v_n ≥ 0` below that speed, so resting bodies never bounce
//!   on the speed gravity gives them in one step.
//!
//! The contacts are solved island by island ([`Islands`]): bodies touching through moving
//! bodies, each swept until its contacts' speeds stop changing; an island that has not
//! converged within the sweeps is finished by shock propagation (Guendelman, Bridson &
//! Fedkiw 2003): layer by layer from the supports up, with the layers below held fixed.
//!
//! Penetration left after the velocity solve (the solve is iterative, so a tall stack is not
//! held exactly in one step) is removed by a separate position pass (nonlinear Gauss–Seidel on
//! the contact gaps, as Box2D v2 does): `β = 0.2` of the depth beyond `SLOP` per step, moved
//! as position and orientation corrections that leave the velocities alone. A velocity bias
//! (Baumgarte) would do the same job by adding kinetic energy, which makes a tall stack bounce.
//!
//! The narrow phases that find the contacts are in `rigid::narrow`.

use glam::{DMat3, DQuat, DVec3};

/// Penetration tolerated without correction (m).
pub const SLOP: f64 = 1e-4;
/// Fraction of the penetration beyond `SLOP` corrected per step.
pub const BAUMGARTE: f64 = 0.2;

/// One contact point of body `a` against a plane (`b` none) or against body `b`, with its
/// accumulated impulses.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug)]
pub(crate) struct Contact {
    /// Body, plane or other body, and feature: the same key in consecutive steps is the
    /// same contact.
    pub key: (usize, usize, usize),
    pub a: usize,
    pub b: Option<usize>,
    /// Contact point minus the centres of mass of `a` and `b` (m, world).
    pub ra: DVec3,
    pub rb: DVec3,
    /// Unit normal from `b` (or the plane) towards `a`.
    pub n: DVec3,
    pub t1: DVec3,
    pub t2: DVec3,
    /// Effective masses `1 / Σ (1/m + (r × d) · I⁻¹ (r × d))` along `n`, `t1`, `t2`.
    pub mass: [f64; 3],
    /// Their inverses, the compliances `Σ (1/m + (r × d) · I⁻¹ (r × d))` (m/s per N s).
    pub compliance: [f64; 3],
    /// Angular velocity change of `a` and of `b` per unit impulse along `n`, `t1`, `t2`:
    /// `I⁻¹ (r × d)` (world), fixed while the velocities are solved, so a sweep needs no
    /// rotation of inertia tensors.
    pub spin: [[DVec3; 3]; 2],
    /// Normal velocity change per unit impulse along `t1` and `t2` (the off-diagonal terms
    /// of the contact's 3 × 3 Delassus block; zero for a particle, not for a lever arm).
    pub coupling: [f64; 2],
    /// Lowest normal velocity allowed after the solve (m/s).
    pub target: f64,
    /// Gap along `n` at the start of the step, then after it (m; negative when overlapping).
    pub gap: f64,
    pub mu: f64,
    /// Accumulated impulses along `n`, `t1`, `t2` (N s).
    pub impulse: [f64; 3],
}

/// The dynamic quantities the solver reads per body: inverse mass (1/kg) and inverse inertia
/// tensor in world axes (1/(kg m²), [`world_inverse_inertias`]), both zero for a fixed body.
pub(crate) struct Bodies<'a> {
    pub inv_mass: &'a [f64],
    pub inv_inertia: &'a [DMat3],
}

/// The inverse inertia tensors in world axes, `R diag(1/I) Rᵀ` with `R` the rotation of each
/// body's principal frame `q` and `1/I` its inverse principal moments, into `out`: made once
/// per pose, so that each of a contact's responses is one matrix–vector product instead of
/// two quaternion rotations.
pub(crate) fn world_inverse_inertias(q: &[DQuat], inv_moments: &[DVec3], out: &mut Vec<DMat3>) {
    out.clear();
    out.extend(q.iter().zip(inv_moments).map(|(&q, &d)| {
        let r = DMat3::from_quat(q);
        DMat3::from_cols(r.x_axis * d.x, r.y_axis * d.y, r.z_axis * d.z) * r.transpose()
    }));
}

impl Bodies<'_> {
    /// `I⁻¹ w` in the world frame for body `i`.
    fn inv_inertia(&self, i: usize, w: DVec3) -> DVec3 {
        self.inv_inertia[i] * w
    }

    /// Fill the contact's angular responses (see [`Contact::spin`]), compliances, effective
    /// masses and normal–tangent couplings.
    pub fn prepare(&self, c: &mut Contact) {
        let dirs = [c.n, c.t1, c.t2];
        // The arms `r × d` of each body, made once for the spins, compliances and couplings.
        let arms = [dirs.map(|d| c.ra.cross(d)), dirs.map(|d| c.rb.cross(d))];
        c.spin[0] = arms[0].map(|arm| self.inv_inertia(c.a, arm));
        c.spin[1] = match c.b {
            Some(b) => arms[1].map(|arm| self.inv_inertia(b, arm)),
            None => [DVec3::ZERO; 3],
        };
        // `1/m + (r × d) · I⁻¹ (r × d)` of each body, `I⁻¹ (r × d)` being the spin just made.
        c.compliance = std::array::from_fn(|k| {
            let own = |i: usize, side: usize| self.inv_mass[i] + arms[side][k].dot(c.spin[side][k]);
            own(c.a, 0) + c.b.map_or(0.0, |b| own(b, 1))
        });
        c.mass = c.compliance.map(|k| if k > 0.0 { 1.0 / k } else { 0.0 });
        c.coupling = [1, 2].map(|d| arms[0][0].dot(c.spin[0][d]) + arms[1][0].dot(c.spin[1][d]));
    }

    /// Apply impulses `j` along `n`, `t1`, `t2` to `a` and their opposites to `b`, with the
    /// prepared responses.
    fn apply_prepared(&self, c: &Contact, j: [f64; 3], v: &mut [DVec3], w: &mut [DVec3]) {
        let p = j[0] * c.n + j[1] * c.t1 + j[2] * c.t2;
        let [sa, sb] = &c.spin;
        v[c.a] += p * self.inv_mass[c.a];
        w[c.a] += j[0] * sa[0] + j[1] * sa[1] + j[2] * sa[2];
        if let Some(b) = c.b {
            v[b] -= p * self.inv_mass[b];
            w[b] -= j[0] * sb[0] + j[1] * sb[1] + j[2] * sb[2];
        }
    }
}

/// Velocity of the contact point of `a` relative to `b`'s.
fn relative_velocity(c: &Contact, v: &[DVec3], w: &[DVec3]) -> DVec3 {
    let va = v[c.a] + w[c.a].cross(c.ra);
    va - c.b.map_or(DVec3::ZERO, |b| v[b] + w[b].cross(c.rb))
}

/// Start each contact from the impulses that the same contact ended the previous step with
/// (warm starting). The same contact is the one of the same pair of bodies (or body and
/// plane) whose lever arm on `a` is nearest, within 5 % of its length plus 1 mm: feature
/// numbers of clipped manifolds change when a face turns by a rounding error, positions do
/// not. Both lists are in the order the detection makes them — plane contacts by body, then
/// body pairs by `(a, b)` — so each pair's previous contacts are found by one merge.
/// Resting contacts then begin at their converged impulses, so a stack at rest stays at rest.
pub(crate) fn warm_start(contacts: &mut [Contact], previous: &[Contact]) {
    let pair = |c: &Contact| (c.b.is_some(), c.key.0, c.key.1);
    let mut start = 0;
    for c in contacts.iter_mut() {
        while start < previous.len() && pair(&previous[start]) < pair(c) {
            start += 1;
        }
        let limit = (0.05 * c.ra.length() + 1e-3).powi(2);
        let nearest = previous[start..]
            .iter()
            .take_while(|p| pair(p) == pair(c))
            .map(|p| ((p.ra - c.ra).length_squared(), p))
            .filter(|(d, _)| *d <= limit)
            .min_by(|x, y| x.0.total_cmp(&y.0));
        if let Some((_, p)) = nearest {
            c.impulse = p.impulse;
        }
    }
}

/// Apply the contacts' starting (warm) impulses to the velocities `v` (m/s) and angular
/// velocities `w` (rad/s, world) of the bodies.
pub(crate) fn apply_impulses(
    contacts: &[Contact],
    bodies: &Bodies<'_>,
    v: &mut [DVec3],
    w: &mut [DVec3],
) {
    for c in contacts {
        bodies.apply_prepared(c, c.impulse, v, w);
    }
}

/// One sweep of sequential impulses over all contacts ([`solve`] on each in turn), changing
/// the velocities in place: the sweep of worlds with joints, which share their sweeps with the
/// contacts and so do not stop island by island.
pub(crate) fn sweep(
    contacts: &mut [Contact],
    bodies: &Bodies<'_>,
    v: &mut [DVec3],
    w: &mut [DVec3],
) {
    for c in contacts.iter_mut() {
        solve(c, bodies, v, w);
    }
}

/// The friction update of contact `c` at relative velocity `vel`: the accumulated tangential
/// impulse clamped to the disc `μ λ_n` of the current normal impulse; returns its change.
fn friction(c: &mut Contact, vel: DVec3) -> [f64; 2] {
    let old = [c.impulse[1], c.impulse[2]];
    let mut t = [old[0] - c.mass[1] * vel.dot(c.t1), old[1] - c.mass[2] * vel.dot(c.t2)];
    let limit = c.mu * c.impulse[0];
    // Compared squared (`limit ≥ 0`): a contact inside the cone, as resting ones mostly are,
    // takes no square root (its latency was the sweep's longest wait).
    let squared = t[0] * t[0] + t[1] * t[1];
    if squared > limit * limit {
        let s = limit / squared.sqrt();
        t = [t[0] * s, t[1] * s];
    }
    c.impulse[1] = t[0];
    c.impulse[2] = t[1];
    [t[0] - old[0], t[1] - old[1]]
}

/// One sequential-impulse update of contact `c`: friction (see [`friction`]), then the normal
/// impulse, accumulated and kept non-negative, against the normal velocity the friction
/// update left ([`Contact::coupling`]), both applied together from one reading of the
/// velocities. Returns the largest speed change of the contact along `n`, `t1`, `t2` that
/// its own impulses made, `|Δλ| / m_eff` (m/s).
fn solve(c: &mut Contact, bodies: &Bodies<'_>, v: &mut [DVec3], w: &mut [DVec3]) -> f64 {
    let vel = relative_velocity(c, v, w);
    let dt = friction(c, vel);
    let vn = vel.dot(c.n) + c.coupling[0] * dt[0] + c.coupling[1] * dt[1];
    let new = (c.impulse[0] + c.mass[0] * (c.target - vn)).max(0.0);
    let dn = new - c.impulse[0];
    c.impulse[0] = new;
    bodies.apply_prepared(c, [dn, dt[0], dt[1]], v, w);
    let k = c.compliance;
    (dn.abs() * k[0]).max(dt[0].abs() * k[1]).max(dt[1].abs() * k[2])
}

/// The contacts grouped into islands: sets of bodies that touch each other directly or
/// through other moving bodies (planes and fixed bodies do not join islands). Contacts of
/// different islands share no moving body, so each island is solved on its own and stops
/// when it has converged, while a settling pile elsewhere keeps iterating (Box2D's islands).
#[derive(Clone, Debug, Default)]
pub(crate) struct Islands {
    /// Union–find forest over the bodies.
    parent: Vec<usize>,
    /// Start of each root body's island in `order` (empty ranges for other bodies).
    start: Vec<usize>,
    /// Contact indices, island by island, in detection order within an island.
    order: Vec<usize>,
    /// Workspaces of shock propagation ([`Islands::propagate_shock`]), rebuilt every step:
    /// contacts of the islands that did not converge; the supported ones of those as
    /// `(layer, contact)`, sorted (bottom up, by contact within a layer; each layer read once,
    /// not in every comparison of the sort); each body's layer (contact-graph depth from the
    /// supports); the bodies in breadth-first order; neighbours in compressed rows; inverse
    /// masses with the lower layers held fixed.
    unsettled: Vec<usize>,
    layered: Vec<(usize, usize)>,
    depth: Vec<usize>,
    queue: Vec<usize>,
    neighbours: (Vec<usize>, Vec<usize>),
    held: (Vec<f64>, Vec<DMat3>),
    layer: Vec<Contact>,
}

/// Layer of a body that no support reaches.
const UNSUPPORTED: usize = usize::MAX;

impl Islands {
    fn root(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    /// Group `contacts` among `n` bodies (`moving[i]` false for fixed bodies) into islands.
    pub fn build(&mut self, contacts: &[Contact], moving: impl Fn(usize) -> bool, n: usize) {
        self.parent.clear();
        self.parent.extend(0..n);
        for c in contacts {
            if let Some(b) = c.b {
                if moving(c.a) && moving(b) {
                    let (ra, rb) = (self.root(c.a), self.root(b));
                    self.parent[ra.max(rb)] = ra.min(rb);
                }
            }
        }
        self.start.clear();
        self.start.resize(n + 1, 0);
        for c in contacts {
            let body = if moving(c.a) { c.a } else { c.b.unwrap_or(c.a) };
            let r = self.root(body);
            self.start[r + 1] += 1;
        }
        for i in 0..n {
            self.start[i + 1] += self.start[i];
        }
        self.order.clear();
        self.order.resize(contacts.len(), 0);
        for (k, c) in contacts.iter().enumerate() {
            let body = if moving(c.a) { c.a } else { c.b.unwrap_or(c.a) };
            let r = self.root(body);
            self.order[self.start[r]] = k;
            self.start[r] += 1;
        }
        // `start[r]` now ends island `r`: shift back so that `start[r]..start[r + 1]` is it.
        self.start.rotate_right(1);
        self.start[0] = 0;
    }

    /// Sweep each island up to `sweeps` times, stopping it once no contact's speed changes by
    /// more than `tolerance` (m/s) in a sweep; the islands that did not converge then get
    /// [`Islands::propagate_shock`].
    pub fn solve(
        &mut self,
        contacts: &mut [Contact],
        bodies: &Bodies<'_>,
        sweeps: usize,
        tolerance: f64,
        v: &mut [DVec3],
        w: &mut [DVec3],
    ) {
        self.unsettled.clear();
        for island in self.start.windows(2).filter(|s| s[1] > s[0]) {
            let members = &self.order[island[0]..island[1]];
            let converged = (0..sweeps).any(|_| {
                let change = members.iter().fold(0.0_f64, |largest, &k| {
                    largest.max(solve(&mut contacts[k], bodies, v, w))
                });
                change <= tolerance
            });
            if !converged && sweeps > 0 {
                self.unsettled.extend_from_slice(members);
            }
        }
        if !self.unsettled.is_empty() {
            self.propagate_shock(contacts, bodies, sweeps, tolerance, v, w);
        }
    }

    /// Shock propagation (Guendelman, Bridson & Fedkiw 2003, "Nonconvex rigid bodies with
    /// stacking", SIGGRAPH, §7) over the contacts in `unsettled`: the bodies are layered by
    /// their contact-graph depth from the supports (layer 0 touches a plane or a fixed body,
    /// layer k + 1 touches layer k), and layer by layer from the bottom the contacts of that
    /// layer (with the supports, the layer below and each other) are swept until they
    /// converge (at most `sweeps` times) with every lower layer held fixed (infinite mass).
    /// Gauss–Seidel carries a stack's weight down by one layer per sweep; here each layer
    /// rests on a finished one, so after a sweep of the whole stack no body sinks into or
    /// slides on the one below, whatever its height. The held layers take no reaction, so
    /// this pass is a correction of velocities left unconverged, and the accumulated
    /// impulses it reaches warm-start the next step. Bodies that no support reaches keep the
    /// result of the ordinary sweeps.
    fn propagate_shock(
        &mut self,
        contacts: &mut [Contact],
        bodies: &Bodies<'_>,
        sweeps: usize,
        tolerance: f64,
        v: &mut [DVec3],
        w: &mut [DVec3],
    ) {
        self.layer_bodies(contacts, bodies);
        let moving = |i: usize| bodies.inv_mass[i] > 0.0;
        // The contacts by layer (that of their upper body), bottom up.
        let depth = &self.depth;
        let layer = |c: &Contact| {
            let of = |i: usize| if moving(i) { depth[i] } else { 0 };
            c.b.map_or(of(c.a), |b| of(c.a).max(of(b)))
        };
        self.layered.clear();
        self.layered.extend(
            self.unsettled
                .iter()
                .map(|&k| (layer(&contacts[k]), k))
                .filter(|&(level, _)| level != UNSUPPORTED),
        );
        self.layered.sort_unstable();
        let (inv_mass, inv_inertia) = &mut self.held;
        inv_mass.clear();
        inv_mass.extend_from_slice(bodies.inv_mass);
        inv_inertia.clear();
        inv_inertia.extend_from_slice(bodies.inv_inertia);
        let (mut from, mut frozen) = (0, 0);
        while from < self.layered.len() {
            let level = self.layered[from].0;
            let to = from + self.layered[from..].partition_point(|&(l, _)| l == level);
            // Hold every body below this layer.
            while frozen < self.queue.len() && depth[self.queue[frozen]] < level {
                inv_mass[self.queue[frozen]] = 0.0;
                inv_inertia[self.queue[frozen]] = DMat3::ZERO;
                frozen += 1;
            }
            // The layer's contacts, prepared for the held bodies, swept, and their impulses
            // kept (the originals keep their responses for the position pass).
            let held =
                Bodies { inv_mass: inv_mass.as_slice(), inv_inertia: inv_inertia.as_slice() };
            self.layer.clear();
            self.layer.extend(self.layered[from..to].iter().map(|&(_, k)| contacts[k]));
            for c in self.layer.iter_mut() {
                held.prepare(c);
            }
            for _ in 0..sweeps {
                let change = self
                    .layer
                    .iter_mut()
                    .fold(0.0_f64, |largest, c| largest.max(solve(c, &held, v, w)));
                if change <= tolerance {
                    break;
                }
            }
            for (c, &(_, k)) in self.layer.iter().zip(&self.layered[from..to]) {
                contacts[k].impulse = c.impulse;
            }
            from = to;
        }
    }
    /// The layers of shock propagation: each body's contact-graph depth from the supports
    /// (`depth`, [`UNSUPPORTED`] where none reaches) over the contacts in `unsettled`, and the
    /// bodies in breadth-first order (`queue`, so by layer).
    fn layer_bodies(&mut self, contacts: &[Contact], bodies: &Bodies<'_>) {
        let n = bodies.inv_mass.len();
        let moving = |i: usize| bodies.inv_mass[i] > 0.0;
        // Layers by breadth-first search from the bodies on a support.
        self.depth.clear();
        self.depth.resize(n, UNSUPPORTED);
        self.queue.clear();
        let (start, next) = &mut self.neighbours;
        start.clear();
        start.resize(n + 2, 0);
        for &k in &self.unsettled {
            let c = &contacts[k];
            match c.b {
                Some(b) if moving(c.a) && moving(b) => {
                    start[c.a + 2] += 1;
                    start[b + 2] += 1;
                }
                _ => {
                    let body = if moving(c.a) { c.a } else { c.b.unwrap_or(c.a) };
                    if self.depth[body] != 0 {
                        self.depth[body] = 0;
                        self.queue.push(body);
                    }
                }
            }
        }
        for i in 0..n {
            start[i + 2] += start[i + 1];
        }
        next.clear();
        next.resize(start[n + 1], 0);
        for &k in &self.unsettled {
            let c = &contacts[k];
            if let Some(b) = c.b.filter(|&b| moving(c.a) && moving(b)) {
                next[start[c.a + 1]] = b;
                start[c.a + 1] += 1;
                next[start[b + 1]] = c.a;
                start[b + 1] += 1;
            }
        }
        // `start[i]..start[i + 1]` now holds body i's neighbours.
        let mut head = 0;
        while head < self.queue.len() {
            let i = self.queue[head];
            head += 1;
            for &j in &next[start[i]..start[i + 1]] {
                if self.depth[j] == UNSUPPORTED {
                    self.depth[j] = self.depth[i] + 1;
                    self.queue.push(j);
                }
            }
        }
    }
}

/// Move each contact's gap to its value after the velocity step, `gap + h v_n`, to first order.
pub(crate) fn advance_gaps(contacts: &mut [Contact], h: f64, v: &[DVec3], w: &[DVec3]) {
    for c in contacts.iter_mut() {
        c.gap += h * relative_velocity(c, v, w).dot(c.n);
    }
}

/// Push overlapping contacts apart by changing positions only: `iterations` sweeps over the
/// contacts, each estimating its gap as the advanced gap (see [`advance_gaps`]) plus the
/// corrections made so far (`dx` translations, `dtheta` small world rotations, per body), and
/// moving the bodies by a mass-weighted pseudo-impulse that closes `β` of the depth beyond
/// `SLOP`; returns whether any contact pushed.
pub(crate) fn correct_positions(
    contacts: &[Contact],
    iterations: usize,
    bodies: &Bodies<'_>,
    dx: &mut [DVec3],
    dtheta: &mut [DVec3],
) -> bool {
    let mut pushed = false;
    for _ in 0..iterations {
        for c in contacts {
            let moved = |i: usize, r: DVec3| dx[i] + dtheta[i].cross(r);
            let rel = moved(c.a, c.ra) - c.b.map_or(DVec3::ZERO, |b| moved(b, c.rb));
            let push = BAUMGARTE * (-(c.gap + rel.dot(c.n)) - SLOP);
            if push <= 0.0 || c.mass[0] == 0.0 {
                continue;
            }
            pushed = true;
            let p = c.n * (push * c.mass[0]);
            dx[c.a] += p * bodies.inv_mass[c.a];
            dtheta[c.a] += bodies.inv_inertia(c.a, c.ra.cross(p));
            if let Some(b) = c.b {
                dx[b] -= p * bodies.inv_mass[b];
                dtheta[b] -= bodies.inv_inertia(b, c.rb.cross(p));
            }
        }
    }
    pushed
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The world inverse inertia undoes the world inertia `I w = q ((q̄ w) ⊙ I_k)` of
    /// rotated bodies with unequal principal moments (a transposed rotation fails this).
    #[test]
    fn world_inverse_inertias_invert_the_rotated_inertia() {
        let moments = [DVec3::new(0.5, 2.0, 7.0), DVec3::new(3.0, 0.1, 1.0)];
        let q = [
            DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7),
            DQuat::from_axis_angle(DVec3::new(-2.0, 0.5, 1.0).normalize(), 2.9),
        ];
        let inverse = moments.map(|m| DVec3::ONE / m);
        let mut out = Vec::new();
        world_inverse_inertias(&q, &inverse, &mut out);
        for i in 0..2 {
            let w = DVec3::new(0.3, -1.2, 0.8);
            let inertia_w = q[i] * ((q[i].conjugate() * w) * moments[i]);
            assert!((out[i] * inertia_w - w).length() < 1e-14, "body {i}");
        }
    }
}
