//! The estimator: method choice, free decay (matrix pencil + Levenberg–Marquardt), ambient
//! records (random decrement), the paper's baseline, and the warnings that go with them.

use serde::Serialize;

mod decay;
mod sway;
mod warning;

use decay::free_decay;
use sway::{ambient_estimate, sway_peak};
pub use warning::Warning;

use crate::ambient::{au_cycles_needed, au_uncertainty, band_pass, random_decrement, welch};
use crate::error::{ModalError, Result};
use crate::fit::{Bounds, Fit, Mode, ModeGuess, fit, linear_amplitudes};
use crate::paper::{HalfPower, half_power};
use crate::pencil::pencil_poles;
use crate::segment::{Segment, SegmentConfig, dominant_frequency, onset, peak_frequency};
use crate::signal::{Signal, UniformSignal};
use crate::spectrum::{SpectrumConfig, spectrum};

const TAU: f64 = std::f64::consts::TAU;

/// In `Method::Auto`, a record whose motion after its largest burst exceeds its tail's by
/// this much is a free decay (wind sway keeps its level).
const AMBIENT_MAX_DECAY_RATIO: f64 = 3.0;

/// In `Method::Auto`, a record needs this many cycles to be treated as ambient: random
/// decrement averages segments of 10 cycles and needs many of them.
const AMBIENT_MIN_CYCLES: f64 = 200.0;

/// Ambient records are high-passed above this (a 10-minute period: Jackson et al. 2021,
/// "The motion of trees in the wind: a data synthesis", advise it against sensor drift).
const AMBIENT_DRIFT_HZ: f64 = 1.0 / 600.0;

/// Random decrement averages segments of 10 cycles and needs 4 of them: 40 cycles.
const AMBIENT_RD_CYCLES: f64 = 40.0;

/// An ambient answer more than this fraction from the record's sway peak is doubtful.
const FAR_FROM_PEAK: f64 = 0.15;

/// A further mode must lower the Bayesian information criterion by this much on top of its
/// parameter cost ("very strong" evidence on the Kass & Raftery scale).
const BIC_MARGIN: f64 = 10.0;

/// Which estimator to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Free decay when the record holds one (motion that dies out after its largest burst,
    /// or too few cycles for anything else), otherwise ambient.
    Auto,
    /// The paper's FFT peak and half-power band, eq. (6).
    Paper,
    /// Free decay: matrix pencil, then bounded Levenberg–Marquardt on the timestamps.
    Pencil,
    /// Ambient: random decrement, then the free-decay fit on its signature.
    Ambient,
}

impl Method {
    /// The name used on the command line and in JSON.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Paper => "paper",
            Self::Pencil => "pencil",
            Self::Ambient => "ambient",
        }
    }
}

impl std::str::FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "auto" => Ok(Self::Auto),
            "paper" => Ok(Self::Paper),
            "pencil" => Ok(Self::Pencil),
            "ambient" => Ok(Self::Ambient),
            other => Err(format!(
                "unknown method {other:?} (expected auto, paper, pencil or ambient)"
            )),
        }
    }
}

/// What actually ran.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Estimator {
    /// Matrix pencil and Levenberg–Marquardt on a free decay.
    FreeDecay,
    /// Random decrement signature, fitted as a free decay.
    RandomDecrement,
    /// The paper's FFT half-power method.
    HalfPower,
}

/// Estimation settings. `Default`: automatic method, up to 3 modes chosen by BIC, the band
/// from 1.5 cycles per record to the Nyquist frequency, [`SegmentConfig::default`], offset and
/// drift fitted, damping warning above a c.o.v. of 0.3.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EstimateConfig {
    /// The estimator.
    pub method: Method,
    /// Exactly this many modes; `None` chooses 1..=`max_modes` by the Bayesian information
    /// criterion, keeping a mode only when its amplitude is significant.
    pub modes: Option<usize>,
    /// Most modes tried when `modes` is `None`.
    pub max_modes: usize,
    /// Frequencies searched, hertz; `None` from 1.5 cycles per record to Nyquist.
    pub band_hz: Option<(f64, f64)>,
    /// How a free decay is cut out.
    pub segment: SegmentConfig,
    /// Fit a linear drift as well as an offset.
    pub drift: bool,
    /// Warn when the damping ratio's coefficient of variation (standard error over value,
    /// or Au's rule for ambient records) exceeds this.
    pub max_damping_cov: f64,
}

impl Default for EstimateConfig {
    fn default() -> Self {
        Self {
            method: Method::Auto,
            modes: None,
            max_modes: 3,
            band_hz: None,
            segment: SegmentConfig::default(),
            drift: true,
            max_damping_cov: 0.3,
        }
    }
}

