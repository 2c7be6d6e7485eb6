//! Turbulent wind: noise velocity streams by FFT convolution of white noise with the
//! spectrum's filter (it never loops), advected as frozen turbulence, and the drag it puts
//! on a segment.

use rand_xoshiro::SplitMix64;
use rand_xoshiro::rand_core::{RngCore, SeedableRng};
use std::sync::Arc;

use nalgebra::Vector3;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use serde::Serialize;

use crate::error::{AnimError, Result};

/// Density of air at sea level, 15 °C (ISO 2533 standard atmosphere), kg/m³.
pub const AIR_DENSITY_KG_M3: f64 = 1.225;
/// Drag coefficient of a circular cylinder in cross-flow at subcritical Reynolds numbers
/// (10³–10⁵, a branch in a breeze; Hoerner, *Fluid-Dynamic Drag*, 1965, ch. 3).
pub const CYLINDER_DRAG_COEFFICIENT: f64 = 1.2;
/// Longitudinal turbulence intensity σ_u / U (IEC 61400-1 class A reference, 0.16).
pub const TURBULENCE_INTENSITY: f64 = 0.16;
/// σ_v / σ_u and σ_w / σ_u in the neutral surface layer (Panofsky & Dutton 1984: 0.8, 0.5).
pub const LATERAL_RATIO: f64 = 0.8;
/// See [`LATERAL_RATIO`].
pub const VERTICAL_RATIO: f64 = 0.5;
/// Kolmogorov's inertial-range exponent, the default β of the 1/f^β spectrum.
pub const KOLMOGOROV_BETA: f64 = 5.0 / 3.0;
/// Default low-frequency corner of the 1/f^β spectrum, Hz (gusts of about 20 s).
pub const CORNER_HZ: f64 = 0.05;
/// Filter length in corner periods: the truncated filter resolves the spectrum down to
/// well below the corner.
const FILTER_CORNER_PERIODS: f64 = 8.0;

/// The power spectral density shape of the velocity fluctuations.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[non_exhaustive]
pub enum Spectrum {
    /// S(f) ∝ (f_c² + f²)^(−β/2): 1/f^β above the corner `corner_hz` (the paper's 1/f^β
    /// noise after Khorloo et al.), flat below.
    PowerLaw {
        /// β.
        beta: f64,
        /// f_c, Hz.
        corner_hz: f64,
    },
    /// Kaimal: S(f) ∝ 1 / (1 + 6 f L/U)^(5/3), L the length scale, metres.
    Kaimal {
        /// Integral length scale, metres.
        length_scale_m: f64,
    },
    /// von Kármán: S(f) ∝ 1 / (1 + 70.8 (f L/U)²)^(5/6).
    VonKarman {
        /// Integral length scale, metres.
        length_scale_m: f64,
    },
}

impl Default for Spectrum {
    fn default() -> Self {
        Self::PowerLaw {
            beta: KOLMOGOROV_BETA,
            corner_hz: CORNER_HZ,
        }
    }
}

impl Spectrum {
    /// The (unnormalised) density at `f_hz` for mean speed `u_m_s`.
    pub fn density(&self, f_hz: f64, u_m_s: f64) -> f64 {
        let f = f_hz.abs();
        match *self {
            Self::PowerLaw { beta, corner_hz } => (corner_hz * corner_hz + f * f).powf(-beta / 2.0),
            Self::Kaimal { length_scale_m } => {
                (1.0 + 6.0 * f * length_scale_m / u_m_s.max(0.1)).powf(-5.0 / 3.0)
            }
            Self::VonKarman { length_scale_m } => {
                let n = f * length_scale_m / u_m_s.max(0.1);
                (1.0 + 70.8 * n * n).powf(-5.0 / 6.0)
            }
        }
    }

    /// Lowest frequency the spectrum resolves, Hz (sets the filter length).
    fn corner_hz(&self, u_m_s: f64) -> f64 {
        match *self {
            Self::PowerLaw { corner_hz, .. } => corner_hz,
            Self::Kaimal { length_scale_m } => u_m_s.max(0.1) / (6.0 * length_scale_m),
            Self::VonKarman { length_scale_m } => u_m_s.max(0.1) / (8.4 * length_scale_m),
        }
    }

