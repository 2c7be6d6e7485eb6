//! Free-decay segmentation: where a pull-and-release lets go, where the decay starts to be
//! worth fitting, and (with the fit) where it sinks into the noise.

use serde::Serialize;

use crate::error::{ModalError, Result};
use crate::signal::{Signal, UniformSignal};
use crate::spectrum::{Detrend, Scaling, SpectrumConfig, Window, spectrum_uniform};

/// How a free decay is cut out of a record. `Default`: find the release, start half a cycle
/// after it, end where the fitted envelope falls below half the noise RMS, keep at least two
/// cycles.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SegmentConfig {
    /// Look for a held-still stretch and the moment it is let go; when false the decay is
    /// taken from the first sample.
    pub detect_release: bool,
    /// Cycles skipped after the release (real trees relax fast and non-oscillatorily in the
    /// first half-cycle, which no damped-sine model holds).
    pub skip_cycles: f64,
    /// End the segment where the fitted envelope falls below this multiple of the residual
    /// RMS; `None` keeps the record to its end.
    pub end_noise_factor: Option<f64>,
    /// Fewest cycles a segment keeps (the end is never moved before this).
    pub min_cycles: f64,
}

impl Default for SegmentConfig {
    fn default() -> Self {
        Self {
            detect_release: true,
            skip_cycles: 0.5,
            end_noise_factor: Some(0.5),
            min_cycles: 2.0,
        }
    }
}

impl SegmentConfig {
    /// The whole record, from its first sample to its last.
    #[must_use]
    pub fn whole() -> Self {
        Self {
            detect_release: false,
            skip_cycles: 0.0,
            end_noise_factor: None,
            min_cycles: 0.0,
        }
    }

    /// Check ranges.
    ///
    /// # Errors
    /// [`ModalError::InvalidParameter`] for a negative or non-finite number.
    pub fn validate(&self) -> Result<()> {
        let checks = [
            ("segment.skip_cycles", self.skip_cycles),
            ("segment.min_cycles", self.min_cycles),
            (
                "segment.end_noise_factor",
                self.end_noise_factor.unwrap_or(0.0),
            ),
        ];
        for (name, value) in checks {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ModalError::InvalidParameter {
                    name,
                    reason: format!("{value} (expected finite and not negative)"),
                });
            }
        }
        Ok(())
    }
}

/// The moment a pulled branch is let go.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Release {
    /// Last sample still held, seconds.
    pub time_s: f64,
    /// The level it was held at, in the signal's unit.
    pub held_level: f64,
    /// How long it was held still before, seconds.
    pub held_s: f64,
}

/// The part of a record the free-decay fit used.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Segment {
    /// The release, when a held stretch was found.
    pub release: Option<Release>,
    /// First time fitted, seconds.
    pub start_s: f64,
    /// Last time fitted, seconds.
    pub end_s: f64,
    /// The frequency the skip was measured in, hertz (spectral peak after the release).
    pub skip_frequency_hz: f64,
    /// Cycles of the dominant mode inside the segment.
    pub cycles: f64,
}

/// A motion measure per sample: the change of an `m`-sample moving average over `m`
/// samples (a velocity with the noise averaged down, about 0.8 times the amplitude when `m`
/// is an eighth of a period), then its RMS over a centred window of `w` samples.
fn motion(x: &[f64], m: usize, w: usize) -> Vec<f64> {
    let n = x.len();
    let m = m.max(1);
    if n < 2 * m + 1 {
        return vec![0.0; n];
    }
    let mut prefix = vec![0.0; n + 1];
    for (i, v) in x.iter().enumerate() {
        prefix[i + 1] = prefix[i] + v;
    }
    let avg = |i: usize| (prefix[i + m] - prefix[i]) / m as f64;
    let lagged = n - 2 * m + 1;
    let mut sq = vec![0.0; lagged + 1];
    for i in 0..lagged {
        let d = avg(i + m) - avg(i);
        sq[i + 1] = sq[i] + d * d;
    }
    // Sample i sits at the centre of the lagged difference that starts at i - m.
    let half = w / 2;
    (0..n)
        .map(|i| {
            let c = i.saturating_sub(m).min(lagged - 1);
            let lo = c.saturating_sub(half);
            let hi = (c + half + 1).min(lagged);
            ((sq[hi] - sq[lo]) / (hi - lo) as f64).sqrt()
        })
        .collect()
}

fn percentile(values: &[f64], q: f64) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return 0.0;
    }
    v[((v.len() - 1) as f64 * q).round() as usize]
}

pub(crate) fn median(values: &[f64]) -> f64 {
    percentile(values, 0.5)
}

