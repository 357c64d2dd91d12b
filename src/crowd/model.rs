//! The crowd model: what every step reads and none changes — the agents' common size and
//! speeds, ORCA's neighbourhood and time horizons, the social-force parameters, and the static
//! polygon obstacles with the vertex data of RVO2's obstacle handling (each vertex knows its
//! neighbours, its edge's direction and whether it is convex).

use super::lp::det;
use super::navigation::Roadmap;
use crate::error::{Error, Result};
use glam::DVec2;

/// Which behaviour model moves the agents.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    /// Optimal reciprocal collision avoidance (van den Berg et al. 2011): each step, every
    /// agent takes the permitted velocity closest to its preferred one.
    Orca,
    /// Social forces (Helbing & Molnár 1995; Helbing, Farkas & Vicsek 2000), integrated by
    /// semi-implicit Euler in substeps.
    SocialForce(SocialForce),
}

/// The social-force parameters, defaults those of Helbing, Farkas & Vicsek (2000).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct SocialForce {
    /// Mass of an agent `m` (kg), 80.
    pub mass: f64,
    /// Relaxation time `τ` of the driving term `m (v₀ e - v) / τ` (s), 0.5.
    pub relaxation_time: f64,
    /// Strength `A` of the exponential repulsion (N), 2000.
    pub strength: f64,
    /// Range `B` of the exponential repulsion (m), 0.08.
    pub range: f64,
    /// Body stiffness `k` against overlap (kg/s²), 1.2·10⁵.
    pub body: f64,
    /// Sliding friction `κ` (kg/(m·s)), 2.4·10⁵.
    pub friction: f64,
    /// Longest substep (s), 0.005: a step of `dt` takes `ceil(dt / max_substep)` substeps.
    pub max_substep: f64,
    /// Anisotropy `λ` in [0, 1] of the exponential repulsion (Helbing & Molnár 1995, §2,
    /// weaker forces from behind; the continuous form `w = λ + (1 - λ)(1 + cos φ)/2` of
    /// Helbing, Buzna, Johansson & Werner 2005, eq. 3), `φ` the angle between the agent's
    /// desired direction and the direction to the other: full force from ahead, `λ` times it
    /// from behind. 1 (default): isotropic, as Helbing, Farkas & Vicsek 2000.
    pub anisotropy: f64,
    /// Time gap `b` (s) of the speed-dependent required length `d = a + b v` of Seyfried,
    /// Steffen, Klingsch & Boltes 2005 (`a` = the two radii here): the exponential repulsion
    /// from another agent acts as if the bodies were `b max(0, v_i · e_ij)` larger, `e_ij`
    /// the unit vector to the other, so an agent keeps a headway that grows with its speed
    /// towards the one ahead. 0 (default): off.
    pub time_gap: f64,
}

impl Default for SocialForce {
    fn default() -> Self {
        SocialForce {
            mass: 80.0,
            relaxation_time: 0.5,
            strength: 2000.0,
            range: 0.08,
            body: 1.2e5,
            friction: 2.4e5,
            max_substep: 0.005,
            anisotropy: 1.0,
            time_gap: 0.0,
        }
    }
}

/// Settings shared by every agent.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Agent radius `r` (m).
    pub radius: f64,
    /// Largest speed an agent takes (m/s).
    pub max_speed: f64,
    /// Speed `v₀` at which an agent wants to walk to its goal (m/s).
    pub preferred_speed: f64,
    /// Agents farther apart than this ignore each other (m; ORCA's neighbour distance, the
    /// social forces' cut-off).
    pub neighbour_distance: f64,
    /// ORCA: at most this many nearest neighbours are avoided.
    pub max_neighbours: usize,
    /// ORCA: time horizon `τ` against other agents (s).
    pub time_horizon: f64,
    /// ORCA: time horizon against obstacles (s).
    pub obstacle_time_horizon: f64,
    /// An agent has arrived when it is closer than this to its goal (m).
    pub goal_tolerance: f64,
    /// ORCA: length of the deterministic perturbation added to every preferred velocity
    /// each step (m/s; 0 turns it off), in a direction hashed from `seed`, the step count and
    /// the agent's index. Exactly symmetric starts (agents evenly on a circle) otherwise
    /// deadlock; RVO2's examples perturb the preferred velocity by up to 10⁻⁴ for this.
    pub perturbation: f64,
    /// ORCA: seed of the perturbation's directions.
    pub seed: u64,
    /// ORCA: the agents plan (their half-planes against each other) with the radius
    /// `r (1 + planning_margin)` (dimensionless, ≥ 0), while the separation and the collision
    /// counts keep `r`: a personal space of `planning_margin · r` metres round each body that
    /// ORCA keeps clear while its programs are feasible (0.025 m for a pedestrian of radius
    /// 0.25 m). Default 0.1 (`rvo2_circle` and Python's `Crowd`): on RVO2's 250-agent circle
    /// the mean time to goal over ten perturbation seeds is then 678 s, RVO2's 678 s, against
    /// 855 s with 0; on the ring corridor the speeds are nearer Weidmann's (docs/crowd.md,
    /// "Planning margin").
    #[serde(default)]
    pub planning_margin: f64,
    /// The behaviour model.
    pub kind: Kind,
}

