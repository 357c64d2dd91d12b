//! Clips: named channels (value and rotation tracks) animated together and sampled on one
//! frame grid. The clip spans the earliest to the latest key of all its channels; frame `k`
//! is at `start + k / fps`, for every `k` with `k / fps ≤ duration` (up to `1e-9` frames of
//! rounding, so a duration of a whole number of frames includes its last frame).

use super::{RotationTrack, Track};
use crate::error::{reserve, Error, Result};

/// One channel of a [`Clip`].
#[derive(Clone, Debug)]
pub enum Channel {
    /// A value track (any width).
    Value(Track),
    /// An orientation track.
    Rotation(RotationTrack),
}

impl Channel {
    fn times(&self) -> &[f64] {
        match self {
            Channel::Value(t) => t.times(),
            Channel::Rotation(t) => t.times(),
        }
    }
}

/// Named channels animated together.
#[derive(Clone, Debug)]
pub struct Clip {
    channels: Vec<(String, Channel)>,
    start: f64,
    end: f64,
}

/// A sampled channel: values `(frames x dim)` row by row, or quaternions `(w, x, y, z)`.
#[derive(Clone, Debug, PartialEq)]
pub enum Samples {
    /// Values of a value track, `frames * dim` numbers.
    Value(Vec<f64>),
    /// Orientations of a rotation track, one scalar-first quaternion per frame.
    Rotation(Vec<[f64; 4]>),
}

impl Clip {
    /// A clip of `channels` (at least one), in the given order.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"channels"`) when there is none.
    pub fn new(channels: Vec<(String, Channel)>) -> Result<Self> {
        let (start, end) = channels.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), c| {
            let t = c.1.times();
            (a.min(t[0]), b.max(t[t.len() - 1]))
        });
        if channels.is_empty() {
            return Err(Error::invalid("channels", "expected at least one channel"));
        }
        Ok(Self { channels, start, end })
    }

    /// The channels, by name.
    pub fn channels(&self) -> &[(String, Channel)] {
        &self.channels
    }

    /// Time of the first key of any channel (s).
    pub fn start(&self) -> f64 {
        self.start
    }

    /// Time of the last key of any channel (s).
    pub fn end(&self) -> f64 {
        self.end
    }

    /// Seconds from the first key to the last.
    pub fn duration(&self) -> f64 {
        self.end - self.start
    }

    /// The frame times at `fps` frames per second, from [`Clip::start`] to [`Clip::end`].
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"fps"`) unless `fps` is finite and positive, or
    /// when the frames do not fit in memory.
    pub fn frame_times(&self, fps: f64) -> Result<Vec<f64>> {
        frame_times(self.start, self.duration(), fps)
    }

    /// Every channel sampled at [`Clip::frame_times`]: the times and the samples, in the
    /// order of [`Clip::channels`].
    ///
    /// # Errors
    /// As [`Clip::frame_times`].
    pub fn sample(&self, fps: f64) -> Result<(Vec<f64>, Vec<Samples>)> {
        let t = self.frame_times(fps)?;
        let samples = self
            .channels
            .iter()
            .map(|(_, c)| match c {
                Channel::Value(track) => {
                    let mut out = Vec::new();
                    reserve("fps", &mut out, t.len() * track.dim())?;
                    out.resize(t.len() * track.dim(), 0.0);
                    track.eval_many(&t, 0, &mut out)?;
                    Ok(Samples::Value(out))
                }
                Channel::Rotation(track) => {
                    let mut out = Vec::new();
                    reserve("fps", &mut out, t.len())?;
                    out.resize(t.len(), [0.0; 4]);
                    track.eval_many(&t, &mut out)?;
                    Ok(Samples::Rotation(out))
                }
            })
            .collect::<Result<_>>()?;
        Ok((t, samples))
    }
}

/// Frame times `start + k / fps` for `k = 0 ..= ⌊duration · fps + 1e-9⌋`.
///
/// # Errors
/// [`Error::InvalidInput`] (argument `"fps"`) unless `fps` is finite and positive, or when
/// the frames do not fit in memory.
pub fn frame_times(start: f64, duration: f64, fps: f64) -> Result<Vec<f64>> {
    if !(fps.is_finite() && fps > 0.0) {
        return Err(Error::invalid("fps", "expected a finite positive number"));
    }
    let count = (duration * fps + 1e-9).floor() + 1.0;
    if count >= usize::MAX as f64 {
        return Err(crate::error::too_large("fps", count, size_of::<f64>()));
    }
    let n = count as usize;
    let mut t = Vec::new();
    reserve("fps", &mut t, n)?;
    t.extend((0..n).map(|k| start + k as f64 / fps));
    Ok(t)
}