/// The frequency of the strongest motion in `low_hz..=high_hz`: the most prominent peak of
/// the spectrum of the first differences (a velocity: a held offset becomes a single step,
/// whose spectrum is flat and has no prominence), 4x padding, refined between bins. A guess for window
/// lengths; the free-decay fit re-measures the frequency after the release.
pub(crate) fn dominant_frequency(u: &UniformSignal, low_hz: f64, high_hz: f64) -> Option<f64> {
    let d: Vec<f64> = u.values.windows(2).map(|p| p[1] - p[0]).collect();
    if d.len() < 4 {
        return None;
    }
    let du = UniformSignal {
        start_s: u.start_s,
        interval_s: u.interval_s,
        values: d,
        interpolated: 0,
    };
    most_prominent(&du, Window::Hann, Detrend::Mean, low_hz, high_hz)
}

/// The refined frequency of the most prominent peak in `low_hz..=high_hz` of an amplitude
/// spectrum with 4x padding.
fn most_prominent(
    u: &UniformSignal,
    window: Window,
    detrend: Detrend,
    low_hz: f64,
    high_hz: f64,
) -> Option<f64> {
    let s = spectrum_uniform(
        u,
        &SpectrumConfig {
            window,
            detrend,
            zero_padding: 4,
            scaling: Scaling::Amplitude,
        },
    );
    s.peaks_in(low_hz, high_hz, 0.0)
        .iter()
        .max_by(|a, b| a.prominence.total_cmp(&b.prominence))
        .map(|p| p.refined_frequency_hz)
}

/// The most prominent spectral peak of a decaying segment: rectangular window (a taper would
/// weight the start of the decay, where the signal is, by almost nothing), linear detrend,
/// 4x padding. Prominence, not height: what is left of the release's step is a smooth
/// low-frequency hump.
pub(crate) fn peak_frequency(signal: &Signal, low_hz: f64, high_hz: f64) -> Option<f64> {
    let u = signal.resample_uniform(None).ok()?;
    if u.values.len() < 4 {
        return None;
    }
    most_prominent(&u, Window::Rectangular, Detrend::Linear, low_hz, high_hz)
}

/// What the motion envelope says about a record: the release of a held stretch (if any) and
/// how strongly the motion decays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Onset {
    pub release: Option<Release>,
    /// Median motion level over a fiftieth of the record after the largest motion, over the
    /// median level of the last quarter of the record.
    pub decay_ratio: f64,
}

/// Peak motion over quiet motion at which a smoothing scale is taken as clear enough (the
/// finest such scale times the release best).
const CLEAR_CONTRAST: f64 = 12.0;

/// Motion up to this share of the release's peak motion still counts as held: a hand that
/// holds a branch jitters (on a twin's Kinect-noise capture, seed 4, a held twig's motion
/// level reached 0.23 of its release peak, over four times the level of its quiet end,
/// and the release was not found), and a release
/// whose peak is less than four times its holding jitter is no clear release anyway. The
/// threshold only matters when the contrast exceeds about 17 (below that the quiet level's
/// threshold is higher).
const HELD_SHARE_OF_PEAK: f64 = 0.25;

