//! Seeded synthetic records with known modes: free decays after a pull-and-release (the
//! issue's Monte Carlo: jitter, drops, offset, drift, a held stretch, a second mode, noise)
//! and ambient records (a modal oscillator driven by white noise).

use rand_xoshiro::SplitMix64;
use rand_xoshiro::rand_core::{RngCore, SeedableRng};
use serde::Serialize;

use crate::error::{ModalError, Result};
use crate::fit::Mode;
use crate::signal::Signal;

const TAU: f64 = std::f64::consts::TAU;

/// SplitMix64 (Steele, Lea, Flood 2014): a seed gives the same record forever.
/// (`rand_xoshiro`'s, the workspace's one generator.)
#[derive(Debug, Clone)]
pub struct Rng(SplitMix64);

impl Rng {
    /// A generator from a seed.
    #[must_use]
    pub fn new(seed: u64) -> Self {
        Self(SplitMix64::seed_from_u64(seed ^ 0x6d6f_6461_6c00_0000)) // "modal"
    }

    fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Standard normal (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos()
    }
}

/// A weaker, faster-decaying second mode.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SecondMode {
    /// Its frequency over the first mode's.
    pub frequency_ratio: f64,
    /// Its initial displacement over the first mode's.
    pub amplitude_ratio: f64,
    /// Its damping ratio.
    pub damping_ratio: f64,
}

/// A pull-and-release record: held still at a deflection, let go, free decay.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DecaySpec {
    /// Natural frequency of the first mode, hertz.
    pub frequency_hz: f64,
    /// Damping ratio of the first mode.
    pub damping_ratio: f64,
    /// Samples in the record.
    pub samples: usize,
    /// Nominal sample rate, hertz.
    pub sample_rate_hz: f64,
    /// Each timestamp moves uniformly within +- this, seconds (the values are taken at the
    /// moved times: irregular sampling, not timestamp noise).
    pub jitter_s: f64,
    /// Share of samples dropped (missing).
    pub drop_fraction: f64,
    /// Deflection at the release (first mode), in the signal's unit (radians).
    pub amplitude: f64,
    /// Constant offset.
    pub offset: f64,
    /// Linear drift per second.
    pub drift_per_s: f64,
    /// Held-still time before the release, seconds.
    pub held_s: f64,
    /// Optional second mode.
    pub second_mode: Option<SecondMode>,
    /// Signal-to-noise ratio at the release, dB: `10 log10((amplitude^2 / 2) / noise_var)`.
    pub snr_db: f64,
    /// Seed of the noise, jitter and drops.
    pub seed: u64,
}

impl DecaySpec {
    /// A clean default: the paper's branch C (1.46 Hz, xi 0.086), 409 samples at 30 Hz,
    /// released after 1 s, 30 dB.
    #[must_use]
    pub fn paper_branch() -> Self {
        Self {
            frequency_hz: 1.46,
            damping_ratio: 0.086,
            samples: 409,
            sample_rate_hz: 30.0,
            jitter_s: 0.002,
            drop_fraction: 0.02,
            amplitude: 0.1,
            offset: 0.6,
            drift_per_s: 0.0005,
            held_s: 1.0,
            second_mode: None,
            snr_db: 30.0,
            seed: 1,
        }
    }

    /// A record drawn from the Monte Carlo ranges: f 0.8–3 Hz, xi 0.02–0.25
    /// (log-uniform), 300–600 samples at 15–30 Hz, +-2 ms jitter, up to 5 % dropped, an
    /// offset and a slow drift, held 0.5–2 s, a second mode at 1.5–2.6 f on half the
    /// records (10–40 % of the amplitude, 1–2x the damping), SNR 18–35 dB.
    #[must_use]
    pub fn monte_carlo(seed: u64) -> Self {
        let mut r = Rng::new(seed.wrapping_mul(0x2545_F491_4F6C_DD1D));
        let damping_ratio = (r.range(0.02_f64.ln(), 0.25_f64.ln())).exp();
        let amplitude = 0.1;
        let second = r.uniform() < 0.5;
        let second_mode = SecondMode {
            frequency_ratio: r.range(1.5, 2.6),
            amplitude_ratio: r.range(0.1, 0.4),
            damping_ratio: (damping_ratio * r.range(1.0, 2.0)).min(0.3),
        };
        Self {
            frequency_hz: r.range(0.8, 3.0),
            damping_ratio,
            samples: 300 + (r.uniform() * 301.0) as usize,
            sample_rate_hz: r.range(15.0, 30.0),
            jitter_s: 0.002,
            drop_fraction: r.range(0.0, 0.05),
            amplitude,
            offset: r.range(-0.5, 0.5),
            drift_per_s: amplitude * r.range(-0.01, 0.01),
            held_s: r.range(0.5, 2.0),
            second_mode: second.then_some(second_mode),
            snr_db: r.range(18.0, 35.0),
            seed,
        }
    }

