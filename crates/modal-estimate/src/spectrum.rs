//! One-sided spectra of a record (rustfft): detrending, windows, zero-padding, amplitude or
//! power spectral density with units, and a peak list with prominence.

use std::cell::RefCell;
use std::sync::Arc;

use rustfft::{Fft, FftPlanner, num_complex::Complex};
use serde::Serialize;

use crate::error::{ModalError, Result};
use crate::signal::{Signal, UniformSignal};

thread_local! {
    /// One planner per thread: it keeps the plans (twiddle factors) of the lengths used.
    static PLANNER: RefCell<FftPlanner<f64>> = RefCell::new(FftPlanner::new());
}

/// A forward or inverse FFT of length `n` from the thread's planner.
pub(crate) fn fft_plan(n: usize, inverse: bool) -> Arc<dyn Fft<f64>> {
    PLANNER.with(|p| {
        let mut p = p.borrow_mut();
        if inverse {
            p.plan_fft_inverse(n)
        } else {
            p.plan_fft_forward(n)
        }
    })
}

/// Taper applied before the FFT.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Window {
    /// No taper (the paper's choice): the narrowest main lobe, the highest leakage.
    Rectangular,
    /// Hann (raised cosine): sidelobes fall at 18 dB per octave.
    Hann,
    /// Hamming: lower first sidelobe than Hann, slower fall-off.
    Hamming,
    /// Blackman (0.42, 0.5, 0.08): low leakage, wide main lobe.
    Blackman,
}

impl Window {
    /// The window's weight at sample `i` of `n` (periodic-free, symmetric form).
    #[must_use]
    pub fn weight(self, i: usize, n: usize) -> f64 {
        if n < 2 {
            return 1.0;
        }
        let x = 2.0 * std::f64::consts::PI * i as f64 / (n - 1) as f64;
        match self {
            Self::Rectangular => 1.0,
            Self::Hann => 0.5 - 0.5 * x.cos(),
            Self::Hamming => 0.54 - 0.46 * x.cos(),
            Self::Blackman => 0.42 - 0.5 * x.cos() + 0.08 * (2.0 * x).cos(),
        }
    }
}

/// What is removed before the transform.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Detrend {
    /// Nothing: the mean lands in bin 0 and leaks into the low bins.
    None,
    /// The mean.
    Mean,
    /// A least-squares straight line (offset and drift).
    Linear,
}

/// How the spectrum is scaled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Scaling {
    /// One-sided amplitude, in the signal's unit: a sinusoid of amplitude `a` whose
    /// frequency falls on a bin reads `a` there, whatever the window (divided by the
    /// window's coherent gain).
    Amplitude,
    /// One-sided power spectral density, in unit^2 / Hz: integrating it over frequency gives
    /// the windowed signal's variance (divided by the window's energy).
    PowerSpectralDensity,
}

/// Spectrum settings. `Default`: Hann window, linear detrend, 4x zero-padding, amplitude.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SpectrumConfig {
    /// Taper.
    pub window: Window,
    /// What is removed first.
    pub detrend: Detrend,
    /// FFT length as a multiple of the number of samples (1 = no padding, the bins are then
    /// exactly sample rate / samples); above 1 the length is rounded up to a power of two.
    /// Padding interpolates the spectrum between bins; it does not add resolution.
    pub zero_padding: usize,
    /// Amplitude or PSD.
    pub scaling: Scaling,
}

impl Default for SpectrumConfig {
    fn default() -> Self {
        Self {
            window: Window::Hann,
            detrend: Detrend::Linear,
            zero_padding: 4,
            scaling: Scaling::Amplitude,
        }
    }
}

impl SpectrumConfig {
    /// The paper's FFT (section 5.3): the plain record (mean removed, which any FFT of an
    /// angle series needs for the peak not to be bin 0), rectangular window, no padding,
    /// amplitude.
    #[must_use]
    pub fn paper() -> Self {
        Self {
            window: Window::Rectangular,
            detrend: Detrend::Mean,
            zero_padding: 1,
            scaling: Scaling::Amplitude,
        }
    }

    /// Check ranges.
    ///
    /// # Errors
    /// [`ModalError::InvalidParameter`] when `zero_padding` is 0 or above 64.
    pub fn validate(&self) -> Result<()> {
        if !(1..=64).contains(&self.zero_padding) {
            return Err(ModalError::InvalidParameter {
                name: "zero_padding",
                reason: format!("{} (expected 1 to 64)", self.zero_padding),
            });
        }
        Ok(())
    }
}

