//! Contacts between bodies and static planes and between bodies: detection (a
//! sweep-and-prune broad phase on bounding spheres, then per-shape-pair narrow phases) and an
//! impulse response with restitution and Coulomb friction.
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
//! Narrow phases between bodies: sphere–sphere, sphere–box (closest point), box–box (the
//! corners of each box against the other: exact for face contacts, which stacks and piles
//! have; an edge crossing an edge is not detected), capsules as swept spheres (closest points
//! of the segments, and the segment ends and middle against a box). Cylinders and meshes
//! collide with planes only.

use crate::geometry::Solid;
use glam::{DQuat, DVec3};

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

/// The points of `shape` (body frame, about the body origin) that can touch a plane of
/// normal `n` first, in world coordinates for a body at `origin` turned by `orient`.
///
/// Spheres and capsules give their lowest surface point(s); boxes their corners; meshes their
/// vertices; a cylinder the lowest point of each rim, and three more rim points per cap when
/// the cap lies within 5° of the plane (so it can stand on it).
pub(crate) fn candidate_points(
    shape: &Solid,
    origin: DVec3,
    orient: DQuat,
    n: DVec3,
    out: &mut Vec<DVec3>,
) {
    let world = |p: DVec3| origin + orient * p;
    match shape {
        Solid::Sphere { radius } => out.push(origin - *radius * n),
        Solid::Capsule { radius, height } => {
            for s in [-0.5, 0.5] {
                out.push(world(DVec3::new(0.0, s * height, 0.0)) - *radius * n);
            }
        }
        Solid::Box { half_extents } => out.extend(corners(origin, orient, *half_extents)),
        Solid::Cylinder { radius, height } => {
            let axis = orient * DVec3::Y;
            let radial = n - n.dot(axis) * axis;
            let u = if radial.length() > 1e-9 {
                -radial.normalize()
            } else {
                axis.any_orthonormal_vector()
            };
            let flat = n.dot(axis).abs() > 5f64.to_radians().cos();
            for s in [-0.5, 0.5] {
                let c = world(DVec3::new(0.0, s * height, 0.0));
                out.push(c + *radius * u);
                if flat {
                    let v = axis.cross(u);
                    out.extend([c + *radius * v, c - *radius * u, c - *radius * v]);
                }
            }
        }
        Solid::Mesh { vertices, .. } => out.extend(vertices.iter().map(|&p| world(p))),
    }
}

/// The dynamic quantities the solver reads per body: inverse mass and inverse principal
/// moments (zero for a fixed body) and the principal frame.
pub(crate) struct Bodies<'a> {
    pub inv_mass: &'a [f64],
    pub inv_moments: &'a [DVec3],
    pub q: &'a [DQuat],
}