impl Settings {
    /// RVO2's circle-crossing set-up (its example): radius 1.5 m, max speed 2 m/s, neighbour
    /// distance 15 m, 10 neighbours, horizons 10 s / 10 s; preferred speed 1 m/s (the example
    /// clips the goal vector to 1), goal tolerance one radius, no perturbation (seed 0); and
    /// kinema's planning margin 0.1.
    pub fn rvo2_circle() -> Self {
        Settings {
            radius: 1.5,
            max_speed: 2.0,
            preferred_speed: 1.0,
            neighbour_distance: 15.0,
            max_neighbours: 10,
            time_horizon: 10.0,
            obstacle_time_horizon: 10.0,
            goal_tolerance: 1.5,
            perturbation: 0.0,
            seed: 0,
            planning_margin: 0.1,
            kind: Kind::Orca,
        }
    }

    fn validate(&self) -> Result<()> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        let checks: [(&str, bool); 7] = [
            ("radius", positive(self.radius)),
            ("max_speed", positive(self.max_speed)),
            ("preferred_speed", positive(self.preferred_speed)),
            ("neighbour_distance", positive(self.neighbour_distance)),
            ("time_horizon", positive(self.time_horizon)),
            ("obstacle_time_horizon", positive(self.obstacle_time_horizon)),
            ("goal_tolerance", positive(self.goal_tolerance)),
        ];
        for (arg, ok) in checks {
            if !ok {
                return Err(Error::invalid(arg, "must be finite and > 0"));
            }
        }
        for (arg, v) in
            [("perturbation", self.perturbation), ("planning_margin", self.planning_margin)]
        {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(arg, "must be finite and >= 0"));
            }
        }
        if self.max_neighbours > 1024 {
            return Err(Error::invalid("max_neighbours", "must be at most 1024"));
        }
        if let Kind::SocialForce(s) = self.kind {
            let params = [
                ("mass", s.mass),
                ("relaxation_time", s.relaxation_time),
                ("strength", s.strength),
                ("range", s.range),
                ("max_substep", s.max_substep),
            ];
            for (arg, v) in params {
                if !positive(v) {
                    return Err(Error::invalid(arg, "must be finite and > 0"));
                }
            }
            if !(0.0..=1.0).contains(&s.anisotropy) {
                return Err(Error::invalid("anisotropy", "must be in [0, 1]"));
            }
            for (arg, v) in [("body", s.body), ("friction", s.friction), ("time_gap", s.time_gap)] {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(Error::invalid(arg, "must be finite and >= 0"));
                }
            }
        }
        Ok(())
    }
}

/// A vertex of an obstacle polygon, with RVO2's data for it.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Vertex {
    /// Position (m).
    pub point: DVec2,
    /// Unit direction of the edge from this vertex to the next.
    pub direction: DVec2,
    /// Index of the next vertex of the polygon.
    pub next: u32,
    /// Index of the previous vertex of the polygon.
    pub previous: u32,
    /// Whether the polygon turns left (or goes straight on) at this vertex; the two ends of
    /// a segment count as convex.
    pub convex: bool,
}