    fn validate(&self) -> Result<()> {
        let ok = |x: f64| x.is_finite() && x > 0.0;
        match *self {
            Self::PowerLaw { beta, .. } if !(beta.is_finite() && beta >= 0.0) => Err(
                AnimError::param("spectrum.beta", format!("{beta}; must be finite and ≥ 0")),
            ),
            Self::PowerLaw { corner_hz, .. } if !ok(corner_hz) => Err(AnimError::param(
                "spectrum.corner_hz",
                format!("{corner_hz} Hz; must be positive"),
            )),
            Self::Kaimal { length_scale_m } | Self::VonKarman { length_scale_m }
                if !ok(length_scale_m) =>
            {
                Err(AnimError::param(
                    "spectrum.length_scale_m",
                    format!("{length_scale_m} m; must be positive"),
                ))
            }
            _ => Ok(()),
        }
    }
}

/// The wind: mean speed and direction, turbulence, air and drag.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindConfig {
    /// Mean speed U, m/s (0: still air plus nothing).
    pub mean_speed_m_s: f64,
    /// Direction the wind blows toward (horizontal unit vector, tree frame).
    pub direction: Vector3<f64>,
    /// σ_u / U. Default [`TURBULENCE_INTENSITY`].
    pub turbulence_intensity: f64,
    /// Spectrum of the fluctuations.
    pub spectrum: Spectrum,
    /// Air density, kg/m³.
    pub air_density_kg_m3: f64,
    /// Drag coefficient of a branch segment.
    pub drag_coefficient: f64,
    /// Advect the fluctuations with the mean wind (Taylor's frozen turbulence), so that
    /// nearby branches see the same gust a moment apart. Default true.
    pub frozen_turbulence: bool,
    /// Seed of the noise.
    pub seed: u64,
}

impl Default for WindConfig {
    fn default() -> Self {
        Self {
            mean_speed_m_s: 5.0,
            direction: Vector3::x(),
            turbulence_intensity: TURBULENCE_INTENSITY,
            spectrum: Spectrum::default(),
            air_density_kg_m3: AIR_DENSITY_KG_M3,
            drag_coefficient: CYLINDER_DRAG_COEFFICIENT,
            frozen_turbulence: true,
            seed: 1,
        }
    }
}

impl WindConfig {
    /// Check every field.
    ///
    /// # Errors
    /// [`AnimError::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<()> {
        let nonneg = |name, x: f64| {
            if x.is_finite() && x >= 0.0 {
                Ok(())
            } else {
                Err(AnimError::param(
                    name,
                    format!("{x}; must be finite and ≥ 0"),
                ))
            }
        };
        nonneg("mean_speed_m_s", self.mean_speed_m_s)?;
        if self.mean_speed_m_s > MAX_WIND_SPEED_M_S {
            return Err(AnimError::param(
                "mean_speed_m_s",
                format!(
                    "{} m/s; above {MAX_WIND_SPEED_M_S} m/s, the highest gust ever measured, nothing here means anything",
                    self.mean_speed_m_s
                ),
            ));
        }
        nonneg("turbulence_intensity", self.turbulence_intensity)?;
        nonneg("air_density_kg_m3", self.air_density_kg_m3)?;
        nonneg("drag_coefficient", self.drag_coefficient)?;
        let n = self.direction.norm();
        if !(n.is_finite() && (n - 1.0).abs() < 1e-6) {
            return Err(AnimError::param(
                "direction",
                format!("{:?}; must be a unit vector", self.direction),
            ));
        }
        self.spectrum.validate()
    }
}

/// Highest wind speed accepted, m/s: the highest gust measured on Earth (113.3 m/s, Barrow
/// Island, 1996; WMO Archive of Weather and Climate Extremes). Trees break far below it
/// (about 42 m/s whatever their size: Virot et al. 2016, Phys. Rev. E 93, 023001).
pub const MAX_WIND_SPEED_M_S: f64 = 113.3;

