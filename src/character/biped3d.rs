//! The 3-D SIMBICON biped (Yin, Loken & van de Panne 2007, §5 "3D walking"): a torso (with
//! the pelvis) on a free root, two legs of thigh, shin and foot on a ball hip, a hinge knee
//! and a ball ankle. Masses and lengths are the planar model's ([`super::biped`]: torso
//! 70 kg, 0.48 m; thigh 5 kg, 0.45 m; shin 4 kg, 0.42 m; foot 1 kg, 0.2 m); the hips are
//! [`HIP_WIDTH`] apart and the links are uniform boxes of the sizes below (our choice).
//!
//! A foot is two bodies: the heel half (0.5 kg, on the ankle) and the toe half (0.5 kg,
//! welded to it by a fixed joint), each with a capsule across the foot ([`FOOT_WIDTH`])
//! at the sole, so that a flat foot stands on four spheres (heel and toe, inside and
//! outside) and can carry an ankle torque about every axis.
//!
//! Axes: x forward, y up, z to the right. Positive angles about z turn a hanging leg
//! forward (a bent knee is negative, a lifted toe a positive ankle angle), as in the
//! planar model.

use super::biped::TORSO_LENGTH;
use super::biped::{ANKLE_HEIGHT, FOOT_LENGTH, HEEL, SHIN_LENGTH, SOLE_RADIUS, THIGH_LENGTH};
use super::model::{Body, Capsule, Joint, Model, Settings};
use crate::error::Result;
use glam::{DMat3, DVec3};

/// Body indices of [`biped3d`]: the torso (root), then the right leg's thigh, shin, heel
/// and toe, then the left's.
pub const TORSO_3D: usize = 0;
/// Thigh, shin, foot (heel half, on the ankle) and toes of the right leg (at +z; the first
/// to swing).
pub const RIGHT_3D: [usize; 4] = [1, 2, 3, 4];
/// Thigh, shin, foot and toes of the left leg (at −z).
pub const LEFT_3D: [usize; 4] = [5, 6, 7, 8];
/// Distance between the hip joints (m).
pub const HIP_WIDTH: f64 = 0.2;
/// Width of the foot's contact capsules (m, between the sphere centres).
pub const FOOT_WIDTH: f64 = 0.1;

/// Sizes (m) of the boxes (depth along x, width along z) of the torso, thigh, shin and foot.
const TORSO_BOX: (f64, f64) = (0.2, 0.3);
const THIGH_BOX: f64 = 0.1;
const SHIN_BOX: f64 = 0.08;

/// Inertia (kg m², about the centre) of a uniform box of `mass` (kg) and sides `s` (m).
fn box_inertia(mass: f64, s: DVec3) -> DMat3 {
    let s2 = s * s;
    DMat3::from_diagonal(mass / 12.0 * DVec3::new(s2.y + s2.z, s2.x + s2.z, s2.x + s2.y))
}

/// The boxes of [`biped3d`] in their body frames, centre and half extents (m): the
/// uniform boxes whose inertias the model uses, a foot's halves from heel to mid-foot and
/// on to the toe, from the ankle down to the sole, [`FOOT_WIDTH`] + 2 [`SOLE_RADIUS`]
/// across.
pub fn link_boxes_3d() -> [(DVec3, DVec3); 9] {
    let torso = (
        DVec3::new(0.0, TORSO_LENGTH / 2.0, 0.0),
        DVec3::new(TORSO_BOX.0, TORSO_LENGTH, TORSO_BOX.1) / 2.0,
    );
    let leg = |length: f64, width: f64| {
        (DVec3::new(0.0, -length / 2.0, 0.0), DVec3::new(width, length, width) / 2.0)
    };
    let half = FOOT_LENGTH / 2.0;
    let across = FOOT_WIDTH + 2.0 * SOLE_RADIUS;
    let size = DVec3::new(half, ANKLE_HEIGHT, across) / 2.0;
    let heel = (DVec3::new(half / 2.0 - HEEL, -ANKLE_HEIGHT / 2.0, 0.0), size);
    let toes = (DVec3::new(1.5 * half - HEEL, -ANKLE_HEIGHT / 2.0, 0.0), size);
    let [thigh, shin] = [leg(THIGH_LENGTH, THIGH_BOX), leg(SHIN_LENGTH, SHIN_BOX)];
    [torso, thigh, shin, heel, toes, thigh, shin, heel, toes]
}

