//! Easing: timing curves `u ↦ e(u)` on `[0, 1]` with `e(0) = 0` and `e(1) = 1` that give a
//! motion a speed profile (Parent, *Computer Animation: Algorithms and Techniques*, 3rd ed.,
//! §3.2.2). With an [`super::ArcLengthCurve`], `curve.time_at(ease(u) · length)` moves
//! along a path with that profile.

use crate::batch;
use crate::error::{Error, Result};
use std::f64::consts::PI;

/// A timing curve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Easing {
    /// `u`: constant speed.
    Linear,
    /// `u²`: starts at rest, accelerates.
    EaseIn,
    /// `1 - (1 - u)²`: decelerates, ends at rest.
    EaseOut,
    /// `(1 - cos πu) / 2`: sinusoidal, at rest at both ends (Parent eq. 3.22).
    EaseInOut,
    /// `3u² - 2u³`: the cubic Hermite step, at rest at both ends.
    Smoothstep,
}

impl Easing {
    /// Every easing's name, in the order of the enum.
    pub const NAMES: [&'static str; 5] =
        ["linear", "ease_in", "ease_out", "ease_in_out", "smoothstep"];

    /// The easing called `name` (one of [`Easing::NAMES`]).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"kind"`) for any other name (not quoted back).
    pub fn parse(name: &str) -> Result<Self> {
        Ok(match name {
            "linear" => Easing::Linear,
            "ease_in" => Easing::EaseIn,
            "ease_out" => Easing::EaseOut,
            "ease_in_out" => Easing::EaseInOut,
            "smoothstep" => Easing::Smoothstep,
            _ => {
                return Err(Error::invalid(
                    "kind",
                    format!("is not one of {}", Easing::NAMES.join(", ")),
                ))
            }
        })
    }

    /// `e(u)` for `u` clamped to `[0, 1]`.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"u"`) for NaN.
    pub fn eval(self, u: f64) -> Result<f64> {
        if u.is_nan() {
            return Err(Error::invalid("u", "contains NaN"));
        }
        let x = u.clamp(0.0, 1.0);
        Ok(match self {
            Easing::Linear => x,
            Easing::EaseIn => x * x,
            Easing::EaseOut => 1.0 - (1.0 - x) * (1.0 - x),
            Easing::EaseInOut => (1.0 - (PI * x).cos()) / 2.0,
            Easing::Smoothstep => x * x * (3.0 - 2.0 * x),
        })
    }

    /// [`Easing::eval`] for every row of `u` into `out`, in parallel.
    ///
    /// # Errors
    /// As [`Easing::eval`], for the lowest failing row (named by its index).
    pub fn eval_many(
        self,
        u: &[[f64; 1]],
        out: &mut (impl batch::Output<1> + ?Sized),
    ) -> Result<()> {
        batch::map(u, out, |&[u]| Ok([self.eval(u)?]))
    }
}
