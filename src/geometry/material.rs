//! The surface material of a collider, apart from its shape.

use crate::error::{Error, Result};

/// How a surface responds to a contact: Newton's coefficient of restitution and Coulomb's
/// coefficient of friction (both dimensionless).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Ratio of the normal separation speed to the approach speed, in `[0, 1]`.
    pub restitution: f64,
    /// Coulomb friction coefficient, finite and `>= 0`.
    pub friction: f64,
}

impl Material {
    /// The material, checked.
    ///
    /// # Errors
    /// Restitution outside `[0, 1]` (named `restitution`), a negative or non-finite friction
    /// (named `friction`).
    pub fn checked(self) -> Result<Material> {
        let e = self.restitution;
        if !(0.0..=1.0).contains(&e) {
            return Err(Error::invalid("restitution", format!("must be in [0, 1], got {e}")));
        }
        friction(self.friction)?;
        Ok(self)
    }
}

/// A Coulomb friction coefficient, checked (for surfaces that model no restitution).
///
/// # Errors
/// A negative or non-finite coefficient, named `friction`.
pub fn friction(mu: f64) -> Result<f64> {
    if mu.is_finite() && mu >= 0.0 {
        Ok(mu)
    } else {
        Err(Error::invalid("friction", format!("must be finite and >= 0, got {mu}")))
    }
}