fn body(
    name: String,
    parent: Option<usize>,
    joint: Joint,
    offset: DVec3,
    (c, h): (DVec3, DVec3),
    mass: f64,
) -> Body {
    Body {
        name,
        parent,
        joint,
        offset,
        mass,
        com: c,
        inertia: box_inertia(mass, 2.0 * h),
        shape: None,
        limits: None,
        damping: 0.0,
        servo: None,
    }
}

/// The 3-D SIMBICON biped with `settings`, upright in its zero pose with its hips' midpoint
/// at the origin (lift it by setting the root's `y` to [`super::hip_height`]).
/// Coordinates: the torso's position (m) and quaternion `(w, x, y, z)`, then per leg
/// (right, then left) the hip's quaternion, the knee's angle (rad, about z) and the ankle's
/// quaternion; rates: the torso's `[ω (body axes); v (world)]`, the hip's and ankle's
/// angular velocities (body axes) and the knee's rate.
///
/// # Errors
/// None for valid settings (the bodies are fixed); the `Result` is that of
/// [`Model::add_body`].
pub fn biped3d(settings: Settings) -> Result<Model> {
    let mut model = Model::new(settings);
    let boxes = link_boxes_3d();
    model.add_body(body("torso".into(), None, Joint::Free, DVec3::ZERO, boxes[0], 70.0))?;
    let y = -(ANKLE_HEIGHT - SOLE_RADIUS);
    let across = |x: f64| Capsule {
        a: DVec3::new(x, y, -FOOT_WIDTH / 2.0),
        b: DVec3::new(x, y, FOOT_WIDTH / 2.0),
        radius: SOLE_RADIUS,
    };
    for (side, z) in [("right", HIP_WIDTH / 2.0), ("left", -HIP_WIDTH / 2.0)] {
        let hip = DVec3::new(0.0, 0.0, z);
        let name = |part: &str| format!("{side}_{part}");
        let t =
            model.add_body(body(name("thigh"), Some(TORSO_3D), Joint::Ball, hip, boxes[1], 5.0))?;
        let knee = Joint::Revolute { axis: DVec3::Z };
        let down = |l: f64| DVec3::new(0.0, -l, 0.0);
        let s =
            model.add_body(body(name("shin"), Some(t), knee, down(THIGH_LENGTH), boxes[2], 4.0))?;
        let heel = Body {
            shape: Some(across(-HEEL)),
            ..body(name("foot"), Some(s), Joint::Ball, down(SHIN_LENGTH), boxes[3], 0.5)
        };
        let f = model.add_body(heel)?;
        let toes = Body {
            shape: Some(across(FOOT_LENGTH - HEEL)),
            ..body(name("toes"), Some(f), Joint::Fixed, DVec3::ZERO, boxes[4], 0.5)
        };
        model.add_body(toes)?;
    }
    Ok(model)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_model_has_the_planar_masses_and_a_foot_of_four_soles() {
        let model = biped3d(Settings::default()).unwrap();
        assert_eq!((model.nq(), model.nv()), (7 + 2 * 9, 6 + 2 * 7));
        assert!((model.mass() - 90.0).abs() < 1e-12);
        let foot: f64 = RIGHT_3D[2..].iter().map(|&b| model.bodies()[b].mass).sum();
        assert!((foot - 1.0).abs() < 1e-15);
        for &b in &RIGHT_3D[2..] {
            let c = model.bodies()[b].shape.unwrap();
            assert!((c.a.y + ANKLE_HEIGHT - SOLE_RADIUS).abs() < 1e-15);
            assert!(((c.b - c.a).length() - FOOT_WIDTH).abs() < 1e-15);
        }
    }
}
