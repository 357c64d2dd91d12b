//! The fluid model: what every step reads and no step changes — the settings (spacing, rest
//! density, kernel, viscosity, pressure solver and its tolerances, time-step limits, gravity),
//! the particle mass and volume derived from them, and the walls with their boundary
//! particles and Akinci volumes, the colliders' boundary particles in their own frames, the
//! emitters and the kill box.

use super::boundary::{offset, volumes, Wall};
use super::collider::{sample, Body, Collider};
use super::emitter::{validate_kill_box, Emitter};
use super::Kernel;
use crate::error::{Error, Result};
use glam::DVec3;

/// The pressure solver and its parameters.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub enum Pressure {
    /// Divergence-free SPH (Bender & Koschier 2015, 2017): a divergence-free solve then a
    /// constant-density solve per substep, each a Jacobi iteration on the pressures.
    Dfsph {
        /// The mean density error (compression, in percent of the rest density) at which the
        /// constant-density solve stops (default 0.05).
        density_tolerance: f64,
        /// The mean density change per substep due to the velocity divergence (percent) at
        /// which the divergence-free solve stops (default 0.1).
        divergence_tolerance: f64,
        /// The most iterations of each solve per substep (default 100).
        max_iterations: usize,
    },
    /// Position-based fluids (Macklin & Müller 2013): per substep, predict the positions
    /// under gravity, then Jacobi iterations on the density constraints `C_i = ρ̂_i - 1 ≤ 0`
    /// move them (`λ_i = -C_i α_i`, eq. 11, with the DFSPH factor `α` as the denominator),
    /// with the tensile-instability term `s_corr` (eq. 13-14); velocities from the
    /// displacement, then XSPH viscosity.
    Pbf {
        /// The mean density error (compression, percent) at which the iterations stop
        /// (default 0.05).
        density_tolerance: f64,
        /// The most iterations per substep (default 100).
        max_iterations: usize,
        /// `k` of the artificial pressure `s_corr = -k (W(r) / W(0.2 h))⁴` (eq. 14, `n = 4`,
        /// `Δq = 0.2 h`), read as a compression of the pair (default 0.1; 0 turns it off).
        tensile: f64,
    },
    /// Weakly compressible SPH (Becker & Teschner 2007): pressure from the Tait equation
    /// `p = ρ₀ c² / γ ((ρ/ρ₀)^γ - 1)` (clamped at 0), `γ = 7`.
    Wcsph {
        /// The numerical speed of sound `c` (m/s, default 30): density errors are about
        /// `(v/c)²`, and the substep shrinks as `1/c`.
        sound_speed: f64,
    },
}

impl Pressure {
    /// DFSPH with its defaults (0.05 % density error, 0.1 % divergence error, 100 iterations).
    pub const DFSPH: Pressure =
        Pressure::Dfsph { density_tolerance: 0.05, divergence_tolerance: 0.1, max_iterations: 100 };
    /// PBF with its defaults (0.05 % density error, 100 iterations, `k = 0.1`).
    pub const PBF: Pressure =
        Pressure::Pbf { density_tolerance: 0.05, max_iterations: 100, tensile: 0.1 };
    /// WCSPH with a speed of sound of 30 m/s.
    pub const WCSPH: Pressure = Pressure::Wcsph { sound_speed: 30.0 };
}

/// The viscosity model and its coefficient.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub enum Viscosity {
    /// XSPH (dimensionless, in [0, 1]): each substep moves a particle's velocity this
    /// fraction towards the kernel-weighted mean of its neighbours' (Schechter & Bridson
    /// 2012, eq. 11; SPlisHSPlasH's `Viscosity_XSPH`). Not a physical viscosity: its effect
    /// depends on the spacing and the substep.
    Xsph(f64),
    /// The kinematic viscosity `ν` (m²/s; water 1e-6, honey about 1e-2) of the implicit
    /// solve of Weiler, Koschier, Brochard & Bender (2018) (the `viscosity` module): no-slip
    /// walls and colliders, stable at any substep.
    Implicit(f64),
}

