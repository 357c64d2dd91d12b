//! Articulated snapshots: the body's (model and state), and a state's alone, stamped with
//! its model's fingerprint so that it is restored only onto it.

use super::model::Joint;
use super::simbicon::SERVOED;
use super::simbicon3d::SERVOED_3D;
use super::{biped3d, planar_biped, ArticulatedBody, Model, State, Walker, Walker3d};
use crate::error::Result;
use crate::snapshot::{check, finite, Snapshot, Stamped};

impl Stamped for State {
    const TAG: &'static str = "ArticulatedState";
    type Model = Model;

    /// Check a decoded state against its model: lengths, finite values, unit quaternions,
    /// pushes on existing bodies.
    fn validate(&self, model: &Model) -> Result<()> {
        let (nq, nv) = (model.nq(), model.nv());
        for (field, len, want) in [
            ("q", self.q.len(), nq),
            ("targets", self.targets.len(), nq),
            ("qd", self.qd.len(), nv),
            ("torques", self.torques.len(), nv),
        ] {
            check(len == want, field, || format!("{len} entries, expected {want}"))?;
        }
        let values = self.q.iter().chain(&self.qd).chain(&self.targets).chain(&self.torques);
        check(finite(values.copied()) && self.time.is_finite(), "q", || "non-finite".into())?;
        for (i, b) in model.bodies().iter().enumerate() {
            let at = model.starts(i).0 + usize::from(b.joint == Joint::Free) * 3;
            if matches!(b.joint, Joint::Ball | Joint::Free) {
                for v in [&self.q, &self.targets] {
                    let n: f64 = v[at..at + 4].iter().map(|x| x * x).sum();
                    check((n - 1.0).abs() < 1e-9, "q", || "quaternions must be unit".into())?;
                }
            }
        }
        let pushes_ok = self.pushes.iter().all(|p| {
            p.body < model.bodies().len() && p.force.is_finite() && p.remaining.is_finite()
        });
        check(pushes_ok, "pushes", || "a push on a missing body or non-finite".into())
    }
}

impl Snapshot for ArticulatedBody {
    const TAG: &'static str = "ArticulatedBody";

    fn validate(&self) -> Result<()> {
        let mut rebuilt = Model::new(self.model.settings);
        for b in &self.model.bodies {
            rebuilt.add_body(b.clone())?;
        }
        let m = &self.model;
        let near = |a: &super::spatial::SMat, b: &super::spatial::SMat| {
            (a - b).norm() <= 1e-9 * (1.0 + a.norm())
        };
        let same = rebuilt.q_start == m.q_start
            && rebuilt.v_start == m.v_start
            && rebuilt.tree == m.tree
            && rebuilt.inertias.len() == m.inertias.len()
            && rebuilt.inertias.iter().zip(&m.inertias).all(|(a, b)| near(a, b));
        check(same, "model", || "derived data do not match the bodies".into())?;
        self.model.check_settings()?;
        self.state.validate(&self.model)
    }
}

impl Snapshot for Walker {
    const TAG: &'static str = "Walker";

    /// The model must be the planar biped of its settings with servos at the knees and
    /// ankles only; the gait, state and phase valid.
    fn validate(&self) -> Result<()> {
        let mut rebuilt = planar_biped(self.model.settings)?;
        for body in SERVOED {
            rebuilt.set_servo(body, self.model.bodies()[body].servo)?;
        }
        check(rebuilt == self.model, "model", || "not the planar biped".into())?;
        self.model.check_settings()?;
        self.gait.check()?;
        let phase_ok = self.phase.state < 4 && self.phase.time.is_finite();
        check(phase_ok, "phase", || "state beyond 3 or a non-finite time".into())?;
        self.state.validate(&self.model)
    }
}

impl Snapshot for Walker3d {
    const TAG: &'static str = "Walker3d";

    /// The model must be the 3-D biped of its settings with servos at the knees and ankles
    /// only; the gait, coronal feedback, state and phase valid.
    fn validate(&self) -> Result<()> {
        let mut rebuilt = biped3d(self.model.settings)?;
        for body in SERVOED_3D {
            rebuilt.set_servo(body, self.model.bodies()[body].servo)?;
        }
        check(rebuilt == self.model, "model", || "not the 3-D biped".into())?;
        self.model.check_settings()?;
        self.gait.check()?;
        self.coronal.check()?;
        let phase_ok = self.phase.state < 4 && self.phase.time.is_finite();
        check(phase_ok, "phase", || "state beyond 3 or a non-finite time".into())?;
        self.state.validate(&self.model)
    }
}