impl EstimateConfig {
    /// The paper's method (section 5.3): FFT with a rectangular window from the release to
    /// the end of the record (the whole record when it holds no held stretch), the highest
    /// peak, eq. (6).
    #[must_use]
    pub fn paper() -> Self {
        Self {
            method: Method::Paper,
            modes: Some(1),
            segment: SegmentConfig {
                detect_release: true,
                skip_cycles: 0.0,
                end_noise_factor: None,
                min_cycles: 0.0,
            },
            ..Self::default()
        }
    }

    /// Check ranges.
    ///
    /// # Errors
    /// [`ModalError::InvalidParameter`] or [`ModalError::InvalidBand`].
    pub fn validate(&self) -> Result<()> {
        self.segment.validate()?;
        if let Some(k) = self.modes
            && !(1..=8).contains(&k)
        {
            return Err(ModalError::InvalidParameter {
                name: "modes",
                reason: format!("{k} (expected 1 to 8)"),
            });
        }
        if !(1..=8).contains(&self.max_modes) {
            return Err(ModalError::InvalidParameter {
                name: "max_modes",
                reason: format!("{} (expected 1 to 8)", self.max_modes),
            });
        }
        if !(self.max_damping_cov.is_finite() && self.max_damping_cov > 0.0) {
            return Err(ModalError::InvalidParameter {
                name: "max_damping_cov",
                reason: format!("{} (expected positive and finite)", self.max_damping_cov),
            });
        }
        if let Some((low_hz, high_hz)) = self.band_hz
            && !(low_hz.is_finite() && high_hz.is_finite() && low_hz >= 0.0 && low_hz < high_hz)
        {
            return Err(ModalError::InvalidBand { low_hz, high_hz });
        }
        Ok(())
    }
}

/// The result of [`estimate`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Estimate {
    /// The method asked for.
    pub method: Method,
    /// What ran.
    pub estimator: Estimator,
    /// Modes, largest amplitude first.
    pub modes: Vec<Mode>,
    /// The part of the record used.
    pub segment: Option<Segment>,
    /// The paper method's reading, when it ran.
    pub half_power: Option<HalfPower>,
    /// RMS of the fit's residual (the noise level), in the signal's unit.
    pub residual_rms: Option<f64>,
    /// What the caller should know.
    pub warnings: Vec<Warning>,
}

/// A mode within this relative distance of an excluded frequency is that frequency's mode
/// (4 %: the spread of one mode's estimates across a tree's levels in the paper's Table 1).
pub const OWN_MODE_TOLERANCE: f64 = 0.04;

/// Fewest cycles a mode must complete in the fitted segment to be a swing rather than the
/// fit's stand-in for a slow trend.
pub const MIN_SWING_CYCLES: f64 = 2.0;

impl Estimate {
    /// The strongest mode that is a swing (at least [`MIN_SWING_CYCLES`] cycles in the fitted
    /// segment) and none of `excluded_hz` (within [`OWN_MODE_TOLERANCE`]): a branch's own
    /// mode when its relative angle also carries its ancestors' swings (the paper's Fig. 12:
    /// higher levels show more modes, the stem's among them). Modes are in the estimate's
    /// order (largest amplitude first).
    pub fn own_mode(&self, excluded_hz: &[f64]) -> Option<Mode> {
        let span_s = self.segment.map_or(f64::INFINITY, |s| s.end_s - s.start_s);
        self.modes
            .iter()
            .find(|m| {
                m.frequency_hz * span_s >= MIN_SWING_CYCLES
                    && !excluded_hz
                        .iter()
                        .any(|f| (m.frequency_hz - f).abs() <= OWN_MODE_TOLERANCE * f)
            })
            .copied()
    }
}

/// The band searched: configured or from 1.5 cycles per record to Nyquist.
fn search_band(signal: &Signal, config: &EstimateConfig) -> Result<(f64, f64)> {
    let nyquist_hz = signal.nyquist_hz().ok_or(ModalError::TooFewSamples {
        what: "modal estimation",
        present: signal.len(),
        needed: 8,
    })?;
    let duration_s = signal.duration_s();
    match config.band_hz {
        Some((low_hz, high_hz)) => {
            if high_hz > nyquist_hz * (1.0 + 1e-9) {
                return Err(ModalError::BandAboveNyquist {
                    high_hz,
                    nyquist_hz,
                });
            }
            let needed_s = 1.0 / high_hz;
            if duration_s < needed_s {
                return Err(ModalError::RecordTooShort {
                    duration_s,
                    frequency_hz: high_hz,
                    needed_s,
                });
            }
            Ok((low_hz, high_hz))
        }
        None => {
            let low_hz = 1.5 / duration_s;
            if low_hz >= nyquist_hz {
                return Err(ModalError::RecordTooShort {
                    duration_s,
                    frequency_hz: nyquist_hz,
                    needed_s: 1.5 / nyquist_hz,
                });
            }
            Ok((low_hz, nyquist_hz))
        }
    }
}