/// A one-sided spectrum.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Spectrum {
    /// Bin frequencies, hertz, from 0 to the Nyquist frequency.
    pub frequencies_hz: Vec<f64>,
    /// Amplitude (signal unit) or PSD (unit^2/Hz) per bin, see `scaling`.
    pub values: Vec<f64>,
    /// What `values` are.
    pub scaling: Scaling,
    /// Spacing of the bins, hertz (sample rate / FFT length).
    pub bin_width_hz: f64,
    /// Resolution of the record, hertz (sample rate / samples): the spacing without padding.
    pub resolution_hz: f64,
    /// Sample rate of the uniform grid, hertz.
    pub sample_rate_hz: f64,
    /// Samples transformed.
    pub samples: usize,
    /// Grid samples interpolated across missing samples.
    pub interpolated: usize,
}

/// A local maximum of a spectrum.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Peak {
    /// Bin index.
    pub bin: usize,
    /// Bin frequency, hertz.
    pub frequency_hz: f64,
    /// Frequency refined by a parabola through the bin and its neighbours (log values for a
    /// tapered window), hertz.
    pub refined_frequency_hz: f64,
    /// Spectrum value at the bin.
    pub value: f64,
    /// Height above the higher of the two lowest points that separate it from a higher peak
    /// (or the spectrum's ends): the topographic prominence.
    pub prominence: f64,
}

/// The spectrum of a record: resampled to a uniform grid at its median interval when the
/// timestamps are irregular or samples are missing (linear interpolation, counted in
/// [`Spectrum::interpolated`]), then detrended, windowed, padded and transformed.
///
/// # Errors
/// [`ModalError::TooFewSamples`] below 4 present samples, [`ModalError::Constant`],
/// [`ModalError::AllMissing`], [`ModalError::InvalidParameter`].
pub fn spectrum(signal: &Signal, config: &SpectrumConfig) -> Result<Spectrum> {
    config.validate()?;
    signal.check_usable("a spectrum", 4)?;
    let mut uniform = signal.resample_uniform(None)?;
    // Squares of values near 1e155 overflow and those near 1e-160 vanish: the transform runs
    // on the record divided by its largest magnitude, and the values are scaled back, which
    // must stay inside f64's range.
    let scale = uniform.values.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    if !(scale.is_finite() && scale > 0.0) {
        return Err(ModalError::Numerical {
            what: "the spectrum (the record's magnitude is not a finite positive number)",
        });
    }
    uniform.values.iter_mut().for_each(|v| *v /= scale);
    let mut s = spectrum_uniform(&uniform, config);
    let factor = match config.scaling {
        Scaling::Amplitude => scale,
        Scaling::PowerSpectralDensity => scale * scale,
    };
    // Scaled back, the largest value must stay 6 orders of magnitude above f64's smallest
    // normal number, or the spectrum's shape is lost to underflow.
    let top = s.values.iter().fold(0.0_f64, |m, v| m.max(*v));
    s.values.iter_mut().for_each(|v| *v *= factor);
    if s.values.iter().any(|v| !v.is_finite())
        || (top > 0.0 && top * factor < 1e6 * f64::MIN_POSITIVE)
    {
        return Err(ModalError::Numerical {
            what: "the spectrum (its values leave the range of f64 in this unit: rescale the record)",
        });
    }
    Ok(s)
}

