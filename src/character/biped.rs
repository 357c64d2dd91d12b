//! The planar 7-link biped of SIMBICON (Yin, Loken & van de Panne 2007, §3 and Table 1: the
//! 2-D model): a torso on a planar root joint, two legs of thigh, shin and foot on hinges
//! about z. Masses and lengths are the paper's (torso 70 kg, 0.48 m; thigh 5 kg, 0.45 m;
//! shin 4 kg, 0.42 m; foot 1 kg, 0.2 m); the links are uniform boxes of the widths below
//! (our choice) for their inertias, and each foot touches the ground at heel and toe (a
//! capsule of radius [`SOLE_RADIUS`] between them).
//!
//! Axes: x forward, y up, z out of the plane (positive angles turn a hanging leg forward; a
//! bent knee has a negative angle, a lifted toe a positive ankle angle).

use super::model::{Body, Capsule, Joint, Model, Settings};
use crate::error::Result;
use glam::{DMat3, DVec3};

/// Body indices of [`planar_biped`]: the torso (root), then the right leg, then the left.
pub const TORSO: usize = 0;
/// Thigh, shin and foot of the right leg (the first to swing).
pub const RIGHT: [usize; 3] = [1, 2, 3];
/// Thigh, shin and foot of the left leg.
pub const LEFT: [usize; 3] = [4, 5, 6];
/// Torso length (m), from the hips up.
pub const TORSO_LENGTH: f64 = 0.48;
/// Thigh length (m), hip to knee.
pub const THIGH_LENGTH: f64 = 0.45;
/// Shin length (m), knee to ankle.
pub const SHIN_LENGTH: f64 = 0.42;
/// Foot length (m), heel to toe.
pub const FOOT_LENGTH: f64 = 0.2;
/// Height of the sole below the ankle (m).
pub const ANKLE_HEIGHT: f64 = 0.07;
/// Radius of the heel and toe contact spheres (m).
pub const SOLE_RADIUS: f64 = 0.02;
/// How far the heel is behind the ankle (m).
pub const HEEL: f64 = 0.05;

/// Side of the square cross-section (m) of the torso, thigh, shin and foot boxes.
const WIDTHS: [f64; 4] = [0.2, 0.1, 0.08, 0.06];

/// The box drawn for each body of [`planar_biped`], in its body frame: centre and half
/// extents (m). The torso, thighs and shins are the uniform boxes whose inertias the model
/// uses (length along y, the square cross-sections of [`WIDTHS`], centred at the centre of
/// mass); a foot is laid along x from heel to toe and reaches from the ankle down to the
/// sole ([`ANKLE_HEIGHT`]), [`WIDTHS`]`[3]` across (for drawing: its inertia is the box of
/// the same length and width along y, whose moment about z is the same up to the height).
pub fn link_boxes() -> [(DVec3, DVec3); 7] {
    let leg = |length: f64, width: f64| {
        (DVec3::new(0.0, -length / 2.0, 0.0), DVec3::new(width, length, width) / 2.0)
    };
    let foot = (
        DVec3::new(FOOT_LENGTH / 2.0 - HEEL, -ANKLE_HEIGHT / 2.0, 0.0),
        DVec3::new(FOOT_LENGTH, ANKLE_HEIGHT, WIDTHS[3]) / 2.0,
    );
    let [thigh, shin] = [leg(THIGH_LENGTH, WIDTHS[1]), leg(SHIN_LENGTH, WIDTHS[2])];
    let torso = (
        DVec3::new(0.0, TORSO_LENGTH / 2.0, 0.0),
        DVec3::new(WIDTHS[0], TORSO_LENGTH, WIDTHS[0]) / 2.0,
    );
    [torso, thigh, shin, foot, thigh, shin, foot]
}

/// Inertia (kg m², about the centre) of a uniform box of `mass` (kg), `length` along y and a
/// square cross-section of side `width` (m).
fn box_inertia(mass: f64, length: f64, width: f64) -> DMat3 {
    let across = mass * (length * length + width * width) / 12.0;
    DMat3::from_diagonal(DVec3::new(across, mass * width * width / 6.0, across))
}