/// One endless stream of zero-mean, unit-variance noise with a given spectrum: white
/// Gaussian noise convolved (overlap-save FFT) with the zero-phase filter √S, windowed.
struct NoiseStream {
    filter_spectrum: Vec<Complex<f64>>,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
    /// Last `taps − 1` white samples, then the new block.
    input: Vec<f64>,
    taps: usize,
    out: Vec<f64>,
    next: usize,
    rng: SplitMix64,
    spare: Option<f64>,
    scratch: Vec<Complex<f64>>,
}

impl NoiseStream {
    fn new(spectrum: &Spectrum, u_m_s: f64, sample_rate_hz: f64, seed: u64) -> Self {
        let wanted = FILTER_CORNER_PERIODS * sample_rate_hz / spectrum.corner_hz(u_m_s);
        let taps = (wanted.ceil() as usize)
            .clamp(256, 1 << 20)
            .next_power_of_two();
        let n = 2 * taps;
        let mut planner = FftPlanner::new();
        let forward = planner.plan_fft_forward(n);
        let inverse = planner.plan_fft_inverse(n);
        // Zero-phase √S on the taps-long grid, to a centred, Hann-windowed impulse response.
        let mut h: Vec<Complex<f64>> = (0..taps)
            .map(|k| {
                let kk = if k <= taps / 2 { k } else { taps - k };
                let f = kk as f64 * sample_rate_hz / taps as f64;
                Complex::new(
                    if k == 0 {
                        0.0
                    } else {
                        spectrum.density(f, u_m_s).sqrt()
                    },
                    0.0,
                )
            })
            .collect();
        planner.plan_fft_inverse(taps).process(&mut h);
        let mut kernel = vec![0.0; taps];
        for (i, k) in kernel.iter_mut().enumerate() {
            let src = (i + taps / 2) % taps;
            let w = 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / taps as f64).cos();
            *k = h[src].re * w;
        }
        let energy: f64 = kernel.iter().map(|k| k * k).sum();
        let scale = if energy > 0.0 {
            energy.sqrt().recip()
        } else {
            0.0
        };
        let mut filter_spectrum: Vec<Complex<f64>> = kernel
            .iter()
            .map(|&k| Complex::new(k * scale, 0.0))
            .chain(std::iter::repeat_n(Complex::new(0.0, 0.0), n - taps))
            .collect();
        forward.process(&mut filter_spectrum);
        let mut s = Self {
            filter_spectrum,
            forward,
            inverse,
            input: vec![0.0; taps - 1],
            taps,
            out: Vec::new(),
            next: 0,
            rng: SplitMix64::seed_from_u64(seed),
            spare: None,
            scratch: vec![Complex::new(0.0, 0.0); n],
        };
        for i in 0..taps - 1 {
            s.input[i] = s.gaussian();
        }
        s
    }

    fn uniform(&mut self) -> f64 {
        // SplitMix64 (rand_xoshiro's, the workspace's one generator).
        (self.rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn gaussian(&mut self) -> f64 {
        if let Some(s) = self.spare.take() {
            return s;
        }
        // Box–Muller.
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
        self.spare = Some(r * s);
        r * c
    }

    fn refill(&mut self) {
        let n = 2 * self.taps;
        let fresh = n - (self.taps - 1);
        let mut block = std::mem::take(&mut self.input);
        block.reserve(fresh);
        for _ in 0..fresh {
            block.push(self.gaussian());
        }
        for (c, &x) in self.scratch.iter_mut().zip(&block) {
            *c = Complex::new(x, 0.0);
        }
        self.forward.process(&mut self.scratch);
        for (c, h) in self.scratch.iter_mut().zip(&self.filter_spectrum) {
            *c *= h;
        }
        self.inverse.process(&mut self.scratch);
        let norm = 1.0 / n as f64;
        self.out.clear();
        self.out
            .extend(self.scratch[self.taps - 1..].iter().map(|c| c.re * norm));
        self.next = 0;
        self.input = block[block.len() - (self.taps - 1)..].to_vec();
    }

    fn sample(&mut self) -> f64 {
        if self.next >= self.out.len() {
            self.refill();
        }
        let v = self.out[self.next];
        self.next += 1;
        v
    }
}

/// Wind velocity samples over time and space: three noise streams (along-wind, lateral,
/// vertical) at the animation's rate, and a history long enough to advect them over the tree.
pub struct WindField {
    config: WindConfig,
    dt_s: f64,
    streams: [NoiseStream; 3],
    sigma: [f64; 3],
    /// Ring buffer of fluctuation samples (u, v, w) in the tree frame.
    history: Vec<Vector3<f64>>,
    head: usize,
    /// Unit vectors of the along-wind, lateral and vertical axes.
    axes: [Vector3<f64>; 3],
    mean: Vector3<f64>,
    time_s: f64,
}

impl WindField {
    /// A wind sampled every `dt_s`, coherent over `extent_m` along the wind (the tree's
    /// size: the delay of frozen turbulence across it).
    ///
    /// # Errors
    /// [`AnimError::InvalidTimeStep`], or a bad [`WindConfig`].
    pub fn new(config: WindConfig, dt_s: f64, extent_m: f64) -> Result<Self> {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(AnimError::InvalidTimeStep { dt_s });
        }
        config.validate()?;
        let u = config.mean_speed_m_s;
        let rate = 1.0 / dt_s;
        let s = |k: u64| {
            NoiseStream::new(
                &config.spectrum,
                u,
                rate,
                config.seed.wrapping_mul(3).wrapping_add(k),
            )
        };
        let su = config.turbulence_intensity * u;
        let delay_samples = if config.frozen_turbulence && u > 0.0 {
            (extent_m.max(0.0) / u / dt_s).ceil() as usize
        } else {
            0
        };
        let len = (delay_samples + 2).min(1 << 22).next_power_of_two();
        let d = config.direction;
        let lateral = Vector3::z()
            .cross(&d)
            .try_normalize(1e-9)
            .unwrap_or_else(Vector3::y);
        let mut w = Self {
            config,
            dt_s,
            streams: [s(0), s(1), s(2)],
            sigma: [su, LATERAL_RATIO * su, VERTICAL_RATIO * su],
            history: vec![Vector3::zeros(); len],
            head: 0,
            axes: [d, lateral, d.cross(&lateral)],
            mean: d * u,
            time_s: 0.0,
        };
        for _ in 0..len {
            w.advance();
        }
        w.time_s = 0.0;
        Ok(w)
    }

    /// The configuration.
    pub fn config(&self) -> &WindConfig {
        &self.config
    }

    /// Time of the newest sample, seconds.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The sample step and history length (what [`Self::delay`] depends on).
    pub fn time_step_and_size(&self) -> (f64, usize) {
        (self.dt_s, self.history.len())
    }

    /// Draw the next sample (one `dt_s` later).
    pub fn advance(&mut self) {
        let mut v = Vector3::zeros();
        for k in 0..3 {
            v += self.axes[k] * (self.sigma[k] * self.streams[k].sample());
        }
        self.head = (self.head + 1) & (self.history.len() - 1);
        self.history[self.head] = v;
        self.time_s += self.dt_s;
    }

    /// Velocity at a point `downstream_m` metres downstream of the most upstream point of
    /// the tree (its position along the wind), at the current time, m/s.
    #[inline]
    pub fn velocity_at(&self, downstream_m: f64) -> Vector3<f64> {
        self.velocity_delayed(self.delay(downstream_m))
    }

    /// The frozen-turbulence delay of a point `downstream_m` along the wind: whole samples
    /// and the fraction of the next (for [`Self::velocity_delayed`]).
    pub fn delay(&self, downstream_m: f64) -> (usize, f64) {
        let n = self.history.len();
        let d = if self.config.mean_speed_m_s > 0.0 && self.config.frozen_turbulence {
            (downstream_m.max(0.0) / self.config.mean_speed_m_s / self.dt_s).min((n - 2) as f64)
        } else {
            0.0
        };
        (d.floor() as usize, d - d.floor())
    }

    /// Velocity `delay` samples back (from [`Self::delay`]), m/s.
    #[inline]
    pub fn velocity_delayed(&self, (whole, frac): (usize, f64)) -> Vector3<f64> {
        let mask = self.history.len() - 1;
        let a = self.head.wrapping_sub(whole) & mask;
        let b = a.wrapping_sub(1) & mask;
        self.mean + self.history[a] * (1.0 - frac) + self.history[b] * frac
    }

    /// The along-wind fluctuation stream itself, `count` new samples, m/s (for spectra).
    pub fn along_wind_series(&mut self, count: usize) -> Vec<f64> {
        (0..count)
            .map(|_| {
                self.advance();
                self.history[self.head].dot(&self.axes[0])
            })
            .collect()
    }
}