/// The spectrum of samples already on a uniform grid.
#[must_use]
pub fn spectrum_uniform(uniform: &UniformSignal, config: &SpectrumConfig) -> Spectrum {
    let n = uniform.values.len();
    let fs = uniform.sample_rate_hz();
    let mut x = uniform.values.clone();
    detrend(&mut x, config.detrend);
    let weights: Vec<f64> = (0..n).map(|i| config.window.weight(i, n)).collect();
    let coherent: f64 = weights.iter().sum();
    let energy: f64 = weights.iter().map(|w| w * w).sum();
    // Padded transforms round up to a power of two (fast for any record length); without
    // padding the length is the record's, so the bins are exactly fs / n.
    let n_fft = if config.zero_padding > 1 {
        (n * config.zero_padding).next_power_of_two()
    } else {
        n.max(2)
    };
    let mut buf: Vec<Complex<f64>> = vec![Complex::new(0.0, 0.0); n_fft];
    for (b, (v, w)) in buf.iter_mut().zip(x.iter().zip(&weights)) {
        *b = Complex::new(v * w, 0.0);
    }
    fft_plan(n_fft, false).process(&mut buf);
    let bins = n_fft / 2 + 1;
    let bin_width_hz = fs / n_fft as f64;
    let mut values = Vec::with_capacity(bins);
    for (k, c) in buf.iter().take(bins).enumerate() {
        let edge = k == 0 || (n_fft.is_multiple_of(2) && k == n_fft / 2);
        let one_sided = if edge { 1.0 } else { 2.0 };
        values.push(match config.scaling {
            Scaling::Amplitude => one_sided * c.norm() / coherent,
            Scaling::PowerSpectralDensity => one_sided * c.norm_sqr() / (fs * energy),
        });
    }
    Spectrum {
        frequencies_hz: (0..bins).map(|k| k as f64 * bin_width_hz).collect(),
        values,
        scaling: config.scaling,
        bin_width_hz,
        resolution_hz: fs / n as f64,
        sample_rate_hz: fs,
        samples: n,
        interpolated: uniform.interpolated,
    }
}

/// Remove the mean or a least-squares line in place.
pub(crate) fn detrend(x: &mut [f64], how: Detrend) {
    let n = x.len();
    if n == 0 || how == Detrend::None {
        return;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    if how == Detrend::Mean || n < 2 {
        x.iter_mut().for_each(|v| *v -= mean);
        return;
    }
    let ic = (n as f64 - 1.0) / 2.0;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, v) in x.iter().enumerate() {
        let d = i as f64 - ic;
        sxy += d * (v - mean);
        sxx += d * d;
    }
    let slope = sxy / sxx;
    for (i, v) in x.iter_mut().enumerate() {
        *v -= mean + slope * (i as f64 - ic);
    }
}

impl Spectrum {
    /// The unit of `values` given the signal's unit, e.g. `"rad"` or `"rad^2/Hz"`.
    #[must_use]
    pub fn unit(&self, signal_unit: &str) -> String {
        match self.scaling {
            Scaling::Amplitude => signal_unit.to_owned(),
            Scaling::PowerSpectralDensity => format!("{signal_unit}^2/Hz"),
        }
    }

    /// Local maxima above bin 0 in `low_hz..=high_hz` whose prominence is at least
    /// `min_prominence` times the highest value in the band, highest first.
    #[must_use]
    pub fn peaks_in(&self, low_hz: f64, high_hz: f64, min_prominence: f64) -> Vec<Peak> {
        let v = &self.values;
        let n = v.len();
        let in_band = |k: usize| {
            let f = self.frequencies_hz[k];
            k > 0 && f >= low_hz && f <= high_hz
        };
        let top = (0..n)
            .filter(|&k| in_band(k))
            .map(|k| v[k])
            .fold(0.0_f64, f64::max);
        let mut peaks = Vec::new();
        for k in 1..n {
            if !in_band(k) {
                continue;
            }
            let left_ok = v[k] > v[k - 1];
            let right_ok = k + 1 >= n || v[k] >= v[k + 1];
            if !(left_ok && right_ok) {
                continue;
            }
            let prominence = v[k] - self.saddle(k);
            if prominence >= min_prominence * top && prominence > 0.0 {
                peaks.push(Peak {
                    bin: k,
                    frequency_hz: self.frequencies_hz[k],
                    refined_frequency_hz: self.refine(k),
                    value: v[k],
                    prominence,
                });
            }
        }
        peaks.sort_by(|a, b| b.value.total_cmp(&a.value));
        peaks
    }

    /// Peaks over the whole spectrum (bin 0 excluded), see [`Spectrum::peaks_in`].
    #[must_use]
    pub fn peaks(&self, min_prominence: f64) -> Vec<Peak> {
        self.peaks_in(0.0, f64::INFINITY, min_prominence)
    }