/// What a fluid is made of and how it is stepped; [`Settings::new`] gives the defaults.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Distance between neighbouring particles at rest (m); the kernel's support radius is
    /// twice it (as in SPlisHSPlasH: four particle radii).
    pub spacing: f64,
    /// Rest density `ρ₀` (kg/m³, default 1000).
    pub rest_density: f64,
    /// The smoothing kernel (default cubic spline).
    pub kernel: Kernel,
    /// The viscosity (default XSPH 0.01).
    pub viscosity: Viscosity,
    /// Surface tension `γ` of Akinci, Akinci & Teschner (2013, eq. 1-6), default 0 (off):
    /// the acceleration `a_i = -γ Σ_j K_ij [m_j C(r_ij) x̂_ij + (n_i - n_j)]` with
    /// `K_ij = 2ρ₀ / (ρ_i + ρ_j)`, the cohesion spline `C` ([`super::kernel::cohesion`],
    /// 1/m³) and the outward normals `n_i = -h Σ_j (m_j / ρ_j) ∇W_ij` (dimensionless). As in the paper
    /// (and SPlisHSPlasH) one number scales both terms, so `γ` is in m⁴/(kg s²) for the
    /// cohesion and m/s² for the curvature term: it is not the physical `σ` in N/m.
    pub surface_tension: f64,
    /// The pressure solver (default DFSPH).
    pub pressure: Pressure,
    /// Courant number: a substep moves no particle more than `cfl` spacings (default 0.4).
    pub cfl: f64,
    /// The longest substep (s, default 0.005).
    pub max_dt: f64,
    /// The most substeps one frame may take before the step fails (default 10000).
    pub max_substeps: usize,
    /// Gravity (m/s², default `(0, -9.81, 0)`).
    pub gravity: DVec3,
}

impl Settings {
    /// The defaults for particles `spacing` apart (m).
    pub fn new(spacing: f64) -> Self {
        Settings {
            spacing,
            rest_density: 1000.0,
            kernel: Kernel::CubicSpline,
            viscosity: Viscosity::Xsph(0.01),
            surface_tension: 0.0,
            pressure: Pressure::DFSPH,
            cfl: 0.4,
            max_dt: 0.005,
            max_substeps: 10_000,
            gravity: DVec3::new(0.0, -9.81, 0.0),
        }
    }

    fn validate(&self) -> Result<()> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        let checks: [(&str, bool, &str); 7] = [
            ("spacing", positive(self.spacing), "must be finite and > 0"),
            ("rest_density", positive(self.rest_density), "must be finite and > 0"),
            match self.viscosity {
                Viscosity::Xsph(c) => ("viscosity", (0.0..=1.0).contains(&c), "must be in [0, 1]"),
                Viscosity::Implicit(nu) => {
                    ("viscosity", nu.is_finite() && nu >= 0.0, "must be finite and >= 0 (m²/s)")
                }
            },
            (
                "surface_tension",
                self.surface_tension.is_finite() && self.surface_tension >= 0.0,
                "must be finite and >= 0",
            ),
            ("cfl", self.cfl > 0.0 && self.cfl <= 1.0, "must be in (0, 1]"),
            ("max_dt", positive(self.max_dt), "must be finite and > 0"),
            ("gravity", self.gravity.is_finite(), "must be finite"),
        ];
        for (arg, ok, why) in checks {
            if !ok {
                return Err(Error::invalid(arg, why));
            }
        }
        if self.max_substeps == 0 {
            return Err(Error::invalid("max_substeps", "must be at least 1"));
        }
        match self.pressure {
            Pressure::Dfsph { density_tolerance, divergence_tolerance, max_iterations } => {
                if !positive(density_tolerance) {
                    return Err(Error::invalid("density_tolerance", "must be finite and > 0"));
                }
                if !positive(divergence_tolerance) {
                    return Err(Error::invalid("divergence_tolerance", "must be finite and > 0"));
                }
                if max_iterations == 0 {
                    return Err(Error::invalid("max_iterations", "must be at least 1"));
                }
            }
            Pressure::Pbf { density_tolerance, max_iterations, tensile } => {
                if !positive(density_tolerance) {
                    return Err(Error::invalid("density_tolerance", "must be finite and > 0"));
                }
                if max_iterations == 0 {
                    return Err(Error::invalid("max_iterations", "must be at least 1"));
                }
                if !(0.0..=1.0).contains(&tensile) {
                    return Err(Error::invalid("tensile", "must be in [0, 1]"));
                }
            }
            Pressure::Wcsph { sound_speed } => {
                if !positive(sound_speed) {
                    return Err(Error::invalid("sound_speed", "must be finite and > 0"));
                }
            }
        }
        Ok(())
    }
}

