//! The paper's method (section 5.3, eq. 6): the highest FFT peak is the natural frequency,
//! and the damping ratio is `xi = delta_f / (2 f)` from the half-power band.

use serde::Serialize;

use crate::error::{ModalError, Result};
use crate::signal::Signal;
use crate::spectrum::{Scaling, Spectrum, SpectrumConfig, spectrum};

/// What the half-power method reads off a spectrum.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HalfPower {
    /// The peak bin's frequency, hertz: quantised to the bin width, as in the paper.
    pub frequency_hz: f64,
    /// The peak bin.
    pub bin: usize,
    /// Spacing of the bins, hertz.
    pub bin_width_hz: f64,
    /// Spectrum value at the peak (amplitude in the signal's unit, or PSD).
    pub peak_value: f64,
    /// Lower half-power frequency, hertz, linearly interpolated between bins; `None` when
    /// the spectrum never falls to half power below the peak.
    pub lower_hz: Option<f64>,
    /// Upper half-power frequency, hertz; `None` when it never falls to half power above.
    pub upper_hz: Option<f64>,
    /// `(upper - lower) / (2 f)`, eq. (6); `None` when either side is missing.
    pub damping_ratio: Option<f64>,
}

/// Eq. (6) on a spectrum: the highest bin in `low_hz..=high_hz` (bin 0 excluded), the band
/// where the spectrum stays above half power (1/sqrt 2 of the peak amplitude, or half the
/// peak PSD), its edges interpolated linearly between the bins that straddle the threshold.
///
/// # Errors
/// [`ModalError::NoPeak`] when the band holds no bin with a positive value.
pub fn half_power(spectrum: &Spectrum, low_hz: f64, high_hz: f64) -> Result<HalfPower> {
    let v = &spectrum.values;
    let f = &spectrum.frequencies_hz;
    let peak = (1..v.len())
        .filter(|&k| f[k] >= low_hz && f[k] <= high_hz)
        .max_by(|&a, &b| v[a].total_cmp(&v[b]))
        .filter(|&k| v[k] > 0.0)
        .ok_or(ModalError::NoPeak { low_hz, high_hz })?;
    let threshold = match spectrum.scaling {
        Scaling::Amplitude => v[peak] / std::f64::consts::SQRT_2,
        Scaling::PowerSpectralDensity => v[peak] / 2.0,
    };
    let crossing = |inside: usize, outside: usize| {
        let w = (v[inside] - threshold) / (v[inside] - v[outside]);
        f[inside] + w * (f[outside] - f[inside])
    };
    let lower_hz = (1..=peak)
        .rev()
        .find(|&k| v[k - 1] < threshold)
        .map(|k| crossing(k, k - 1));
    let upper_hz = (peak..v.len() - 1)
        .find(|&k| v[k + 1] < threshold)
        .map(|k| crossing(k, k + 1));
    let frequency_hz = f[peak];
    let damping_ratio = match (lower_hz, upper_hz) {
        (Some(lo), Some(hi)) => Some((hi - lo) / (2.0 * frequency_hz)),
        _ => None,
    };
    Ok(HalfPower {
        frequency_hz,
        bin: peak,
        bin_width_hz: spectrum.bin_width_hz,
        peak_value: v[peak],
        lower_hz,
        upper_hz,
        damping_ratio,
    })
}

/// The paper's whole method on a record: [`SpectrumConfig::paper`] (rectangular window, no
/// padding) and [`half_power`] over `low_hz..=high_hz`.
///
/// # Errors
/// The errors of [`spectrum`] and [`half_power`].
pub fn paper_half_power(signal: &Signal, low_hz: f64, high_hz: f64) -> Result<HalfPower> {
    let s = spectrum(signal, &SpectrumConfig::paper())?;
    half_power(&s, low_hz, high_hz)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_power_band_of_a_known_lorentzian_shape() {
        // A hand-made amplitude spectrum: peak 1.0 at 2 Hz, 0.5 one bin either side.
        let values = vec![0.0, 0.1, 0.5, 1.0, 0.5, 0.1, 0.0];
        let s = Spectrum {
            frequencies_hz: (0..7).map(f64::from).collect(),
            values,
            scaling: Scaling::Amplitude,
            bin_width_hz: 1.0,
            resolution_hz: 1.0,
            sample_rate_hz: 12.0,
            samples: 12,
            interpolated: 0,
        };
        let hp = half_power(&s, 0.0, 10.0).unwrap();
        assert_eq!(hp.bin, 3);
        let w = (1.0 - std::f64::consts::FRAC_1_SQRT_2) / 0.5;
        assert!((hp.lower_hz.unwrap() - (3.0 - w)).abs() < 1e-12);
        assert!((hp.upper_hz.unwrap() - (3.0 + w)).abs() < 1e-12);
        assert!((hp.damping_ratio.unwrap() - 2.0 * w / 6.0).abs() < 1e-12);
    }
}
