//! Motion-capture snapshots: a decoded skeleton or motion is checked by its own `validate`
//! (the check the Python unpickling runs too) before forward kinematics, editing or writing
//! read it.

use super::{BvhSkeleton, Motion, Skeleton};
use crate::error::Result;
use crate::snapshot::Snapshot;

impl Snapshot for Skeleton {
    const TAG: &'static str = "Skeleton";

    /// [`Skeleton::validate`].
    fn validate(&self) -> Result<()> {
        Skeleton::validate(self)
    }
}

impl Snapshot for Motion {
    const TAG: &'static str = "Motion";

    /// [`Motion::validate`].
    fn validate(&self) -> Result<()> {
        Motion::validate(self)
    }
}

impl Snapshot for BvhSkeleton {
    const TAG: &'static str = "BvhSkeleton";

    /// [`BvhSkeleton::validate`].
    fn validate(&self) -> Result<()> {
        BvhSkeleton::validate(self)
    }
}
