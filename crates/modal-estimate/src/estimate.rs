//! The estimator: method choice, free decay (matrix pencil + Levenberg–Marquardt), ambient
//! records (random decrement), the paper's baseline, and the warnings that go with them.

use std::fmt;

use serde::{Serialize, Serializer};

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

/// Something the caller should know about an estimate.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Warning {
    /// Missing samples or irregular timestamps were bridged by linear interpolation for the
    /// spectrum or the matrix pencil (the fit itself uses the measured samples only).
    Interpolated {
        /// Grid samples interpolated.
        samples: usize,
    },
    /// No held stretch before the motion: the decay is taken from the record's start.
    NoRelease,
    /// The segment holds few cycles of the dominant mode.
    ShortDecay {
        /// Cycles in the segment.
        cycles: f64,
    },
    /// Damping ratio too uncertain to trust.
    DampingUncertain {
        /// Coefficient of variation of the damping ratio.
        cov: f64,
        /// Cycles in the record.
        cycles: f64,
        /// Cycles that would bring the c.o.v. to the configured limit.
        cycles_needed: f64,
    },
    /// Fewer modes found than asked for.
    ModesNotResolved {
        /// Asked for.
        requested: usize,
        /// Found.
        found: usize,
    },
    /// The nonlinear fit stopped at its iteration limit.
    NotConverged {
        /// Iterations run.
        iterations: usize,
    },
    /// The half-power band did not close on one side: no damping ratio.
    HalfPowerOpen,
    /// The paper's method has no uncertainty model: the frequency standard error given is
    /// the bin quantisation (bin width / sqrt 12), the damping's is unknown.
    PaperUncertainty {
        /// Bin width, hertz.
        bin_width_hz: f64,
    },
    /// The record was judged ambient (no release, no decay).
    Ambient {
        /// Random-decrement segments averaged.
        triggers: usize,
    },
    /// The mode found is far from the record's spectral peak.
    FarFromPeak {
        /// The mode's frequency, hertz.
        frequency_hz: f64,
        /// The peak's, hertz.
        peak_hz: f64,
    },
    /// A mode outside the band searched (the fit or the spectrum's edge pulled it out).
    OutsideBand {
        /// The mode's frequency, hertz.
        frequency_hz: f64,
        /// Lower band edge, hertz.
        low_hz: f64,
        /// Upper band edge, hertz.
        high_hz: f64,
    },
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Interpolated { samples } => write!(
                f,
                "{samples} missing or irregular samples were interpolated for the spectrum and the matrix pencil; the fit uses measured samples only"
            ),
            Self::NoRelease => write!(
                f,
                "no held stretch before the motion: the decay is taken from the start of the record"
            ),
            Self::ShortDecay { cycles } => write!(
                f,
                "the decay segment holds only {cycles:.1} cycles; frequency and damping are uncertain"
            ),
            Self::DampingUncertain {
                cov,
                cycles,
                cycles_needed,
            } => write!(
                f,
                "damping ratio c.o.v. is {:.0} % with {cycles:.0} cycles (Au's rule 1/sqrt(2 pi xi N)); about {cycles_needed:.0} cycles are needed for a trustworthy damping",
                100.0 * cov
            ),
            Self::ModesNotResolved { requested, found } => {
                write!(f, "{requested} modes requested, {found} could be resolved")
            }
            Self::NotConverged { iterations } => write!(
                f,
                "the nonlinear fit stopped after {iterations} iterations without converging"
            ),
            Self::HalfPowerOpen => write!(
                f,
                "the half-power band does not close on both sides of the peak: no damping ratio"
            ),
            Self::PaperUncertainty { bin_width_hz } => write!(
                f,
                "the paper's method has no uncertainty model: frequency_std_hz is the bin quantisation ({bin_width_hz:.4} Hz / sqrt 12), damping_std is unknown"
            ),
            Self::Ambient { triggers } => write!(
                f,
                "no free decay: treated as an ambient record (random decrement over {triggers} triggers)"
            ),
            Self::FarFromPeak {
                frequency_hz,
                peak_hz,
            } => write!(
                f,
                "the mode found ({frequency_hz:.4} Hz) is far from the record's spectral peak ({peak_hz:.4} Hz): check the band (--band) and the column"
            ),
            Self::OutsideBand {
                frequency_hz,
                low_hz,
                high_hz,
            } => write!(
                f,
                "a mode at {frequency_hz:.4} Hz lies outside the band searched ({low_hz:.4}..{high_hz:.4} Hz)"
            ),
        }
    }
}