    /// Noise standard deviation for the SNR.
    #[must_use]
    pub fn noise_std(&self) -> f64 {
        (self.amplitude * self.amplitude / 2.0 / 10f64.powf(self.snr_db / 10.0)).sqrt()
    }

    /// Release time, seconds (the record starts at 0).
    #[must_use]
    pub fn release_s(&self) -> f64 {
        self.held_s
    }

    /// The true modes as [`Mode`]s referenced to `t_ref` (amplitude and phase of the
    /// displacement there), standard errors `None`.
    #[must_use]
    pub fn true_modes(&self, t_ref: f64) -> Vec<Mode> {
        let mut out = vec![mode_at(
            self.frequency_hz,
            self.damping_ratio,
            self.amplitude,
            t_ref - self.release_s(),
            t_ref,
        )];
        if let Some(m) = self.second_mode {
            out.push(mode_at(
                self.frequency_hz * m.frequency_ratio,
                m.damping_ratio,
                self.amplitude * m.amplitude_ratio,
                t_ref - self.release_s(),
                t_ref,
            ));
        }
        out
    }

    /// The noise-free displacement at time `t_s`.
    #[must_use]
    pub fn clean(&self, t_s: f64) -> f64 {
        let tau = t_s - self.release_s();
        let mut y = self.offset + self.drift_per_s * t_s;
        y += release_response(self.frequency_hz, self.damping_ratio, self.amplitude, tau);
        if let Some(m) = self.second_mode {
            y += release_response(
                self.frequency_hz * m.frequency_ratio,
                m.damping_ratio,
                self.amplitude * m.amplitude_ratio,
                tau,
            );
        }
        y
    }

    /// Generate the record.
    ///
    /// # Errors
    /// [`ModalError::TooLarge`] above [`MAX_SYNTHETIC_SAMPLES`], [`ModalError::InvalidParameter`]
    /// for a rate that is not positive and finite (both before allocating); the errors of
    /// [`Signal::new`] (for a jitter of half an interval or more, which breaks the order).
    pub fn generate(&self) -> Result<Signal> {
        check_size(self.samples as f64, self.sample_rate_hz)?;
        let mut r = Rng::new(self.seed);
        let sigma = self.noise_std();
        let mut times = Vec::with_capacity(self.samples);
        let mut values = Vec::with_capacity(self.samples);
        for i in 0..self.samples {
            let t = i as f64 / self.sample_rate_hz + self.jitter_s * (2.0 * r.uniform() - 1.0);
            let noise = sigma * r.normal();
            let dropped = r.uniform() < self.drop_fraction;
            times.push(t);
            values.push((!dropped).then(|| self.clean(t) + noise));
        }
        Signal::new(times, values)
    }
}

/// Free response from rest at displacement `d` (zero velocity) `tau` seconds after the
/// release; `d` before it.
fn release_response(f: f64, xi: f64, d: f64, tau: f64) -> f64 {
    if tau <= 0.0 {
        return d;
    }
    let wn = TAU * f;
    let sigma = xi * wn;
    let wd = wn * (1.0 - xi * xi).sqrt();
    d * (-sigma * tau).exp() * ((wd * tau).cos() + sigma / wd * (wd * tau).sin())
}

/// The mode of a release from `d` seen at `tau` after the release, as amplitude and phase
/// at `t_ref`.
fn mode_at(f: f64, xi: f64, d: f64, tau: f64, t_ref: f64) -> Mode {
    let wn = TAU * f;
    let sigma = xi * wn;
    let wd = wn * (1.0 - xi * xi).sqrt();
    // d e^{-s t}(cos wd t + s/wd sin wd t) = A0 e^{-s t} cos(wd t + p0).
    let a0 = d * (1.0 + (sigma / wd).powi(2)).sqrt();
    let p0 = (-(sigma / wd)).atan();
    Mode {
        frequency_hz: f,
        frequency_std_hz: None,
        damping_ratio: xi,
        damping_std: None,
        damped_frequency_hz: wd / TAU,
        decay_rate_per_s: sigma,
        amplitude: a0 * (-sigma * tau).exp(),
        amplitude_std: None,
        phase_rad: p0 + wd * tau,
        reference_time_s: t_ref,
    }
}