/// Drag on a cylinder segment of radius `radius_m` and length `length_m` with unit axis
/// `axis`, in wind `velocity`: F = ½ ρ C_d A |u_n| u_n with A = 2 r l and u_n the
/// cross-flow part of the velocity, newtons.
#[inline]
pub fn drag_n(
    velocity: &Vector3<f64>,
    axis: &Vector3<f64>,
    radius_m: f64,
    length_m: f64,
    config: &WindConfig,
) -> Vector3<f64> {
    drag_on_area_n(velocity, axis, 2.0 * radius_m * length_m, config)
}

/// [`drag_n`] for a frontal area `area_m2` = 2 r l.
#[inline]
pub(crate) fn drag_on_area_n(
    velocity: &Vector3<f64>,
    axis: &Vector3<f64>,
    area_m2: f64,
    config: &WindConfig,
) -> Vector3<f64> {
    let un = velocity - axis * velocity.dot(axis);
    un * (0.5 * config.air_density_kg_m3 * config.drag_coefficient * area_m2 * un.norm())
}

/// Power spectral density by Welch's method (Hann windows of `segment` samples, half
/// overlap): frequencies (Hz) and densities, DC left out.
pub fn welch_psd(x: &[f64], sample_rate_hz: f64, segment: usize) -> (Vec<f64>, Vec<f64>) {
    let seg = segment.max(8).min(x.len().max(8));
    if x.len() < seg {
        return (Vec::new(), Vec::new());
    }
    let mut planner = FftPlanner::new();
    let fft = planner.plan_fft_forward(seg);
    let win: Vec<f64> = (0..seg)
        .map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / seg as f64).cos())
        .collect();
    let wsum: f64 = win.iter().map(|w| w * w).sum();
    let mut acc = vec![0.0; seg / 2 + 1];
    let mut count = 0;
    let mut start = 0;
    let mut buf = vec![Complex::new(0.0, 0.0); seg];
    while start + seg <= x.len() {
        let mean = x[start..start + seg].iter().sum::<f64>() / seg as f64;
        for (i, b) in buf.iter_mut().enumerate() {
            *b = Complex::new((x[start + i] - mean) * win[i], 0.0);
        }
        fft.process(&mut buf);
        for (k, a) in acc.iter_mut().enumerate() {
            *a += buf[k].norm_sqr();
        }
        count += 1;
        start += seg / 2;
    }
    let scale = 2.0 / (sample_rate_hz * wsum * count as f64);
    let f = (1..acc.len())
        .map(|k| k as f64 * sample_rate_hz / seg as f64)
        .collect();
    let p = acc[1..].iter().map(|a| a * scale).collect();
    (f, p)
}

/// Least-squares slope of log10 PSD against log10 f over [lo, hi] Hz.
pub fn log_slope(f: &[f64], p: &[f64], lo_hz: f64, hi_hz: f64) -> Option<f64> {
    let pts: Vec<(f64, f64)> = f
        .iter()
        .zip(p)
        .filter(|(f, p)| **f >= lo_hz && **f <= hi_hz && **p > 0.0)
        .map(|(f, p)| (f.log10(), p.log10()))
        .collect();
    if pts.len() < 3 {
        return None;
    }
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}