fn link(name: &str, parent: Option<usize>, joint: Joint, offset: DVec3, mass: f64) -> Body {
    Body {
        name: name.into(),
        parent,
        joint,
        offset,
        mass,
        com: DVec3::ZERO,
        inertia: DMat3::IDENTITY,
        shape: None,
        limits: None,
        damping: 0.0,
        servo: None,
    }
}

/// The planar SIMBICON biped with `settings`, standing upright in its zero pose with its
/// hips at the origin (lift it by setting the root's `y` to [`hip_height`]). Coordinates:
/// `[x, y, θ]` of the torso (hips), then hip, knee and ankle angles of the right leg, then
/// of the left (rad).
///
/// # Errors
/// None for valid settings (the bodies are fixed); the `Result` is that of
/// [`Model::add_body`].
pub fn planar_biped(settings: Settings) -> Result<Model> {
    let mut model = Model::new(settings);
    let hinge = Joint::Revolute { axis: DVec3::Z };
    let down = |l: f64| DVec3::new(0.0, -l, 0.0);
    let torso = Body {
        com: DVec3::new(0.0, TORSO_LENGTH / 2.0, 0.0),
        inertia: box_inertia(70.0, TORSO_LENGTH, WIDTHS[0]),
        ..link("torso", None, Joint::Planar, DVec3::ZERO, 70.0)
    };
    model.add_body(torso)?;
    for side in ["right", "left"] {
        let thigh = Body {
            com: down(THIGH_LENGTH / 2.0),
            inertia: box_inertia(5.0, THIGH_LENGTH, WIDTHS[1]),
            ..link(&format!("{side}_thigh"), Some(TORSO), hinge, DVec3::ZERO, 5.0)
        };
        let t = model.add_body(thigh)?;
        let shin = Body {
            com: down(SHIN_LENGTH / 2.0),
            inertia: box_inertia(4.0, SHIN_LENGTH, WIDTHS[2]),
            ..link(&format!("{side}_shin"), Some(t), hinge, down(THIGH_LENGTH), 4.0)
        };
        let s = model.add_body(shin)?;
        let y = -(ANKLE_HEIGHT - SOLE_RADIUS);
        let foot = Body {
            com: DVec3::new(FOOT_LENGTH / 2.0 - HEEL, -ANKLE_HEIGHT / 2.0, 0.0),
            inertia: box_inertia(1.0, FOOT_LENGTH, WIDTHS[3]),
            shape: Some(Capsule {
                a: DVec3::new(-HEEL, y, 0.0),
                b: DVec3::new(FOOT_LENGTH - HEEL, y, 0.0),
                radius: SOLE_RADIUS,
            }),
            ..link(&format!("{side}_foot"), Some(s), hinge, down(SHIN_LENGTH), 1.0)
        };
        model.add_body(foot)?;
    }
    Ok(model)
}

/// Height of the hips (m) of the straight biped with its soles on y = 0.
pub fn hip_height() -> f64 {
    THIGH_LENGTH + SHIN_LENGTH + ANKLE_HEIGHT
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_drawn_boxes_are_the_inertia_boxes_and_the_feet_reach_the_sole() {
        let model = planar_biped(Settings::default()).unwrap();
        for (body, (centre, half)) in model.bodies().iter().zip(link_boxes()) {
            if body.name.ends_with("foot") {
                assert!((centre.y - half.y + ANKLE_HEIGHT).abs() < 1e-15);
                assert!((centre.x - half.x + HEEL).abs() < 1e-15);
                continue;
            }
            assert!((centre - body.com).length() < 1e-15, "{}", body.name);
            let inertia = box_inertia(body.mass, 2.0 * half.y, 2.0 * half.x);
            assert!(inertia.abs_diff_eq(body.inertia, 1e-15), "{}", body.name);
        }
    }
}