/// A record of a single-mode oscillator driven by white noise (ambient sway), sampled at
/// `sample_rate_hz` for `duration_s`, with measurement noise at `snr_db` of the response
/// variance. Integrated exactly per sample for a force held over the step.
///
/// # Errors
/// [`ModalError::InvalidParameter`] for parameters out of range, [`ModalError::TooLarge`] above
/// [`MAX_SYNTHETIC_SAMPLES`] (before allocating); the errors of [`Signal::uniform`].
pub fn ambient(
    frequency_hz: f64,
    damping_ratio: f64,
    sample_rate_hz: f64,
    duration_s: f64,
    snr_db: f64,
    seed: u64,
) -> Result<Signal> {
    if !(frequency_hz.is_finite()
        && frequency_hz > 0.0
        && (0.0..1.0).contains(&damping_ratio)
        && duration_s.is_finite()
        && duration_s > 0.0
        && snr_db.is_finite())
    {
        return Err(ModalError::InvalidParameter {
            name: "ambient",
            reason: format!(
                "frequency {frequency_hz} Hz, damping ratio {damping_ratio}, duration {duration_s} s, SNR {snr_db} dB (expected a positive frequency, a damping ratio in [0, 1), a positive duration and a finite SNR)"
            ),
        });
    }
    check_size((duration_s * sample_rate_hz).round(), sample_rate_hz)?;
    let mut r = Rng::new(seed);
    let dt = 1.0 / sample_rate_hz;
    let n = (duration_s * sample_rate_hz).round() as usize;
    let wn = TAU * frequency_hz;
    let sigma = damping_ratio * wn;
    let wd = wn * (1.0 - damping_ratio * damping_ratio).sqrt();
    // Exact state transition of x'' + 2 sigma x' + wn^2 x = u over dt.
    let e = (-sigma * dt).exp();
    let (s, c) = (wd * dt).sin_cos();
    let phi = [
        [e * (c + sigma / wd * s), e * s / wd],
        [-e * wn * wn / wd * s, e * (c - sigma / wd * s)],
    ];
    // Response to a unit force held over the step.
    let g0 = (1.0 - phi[0][0]) / (wn * wn);
    let g1 = -phi[1][0] / (wn * wn);
    let (mut x, mut v) = (0.0, 0.0);
    let mut out = Vec::with_capacity(n);
    // Twenty decay times of burn-in so the record starts stationary.
    let burn = ((20.0 / sigma) / dt) as usize;
    for i in 0..n + burn {
        let u = r.normal();
        let nx = phi[0][0] * x + phi[0][1] * v + g0 * u;
        let nv = phi[1][0] * x + phi[1][1] * v + g1 * u;
        x = nx;
        v = nv;
        if i >= burn {
            out.push(x);
        }
    }
    let var = out.iter().map(|v| v * v).sum::<f64>() / n.max(1) as f64;
    let noise = (var / 10f64.powf(snr_db / 10.0)).sqrt();
    let values = out.iter().map(|&x| Some(x + noise * r.normal())).collect();
    Signal::uniform(sample_rate_hz, values)
}

/// Most samples a synthetic record may hold (the limit of a uniform grid, 2^26).
pub const MAX_SYNTHETIC_SAMPLES: usize = 1 << 26;

/// A record of `samples` at `sample_rate_hz`, checked before anything is allocated.
fn check_size(samples: f64, sample_rate_hz: f64) -> Result<()> {
    if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
        return Err(ModalError::InvalidParameter {
            name: "sample_rate_hz",
            reason: format!("{sample_rate_hz} (expected positive and finite)"),
        });
    }
    if samples.is_nan() || samples > MAX_SYNTHETIC_SAMPLES as f64 {
        return Err(ModalError::TooLarge {
            what: "a synthetic record: samples".to_owned(),
            count: samples,
            limit: MAX_SYNTHETIC_SAMPLES,
        });
    }
    Ok(())
}