/// Estimate natural frequencies and damping ratios.
///
/// # Errors
/// Invalid configuration, the input errors of [`Signal`] checks ([`ModalError::AllMissing`],
/// [`ModalError::Constant`], [`ModalError::TooFewSamples`]), a band beyond Nyquist, a record
/// shorter than a cycle, no spectral peak, or a numerical failure.
pub fn estimate(signal: &Signal, config: &EstimateConfig) -> Result<Estimate> {
    config.validate()?;
    signal.check_usable("modal estimation", 8)?;
    // Every step below (spectra, Hankel products, least squares) squares the values: on a
    // record in units of 1e155 they overflow and the SVD never converges, in units of 1e-160
    // they underflow. The estimate runs on the record centred and scaled to a unit spread,
    // and the amplitudes are scaled back; frequency and damping do not depend on the unit.
    let scale = ValueScale::of(signal)?;
    let mut est = estimate_normalised(&scale.apply(signal)?, config)?;
    scale.restore(&mut est);
    Ok(est)
}

/// A normalised value further from the record's centre than this many spreads is not a
/// measurement: no sensor has a dynamic range of 1e9 (180 dB; a 24-bit converter has 1.7e7).
const OUTLIER_SPREADS: f64 = 1e9;

/// Centre and spread of a record's values, for normalising them.
#[derive(Debug, Clone, Copy)]
struct ValueScale {
    centre: f64,
    spread: f64,
}

impl ValueScale {
    /// The median and the median absolute deviation from it (the largest deviation where
    /// more than half the samples sit exactly at the median, as on a noiseless hold).
    fn of(signal: &Signal) -> Result<Self> {
        let mut v: Vec<f64> = signal.values().iter().flatten().copied().collect();
        let centre = median_in_place(&mut v);
        let mut dev: Vec<f64> = v.iter().map(|x| (x - centre).abs()).collect();
        let mut spread = median_in_place(&mut dev);
        if !(spread > 0.0 && spread.is_finite()) {
            spread = dev.iter().copied().fold(0.0, f64::max);
        }
        if !(spread > 0.0 && spread.is_finite()) {
            return Err(ModalError::Constant { value: centre });
        }
        Ok(Self { centre, spread })
    }

    /// The record centred and divided by the spread.
    ///
    /// # Errors
    /// [`ModalError::Outlier`] for a value more than [`OUTLIER_SPREADS`] from the centre.
    fn apply(&self, signal: &Signal) -> Result<Signal> {
        let times = signal.times_s();
        let mut values = Vec::with_capacity(signal.len());
        for (index, v) in signal.values().iter().enumerate() {
            values.push(match *v {
                None => None,
                Some(v) => {
                    let z = (v - self.centre) / self.spread;
                    if z.is_nan() || z.abs() > OUTLIER_SPREADS {
                        return Err(ModalError::Outlier {
                            index,
                            time_s: times[index],
                            value: v,
                            spreads: z.abs(),
                        });
                    }
                    Some(z)
                }
            });
        }
        Signal::new(times.to_vec(), values)
    }

    /// Amplitudes and residuals back in the record's unit.
    fn restore(&self, est: &mut Estimate) {
        let s = self.spread;
        for m in &mut est.modes {
            m.amplitude *= s;
            m.amplitude_std = m.amplitude_std.map(|a| a * s);
        }
        est.residual_rms = est.residual_rms.map(|r| r * s);
        if let Some(hp) = est.half_power.as_mut() {
            hp.peak_value *= s;
        }
    }
}