/// A fluid model (see the module docs): read-only during a step (`&Model`); several
/// [`super::State`]s may share it.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct Model {
    pub(super) settings: Settings,
    /// The kernel's support radius `h = 2 spacing` (m).
    pub(super) support: f64,
    /// Volume of a fluid particle `V = m / ρ₀` (m³), such that a cubic lattice of the spacing
    /// has exactly the rest density: `V = 1 / Σ_k W(x_k)` over the lattice points `x_k`.
    pub(super) volume: f64,
    /// How far behind a wall's surface its boundary particles lie (m; see
    /// `boundary::offset`).
    pub(super) offset: f64,
    /// The walls, in the order added.
    pub(super) walls: Vec<Wall>,
    /// The boundary particles of every wall (m).
    pub(super) boundary: Vec<DVec3>,
    /// The Akinci volumes `V_b` (m³) of the walls' boundary particles, then of each
    /// collider's (in the order of `colliders`), the order of the solver's boundary points.
    pub(super) boundary_volume: Vec<f64>,
    /// The colliders' sizes and boundary particles in their own frames, in the order added
    /// (their poses are state).
    pub(super) colliders: Vec<Body>,
    /// The emitters, in the order added.
    pub(super) emitters: Vec<Emitter>,
    /// The kill box `(lower, upper)` (m): particles outside it are removed.
    pub(super) kill_box: Option<(DVec3, DVec3)>,
}

impl Model {
    /// A model without walls.
    ///
    /// # Errors
    /// A setting out of its range (named).
    pub fn new(settings: Settings) -> Result<Self> {
        settings.validate()?;
        let (s, h) = (settings.spacing, 2.0 * settings.spacing);
        let mut sum = 0.0;
        for k in -2i32..=2 {
            for j in -2i32..=2 {
                for i in -2i32..=2 {
                    let r = s * f64::from(i * i + j * j + k * k).sqrt();
                    sum += settings.kernel.value(r, h);
                }
            }
        }
        Ok(Model {
            settings,
            support: h,
            volume: 1.0 / sum,
            offset: offset(settings.kernel, s, h, 1.0 / sum),
            walls: Vec::new(),
            boundary: Vec::new(),
            boundary_volume: Vec::new(),
            colliders: Vec::new(),
            emitters: Vec::new(),
            kill_box: None,
        })
    }

    /// The DFSPH factor `α` (m²) of a particle inside a lattice of the spacing at rest:
    /// `1 / Σ_k |V ∇W(x_k)|²` (the gradients' sum vanishes by symmetry).
    pub(super) fn lattice_factor(&self) -> f64 {
        let (s, h) = (self.settings.spacing, self.support);
        let mut sum = 0.0;
        for k in -2i32..=2 {
            for j in -2i32..=2 {
                for i in -2i32..=2 {
                    let x = DVec3::new(f64::from(i), f64::from(j), f64::from(k)) * s;
                    sum += (self.settings.kernel.gradient(x, h) * self.volume).length_squared();
                }
            }
        }
        1.0 / sum
    }

    /// The settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The kernel's support radius (m), twice the spacing.
    pub fn support(&self) -> f64 {
        self.support
    }

    /// The mass of a fluid particle (kg): `ρ₀ V` (see [`Model`]'s `volume`).
    pub fn particle_mass(&self) -> f64 {
        self.settings.rest_density * self.volume
    }

    /// The walls, in the order added.
    pub fn walls(&self) -> &[Wall] {
        &self.walls
    }

    /// The boundary particles (m), `(B, 3)`.
    pub fn boundary_particles(&self) -> &[DVec3] {
        &self.boundary
    }