impl Bodies<'_> {
    /// `I⁻¹ w` in the world frame for body `i`.
    fn inv_inertia(&self, i: usize, w: DVec3) -> DVec3 {
        self.q[i] * ((self.q[i].conjugate() * w) * self.inv_moments[i])
    }

    /// `1/m + (r × d) · I⁻¹ (r × d)` of body `i`.
    fn compliance(&self, i: usize, r: DVec3, d: DVec3) -> f64 {
        let rd = r.cross(d);
        self.inv_mass[i] + rd.dot(self.inv_inertia(i, rd))
    }

    /// Fill the contact's angular responses (see [`Contact::spin`]), compliances, effective
    /// masses and normal–tangent couplings.
    pub fn prepare(&self, c: &mut Contact) {
        let dirs = [c.n, c.t1, c.t2];
        c.spin[0] = dirs.map(|d| self.inv_inertia(c.a, c.ra.cross(d)));
        c.spin[1] = match c.b {
            Some(b) => dirs.map(|d| self.inv_inertia(b, c.rb.cross(d))),
            None => [DVec3::ZERO; 3],
        };
        c.compliance = dirs.map(|d| {
            self.compliance(c.a, c.ra, d) + c.b.map_or(0.0, |b| self.compliance(b, c.rb, d))
        });
        c.mass = c.compliance.map(|k| if k > 0.0 { 1.0 / k } else { 0.0 });
        let (arm_a, arm_b) = (c.ra.cross(c.n), c.rb.cross(c.n));
        c.coupling = [1, 2].map(|d| arm_a.dot(c.spin[0][d]) + arm_b.dot(c.spin[1][d]));
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

    /// Velocity of the contact point of `a` relative to `b`'s.
    fn relative_velocity(&self, c: &Contact, v: &[DVec3], w: &[DVec3]) -> DVec3 {
        let va = v[c.a] + w[c.a].cross(c.ra);
        va - c.b.map_or(DVec3::ZERO, |b| v[b] + w[b].cross(c.rb))
    }
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
    let len = (t[0] * t[0] + t[1] * t[1]).sqrt();
    if len > limit {
        let s = if len > 0.0 { limit / len } else { 0.0 };
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
    let vel = bodies.relative_velocity(c, v, w);
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
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, Default)]
pub(crate) struct Islands {
    /// Union–find forest over the bodies.
    parent: Vec<usize>,
    /// Start of each root body's island in `order` (empty ranges for other bodies).
    start: Vec<usize>,
    /// Contact indices, island by island, in detection order within an island.
    order: Vec<usize>,
    /// Workspaces of shock propagation ([`Islands::propagate_shock`]), rebuilt every step:
    /// contacts of the islands that did not converge, then sorted by layer; each body's
    /// layer (contact-graph depth from the supports); the bodies in breadth-first order;
    /// neighbours in compressed rows; inverse masses with the lower layers held fixed.
    #[serde(skip)]
    unsettled: Vec<usize>,
    #[serde(skip)]
    depth: Vec<usize>,
    #[serde(skip)]
    queue: Vec<usize>,
    #[serde(skip)]
    neighbours: (Vec<usize>, Vec<usize>),
    #[serde(skip)]
    held: (Vec<f64>, Vec<DVec3>),
    #[serde(skip)]
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
        // The contacts by layer (that of their upper body), bottom up.
        let depth = &self.depth;
        let layer = |c: &Contact| {
            let of = |i: usize| if moving(i) { depth[i] } else { 0 };
            c.b.map_or(of(c.a), |b| of(c.a).max(of(b)))
        };
        self.unsettled.retain(|&k| layer(&contacts[k]) != UNSUPPORTED);
        self.unsettled.sort_unstable_by_key(|&k| (layer(&contacts[k]), k));
        let (inv_mass, inv_moments) = &mut self.held;
        inv_mass.clear();
        inv_mass.extend_from_slice(bodies.inv_mass);
        inv_moments.clear();
        inv_moments.extend_from_slice(bodies.inv_moments);
        let (mut from, mut frozen) = (0, 0);
        while from < self.unsettled.len() {
            let level = layer(&contacts[self.unsettled[from]]);
            let to =
                from + self.unsettled[from..].partition_point(|&k| layer(&contacts[k]) == level);
            // Hold every body below this layer.
            while frozen < self.queue.len() && depth[self.queue[frozen]] < level {
                inv_mass[self.queue[frozen]] = 0.0;
                inv_moments[self.queue[frozen]] = DVec3::ZERO;
                frozen += 1;
            }
            // The layer's contacts, prepared for the held bodies, swept, and their impulses
            // kept (the originals keep their responses for the position pass).
            let held = Bodies {
                inv_mass: inv_mass.as_slice(),
                inv_moments: inv_moments.as_slice(),
                q: bodies.q,
            };
            self.layer.clear();
            self.layer.extend(self.unsettled[from..to].iter().map(|&k| contacts[k]));
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
            for (c, &k) in self.layer.iter().zip(&self.unsettled[from..to]) {
                contacts[k].impulse = c.impulse;
            }
            from = to;
        }
    }
}

