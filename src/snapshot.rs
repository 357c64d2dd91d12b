//! Snapshots: a whole system (model and state, down to integrator history and warm-start
//! caches) as bytes, and back.
//!
//! A system restored from its snapshot continues bit for bit as the original would have: every
//! field that influences a later step is stored (`f64` as its exact IEEE-754 bits, by
//! [postcard](https://docs.rs/postcard)); only factorisations that are rebuilt identically from
//! the stored pattern, and the cloth PCG's workspace that every solve overwrites before
//! reading, are left out. Workspaces are stored too, which keeps the rule simple (no
//! field is forgotten) at the price of larger files.
//!
//! Layout: `b"kinema:"`, the type's tag (e.g. `b"Cloth"`), `b":"`, [`VERSION`] as 4 bytes
//! little-endian, then the postcard encoding. The tag and version are checked when reading, so
//! bytes of another type or of an incompatible kinema are refused with a clear error. Integrity
//! against damaged files (checksums) is the job of the container that stores snapshots
//! (`kinema.Scene.save`).

use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use serde::Serialize;

/// Version of the snapshot layout; raised whenever a stored type changes its fields.
pub const VERSION: u32 = 5;

/// A type that can be stored as a snapshot, under a tag naming it.
pub trait Snapshot: Serialize + DeserializeOwned {
    /// The tag written before the data, e.g. `"Cloth"`.
    const TAG: &'static str;

    /// The system as bytes (see the module documentation for the layout).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"system"`) if it holds something that cannot be
    /// stored, such as a constraint given as a user function.
    fn to_snapshot(&self) -> Result<Vec<u8>> {
        let mut out = header(Self::TAG);
        postcard::to_io(self, &mut out).map_err(|e| {
            Error::invalid(
                "system",
                format!("cannot be saved: {e} (custom user functions cannot be stored)"),
            )
        })?;
        Ok(out)
    }

    /// The system stored by [`Snapshot::to_snapshot`].
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"data"`) if the bytes are not a snapshot of this type
    /// and version, or are damaged.
    fn from_snapshot(data: &[u8]) -> Result<Self> {
        let head = header(Self::TAG);
        let Some(body) = data.strip_prefix(head.as_slice()) else {
            let what = if data.starts_with(b"kinema:") {
                let found: String = data[7..]
                    .iter()
                    .take_while(|&&b| b != b':')
                    .take(32)
                    .map(|&b| b as char)
                    .collect();
                format!("a snapshot of '{found}' (or of snapshot version other than {VERSION}), not of '{}'", Self::TAG)
            } else {
                "not a kinema snapshot".to_string()
            };
            return Err(Error::invalid("data", what));
        };
        let (value, rest) = postcard::take_from_bytes(body)
            .map_err(|e| Error::invalid("data", format!("damaged {} snapshot: {e}", Self::TAG)))?;
        if !rest.is_empty() {
            return Err(Error::invalid(
                "data",
                format!("damaged {} snapshot: {} trailing bytes", Self::TAG, rest.len()),
            ));
        }
        Ok(value)
    }
}

fn header(tag: &str) -> Vec<u8> {
    let mut h = Vec::with_capacity(tag.len() + 12);
    h.extend_from_slice(b"kinema:");
    h.extend_from_slice(tag.as_bytes());
    h.push(b':');
    h.extend_from_slice(&VERSION.to_le_bytes());
    h
}

impl Snapshot for crate::particles::ParticleSystem {
    const TAG: &'static str = "ParticleSystem";
}
impl Snapshot for crate::constraints::ConstrainedSystem {
    const TAG: &'static str = "ConstrainedSystem";
}
impl Snapshot for crate::cloth::Cloth {
    const TAG: &'static str = "Cloth";
}
impl Snapshot for crate::rigid::World {
    const TAG: &'static str = "World";
}
impl Snapshot for crate::anim::Track {
    const TAG: &'static str = "Track";
}
impl Snapshot for crate::anim::RotationTrack {
    const TAG: &'static str = "RotationTrack";
}
impl Snapshot for crate::mocap::Skeleton {
    const TAG: &'static str = "Skeleton";
}
impl Snapshot for crate::mocap::Motion {
    const TAG: &'static str = "Motion";
}
impl Snapshot for crate::mocap::BvhSkeleton {
    const TAG: &'static str = "BvhSkeleton";
}