    /// Add a wall, sample it with boundary particles one spacing apart (behind its surface,
    /// see the `boundary` module) and recompute every
    /// boundary particle's volume (walls that meet share their neighbours).
    ///
    /// # Errors
    /// A wall with non-finite values, a box narrower than two spacings, a plane's normal not
    /// unit or a square smaller than the spacing (each named).
    pub fn add_wall(&mut self, wall: Wall) -> Result<()> {
        wall.validate(self.settings.spacing)?;
        let mut boundary = self.boundary.clone();
        wall.sample(self.settings.spacing, self.offset, &mut boundary);
        let moving = self.boundary_volume.len() - self.boundary.len();
        if boundary.len() + moving >= u32::MAX as usize / 2 {
            return Err(Error::invalid("upper", "the wall needs too many boundary particles"));
        }
        let mut all = Vec::new();
        volumes(&boundary, self.settings.kernel, self.support, &mut all);
        all.extend_from_slice(&self.boundary_volume[self.boundary.len()..]);
        self.boundary_volume = all;
        self.boundary = boundary;
        self.walls.push(wall);
        Ok(())
    }

    /// Add a collider (see the `collider` module): sample it in its own frame and give its
    /// boundary particles Akinci volumes over its own particles. `collider` must have been
    /// checked ([`Collider::checked`]); its pose is the state's.
    ///
    /// # Errors
    /// More boundary particles than the limit of 2³¹ (`shape`).
    pub(super) fn add_collider(&mut self, collider: &Collider) -> Result<()> {
        let points = sample(&collider.shape, self.settings.spacing, self.offset);
        if self.boundary_volume.len() + points.len() >= u32::MAX as usize / 2 {
            return Err(Error::invalid("shape", "the collider needs too many boundary particles"));
        }
        let mut v = Vec::new();
        volumes(&points, self.settings.kernel, self.support, &mut v);
        self.boundary_volume.extend_from_slice(&v);
        self.colliders.push(Body { shape: collider.shape, points });
        Ok(())
    }

    /// Keep only the first `count` colliders (a scene's undo of colliders added in a failed
    /// frame); their states must be truncated too ([`super::Fluid::truncate_colliders`]).
    pub(super) fn truncate_colliders(&mut self, count: usize) {
        if count < self.colliders.len() {
            let kept: usize = self.colliders[..count].iter().map(|b| b.points.len()).sum();
            self.boundary_volume.truncate(self.boundary.len() + kept);
            self.colliders.truncate(count);
        }
    }

    /// The number of colliders.
    pub fn colliders(&self) -> usize {
        self.colliders.len()
    }

    /// Every collider's boundary particles at the poses of `colliders` (one per collider of
    /// the model, m), appended to `out` in the order of the model's boundary volumes.
    pub(super) fn place_colliders(&self, colliders: &[Collider], out: &mut Vec<DVec3>) {
        for (body, c) in self.colliders.iter().zip(colliders) {
            super::collider::place(body, c, out);
        }
    }

    /// The emitters, in the order added.
    pub fn emitters(&self) -> &[Emitter] {
        &self.emitters
    }

    /// Add an emitter (see the `emitter` module).
    ///
    /// # Errors
    /// Non-finite values, a direction not unit, a speed not > 0, a radius under half a
    /// spacing (each named).
    pub fn add_emitter(&mut self, emitter: Emitter) -> Result<()> {
        emitter.validate(self.settings.spacing)?;
        self.emitters.push(emitter);
        Ok(())
    }

    /// The kill box `(lower, upper)` (m), if any.
    pub fn kill_box(&self) -> Option<(DVec3, DVec3)> {
        self.kill_box
    }

    /// Remove every particle that is outside `[lower, upper]` (m) at the end of a substep
    /// (replacing an earlier kill box).
    ///
    /// # Errors
    /// Non-finite corners (`lower`), `lower` not below `upper` on every axis (`upper`).
    pub fn set_kill_box(&mut self, lower: DVec3, upper: DVec3) -> Result<()> {
        validate_kill_box(lower, upper)?;
        self.kill_box = Some((lower, upper));
        Ok(())
    }

    /// A deterministic 64-bit hash of the model ([`crate::snapshot::fingerprint`]), recorded
    /// by state snapshots so that a state is not restored onto another model.
    pub fn fingerprint(&self) -> u64 {
        crate::snapshot::fingerprint(self)
    }
}
