//! `kinema.character.Biped(dims=3)`: the compiled 3-D SIMBICON walker.

use super::character::{gait, walker_settings};
use super::walker::walker_class;
use crate::character::{link_boxes_3d, Coronal, Walker3d as Core};
use pyo3::prelude::*;

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Walker3d>()
}

walker_class! {
    /// The 3-D SIMBICON walker; see `kinema.character.Biped` (`dims=3`) for the API.
    Walker3d(Core, link_boxes_3d) {
        /// The walker at `speed` (m/s) with the gait's `lift` and `strike` poses (8 values
        /// each), `[duration, kp, kd, torso_kp, torso_kd, max_torque]`, the coronal feedback
        /// `[cd, cv, swing_hip]`, the ground's `contact_frequency` (rad/s) and `friction`, on a
        /// `slope` (rad, positive climbs +x; gravity turns by it).
        #[new]
        #[allow(clippy::too_many_arguments)]
        fn new(
            lift: [f64; 8],
            strike: [f64; 8],
            control: [f64; 6],
            coronal: [f64; 3],
            speed: f64,
            contact_frequency: f64,
            friction: f64,
            slope: f64,
        ) -> PyResult<Self> {
            let settings = walker_settings(contact_frequency, friction, slope)?;
            let [cd, cv, swing_hip] = coronal;
            let coronal = Coronal { cd, cv, swing_hip };
            let walker = Core::new(settings, gait(lift, strike, control), coronal, speed)?;
            Ok(Walker3d { walker, saved: None })
        }

        /// The coronal feedback `[cd, cv, swing_hip]`.
        fn coronal(&self) -> [f64; 3] {
            let c = self.walker.coronal;
            [c.cd, c.cv, c.swing_hip]
        }
    }
}
