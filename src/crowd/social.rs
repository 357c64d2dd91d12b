//! Social forces: the acceleration of a pedestrian as the sum of a driving term towards its
//! preferred velocity (Helbing & Molnár 1995, "Social force model for pedestrian dynamics",
//! eq. 2) and the interactions of Helbing, Farkas & Vicsek (2000, "Simulating dynamical
//! features of escape panic", eqs. 1–3): with another pedestrian
//!
//! `f_ij = (A exp((r_ij - d_ij)/B) + k g(r_ij - d_ij)) n_ij + κ g(r_ij - d_ij) Δv_ji^t t_ij`,
//!
//! and with a wall
//!
//! `f_iW = (A exp((r_i - d_iW)/B) + k g(r_i - d_iW)) n_iW - κ g(r_i - d_iW) (v_i · t_iW) t_iW`,
//!
//! where `d` is the distance between centres (to the nearest point of the wall), `n` the unit
//! vector pointing to the pedestrian, `t` its tangent, `g(x) = max(x, 0)` (the body force
//! `k` and sliding friction `κ` act only on contact) and `Δv_ji^t = (v_j - v_i) · t_ij`. Each
//! obstacle polygon acts as one wall through its nearest point.
//!
//! Two options make the speed fall with density (the fundamental diagram, docs/crowd.md):
//! the anisotropy `λ` weights the exponential term of `f_ij` by
//! `w = λ + (1 - λ)(1 + cos φ)/2`, `cos φ = -n_ij · e_i` with `e_i` the desired direction
//! (Helbing & Molnár 1995, §2; continuous form of Helbing, Buzna, Johansson & Werner 2005,
//! eq. 3), and the time gap `b` replaces `r_ij` in it by `r_ij + b max(0, -v_i · n_ij)`, the
//! speed-dependent required length `d = a + b v` of Seyfried et al. 2005 along the line to
//! the other agent. The body and friction terms stay those of the touching discs.

use super::orca::{apart, segment_distance2};
use super::{Model, SocialForce};
use glam::DVec2;

/// The positions, velocities and preferred velocities the forces read (m, m/s).
pub(super) struct Agents<'a> {
    pub positions: &'a [DVec2],
    pub velocities: &'a [DVec2],
    pub preferred: &'a [DVec2],
}

/// The acceleration (m/s²) of agent `i` among `agents`; `candidates` are the agents within
/// the neighbour distance.
pub(super) fn acceleration(
    model: &Model,
    sf: &SocialForce,
    agents: &Agents<'_>,
    i: usize,
    candidates: &[u32],
) -> DVec2 {
    let r = model.settings.radius;
    let (p, v) = (agents.positions[i], agents.velocities[i]);
    let e = agents.preferred[i].normalize_or_zero();
    let mut f = sf.mass * (agents.preferred[i] - v) / sf.relaxation_time;
    for &j in candidates {
        let j = j as usize;
        let offset = p - agents.positions[j];
        let d = offset.length();
        let n = if d > 1e-12 * r { offset / d } else { apart(i, j) };
        let overlap = 2.0 * r - d;
        let contact = overlap.max(0.0);
        let t = n.perp();
        let slip = (agents.velocities[j] - v).dot(t);
        let weight = sf.anisotropy + (1.0 - sf.anisotropy) * 0.5 * (1.0 - n.dot(e));
        let reach = overlap + sf.time_gap * (-v.dot(n)).max(0.0);
        f += (weight * sf.strength * (reach / sf.range).exp() + sf.body * contact) * n
            + sf.friction * contact * slip * t;
    }
    let reach2 = model.settings.neighbour_distance * model.settings.neighbour_distance;
    for w in model.polygons.windows(2) {
        let (d2, nearest) = (w[0] as usize..w[1] as usize)
            .map(|k| {
                let a = &model.vertices[k];
                let b = model.vertices[a.next as usize].point;
                (segment_distance2(p, a.point, b), closest(p, a.point, b))
            })
            .fold((f64::INFINITY, p), |best, x| if x.0 < best.0 { x } else { best });
        if d2 >= reach2 || d2 == 0.0 {
            continue;
        }
        let d = d2.sqrt();
        let n = (p - nearest) / d;
        let overlap = r - d;
        let contact = overlap.max(0.0);
        let t = n.perp();
        f += (sf.strength * (overlap / sf.range).exp() + sf.body * contact) * n
            - sf.friction * contact * v.dot(t) * t;
    }
    f / sf.mass
}

