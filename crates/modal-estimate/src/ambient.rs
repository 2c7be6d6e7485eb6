//! Ambient (wind-driven) records: Welch spectrum, zero-phase band-pass, random decrement, and
//! Au's uncertainty law for what such a record can say about damping.

use rustfft::num_complex::Complex;
use serde::Serialize;

use crate::signal::UniformSignal;
use crate::spectrum::{
    Detrend, Scaling, Spectrum, SpectrumConfig, Window, detrend, fft_plan, spectrum_uniform,
};

/// Welch's averaged periodogram: Hann segments of `segment` samples overlapping by half,
/// linear detrend per segment, PSD scaling.
#[must_use]
pub fn welch(u: &UniformSignal, segment: usize) -> Spectrum {
    let n = u.values.len();
    let seg = segment.clamp(8.min(n), n.max(1));
    let step = (seg / 2).max(1);
    let config = SpectrumConfig {
        window: Window::Hann,
        detrend: Detrend::Linear,
        zero_padding: 1,
        scaling: Scaling::PowerSpectralDensity,
    };
    let mut total: Option<Spectrum> = None;
    let mut count = 0usize;
    let mut start = 0;
    while start + seg <= n {
        let piece = UniformSignal {
            start_s: u.start_s + start as f64 * u.interval_s,
            interval_s: u.interval_s,
            values: u.values[start..start + seg].to_vec(),
            interpolated: 0,
        };
        let s = spectrum_uniform(&piece, &config);
        match total.as_mut() {
            None => total = Some(s),
            Some(t) => t
                .values
                .iter_mut()
                .zip(&s.values)
                .for_each(|(a, b)| *a += b),
        }
        count += 1;
        start += step;
    }
    let mut total = total.unwrap_or_else(|| spectrum_uniform(u, &config));
    if count > 1 {
        total.values.iter_mut().for_each(|v| *v /= count as f64);
    }
    total.interpolated = u.interpolated;
    total
}

/// Zero-phase band-pass by an FFT mask with raised-cosine edges a fifth of the band edge
/// wide; the linear trend is removed first.
#[must_use]
pub fn band_pass(values: &[f64], interval_s: f64, low_hz: f64, high_hz: f64) -> Vec<f64> {
    let n = values.len();
    if n < 2 {
        return values.to_vec();
    }
    let mut x = values.to_vec();
    detrend(&mut x, Detrend::Linear);
    let mut buf: Vec<Complex<f64>> = x.iter().map(|&v| Complex::new(v, 0.0)).collect();
    fft_plan(n, false).process(&mut buf);
    let fs = 1.0 / interval_s;
    let gain = |f: f64| {
        let edge = |f: f64, corner: f64, rising: bool| {
            let width = 0.2 * corner;
            let a = if rising { corner - width } else { corner };
            let r = ((f - a) / width).clamp(0.0, 1.0);
            let g = 0.5 - 0.5 * (std::f64::consts::PI * r).cos();
            if rising { g } else { 1.0 - g }
        };
        edge(f, low_hz, true) * edge(f, high_hz, false)
    };
    for (k, c) in buf.iter_mut().enumerate() {
        let kk = k.min(n - k);
        *c *= gain(kk as f64 * fs / n as f64);
    }
    fft_plan(n, true).process(&mut buf);
    buf.iter().map(|c| c.re / n as f64).collect()
}

/// A random-decrement signature: the average of the segments that start where the signal
/// crosses a level, which for a linear system driven by broadband noise decays like the free
/// response from that level.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RandomDecrement {
    /// The signature, starting at the trigger, on the record's grid.
    pub values: Vec<f64>,
    /// Its sample interval, seconds.
    pub interval_s: f64,
    /// Trigger level, in the signal's unit.
    pub level: f64,
    /// Number of segments averaged.
    pub triggers: usize,
}

/// Random decrement with a level-crossing trigger (both directions, so the initial velocity
/// averages to zero) at `level`, segments of `length` samples.
#[must_use]
pub fn random_decrement(x: &[f64], interval_s: f64, level: f64, length: usize) -> RandomDecrement {
    let mut sum = vec![0.0; length];
    let mut triggers = 0;
    if length > 0 && x.len() > length {
        for i in 0..x.len() - length {
            let (a, b) = (x[i] - level, x[i + 1] - level);
            if a == 0.0 || a * b < 0.0 {
                let start = if a.abs() <= b.abs() { i } else { i + 1 };
                if start + length <= x.len() {
                    sum.iter_mut()
                        .zip(&x[start..start + length])
                        .for_each(|(s, v)| *s += v);
                    triggers += 1;
                }
            }
        }
    }
    if triggers > 0 {
        sum.iter_mut().for_each(|v| *v /= triggers as f64);
    }
    RandomDecrement {
        values: sum,
        interval_s,
        level,
        triggers,
    }
}

/// Au's uncertainty law for ambient modal identification (Au 2014, "Uncertainty law in
/// ambient modal identification, Part I", Mech. Syst. Signal Process. 48; long-data,
/// high-SNR limit with the bandwidth factor taken as 1): coefficients of variation of the
/// frequency and of the damping ratio for a record of `cycles` natural periods.
#[must_use]
pub fn au_uncertainty(damping_ratio: f64, cycles: f64) -> (f64, f64) {
    let xi = damping_ratio.max(1e-6);
    let c = cycles.max(1e-9);
    let tau_pi = 2.0 * std::f64::consts::PI;
    ((xi / (tau_pi * c)).sqrt(), 1.0 / (tau_pi * xi * c).sqrt())
}

/// Cycles a record needs for Au's c.o.v. of the damping ratio to reach `cov`.
#[must_use]
pub fn au_cycles_needed(damping_ratio: f64, cov: f64) -> f64 {
    1.0 / (2.0 * std::f64::consts::PI * damping_ratio.max(1e-6) * cov * cov)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn band_pass_keeps_the_band_and_removes_the_rest() {
        let dt = 0.05;
        let x: Vec<f64> = (0..2000)
            .map(|i| {
                let t = f64::from(i) * dt;
                (std::f64::consts::TAU * 1.0 * t).sin() + (std::f64::consts::TAU * 6.0 * t).sin()
            })
            .collect();
        let y = band_pass(&x, dt, 0.5, 2.0);
        let rms = (y[200..1800].iter().map(|v| v * v).sum::<f64>() / 1600.0).sqrt();
        assert!(
            (rms - std::f64::consts::FRAC_1_SQRT_2).abs() < 0.01,
            "{rms}"
        );
    }

    #[test]
    fn au_rule_matches_its_formula() {
        let (cf, cx) = au_uncertainty(0.05, 100.0);
        assert!((cx - 1.0 / (std::f64::consts::TAU * 5.0).sqrt()).abs() < 1e-12);
        assert!((cf - (0.05 / (std::f64::consts::TAU * 100.0)).sqrt()).abs() < 1e-12);
        assert!((au_cycles_needed(0.05, cx) - 100.0).abs() < 1e-9);
    }
}