impl Serialize for Warning {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
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

#[allow(clippy::too_many_lines)] // longer than 100 lines; to be split by concept (issue 21)
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
    let method = match config.method {
        Method::Auto => {
            let cycles = guess_hz * signal.duration_s();
            if on.decay_ratio >= AMBIENT_MAX_DECAY_RATIO || cycles < AMBIENT_MIN_CYCLES {
                Method::Pencil
            } else {
                Method::Ambient
            }
        }
        m => m,
    };
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

/// Free decay from `release_s` (or the record's start): skip, fit, trim the tail, refit.
fn free_decay(
    signal: &Signal,
    release_s: Option<f64>,
    guess_hz: f64,
    band: (f64, f64),
    config: &EstimateConfig,
    warnings: &mut Vec<Warning>,
) -> Result<Estimate> {
    let times = signal.times_s();
    let t_last = times[times.len() - 1];
    let from_s = release_s.unwrap_or(times[0]);
    let after = signal.slice_time(from_s, t_last);
    let f0 = peak_frequency(&after, band.0, band.1).unwrap_or(guess_hz);
    let seg_cfg = &config.segment;
    let mut start_s = from_s + seg_cfg.skip_cycles / f0;
    if (t_last - start_s) * f0 < seg_cfg.min_cycles.max(1.0) {
        start_s = from_s;
    }
    let part = signal.slice_time(start_s, t_last);
    let mut fitted = fit_modes(&part, start_s, f0, band, config, warnings)?;
    let mut end_s = t_last;
    if let Some(factor) = seg_cfg.end_noise_factor {
        let limit = factor * fitted.residual_rms;
        let envelope = |t: f64| {
            fitted
                .modes
                .iter()
                .map(|m| m.amplitude * (-m.decay_rate_per_s * (t - start_s)).exp())
                .sum::<f64>()
        };
        let min_end = start_s + seg_cfg.min_cycles / f0;
        if let Some(&t_cut) = part
            .times_s()
            .iter()
            .find(|&&t| t > min_end && envelope(t) < limit)
        {
            let shorter = signal.slice_time(start_s, t_cut);
            let guesses = fitted.guesses();
            if let Ok(refit) = fit(
                &shorter.present().0,
                &shorter.present().1,
                start_s,
                &guesses,
                &bounds(&shorter, band),
                config.drift,
            ) {
                fitted = refit;
                end_s = t_cut;
            }
        }
    }
    let dominant = fitted
        .modes
        .iter()
        .max_by(|a, b| a.amplitude.total_cmp(&b.amplitude))
        .map_or(f0, |m| m.frequency_hz);
    let cycles = dominant * (end_s - start_s);
    if cycles < seg_cfg.min_cycles.max(2.0) {
        warnings.push(Warning::ShortDecay { cycles });
    }
    if !fitted.converged {
        warnings.push(Warning::NotConverged {
            iterations: fitted.iterations,
        });
    }
    let mut modes = fitted.modes.clone();
    modes.sort_by(|a, b| b.amplitude.total_cmp(&a.amplitude));
    if let Some(m) = modes.first()
        && let Some(sd) = m.damping_std
    {
        let cov = sd / m.damping_ratio.max(1e-12);
        if cov > config.max_damping_cov {
            warnings.push(Warning::DampingUncertain {
                cov,
                cycles,
                cycles_needed: cycles * (cov / config.max_damping_cov).powi(2),
            });
        }
    }
    Ok(Estimate {
        method: Method::Pencil,
        estimator: Estimator::FreeDecay,
        modes,
        segment: Some(Segment {
            release: None,
            start_s,
            end_s,
            skip_frequency_hz: f0,
            cycles,
        }),
        half_power: None,
        residual_rms: Some(fitted.residual_rms),
        warnings: Vec::new(),
    })
}

fn bounds(part: &Signal, band: (f64, f64)) -> Bounds {
    let nyquist = part.nyquist_hz().unwrap_or(band.1);
    Bounds {
        omega_min: TAU * 0.5 * band.0,
        omega_max: TAU * nyquist.min(band.1.max(band.0)),
        // xi up to 0.9.
        sigma_over_omega_max: 2.0,
    }
}

/// Starting poles: matrix pencil on the uniform grid (decimated to about 8 samples per
/// period of `f0`), completed by spectral peaks, ranked by their least-squares amplitude.
fn starting_poles(
    part: &Signal,
    t_ref: f64,
    f0: f64,
    band: (f64, f64),
    kmax: usize,
    drift: bool,
) -> Vec<ModeGuess> {
    let (t, y) = part.present();
    let in_band = |g: &ModeGuess| {
        let f = g.omega / TAU;
        f >= band.0 * 0.9 && f <= band.1 && g.sigma > -0.05 * g.omega && g.sigma < 2.0 * g.omega
    };
    let mut guesses: Vec<ModeGuess> = Vec::new();
    if let Ok(u) = part.resample_uniform(None) {
        let fs = u.sample_rate_hz();
        let decimation = ((fs / (8.0 * f0)).floor() as usize).max(1);
        let order = 2 * kmax + 2;
        if let Ok(poles) = pencil_poles(&u.values, u.interval_s, order, decimation) {
            guesses.extend(poles.into_iter().filter(in_band).map(|g| ModeGuess {
                sigma: g.sigma.max(0.0),
                omega: g.omega,
            }));
        }
        // Spectral peaks the pencil missed.
        let s = crate::spectrum::spectrum_uniform(
            &u,
            &SpectrumConfig {
                zero_padding: 4,
                ..SpectrumConfig::default()
            },
        );
        for p in s.peaks_in(band.0, band.1, 0.02).iter().take(kmax + 1) {
            let omega = TAU * p.refined_frequency_hz;
            if !guesses
                .iter()
                .any(|g| (g.omega - omega).abs() < 0.05 * omega)
            {
                guesses.push(ModeGuess {
                    sigma: 0.05 * omega,
                    omega,
                });
            }
        }
    }
    if guesses.is_empty() {
        guesses.push(ModeGuess {
            sigma: 0.05 * TAU * f0,
            omega: TAU * f0,
        });
    }
    // Rank by the variance each pole explains on its own (with offset and drift): joint
    // least squares would give near-duplicate poles huge cancelling amplitudes, and a
    // single pole's amplitude can be large where its basis is small.
    let base = linear_amplitudes(&t, &y, t_ref, &[], drift).map_or(f64::INFINITY, |p| {
        crate::fit::residual_sum(&t, &y, t_ref, &p, drift)
    });
    let mut ranked: Vec<(f64, ModeGuess)> = guesses
        .iter()
        .filter(|g| g.sigma < g.omega)
        .map(|g| {
            let explained = linear_amplitudes(&t, &y, t_ref, std::slice::from_ref(g), drift)
                .map_or(0.0, |p| {
                    base - crate::fit::residual_sum(&t, &y, t_ref, &p, drift)
                });
            (explained, *g)
        })
        .collect();
    ranked.sort_by(|a, b| b.0.total_cmp(&a.0));
    // Poles that explain less than 1 % of what the best one does are noise.
    let best = ranked.first().map_or(0.0, |r| r.0);
    ranked
        .into_iter()
        .filter(|(e, _)| *e >= 0.01 * best)
        .map(|(_, g)| g)
        .collect()
}

/// Fit 1..=kmax modes and keep the best by BIC (or exactly `config.modes`).
fn fit_modes(
    part: &Signal,
    t_ref: f64,
    f0: f64,
    band: (f64, f64),
    config: &EstimateConfig,
    warnings: &mut Vec<Warning>,
) -> Result<Fit> {
    let kmax = config.modes.unwrap_or(config.max_modes);
    let mut guesses = starting_poles(part, t_ref, f0, band, kmax, config.drift);
    let (t, y) = part.present();
    let b = bounds(part, band);
    if let Some(k) = config.modes {
        if guesses.len() < k {
            warnings.push(Warning::ModesNotResolved {
                requested: k,
                found: guesses.len(),
            });
        }
        return fit(
            &t,
            &y,
            t_ref,
            &guesses[..k.min(guesses.len())],
            &b,
            config.drift,
        );
    }
    if guesses.is_empty() {
        return Err(ModalError::NoPeak {
            low_hz: band.0,
            high_hz: band.1,
        });
    }
    let mut best = fit(&t, &y, t_ref, &guesses[..1], &b, config.drift)?;
    let n = t.len() as f64;
    let bic_gain_needed = 4.0 * n.ln() + BIC_MARGIN;
    for k in 2..=kmax.min(guesses.len()) {
        // A cheap look first: what each pole not yet used explains of the residual at fixed
        // decay and frequency; the one that explains most is tried next. Not even half the
        // needed gain there, and the full fit is not tried.
        let resid = crate::fit::residuals(&t, &y, t_ref, &best.params, config.drift);
        let before: f64 = resid.iter().map(|r| r * r).sum();
        let (next, explained) = (k - 1..guesses.len())
            .map(|j| {
                let gain = linear_amplitudes(&t, &resid, t_ref, &guesses[j..=j], false)
                    .map_or(0.0, |p| {
                        before - crate::fit::residual_sum(&t, &resid, t_ref, &p, false)
                    });
                (j, gain)
            })
            .fold(
                (k - 1, f64::NEG_INFINITY),
                |a, b| if b.1 > a.1 { b } else { a },
            );
        if explained.is_nan() || explained / (best.rss / n) < 0.5 * bic_gain_needed {
            break;
        }
        guesses.swap(k - 1, next);
        let Ok(candidate) = fit(&t, &y, t_ref, &guesses[..k], &b, config.drift) else {
            break;
        };
        if candidate.bic() < best.bic() - BIC_MARGIN && modes_are_distinct(&candidate) {
            best = candidate;
        } else {
            break;
        }
    }
    Ok(best)
}

/// Every mode significant (amplitude over 4 standard errors), below xi 0.5, and no two
/// within 3 % in frequency.
fn modes_are_distinct(fit: &Fit) -> bool {
    let ok = fit
        .modes
        .iter()
        .all(|m| m.damping_ratio < 0.5 && m.amplitude_std.is_some_and(|s| m.amplitude > 4.0 * s));
    let mut f: Vec<f64> = fit.modes.iter().map(|m| m.frequency_hz).collect();
    f.sort_by(f64::total_cmp);
    ok && f.windows(2).all(|w| w[1] > 1.03 * w[0])
}

/// The ambient search band's lower edge and the record's sway peak in it.
///
/// The lower edge leaves out what random decrement could not average (it needs 40 cycles)
/// and sensor drift (Jackson et al. 2021 advise a 10-minute high-pass for their records).
/// When the method is chosen automatically and no band was given, the mode must show 200
/// cycles (`AMBIENT_MIN_CYCLES`, what makes a record ambient): below that lie the gusts,
/// whose spectrum has its own bumps.
///
/// A sway mode stands out of the wind's falling spectrum by a factor: the Welch peak that
/// rises most over its saddle (value / (value - prominence)) is the mode, not the tallest
/// one, which on a real record is the gusts' low-frequency end. (Welch detrends each
/// segment; a falling spectrum's edge at the lower edge is no peak, its left neighbour being
/// higher.)
fn sway_peak(
    uniform: &UniformSignal,
    guess_hz: f64,
    low_hz: f64,
    high_hz: f64,
    config: &EstimateConfig,
) -> (f64, Option<f64>) {
    let n = uniform.values.len();
    let dt = uniform.interval_s;
    let duration_s = n as f64 * dt;
    let cycles_floor = if config.method == Method::Auto && config.band_hz.is_none() {
        AMBIENT_MIN_CYCLES
    } else {
        AMBIENT_RD_CYCLES
    };
    let low_hz = low_hz.max(
        AMBIENT_DRIFT_HZ
            .max(cycles_floor / duration_s)
            .min(0.5 * high_hz),
    );
    // Welch segments of about a sixteenth of the record (at least 64 periods of the guess
    // when the record allows).
    let segment = (n / 16).max(((64.0 / guess_hz) / dt) as usize).min(n);
    let psd = welch(uniform, segment);
    let low = low_hz.max(2.0 * psd.resolution_hz);
    let ratio = |p: &crate::spectrum::Peak| {
        let saddle = p.value - p.prominence;
        if saddle > 0.0 {
            p.value / saddle
        } else {
            f64::INFINITY
        }
    };
    let peak_hz = psd
        .peaks_in(low, high_hz, 0.0)
        .iter()
        .max_by(|a, b| ratio(a).total_cmp(&ratio(b)))
        .map(|p| p.refined_frequency_hz);
    (low_hz, peak_hz)
}

fn ambient_estimate(
    uniform: &UniformSignal,
    signal: &Signal,
    guess_hz: f64,
    low_hz: f64,
    high_hz: f64,
    config: &EstimateConfig,
    warnings: &mut Vec<Warning>,
) -> Result<Estimate> {
    let n = uniform.values.len();
    let dt = uniform.interval_s;
    let nyquist = 0.5 / dt;
    let (low_hz, peak_hz) = sway_peak(uniform, guess_hz, low_hz, high_hz, config);
    let f0 = peak_hz.unwrap_or(guess_hz);
    let x = band_pass(
        &uniform.values,
        dt,
        (0.5 * f0).max(low_hz),
        (2.5 * f0).min(0.95 * nyquist),
    );
    let rms = (x.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
    let length = ((10.0 / f0) / dt).round() as usize;
    if length < 16 || length * 4 > n {
        return Err(ModalError::TooFewSamples {
            what: "random decrement (40 cycles)",
            present: n,
            needed: ((40.0 / f0) / dt).ceil() as usize,
        });
    }
    let rd = random_decrement(&x, dt, rms, length);
    let sig = Signal::new(
        (0..length).map(|i| i as f64 * dt).collect(),
        rd.values.iter().map(|&v| Some(v)).collect(),
    )?;
    let sig_config = EstimateConfig {
        modes: Some(config.modes.unwrap_or(1)),
        segment: SegmentConfig {
            detect_release: false,
            skip_cycles: 0.0,
            ..config.segment
        },
        ..*config
    };
    let mut inner = Vec::new();
    let mut est = free_decay(
        &sig,
        None,
        f0,
        (0.5 * f0, (2.5 * f0).min(nyquist)),
        &sig_config,
        &mut inner,
    )?;
    warnings.push(Warning::Ambient {
        triggers: rd.triggers,
    });
    let cycles_total = signal.duration_s();
    for m in &mut est.modes {
        let cycles = m.frequency_hz * cycles_total;
        let (cov_f, cov_xi) = au_uncertainty(m.damping_ratio, cycles);
        m.frequency_std_hz = Some(m.frequency_hz * cov_f);
        m.damping_std = Some(m.damping_ratio * cov_xi);
        m.reference_time_s = signal.times_s()[0];
    }
    if let Some(m) = est.modes.first() {
        let cycles = m.frequency_hz * cycles_total;
        let (_, cov) = au_uncertainty(m.damping_ratio, cycles);
        if cov > config.max_damping_cov {
            warnings.push(Warning::DampingUncertain {
                cov,
                cycles,
                cycles_needed: au_cycles_needed(m.damping_ratio, config.max_damping_cov),
            });
        }
    }
    if let (Some(m), Some(peak_hz)) = (est.modes.first(), peak_hz)
        && (m.frequency_hz / peak_hz - 1.0).abs() > FAR_FROM_PEAK
    {
        warnings.push(Warning::FarFromPeak {
            frequency_hz: m.frequency_hz,
            peak_hz,
        });
    }
    est.estimator = Estimator::RandomDecrement;
    est.method = Method::Ambient;
    est.segment = None;
    Ok(est)
}