/// The point of the segment `ab` nearest `p`.
fn closest(p: DVec2, a: DVec2, b: DVec2) -> DVec2 {
    let ab = b - a;
    a + ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0) * ab
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::crowd::{Kind, Settings};

    fn model() -> (Model, SocialForce) {
        let sf = SocialForce::default();
        let settings = Settings {
            radius: 0.3,
            neighbour_distance: 3.0,
            kind: Kind::SocialForce(sf),
            ..Settings::rvo2_circle()
        };
        (Model::new(settings).unwrap(), sf)
    }

    #[test]
    fn pair_force_is_the_papers_formula() {
        let (m, sf) = model();
        // Two agents 0.5 m apart (overlap 0.1 m), the second sliding past at 1 m/s.
        let pos = [DVec2::ZERO, DVec2::new(0.5, 0.0)];
        let vel = [DVec2::ZERO, DVec2::new(0.0, 1.0)];
        let pref = [DVec2::ZERO; 2];
        let agents = Agents { positions: &pos, velocities: &vel, preferred: &pref };
        let a = acceleration(&m, &sf, &agents, 0, &[1]);
        // n = (-1, 0), t = (0, -1), Δv^t = (0, 1)·t = -1.
        let push = 2000.0 * (0.1f64 / 0.08).exp() + 1.2e5 * 0.1;
        let want = DVec2::new(-push, 2.4e5 * 0.1) / 80.0; // κ g Δv^t t = κ 0.1 (-1) (0, -1)
        assert!((a - want).length() < 1e-9 * want.length(), "{a} vs {want}");
        // Newton's third law for the normal part.
        let b = acceleration(&m, &sf, &agents, 1, &[0]);
        assert!((a.x + b.x).abs() < 1e-9 * push);
    }

    #[test]
    fn anisotropy_weakens_the_push_from_behind_and_time_gap_lengthens_the_reach() {
        let (m, sf) = model();
        // Agent 0 walks +x at 1 m/s; agent 1 is 1 m ahead of it, agent 2 1 m behind.
        let pos = [DVec2::ZERO, DVec2::new(1.0, 0.0), DVec2::new(-1.0, 0.0)];
        let vel = [DVec2::new(1.0, 0.0), DVec2::ZERO, DVec2::ZERO];
        let pref = [DVec2::new(1.0, 0.0); 3];
        let agents = Agents { positions: &pos, velocities: &vel, preferred: &pref };
        let push = |sf: &SocialForce, j: u32| {
            // Less the driving term (zero here: v = v⁰).
            acceleration(&m, sf, &agents, 0, &[j]).x * sf.mass
        };
        let plain = 2000.0 * (-0.4f64 / 0.08).exp();
        let lam = SocialForce { anisotropy: 0.3, ..sf };
        assert!((push(&lam, 1) + plain).abs() < 1e-9 * plain, "from ahead: full");
        assert!((push(&lam, 2) - 0.3 * plain).abs() < 1e-9 * plain, "from behind: λ");
        // Time gap b: the reach grows by b (v · e) towards the one ahead, not the one behind.
        let gap = SocialForce { time_gap: 0.1, ..sf };
        let ahead = 2000.0 * ((-0.4f64 + 0.1) / 0.08).exp();
        assert!((push(&gap, 1) + ahead).abs() < 1e-9 * ahead);
        assert!((push(&gap, 2) - plain).abs() < 1e-9 * plain);
    }

    #[test]
    fn wall_force_pushes_out_along_the_normal_and_opposes_sliding() {
        let (mut m, sf) = model();
        m.add_obstacle(&[DVec2::new(-5.0, 0.0), DVec2::new(5.0, 0.0)]).unwrap();
        let pos = [DVec2::new(0.0, 0.2)];
        let vel = [DVec2::new(1.0, 0.0)];
        let agents = Agents { positions: &pos, velocities: &vel, preferred: &vel };
        let a = acceleration(&m, &sf, &agents, 0, &[]);
        let push = 2000.0 * (0.1f64 / 0.08).exp() + 1.2e5 * 0.1;
        let want = DVec2::new(-2.4e5 * 0.1 * 1.0, push) / 80.0;
        assert!((a - want).length() < 1e-9 * want.length(), "{a} vs {want}");
    }
}