/// A crowd model (see the module docs); read-only during a step, several
/// [`super::State`]s may share it.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct Model {
    pub(super) settings: Settings,
    /// Every obstacle's vertices, polygon after polygon; edge `k` runs from vertex `k` to
    /// vertex `vertices[k].next`.
    pub(super) vertices: Vec<Vertex>,
    /// Start of each polygon in `vertices` (one more entry than polygons).
    pub(super) polygons: Vec<u32>,
    /// The global navigation layer, if on: the roadmap of the obstacles.
    pub(super) navigation: Option<Roadmap>,
}

impl Model {
    /// A model without obstacles.
    ///
    /// # Errors
    /// A setting out of its range (named).
    pub fn new(settings: Settings) -> Result<Self> {
        settings.validate()?;
        Ok(Model { settings, vertices: Vec::new(), polygons: vec![0], navigation: None })
    }

    /// Turn the global navigation layer on, with paths keeping `clearance` (m) from the
    /// obstacles (at least the agent radius is sensible), or off (`None`): agents then head
    /// for the next waypoint of their shortest path around the obstacles instead of straight
    /// for their goal ([`Roadmap`], `navigation.rs`).
    ///
    /// # Errors
    /// A clearance not finite and > 0 (`clearance`).
    pub fn set_navigation(&mut self, clearance: Option<f64>) -> Result<()> {
        if let Some(c) = clearance {
            if !(c.is_finite() && c > 0.0) {
                return Err(Error::invalid("clearance", "must be finite and > 0"));
            }
        }
        self.navigation = clearance.map(|c| Roadmap::new(self, c));
        Ok(())
    }

    /// The navigation roadmap, if navigation is on.
    pub fn navigation(&self) -> Option<&Roadmap> {
        self.navigation.as_ref()
    }

    /// The settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The obstacle vertices, polygon after polygon.
    pub fn vertices(&self) -> &[Vertex] {
        &self.vertices
    }

    /// Number of obstacle polygons.
    pub fn obstacles(&self) -> usize {
        self.polygons.len() - 1
    }

    /// Add a static obstacle: a polygon of two or more vertices (m) listed
    /// **counterclockwise** (agents stay outside; clockwise keeps them inside, as a room's
    /// walls), or a two-vertex wall segment, avoidable from both sides (RVO2's convention).
    ///
    /// # Errors
    /// Fewer than two vertices, a non-finite vertex, or two consecutive vertices closer than
    /// 1 µm (`polygon`, with the index).
    pub fn add_obstacle(&mut self, polygon: &[DVec2]) -> Result<()> {
        let n = polygon.len();
        if n < 2 {
            return Err(Error::invalid("polygon", "needs at least two vertices"));
        }
        if let Some(i) = polygon.iter().position(|p| !p.is_finite()) {
            return Err(Error::invalid("polygon", "contains NaN or infinity").at(i));
        }
        for i in 0..n {
            if (polygon[(i + 1) % n] - polygon[i]).length() < 1e-6 {
                return Err(Error::invalid("polygon", "two consecutive vertices coincide").at(i));
            }
        }
        if self.vertices.len() + n >= u32::MAX as usize / 2 {
            return Err(Error::invalid("polygon", "too many obstacle vertices"));
        }
        let base = self.vertices.len();
        for i in 0..n {
            let (prev, next) = ((i + n - 1) % n, (i + 1) % n);
            let turn = det(polygon[i] - polygon[prev], polygon[next] - polygon[i]);
            self.vertices.push(Vertex {
                point: polygon[i],
                direction: (polygon[next] - polygon[i]).normalize(),
                next: (base + next) as u32,
                previous: (base + prev) as u32,
                convex: n == 2 || turn >= 0.0,
            });
        }
        self.polygons.push(self.vertices.len() as u32);
        if let Some(c) = self.navigation.as_ref().map(Roadmap::clearance) {
            self.navigation = Some(Roadmap::new(self, c));
        }
        Ok(())
    }

    /// A deterministic 64-bit hash of the model ([`crate::snapshot::fingerprint`]), recorded
    /// by state snapshots so that a state is restored only onto its model.
    pub fn fingerprint(&self) -> u64 {
        crate::snapshot::fingerprint(self)
    }

    /// The polygons as given to [`Model::add_obstacle`] (used to check a decoded model).
    pub(super) fn polygon_points(&self) -> impl Iterator<Item = Vec<DVec2>> + '_ {
        self.polygons
            .windows(2)
            .map(|w| self.vertices[w[0] as usize..w[1] as usize].iter().map(|v| v.point).collect())
    }
}