/// The median of `v` (reordered), 0 for an empty slice.
fn median_in_place(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

/// The method that runs: `Auto` is a free decay (pencil) when the record's envelope decays
/// by `decay_ratio` of at least `AMBIENT_MAX_DECAY_RATIO` or it holds fewer than
/// `AMBIENT_MIN_CYCLES` `cycles` of its dominant frequency, ambient otherwise.
fn chosen_method(asked: Method, decay_ratio: f64, cycles: f64) -> Method {
    match asked {
        Method::Auto if decay_ratio >= AMBIENT_MAX_DECAY_RATIO || cycles < AMBIENT_MIN_CYCLES => {
            Method::Pencil
        }
        Method::Auto => Method::Ambient,
        m => m,
    }
}

fn estimate_normalised(signal: &Signal, config: &EstimateConfig) -> Result<Estimate> {
    let (low_hz, high_hz) = search_band(signal, config)?;
    let uniform = signal.resample_uniform(None)?;
    let mut warnings = Vec::new();
    if uniform.interpolated > 0 {
        warnings.push(Warning::Interpolated {
            samples: uniform.interpolated,
        });
    }
    let guess_hz = dominant_frequency(&uniform, low_hz, high_hz)
        .ok_or(ModalError::NoPeak { low_hz, high_hz })?;
    let on = onset(&uniform);
    let release = if config.segment.detect_release {
        on.release
    } else {
        None
    };
    let method = chosen_method(
        config.method,
        on.decay_ratio,
        guess_hz * signal.duration_s(),
    );
    let ambient = |warnings: &mut Vec<Warning>| {
        ambient_estimate(
            &uniform, signal, guess_hz, low_hz, high_hz, config, warnings,
        )
    };
    let mut est = match method {
        Method::Paper => paper_estimate(signal, release, low_hz, high_hz, &mut warnings)?,
        Method::Ambient => ambient(&mut warnings)?,
        _ => {
            let mut decay_warnings = Vec::new();
            if config.segment.detect_release && release.is_none() {
                decay_warnings.push(Warning::NoRelease);
            }
            let decay = free_decay(
                signal,
                release.map(|r| r.time_s),
                guess_hz,
                (low_hz, high_hz),
                config,
                &mut decay_warnings,
            );
            // A long record (10 minutes or more, and 200 cycles of its sway peak) chosen as a
            // free decay by its envelope (a gust, then calm) whose decay fit has no mode near
            // the record's sway peak is wind sway after all.
            // (The peak is looked for down to 40 cycles per record, so that a short record's
            // peak is its decay's mode, not noise above the 200-cycle floor.)
            let sway_hz = if config.method == Method::Auto {
                let forced = EstimateConfig {
                    method: Method::Ambient,
                    ..*config
                };
                sway_peak(&uniform, guess_hz, low_hz, high_hz, &forced).1
            } else {
                None
            };
            let duration_s = signal.duration_s();
            let long = duration_s >= 1.0 / AMBIENT_DRIFT_HZ
                && sway_hz.is_some_and(|f| f * duration_s >= AMBIENT_MIN_CYCLES);
            let inconsistent = match (&decay, sway_hz) {
                (Ok(e), Some(f)) => !e
                    .modes
                    .iter()
                    .any(|m| (m.frequency_hz / f - 1.0).abs() <= FAR_FROM_PEAK),
                (Ok(_), None) => false,
                (Err(_), _) => true,
            };
            if config.method == Method::Auto && inconsistent && long {
                let mut ambient_warnings = Vec::new();
                match ambient(&mut ambient_warnings) {
                    Ok(e) => {
                        warnings.append(&mut ambient_warnings);
                        e
                    }
                    Err(_) => {
                        warnings.append(&mut decay_warnings);
                        decay?
                    }
                }
            } else {
                warnings.append(&mut decay_warnings);
                decay?
            }
        }
    };
    if let Some(seg) = est.segment.as_mut() {
        seg.release = release;
    }
    for m in &est.modes {
        if !(m.frequency_hz >= low_hz * (1.0 - 1e-9) && m.frequency_hz <= high_hz * (1.0 + 1e-9)) {
            warnings.push(Warning::OutsideBand {
                frequency_hz: m.frequency_hz,
                low_hz,
                high_hz,
            });
        }
    }
    est.method = config.method;
    est.warnings = warnings;
    Ok(est)
}

fn paper_estimate(
    signal: &Signal,
    release: Option<crate::segment::Release>,
    low_hz: f64,
    high_hz: f64,
    warnings: &mut Vec<Warning>,
) -> Result<Estimate> {
    let t_last = signal.times_s()[signal.len() - 1];
    let start_s = release.map_or(signal.times_s()[0], |r| r.time_s);
    let part = signal.slice_time(start_s, t_last);
    let s = spectrum(&part, &SpectrumConfig::paper())?;
    let hp = half_power(&s, low_hz, high_hz)?;
    warnings.push(Warning::PaperUncertainty {
        bin_width_hz: hp.bin_width_hz,
    });
    let modes = match hp.damping_ratio {
        Some(xi) => vec![Mode {
            frequency_hz: hp.frequency_hz,
            frequency_std_hz: Some(hp.bin_width_hz / 12f64.sqrt()),
            damping_ratio: xi,
            damping_std: None,
            damped_frequency_hz: hp.frequency_hz,
            decay_rate_per_s: TAU * hp.frequency_hz * xi,
            amplitude: hp.peak_value,
            amplitude_std: None,
            phase_rad: 0.0,
            reference_time_s: start_s,
        }],
        None => {
            warnings.push(Warning::HalfPowerOpen);
            Vec::new()
        }
    };
    Ok(Estimate {
        method: Method::Paper,
        estimator: Estimator::HalfPower,
        modes,
        segment: Some(Segment {
            release,
            start_s,
            end_s: t_last,
            skip_frequency_hz: hp.frequency_hz,
            cycles: hp.frequency_hz * (t_last - start_s),
        }),
        half_power: Some(hp),
        residual_rms: None,
        warnings: Vec::new(),
    })
}
