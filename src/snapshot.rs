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
//! (`kinema.Scene.save`); but since a checksum only proves that the bytes are the ones written,
//! not that they were written by kinema, every type also checks what it decoded
//! ([`Snapshot::validate`]: every index in range, every length consistent, every value finite
//! where it must be) before [`Snapshot::from_snapshot`] returns it, so no snapshot, however
//! damaged or crafted, can make a later step panic.

use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use serde::Serialize;

/// Version of the snapshot layout; raised whenever a stored type changes its fields.
pub const VERSION: u32 = 19;

/// A type that can be stored as a snapshot, under a tag naming it.
pub trait Snapshot: Serialize + DeserializeOwned {
    /// The tag written before the data, e.g. `"Cloth"`.
    const TAG: &'static str;

    /// Check a decoded value: every index in range, every length consistent with the sizes it
    /// must match, every value finite (or in its domain) where the code that reads it relies on
    /// it. Called by [`Snapshot::from_snapshot`].
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"data"`) naming the first inconsistency.
    fn validate(&self) -> Result<()>;

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
    /// and version, are damaged, or decode into an inconsistent value ([`Snapshot::validate`]).
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
        Snapshot::validate(&value).map_err(|e| {
            Error::invalid("data", format!("inconsistent {} snapshot: {e}", Self::TAG))
        })?;
        Ok(value)
    }
}

/// `Ok` if `ok`, else the validation error about `field` (for [`Snapshot::validate`]).
///
/// # Errors
/// [`Error::InvalidInput`] (argument `field`) with reason `what()` when `ok` is false.
pub fn check(ok: bool, field: &str, what: impl FnOnce() -> String) -> Result<()> {
    if ok {
        Ok(())
    } else {
        Err(Error::invalid(field, what()))
    }
}

/// Whether every value is finite.
pub fn finite(values: impl IntoIterator<Item = f64>) -> bool {
    values.into_iter().all(f64::is_finite)
}

fn header(tag: &str) -> Vec<u8> {
    let mut h = Vec::with_capacity(tag.len() + 12);
    h.extend_from_slice(b"kinema:");
    h.extend_from_slice(tag.as_bytes());
    h.push(b':');
    h.extend_from_slice(&VERSION.to_le_bytes());
    h
}

/// A deterministic 64-bit hash of `value`: FNV-1a (Fowler, Noll & Vo) over its postcard
/// encoding, the bytes a snapshot stores, computed without allocating. Equal values hash
/// equal on every platform and run; a value that cannot be encoded (a user function) hashes
/// the bytes encoded before it.
pub fn fingerprint<T: Serialize>(value: &T) -> u64 {
    struct Fnv(u64);
    impl std::io::Write for Fnv {
        fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
            for &b in bytes {
                self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
            }
            Ok(bytes.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    let mut hash = Fnv(0xcbf2_9ce4_8422_2325);
    // An encoding error only cuts the hashed bytes short (documented above).
    let _ = postcard::to_io(value, &mut hash);
    hash.0
}

/// A system's state whose snapshot alone is stamped with the fingerprint of its model
/// ([`fingerprint`]), so that it is restored only onto that model. Every system's `State`
/// implements it: [`Stamped::to_snapshot`] and [`Stamped::from_snapshot`] are written once,
/// here.
pub trait Stamped: Serialize + DeserializeOwned + Clone {
    /// The tag of the state's snapshots, e.g. `"ConstraintState"`.
    const TAG: &'static str;

    /// The model the state belongs to; its [`fingerprint`] stamps the state's snapshots.
    type Model: Serialize;

    /// Check a decoded state against `model` (sizes, then values), before it is used.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] naming the first inconsistent field.
    fn validate(&self, model: &Self::Model) -> Result<()>;

    /// The state as bytes (see the module documentation), stamped with the fingerprint of
    /// `model`, for [`Stamped::from_snapshot`] onto the same model.
    ///
    /// # Errors
    /// As [`Snapshot::to_snapshot`] (none in practice: a state holds nothing that cannot be
    /// encoded).
    fn to_snapshot(&self, model: &Self::Model) -> Result<Vec<u8>> {
        Stored { fingerprint: fingerprint(model), state: self.clone() }.to_snapshot()
    }

    /// The state stored by [`Stamped::to_snapshot`], for `model`.
    ///
    /// # Errors
    /// Bytes that are not a snapshot of this tag and version or are damaged (argument `data`);
    /// a state of a model of another fingerprint (argument `model`); a state that
    /// [`Stamped::validate`] refuses (argument `data`).
    fn from_snapshot(model: &Self::Model, data: &[u8]) -> Result<Self> {
        let stored = Stored::<Self>::from_snapshot(data)?;
        if stored.fingerprint != fingerprint(model) {
            return Err(Error::invalid(
                "model",
                "the state snapshot was taken of a model with another fingerprint",
            ));
        }
        stored.state.validate(model).map_err(|e| {
            Error::invalid("data", format!("inconsistent {} snapshot: {e}", Self::TAG))
        })?;
        Ok(stored.state)
    }
}

/// A stamped state as stored: the fingerprint of its model and the state.
#[derive(serde::Serialize, serde::Deserialize)]
struct Stored<S> {
    fingerprint: u64,
    state: S,
}

impl<S: Stamped> Snapshot for Stored<S> {
    const TAG: &'static str = S::TAG;

    /// The state is checked against its model by [`Stamped::from_snapshot`], which has it.
    fn validate(&self) -> Result<()> {
        Ok(())
    }
}