/// Find the release without knowing the frequency. The motion measure is computed at
/// smoothing scales of 1, 2, 3, 4, 6, 9, ... samples; the finest scale whose contrast (peak
/// motion over the quiet level, its 10th percentile) reaches 12 is used, or else the one
/// with the highest contrast. The largest burst of
/// motion is walked back to where the motion falls to 2.5 times the typical noise level; a quiet
/// stretch of at least three samples must precede it. The release is the last sample
/// within four noise standard deviations of the held level.
pub(crate) fn onset(u: &UniformSignal) -> Onset {
    let x = &u.values;
    let n = x.len();
    let mut best: Option<(f64, usize, Vec<f64>, f64)> = None;
    let mut m = 1;
    while 16 * m <= n {
        // At least 6 samples per RMS, so the quiet level is not a lucky low.
        let energy = motion(x, m, (4 * m).max(8));
        let quiet = percentile(&energy, 0.1);
        let peak = energy.iter().fold(0.0_f64, |a, &b| a.max(b));
        let contrast = if quiet > 0.0 { peak / quiet } else { 0.0 };
        let enough = contrast >= CLEAR_CONTRAST;
        if best.as_ref().is_none_or(|b| contrast > b.0) {
            best = Some((contrast, m, energy, quiet));
        }
        if enough {
            break;
        }
        m = if m < 4 { m + 1 } else { m + m / 2 };
    }
    let Some((_, m, energy, quiet)) = best else {
        return Onset {
            release: None,
            decay_ratio: 0.0,
        };
    };
    let (peak, &peak_level) = energy
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap_or((0, &0.0));
    let tail = median(&energy[n - n / 4..]);
    let mut release = None;
    // The 10th percentile of an 8-sample RMS of noise is about 0.6 of its typical value.
    // A hand holding a branch jitters more than the branch at rest after its decay: the
    // held stretch may move more than the record's quiet end, but far less than the release.
    let still = (2.5 * quiet / 0.6).max(peak_level * HELD_SHARE_OF_PEAK);
    if peak_level > 2.0 * still && quiet > 0.0 {
        let mut i = peak;
        while i > 0 && energy[i] > still {
            i -= 1;
        }
        let mut h = i;
        while h > 0 && energy[h - 1] <= still {
            h -= 1;
        }
        if i > 0 && i - h >= 3 {
            let held_from = h.max(i.saturating_sub(8 * m));
            let held = &x[held_from..=i];
            let held_level = median(held);
            // Noise: the spread of the held stretch, or from the quiet motion level (the motion
            // of pure noise is sqrt(2 / m) times its standard deviation) when it is shorter.
            let noise = if held.len() >= 6 {
                (held.iter().map(|v| (v - held_level).powi(2)).sum::<f64>() / held.len() as f64)
                    .sqrt()
            } else {
                quiet * (m as f64 / 2.0).sqrt()
            };
            let mut r = held_from;
            for k in held_from..peak.min(n - 1) {
                if (x[k] - held_level).abs() > 4.0 * noise
                    && (x[k + 1] - held_level).abs() > 4.0 * noise
                {
                    break;
                }
                r = k;
            }
            release = Some(Release {
                time_s: u.start_s + r as f64 * u.interval_s,
                held_level,
                held_s: (r - h) as f64 * u.interval_s,
            });
        }
    }
    // Motion just after the peak (a fiftieth of the record) against the record's end: a
    // free decay dies out, wind sway does not.
    let after = median(&energy[peak..(peak + (n / 50).max(8 * m)).min(n)]);
    Onset {
        release,
        decay_ratio: if tail > 0.0 {
            after / tail
        } else {
            f64::INFINITY
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hand's jitter while holding: a held stretch that moves nine times as much as the
    /// record's quiet end (the twin's pulled twig). The release is still found.
    #[test]
    fn a_jittery_hold_is_still_a_hold() {
        let dt = 1.0 / 30.0;
        let (f, xi, release_s) = (2.08, 0.12, 1.0);
        let wn = std::f64::consts::TAU * f;
        let hash = |i: i32| ((f64::from(i) * 12.9898).sin() * 43_758.545_3).fract();
        let x: Vec<f64> = (0..121)
            .map(|i| {
                let t = f64::from(i) * dt;
                if t <= release_s {
                    -0.06 + 0.009 * hash(i)
                } else {
                    let tau = t - release_s;
                    -0.08 * (-xi * wn * tau).exp() * (wn * tau).cos() + 0.02 + 0.001 * hash(i)
                }
            })
            .collect();
        let u = UniformSignal {
            start_s: 0.0,
            interval_s: dt,
            values: x,
            interpolated: 0,
        };
        let r = onset(&u).release.expect("the hold is found");
        assert!((r.time_s - release_s).abs() < 0.1, "{r:?}");
        assert!((r.held_level + 0.06).abs() < 0.009, "{r:?}");
        assert!(r.held_s >= 0.3, "{r:?}");
    }

    #[test]
    fn finds_the_release_after_a_held_stretch() {
        let dt = 1.0 / 30.0;
        let (f, xi, release_s) = (1.5, 0.05, 2.0);
        let wn = std::f64::consts::TAU * f;
        let x: Vec<f64> = (0..450)
            .map(|i| {
                let t = f64::from(i) * dt;
                let noise = 0.002 * (f64::from(i) * 12.9898).sin().fract();
                if t <= release_s {
                    0.3 + noise
                } else {
                    let tau = t - release_s;
                    0.3 * (-xi * wn * tau).exp() * (wn * tau).cos() + noise
                }
            })
            .collect();
        let u = UniformSignal {
            start_s: 0.0,
            interval_s: dt,
            values: x,
            interpolated: 0,
        };
        let f0 = dominant_frequency(&u, 0.2, 14.0).unwrap();
        assert!((f0 - f).abs() < 0.1, "{f0}");
        let on = onset(&u);
        let r = on.release.unwrap();
        assert!((r.time_s - release_s).abs() < 0.1, "{r:?}");
        assert!((r.held_level - 0.3).abs() < 0.01);
        assert!(r.held_s > 1.5, "{r:?}");
        assert!(on.decay_ratio > 4.0);
    }
}
