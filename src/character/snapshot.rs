//! Articulated snapshots: the body's (model and state), a state's alone, stamped with its
//! model's fingerprint so that it is restored only onto it, the walkers' and the mocap
//! tracker's. A model's colliders are stored with it (snapshot version 18), with their
//! velocities and times (19, with a tracker's ASF or BVH skeleton; earlier versions are
//! refused by their version, as every snapshot is).

use super::model::{check_collider, Joint};
use super::simbicon::SERVOED;
use super::simbicon3d::SERVOED_3D;
use super::{biped3d, planar_biped, ArticulatedBody, Model, State, Tracker, Walker, Walker3d};
use crate::error::Result;
use crate::geometry::Shape;
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
            && rebuilt.collision_pairs == m.collision_pairs
            && rebuilt.inertias.len() == m.inertias.len()
            && rebuilt.inertias.iter().zip(&m.inertias).all(|(a, b)| near(a, b));
        check(same, "model", || "derived data do not match the bodies".into())?;
        check_colliders(&self.model)?;
        self.model.check_settings()?;
        self.state.validate(&self.model)
    }
}

/// Check a decoded model's colliders as [`Model::add_collider`] would (a plane's normal
/// unit to 1e-9).
fn check_colliders(model: &Model) -> Result<()> {
    for c in model.colliders() {
        c.shape.checked()?;
        check_collider(c)?;
        if let Shape::Plane(p) = c.shape {
            let unit = (p.normal.length() - 1.0).abs() < 1e-9;
            check(unit, "normal", || "a plane collider's normal must be unit".into())?;
        }
    }
    Ok(())
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
        check_colliders(&self.model)?;
        rebuilt.colliders.clone_from(&self.model.colliders);
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
        check_colliders(&self.model)?;
        rebuilt.colliders.clone_from(&self.model.colliders);
        check(rebuilt == self.model, "model", || "not the 3-D biped".into())?;
        self.model.check_settings()?;
        self.gait.check()?;
        self.coronal.check()?;
        let phase_ok = self.phase.state < 4 && self.phase.time.is_finite();
        check(phase_ok, "phase", || "state beyond 3 or a non-finite time".into())?;
        self.state.validate(&self.model)
    }
}

/// The most frames a restored tracker may have tracked: ten days of a 120 Hz clip. The clip's
/// pose at frame `k` composes one loop turn per loop, so the bound keeps a crafted frame count
/// from making a step take hours.
const MAX_TRACKED_FRAMES: usize = 100_000_000;

impl Snapshot for Tracker {
    const TAG: &'static str = "Tracker";

    /// The ragdoll must be valid and be the tree its skeleton builds (parents and joints), the
    /// clip's lift and loop those its skeleton, clip and options give (rebuilt and compared),
    /// the reference buffers of the model's sizes and finite, the frame count bounded.
    fn validate(&self) -> Result<()> {
        Snapshot::validate(&self.body)?;
        let settings = self.body.model().settings;
        let built =
            Tracker::new(&self.skeleton, &self.motion, &self.ragdoll, settings, self.options)?;
        let (mine, theirs) = (self.body.model().bodies(), built.body.model().bodies());
        let same_tree = mine.len() == theirs.len()
            && mine.iter().zip(theirs).all(|(a, b)| a.parent == b.parent && a.joint == b.joint);
        check(same_tree, "body", || "not the ragdoll of the skeleton".into())?;
        let clip = (self.shift, self.loop_span, self.loop_turn, self.loop_from, self.loop_to);
        let want = (built.shift, built.loop_span, built.loop_turn, built.loop_from, built.loop_to);
        check(clip == want, "loop_span", || "not the lift and loop of the clip".into())?;
        let (nq, nv) = (self.body.model().nq(), self.body.model().nv());
        for (field, len, want) in [
            ("q_ref", self.q_ref.len(), nq),
            ("q_next", self.q_next.len(), nq),
            ("v_ref", self.v_ref.len(), nv),
            ("diff", self.diff.len(), nv),
        ] {
            check(len == want, field, || format!("{len} entries, expected {want}"))?;
        }
        let values = self.q_ref.iter().chain(&self.q_next).chain(&self.v_ref).chain(&self.diff);
        let inertia_ok = self.inertia.iter().all(|m| m.is_finite() && *m >= 0.0);
        check(finite(values.copied()) && inertia_ok, "q_ref", || "non-finite".into())?;
        check(self.frame <= MAX_TRACKED_FRAMES, "frame", || {
            format!("{} frames, more than {MAX_TRACKED_FRAMES}", self.frame)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::character::{RagdollOptions, Settings, TrackingOptions};
    use crate::mocap::{parse_amc, parse_asf};

    fn tracker() -> Tracker {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/mocap/");
        let asf = std::fs::read_to_string(format!("{dir}07-walk.asf")).unwrap();
        let amc = std::fs::read_to_string(format!("{dir}07_05-walk.amc")).unwrap();
        let skeleton = parse_asf(&asf, "07-walk.asf").unwrap();
        let motion = parse_amc(&amc, "07_05-walk.amc", &skeleton).unwrap();
        let ragdoll = RagdollOptions { scale: skeleton.metres_per_unit(), ..Default::default() };
        let options = TrackingOptions::default();
        Tracker::new(&skeleton, &motion, &ragdoll, Settings::default(), options).unwrap()
    }

    /// A tracker whose parts do not belong together is refused, naming the part: each
    /// mutation below is one a crafted snapshot could make.
    #[test]
    fn an_inconsistent_tracker_snapshot_is_refused() {
        let good = tracker();
        assert!(Tracker::from_snapshot(&good.to_snapshot().unwrap()).is_ok());
        type Mutation = fn(&mut Tracker);
        let cases: [(&str, Mutation); 4] = [
            ("loop_span", |t| t.loop_span.1 += 1),
            ("frame", |t| t.frame = MAX_TRACKED_FRAMES + 1),
            ("q_ref", |t| t.q_ref.truncate(3)),
            ("q_ref", |t| t.v_ref[0] = f64::NAN),
        ];
        for (field, mutate) in cases {
            let mut t = good.clone();
            mutate(&mut t);
            let err = refusal(&t);
            assert!(err.contains(field), "{field}: {err}");
        }
        let mut other_clip = good.clone();
        other_clip.motion = good.motion.slice(0, 60).unwrap();
        assert!(refusal(&other_clip).contains("loop_span"));
        let mut walker = good.clone();
        walker.body = ArticulatedBody::new(biped3d(Settings::default()).unwrap());
        assert!(refusal(&walker).contains("body"));
    }

    /// Why the snapshot of `t` is refused (a test failure if it is not).
    fn refusal(t: &Tracker) -> String {
        match Tracker::from_snapshot(&t.to_snapshot().unwrap()) {
            Ok(_) => panic!("accepted"),
            Err(e) => e.to_string(),
        }
    }
}