    /// The higher of the two minima that separate bin `k` from a higher value on each side.
    fn saddle(&self, k: usize) -> f64 {
        let v = &self.values;
        let mut left_min = v[k];
        for &x in v[..k].iter().rev() {
            if x > v[k] {
                break;
            }
            left_min = left_min.min(x);
        }
        let mut right_min = v[k];
        for &x in &v[k + 1..] {
            if x > v[k] {
                break;
            }
            right_min = right_min.min(x);
        }
        left_min.max(right_min)
    }

    /// Parabolic interpolation of the peak at bin `k` (on log values, exact for a Gaussian
    /// lobe and close for tapered windows).
    fn refine(&self, k: usize) -> f64 {
        let v = &self.values;
        if k == 0 || k + 1 >= v.len() {
            return self.frequencies_hz[k];
        }
        let (a, b, c) = (v[k - 1], v[k], v[k + 1]);
        if a <= 0.0 || b <= 0.0 || c <= 0.0 {
            return self.frequencies_hz[k];
        }
        let (a, b, c) = (a.ln(), b.ln(), c.ln());
        let denom = a - 2.0 * b + c;
        if denom >= 0.0 {
            return self.frequencies_hz[k];
        }
        let delta = (0.5 * (a - c) / denom).clamp(-0.5, 0.5);
        (k as f64 + delta) * self.bin_width_hz
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine(n: usize, fs: f64, f: f64, a: f64) -> Signal {
        let v = (0..n)
            .map(|i| Some(a * (2.0 * std::f64::consts::PI * f * i as f64 / fs).sin() + 0.3))
            .collect();
        Signal::uniform(fs, v).unwrap()
    }

    #[test]
    fn amplitude_scaling_reads_the_sinusoid_amplitude_on_a_bin() {
        // 256 samples at 32 Hz: bins 0.125 Hz apart; 2 Hz is bin 16.
        for window in [
            Window::Rectangular,
            Window::Hann,
            Window::Hamming,
            Window::Blackman,
        ] {
            let config = SpectrumConfig {
                window,
                detrend: Detrend::Mean,
                zero_padding: 1,
                scaling: Scaling::Amplitude,
            };
            let s = spectrum(&sine(256, 32.0, 2.0, 0.7), &config).unwrap();
            let peak = s.peaks(0.1)[0];
            assert_eq!(peak.bin, 16, "{window:?}");
            // Symmetric windows of length n have a coherent gain slightly off the periodic
            // one; within 1 %.
            assert!(
                (peak.value - 0.7).abs() < 0.007,
                "{window:?}: {}",
                peak.value
            );
        }
    }

    #[test]
    fn psd_integrates_to_the_variance() {
        let s = spectrum(
            &sine(1000, 50.0, 3.3, 2.0),
            &SpectrumConfig {
                scaling: Scaling::PowerSpectralDensity,
                window: Window::Rectangular,
                zero_padding: 1,
                detrend: Detrend::Mean,
            },
        )
        .unwrap();
        let total: f64 = s.values.iter().sum::<f64>() * s.bin_width_hz;
        // Variance of a sinusoid of amplitude 2 is 2 (Parseval, within leakage of the
        // non-integer number of cycles).
        assert!((total - 2.0).abs() < 0.02, "{total}");
        assert_eq!(s.unit("rad"), "rad^2/Hz");
    }

    #[test]
    fn prominence_separates_a_real_peak_from_ripple() {
        let fs = 20.0;
        let n = 400;
        let v = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                Some(
                    (2.0 * std::f64::consts::PI * 1.5 * t).sin()
                        + 0.3 * (2.0 * std::f64::consts::PI * 4.0 * t).sin(),
                )
            })
            .collect();
        let s = spectrum(&Signal::uniform(fs, v).unwrap(), &SpectrumConfig::default()).unwrap();
        let peaks = s.peaks(0.05);
        assert_eq!(peaks.len(), 2, "{peaks:?}");
        assert!((peaks[0].refined_frequency_hz - 1.5).abs() < 0.01);
        assert!((peaks[1].refined_frequency_hz - 4.0).abs() < 0.01);
        assert!(peaks[0].prominence > peaks[1].prominence);
    }

    #[test]
    fn linear_detrend_removes_a_line_exactly() {
        let mut x: Vec<f64> = (0..9).map(|i| 2.0 + 0.5 * f64::from(i)).collect();
        detrend(&mut x, Detrend::Linear);
        assert!(x.iter().all(|v| v.abs() < 1e-12));
    }
}
