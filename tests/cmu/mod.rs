//! The CMU walk the integration tests read (`tests/data/mocap`, copied into the repository).

use kinema::mocap::{parse_amc, parse_asf, Motion, Skeleton};
use std::path::PathBuf;

/// CMU subject 07, trial 05 (a walk at 120 Hz): its ASF skeleton and AMC motion.
pub fn walk() -> (Skeleton, Motion) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mocap");
    assert!(dir.is_dir(), "the motion-capture data is expected at {}", dir.display());
    let text = |name: &str| std::fs::read_to_string(dir.join(name)).unwrap();
    let skeleton = parse_asf(&text("07-walk.asf"), "07-walk.asf").unwrap();
    let motion = parse_amc(&text("07_05-walk.amc"), "07_05-walk.amc", &skeleton).unwrap();
    (skeleton, motion)
}