/// Move each contact's gap to its value after the velocity step, `gap + h v_n`, to first order.
pub(crate) fn advance_gaps(
    contacts: &mut [Contact],
    bodies: &Bodies<'_>,
    h: f64,
    v: &[DVec3],
    w: &[DVec3],
) {
    for c in contacts.iter_mut() {
        c.gap += h * bodies.relative_velocity(c, v, w).dot(c.n);
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

/// A shape placed in the world, as the narrow phase sees it.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug)]
pub(crate) enum Placed {
    Sphere {
        c: DVec3,
        r: f64,
    },
    Capsule {
        p0: DVec3,
        p1: DVec3,
        r: f64,
    },
    Box {
        c: DVec3,
        q: DQuat,
        h: DVec3,
    },
    /// Cylinders and meshes: no body–body contacts.
    Other,
}

impl Placed {
    /// `shape` (body frame about the body origin) at `origin`, turned by `orient`.
    pub fn new(shape: &Solid, origin: DVec3, orient: DQuat) -> Self {
        match shape {
            Solid::Sphere { radius } => Placed::Sphere { c: origin, r: *radius },
            Solid::Capsule { radius, height } => {
                let a = orient * DVec3::new(0.0, 0.5 * height, 0.0);
                Placed::Capsule { p0: origin - a, p1: origin + a, r: *radius }
            }
            Solid::Box { half_extents } => Placed::Box { c: origin, q: orient, h: *half_extents },
            _ => Placed::Other,
        }
    }
}

/// A contact found by a narrow phase: world point, unit normal from the second shape towards
/// the first, and signed gap (negative when they overlap).
pub(crate) type Touch = (DVec3, DVec3, f64);

fn closest_on_segment(p0: DVec3, p1: DVec3, x: DVec3) -> DVec3 {
    let d = p1 - p0;
    let l2 = d.length_squared();
    if l2 == 0.0 {
        return p0;
    }
    p0 + d * ((x - p0).dot(d) / l2).clamp(0.0, 1.0)
}

/// Closest points of segments `[p0, p1]` and `[q0, q1]` (Ericson, *Real-Time Collision
/// Detection*, §5.1.9).
fn closest_segments(p0: DVec3, p1: DVec3, q0: DVec3, q1: DVec3) -> (DVec3, DVec3) {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, f) = (d1.length_squared(), d2.length_squared(), d2.dot(r));
    let (s, t);
    if a <= 1e-300 && e <= 1e-300 {
        return (p0, q0);
    }
    if a <= 1e-300 {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(r);
        if e <= 1e-300 {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(d2);
            let denom = a * e - b * b;
            let mut s0 =
                if denom > 1e-12 * a * e { ((b * f - c * e) / denom).clamp(0.0, 1.0) } else { 0.0 };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    (p0 + d1 * s, q0 + d2 * t)
}

fn spheres(ca: DVec3, ra: f64, cb: DVec3, rb: f64) -> Touch {
    let d = ca - cb;
    let dist = d.length();
    let n = if dist > 1e-12 { d / dist } else { DVec3::Y };
    (cb + n * rb, n, dist - ra - rb)
}

/// A sphere (centre `c`, radius `r`) against a box: the box's closest point, or the face of
/// least penetration when the centre is inside.
fn sphere_box(c: DVec3, r: f64, bc: DVec3, bq: DQuat, h: DVec3) -> Touch {
    let local = bq.conjugate() * (c - bc);
    let clamped = local.clamp(-h, h);
    if clamped != local {
        let d = local - clamped;
        let dist = d.length();
        let n = bq * (d / dist);
        (bc + bq * clamped, n, dist - r)
    } else {
        let depth = h - local.abs();
        let axis = if depth.x <= depth.y && depth.x <= depth.z {
            0
        } else if depth.y <= depth.z {
            1
        } else {
            2
        };
        let sign = if local[axis] >= 0.0 { 1.0 } else { -1.0 };
        let mut face = local;
        face[axis] = sign * h[axis];
        let n = bq * (DVec3::AXES[axis] * sign);
        (bc + bq * face, n, -depth[axis] - r)
    }
}

fn corners(c: DVec3, q: DQuat, h: DVec3) -> [DVec3; 8] {
    std::array::from_fn(|i| {
        let sign = |b: usize| if i & b == 0 { -1.0 } else { 1.0 };
        c + q * DVec3::new(sign(1) * h.x, sign(2) * h.y, sign(4) * h.z)
    })
}

type PlacedBox = (DVec3, DQuat, DVec3);

/// The face of box `(c, q, h)` whose outward normal is closest to `n`: its axis index and sign.
fn face_towards(q: DQuat, n: DVec3) -> (usize, f64) {
    let local = q.conjugate() * n;
    let k = local.abs().max_position();
    (k, local[k].signum())
}

/// Box–box contacts: the separating axis of least overlap among the six face normals
/// (Gottschalk et al. 1996, faces only) gives the normal `n` (from `b` towards `a`) and the
/// reference face; the incident face of the other box (the one facing it most) is clipped
/// against the reference face's four side planes (Sutherland–Hodgman), and every clipped
/// point within `margin` of the reference plane is a contact — the manifold of Box2D and ODE.
/// When an axis `A_i × B_j` of an edge of each box separates clearly better than every face
/// (two boxes crossing edge on edge), the contact is instead the single pair of closest points
/// of those two edges (feature `16 + 3i + j`), as in ODE's `dBoxBox`.
fn box_box(a: PlacedBox, b: PlacedBox, margin: f64, out: &mut Vec<(usize, Touch)>) {
    let (ca, qa, ha) = a;
    let (cb, qb, hb) = b;
    let d = ca - cb;
    let radius = |q: DQuat, h: DVec3, l: DVec3| (q.conjugate() * l).abs().dot(h);
    // Least overlap among each box's face axes; b's face is the reference only when clearly
    // better (Box2D's tolerances), so resting contacts keep their reference face and warm
    // starting finds them again.
    let least = |q: DQuat| {
        (0..3)
            .map(|k| {
                let axis = q * DVec3::AXES[k];
                let gap = d.dot(axis).abs() - radius(qa, ha, axis) - radius(qb, hb, axis);
                (gap, if d.dot(axis) >= 0.0 { axis } else { -axis })
            })
            .fold((f64::NEG_INFINITY, DVec3::Y), |best, g| if g.0 > best.0 { g } else { best })
    };
    let (from_a, from_b) = (least(qa), least(qb));
    let best = if from_b.0 > 0.95 * from_a.0 + 0.01 * ha.min_element() {
        (from_b.0, from_b.1, false)
    } else {
        (from_a.0, from_a.1, true)
    };
    let (gap, n, reference_is_a) = best;
    if gap > margin {
        return;
    }
    // Edge–edge axes; preferred over the faces only when clearly better, like b's faces.
    let mut edge = (f64::NEG_INFINITY, DVec3::Y, 0, 0);
    for i in 0..3 {
        for j in 0..3 {
            let axis = (qa * DVec3::AXES[i]).cross(qb * DVec3::AXES[j]);
            let len = axis.length();
            if len < 1e-6 {
                continue; // parallel edges: a face axis separates as well
            }
            let axis = axis / len;
            let g = d.dot(axis).abs() - radius(qa, ha, axis) - radius(qb, hb, axis);
            if g > edge.0 {
                edge = (g, if d.dot(axis) >= 0.0 { axis } else { -axis }, i, j);
            }
        }
    }
    if edge.0 > margin {
        return; // separated along an edge axis
    }
    if edge.0 > 0.95 * gap + 0.01 * ha.min_element().min(hb.min_element()) {
        let (g, n, i, j) = edge;
        // Each box's edge along its axis i (j) that lies furthest towards the other box.
        let supporting = |c: DVec3, q: DQuat, h: DVec3, k: usize, toward: DVec3| {
            let mut mid = c;
            for m in (0..3).filter(|&m| m != k) {
                let axis = q * DVec3::AXES[m];
                mid += axis * (h[m] * axis.dot(toward).signum());
            }
            let half = q * DVec3::AXES[k] * h[k];
            (mid - half, mid + half)
        };
        let (a0, a1) = supporting(ca, qa, ha, i, -n);
        let (b0, b1) = supporting(cb, qb, hb, j, n);
        let (pa, pb) = closest_segments(a0, a1, b0, b1);
        out.push((16 + 3 * i + j, (0.5 * (pa + pb), n, g)));
        return;
    }
    // Reference box and its face's outward normal; the incident box.
    let ((cr, qr, hr), m, (ci, qi, hi)) = if reference_is_a { (a, -n, b) } else { (b, n, a) };
    let (k, sign) = face_towards(qr, m);
    let (j1, j2) = ((k + 1) % 3, (k + 2) % 3);
    let face_center = cr + m * hr[k];
    let (u, w) = (qr * DVec3::AXES[j1], qr * DVec3::AXES[j2]);
    debug_assert!((qr * DVec3::AXES[k] * sign - m).length() < 1e-9);
    // The incident face: the face of the other box facing the reference face most.
    let (ki, si) = face_towards(qi, -m);
    let (i1, i2) = ((ki + 1) % 3, (ki + 2) % 3);
    let fc = ci + qi * (DVec3::AXES[ki] * (si * hi[ki]));
    let (e1, e2) = (qi * DVec3::AXES[i1] * hi[i1], qi * DVec3::AXES[i2] * hi[i2]);
    let mut poly = [DVec3::ZERO; 8];
    poly[..4].copy_from_slice(&[fc - e1 - e2, fc + e1 - e2, fc + e1 + e2, fc - e1 + e2]);
    let mut len = 4;
    for (dir, extent) in [(u, hr[j1]), (-u, hr[j1]), (w, hr[j2]), (-w, hr[j2])] {
        let mut clipped = [DVec3::ZERO; 8];
        let mut count = 0;
        let dist = |p: DVec3| dir.dot(p - face_center) - extent;
        for i in 0..len {
            let (p, q) = (poly[i], poly[(i + 1) % len]);
            let (dp, dq) = (dist(p), dist(q));
            if dp <= 0.0 {
                clipped[count] = p;
                count += 1;
            }
            if ((dp < 0.0 && dq > 0.0) || (dp > 0.0 && dq < 0.0)) && count < 8 {
                clipped[count] = p + (q - p) * (dp / (dp - dq));
                count += 1;
            }
        }
        poly = clipped;
        len = count;
    }
    let first = if reference_is_a { 0 } else { 8 };
    let mut kept = [(0, DVec3::ZERO, 0.0); 8];
    let mut count = 0;
    for (i, &p) in poly[..len].iter().enumerate() {
        let g = m.dot(p - face_center);
        if g < margin {
            kept[count] = (first + i, p, g);
            count += 1;
        }
    }
    for &(k, p, g) in reduce_manifold(&mut kept[..count], m, 0.8 * u + 0.6 * w) {
        out.push((k, (p, n, g)));
    }
}

/// At most four of the clipped points `kept` (feature, point, gap) of a face manifold of
/// normal `m`, moved to the front and returned: the one furthest along `along` (a fixed
/// direction in the reference face), the one furthest from it, and the two spanning the
/// largest triangles with those on either side — the quadrilateral that holds the weight as
/// the whole polygon does, with fewer redundant contacts for the solver (Gregorius 2015,
/// "Robust contact creation for physics simulations", GDC). The first point is taken along a
/// fixed direction rather than as the deepest: depths of a resting face differ by rounding,
/// and a choice that flips between steps loses the warm start (boxes at rest in the benchmark
/// were kicked to 1e-3 m/s now and then).
fn reduce_manifold(
    kept: &mut [(usize, DVec3, f64)],
    m: DVec3,
    along: DVec3,
) -> &[(usize, DVec3, f64)] {
    if kept.len() <= 4 {
        return kept;
    }
    let argmax = |kept: &[(usize, DVec3, f64)], from: usize, f: &dyn Fn(DVec3, f64) -> f64| {
        (from..kept.len())
            .max_by(|&i, &j| f(kept[i].1, kept[i].2).total_cmp(&f(kept[j].1, kept[j].2)))
    };
    let first = argmax(kept, 0, &|p, _| p.dot(along)).unwrap_or(0);
    kept.swap(0, first);
    let p0 = kept[0].1;
    let far = argmax(kept, 1, &|p, _| (p - p0).length_squared()).unwrap_or(1);
    kept.swap(1, far);
    let edge = kept[1].1 - p0;
    let area = |p: DVec3| m.dot(edge.cross(p - p0));
    let left = argmax(kept, 2, &|p, _| area(p)).unwrap_or(2);
    kept.swap(2, left);
    let right = argmax(kept, 3, &|p, _| -area(p)).unwrap_or(3);
    kept.swap(3, right);
    &kept[..4]
}

/// Contacts between two placed shapes within `margin` (normals from `b` towards `a`), pushed
/// to `out` with a feature index each.
pub(crate) fn touches(a: &Placed, b: &Placed, margin: f64, out: &mut Vec<(usize, Touch)>) {
    let mut push = |k: usize, t: Touch| {
        if t.2 < margin {
            out.push((k, t));
        }
    };
    let flip = |(p, n, g): Touch| (p, -n, g);
    match (*a, *b) {
        (Placed::Sphere { c: ca, r: ra }, Placed::Sphere { c: cb, r: rb }) => {
            push(0, spheres(ca, ra, cb, rb))
        }
        (Placed::Sphere { c, r }, Placed::Box { c: bc, q, h }) => {
            push(0, sphere_box(c, r, bc, q, h))
        }
        (Placed::Box { c: bc, q, h }, Placed::Sphere { c, r }) => {
            push(0, flip(sphere_box(c, r, bc, q, h)))
        }
        (Placed::Box { c: ca, q: qa, h: ha }, Placed::Box { c: cb, q: qb, h: hb }) => {
            box_box((ca, qa, ha), (cb, qb, hb), margin, out)
        }
        (Placed::Capsule { p0, p1, r }, Placed::Sphere { c, r: rs }) => {
            push(0, spheres(closest_on_segment(p0, p1, c), r, c, rs))
        }
        (Placed::Sphere { c, r: rs }, Placed::Capsule { p0, p1, r }) => {
            push(0, spheres(c, rs, closest_on_segment(p0, p1, c), r))
        }
        (Placed::Capsule { p0, p1, r: ra }, Placed::Capsule { p0: q0, p1: q1, r: rb }) => {
            let (x, y) = closest_segments(p0, p1, q0, q1);
            push(0, spheres(x, ra, y, rb));
            // The ends too, so capsules lying side by side rest on two points.
            push(1, spheres(p0, ra, closest_on_segment(q0, q1, p0), rb));
            push(2, spheres(p1, ra, closest_on_segment(q0, q1, p1), rb));
        }
        (Placed::Capsule { p0, p1, r }, Placed::Box { c, q, h }) => {
            for (k, p) in [p0, 0.5 * (p0 + p1), p1].into_iter().enumerate() {
                push(k, sphere_box(p, r, c, q, h));
            }
        }
        (Placed::Box { c, q, h }, Placed::Capsule { p0, p1, r }) => {
            for (k, p) in [p0, 0.5 * (p0 + p1), p1].into_iter().enumerate() {
                push(k, flip(sphere_box(p, r, c, q, h)));
            }
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boxes_crossing_edge_on_edge_touch_at_the_crossing_with_the_edges_normal() {
        // A unit box turned 45° about z (an edge along z on top) below a unit box turned 45°
        // about x (an edge along x at the bottom), overlapping by 1 cm at the crossing.
        let s = std::f64::consts::SQRT_2 * 0.5;
        let quarter = 0.25 * std::f64::consts::PI;
        let lower = (DVec3::ZERO, DQuat::from_rotation_z(quarter), DVec3::splat(0.5));
        let upper = (
            DVec3::new(0.0, 2.0 * s - 0.01, 0.0),
            DQuat::from_rotation_x(quarter),
            DVec3::splat(0.5),
        );
        let mut out = Vec::new();
        box_box(upper, lower, 0.0, &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        let (feature, (p, n, g)) = out[0];
        assert!(feature >= 16);
        assert!((n - DVec3::Y).length() < 1e-12, "normal {n}");
        assert!((g + 0.01).abs() < 1e-12, "gap {g}");
        assert!((p - DVec3::new(0.0, s - 0.005, 0.0)).length() < 1e-12, "point {p}");
        // Face on face still gives the clipped face manifold.
        let flat = (DVec3::new(0.0, 0.99, 0.0), DQuat::IDENTITY, DVec3::splat(0.5));
        out.clear();
        box_box(flat, (DVec3::ZERO, DQuat::IDENTITY, DVec3::splat(0.5)), 0.0, &mut out);
        assert_eq!(out.len(), 4);
        assert!(out.iter().all(|(k, _)| *k < 16));
    }

    #[test]
    fn a_turned_box_on_a_box_rests_on_four_points_spanning_most_of_the_overlap() {
        // A unit box turned 0.35 rad about y, 1 mm into another: the clipped face is an
        // octagon; the four kept points lie on it at the gap and span at least 80 % of it.
        let lower = (DVec3::ZERO, DQuat::IDENTITY, DVec3::splat(0.5));
        let upper = (DVec3::new(0.0, 0.999, 0.0), DQuat::from_rotation_y(0.35), DVec3::splat(0.5));
        let mut out = Vec::new();
        box_box(upper, lower, 0.0, &mut out);
        assert_eq!(out.len(), 4, "{out:?}");
        for (_, (p, n, g)) in &out {
            assert!((n - DVec3::Y).length() < 1e-12 && (g + 1e-3).abs() < 1e-12);
            assert!((p.y - 0.499).abs() < 1e-12 || (p.y - 0.5).abs() < 1e-12, "{p}");
        }
        // Area of the kept quadrilateral (in x–z, its corners in angular order).
        let mut hull: Vec<DVec3> = out.iter().map(|(_, (p, _, _))| *p).collect();
        let c = hull.iter().sum::<DVec3>() / 4.0;
        hull.sort_by(|a, b| (a.z - c.z).atan2(a.x - c.x).total_cmp(&(b.z - c.z).atan2(b.x - c.x)));
        let area = |ps: &[DVec3]| {
            (0..ps.len())
                .map(|i| {
                    let (a, b) = (ps[i], ps[(i + 1) % ps.len()]);
                    a.x * b.z - b.x * a.z
                })
                .sum::<f64>()
                .abs()
                * 0.5
        };
        // The octagon's area: the overlap of the two squares counted on a 400 × 400 grid.
        let inside = |x: f64, z: f64| {
            let (s, co) = 0.35f64.sin_cos();
            let (u, v) = (co * x - s * z, s * x + co * z);
            x.abs() <= 0.5 && z.abs() <= 0.5 && u.abs() <= 0.5 && v.abs() <= 0.5
        };
        let m = 400;
        let cells = (0..m * m)
            .filter(|k| {
                let x = ((k % m) as f64 + 0.5) / m as f64 - 0.5;
                let z = ((k / m) as f64 + 0.5) / m as f64 - 0.5;
                inside(x, z)
            })
            .count();
        let overlap = cells as f64 / (m * m) as f64;
        assert!(area(&hull) > 0.8 * overlap, "{} of {overlap}", area(&hull));
    }
}
