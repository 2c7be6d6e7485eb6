//! The damped-sine model and its bounded Levenberg–Marquardt fit on the actual timestamps.
//!
//! Model, with `tau = t - t_ref`:
//! `y(t) = c0 + c1 tau + sum_k exp(-sigma_k tau) (a_k cos(omega_k tau) + b_k sin(omega_k tau))`,
//! `sigma_k` the decay rate (1/s) and `omega_k` the damped angular frequency (rad/s) of mode k.
//! Then `omega_n = sqrt(sigma^2 + omega^2)`, `f_n = omega_n / 2 pi`, `xi = sigma / omega_n`.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::error::{ModalError, Result};

const TAU: f64 = std::f64::consts::TAU;

/// One mode of a damped free vibration, with standard errors where they are known.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Mode {
    /// Undamped natural frequency f_n, hertz.
    pub frequency_hz: f64,
    /// Standard error of f_n, hertz (`None` when the information matrix is singular).
    pub frequency_std_hz: Option<f64>,
    /// Damping ratio xi (fraction of critical).
    pub damping_ratio: f64,
    /// Standard error of xi.
    pub damping_std: Option<f64>,
    /// Damped frequency f_d = f_n sqrt(1 - xi^2), hertz.
    pub damped_frequency_hz: f64,
    /// Decay rate sigma = 2 pi f_n xi, 1/s.
    pub decay_rate_per_s: f64,
    /// Amplitude at `reference_time_s`, in the signal's unit.
    pub amplitude: f64,
    /// Standard error of the amplitude.
    pub amplitude_std: Option<f64>,
    /// Phase at `reference_time_s`, radians: the mode is
    /// `amplitude exp(-sigma tau) cos(2 pi f_d tau + phase)`.
    pub phase_rad: f64,
    /// Time the amplitude and phase refer to, seconds.
    pub reference_time_s: f64,
}

/// Starting values of one mode for the fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ModeGuess {
    /// Decay rate, 1/s.
    pub sigma: f64,
    /// Damped angular frequency, rad/s.
    pub omega: f64,
}

/// Limits on the fitted parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Bounds {
    /// Lowest damped angular frequency, rad/s.
    pub omega_min: f64,
    /// Highest damped angular frequency, rad/s.
    pub omega_max: f64,
    /// Highest decay rate as a multiple of the damped angular frequency (xi below
    /// `r / sqrt(1 + r^2)`).
    pub sigma_over_omega_max: f64,
}

/// A converged (or stopped) fit.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Fit {
    pub modes: Vec<Mode>,
    pub params: Vec<f64>,
    pub offset: f64,
    pub drift_per_s: f64,
    pub residual_rms: f64,
    pub rss: f64,
    pub samples: usize,
    pub parameters: usize,
    pub iterations: usize,
    pub converged: bool,
}

impl Fit {
    /// Bayesian information criterion, for choosing the number of modes.
    pub fn bic(&self) -> f64 {
        let n = self.samples as f64;
        n * (self.rss / n).max(f64::MIN_POSITIVE).ln() + self.parameters as f64 * n.ln()
    }

    /// Guesses that restart a fit from this one.
    pub fn guesses(&self) -> Vec<ModeGuess> {
        (0..self.modes.len())
            .map(|k| ModeGuess {
                sigma: self.params[2 + 4 * k + 2],
                omega: self.params[2 + 4 * k + 3],
            })
            .collect()
    }
}

/// Model value and, when `jac` is given, its row of partial derivatives.
fn model(params: &[f64], tau: f64, drift: bool, mut jac: Option<&mut [f64]>) -> f64 {
    let modes = (params.len() - 2) / 4;
    let mut y = params[0] + if drift { params[1] * tau } else { 0.0 };
    if let Some(j) = jac.as_deref_mut() {
        j[0] = 1.0;
        j[1] = if drift { tau } else { 0.0 };
    }
    for k in 0..modes {
        let p = &params[2 + 4 * k..2 + 4 * k + 4];
        let (a, b, sigma, omega) = (p[0], p[1], p[2], p[3]);
        let e = (-sigma * tau).exp();
        let (s, c) = (omega * tau).sin_cos();
        let osc = a * c + b * s;
        y += e * osc;
        if let Some(j) = jac.as_deref_mut() {
            let jk = &mut j[2 + 4 * k..2 + 4 * k + 4];
            jk[0] = e * c;
            jk[1] = e * s;
            jk[2] = -tau * e * osc;
            jk[3] = tau * e * (b * c - a * s);
        }
    }
    y
}

/// Least-squares amplitudes (offset, drift, a_k, b_k) for fixed decay rates and frequencies.
pub(crate) fn linear_amplitudes(
    t: &[f64],
    y: &[f64],
    t_ref: f64,
    guesses: &[ModeGuess],
    drift: bool,
) -> Option<Vec<f64>> {
    let cols = 2 + 2 * guesses.len();
    let mut a = DMatrix::<f64>::zeros(t.len(), cols);
    for (i, &ti) in t.iter().enumerate() {
        let tau = ti - t_ref;
        a[(i, 0)] = 1.0;
        a[(i, 1)] = if drift { tau } else { 0.0 };
        for (k, g) in guesses.iter().enumerate() {
            let e = (-g.sigma * tau).exp();
            let (s, c) = (g.omega * tau).sin_cos();
            a[(i, 2 + 2 * k)] = e * c;
            a[(i, 3 + 2 * k)] = e * s;
        }
    }
    let b = DVector::from_column_slice(y);
    // Normal equations for speed; an SVD when they are too ill-conditioned for Cholesky.
    let mut ata = a.tr_mul(&a);
    if !drift {
        ata[(1, 1)] = 1.0;
    }
    let atb = a.tr_mul(&b);
    let solved = match ata.cholesky() {
        Some(c) => c.solve(&atb),
        None => nalgebra::linalg::SVD::try_new(a, true, true, f64::EPSILON, MAX_SVD_ITERATIONS)?
            .solve(&b, 1e-12)
            .ok()?,
    };
    if solved.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let mut params = vec![0.0; 2 + 4 * guesses.len()];
    params[0] = solved[0];
    params[1] = solved[1];
    for (k, g) in guesses.iter().enumerate() {
        params[2 + 4 * k] = solved[2 + 2 * k];
        params[2 + 4 * k + 1] = solved[2 + 2 * k + 1];
        params[2 + 4 * k + 2] = g.sigma;
        params[2 + 4 * k + 3] = g.omega;
    }
    Some(params)
}

fn clamp_params(params: &mut [f64], bounds: &Bounds) {
    let modes = (params.len() - 2) / 4;
    for k in 0..modes {
        let omega = params[2 + 4 * k + 3].clamp(bounds.omega_min, bounds.omega_max);
        params[2 + 4 * k + 3] = omega;
        params[2 + 4 * k + 2] =
            params[2 + 4 * k + 2].clamp(0.0, bounds.sigma_over_omega_max * omega);
    }
}

/// Residuals `y - model` at every sample.
pub(crate) fn residuals(t: &[f64], y: &[f64], t_ref: f64, params: &[f64], drift: bool) -> Vec<f64> {
    t.iter()
        .zip(y)
        .map(|(&ti, &yi)| yi - model(params, ti - t_ref, drift, None))
        .collect()
}

pub(crate) fn residual_sum(t: &[f64], y: &[f64], t_ref: f64, params: &[f64], drift: bool) -> f64 {
    t.iter()
        .zip(y)
        .map(|(&ti, &yi)| {
            let r = yi - model(params, ti - t_ref, drift, None);
            r * r
        })
        .sum()
}

/// Most sweeps of an SVD (nalgebra's unbounded default loops forever on a matrix whose
/// entries overflowed); a few dozen suffice for any matrix of finite entries.
pub(crate) const MAX_SVD_ITERATIONS: usize = 1000;

/// Most iterations of the Levenberg–Marquardt loop.
const MAX_ITERATIONS: usize = 100;

/// Converged when an accepted step lowers the residual sum by less than this fraction...
const RELATIVE_TOLERANCE: f64 = 1e-10;

/// ... or moves no parameter by more than this fraction of its size.
const STEP_TOLERANCE: f64 = 1e-9;

/// Fit the model from `guesses` by bounded Levenberg–Marquardt (Marquardt's diagonal
/// scaling, steps projected onto the bounds), then standard errors from the Jacobian.
pub(crate) fn fit(
    t: &[f64],
    y: &[f64],
    t_ref: f64,
    guesses: &[ModeGuess],
    bounds: &Bounds,
    drift: bool,
) -> Result<Fit> {
    let p = 2 + 4 * guesses.len();
    let free = p - usize::from(!drift);
    if t.len() <= free {
        return Err(ModalError::TooFewSamples {
            what: "the damped-sine fit",
            present: t.len(),
            needed: free + 1,
        });
    }
    let mut params =
        linear_amplitudes(t, y, t_ref, guesses, drift).ok_or(ModalError::Numerical {
            what: "the starting amplitudes",
        })?;
    clamp_params(&mut params, bounds);
    let mut current = residual_sum(t, y, t_ref, &params, drift);
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let mut converged = false;
    let mut jac = DMatrix::<f64>::zeros(t.len(), p);
    let mut resid = DVector::<f64>::zeros(t.len());
    let mut row = vec![0.0; p];
    while iterations < MAX_ITERATIONS {
        iterations += 1;
        for (i, (&ti, &yi)) in t.iter().zip(y).enumerate() {
            let m = model(&params, ti - t_ref, drift, Some(&mut row));
            resid[i] = yi - m;
            for (j, v) in row.iter().enumerate() {
                jac[(i, j)] = *v;
            }
        }
        let jtj = jac.tr_mul(&jac);
        let jtr = jac.tr_mul(&resid);
        let mut improved = false;
        while lambda < 1e12 {
            let mut a = jtj.clone();
            for j in 0..p {
                let d = jtj[(j, j)];
                a[(j, j)] = d + lambda * d.max(1e-12);
            }
            if !drift {
                a[(1, 1)] = 1.0;
            }
            let step = a.cholesky().map(|c| c.solve(&jtr));
            if let Some(step) = step {
                let mut trial: Vec<f64> =
                    params.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
                if !drift {
                    trial[1] = 0.0;
                }
                clamp_params(&mut trial, bounds);
                let next = residual_sum(t, y, t_ref, &trial, drift);
                if next.is_finite() && next <= current {
                    let relative = (current - next) / current.max(f64::MIN_POSITIVE);
                    let moved = params
                        .iter()
                        .zip(&trial)
                        .map(|(a, b)| (a - b).abs() / (a.abs() + b.abs()).max(1e-300))
                        .fold(0.0_f64, f64::max);
                    if relative < RELATIVE_TOLERANCE || moved < STEP_TOLERANCE {
                        converged = true;
                    }
                    params = trial;
                    current = next;
                    lambda = (lambda / 3.0).max(1e-12);
                    improved = true;
                    break;
                }
            }
            lambda *= 4.0;
        }
        if !improved {
            // No downhill step at any damping: at a minimum (to rounding).
            converged = true;
        }
        if converged {
            break;
        }
    }
    finish(t, t_ref, params, drift, current, iterations, converged)
}

/// `(J^T J)^-1` at `params` (unscaled covariance), `None` when singular.
fn unscaled_covariance(t: &[f64], t_ref: f64, params: &[f64], drift: bool) -> Option<DMatrix<f64>> {
    let p = params.len();
    let mut jac = DMatrix::<f64>::zeros(t.len(), p);
    let mut row = vec![0.0; p];
    for (i, &ti) in t.iter().enumerate() {
        model(params, ti - t_ref, drift, Some(&mut row));
        for (j, v) in row.iter().enumerate() {
            jac[(i, j)] = *v;
        }
    }
    let mut info = jac.tr_mul(&jac);
    if !drift {
        for j in 0..p {
            info[(1, j)] = 0.0;
            info[(j, 1)] = 0.0;
        }
        info[(1, 1)] = 1.0;
    }
    info.cholesky().map(|c| c.inverse())
}

/// Modes from parameters, with standard errors from a parameter covariance.
fn modes_from(params: &[f64], cov: Option<&DMatrix<f64>>, t_ref: f64) -> Vec<Mode> {
    let modes_n = (params.len() - 2) / 4;
    let mut modes = Vec::with_capacity(modes_n);
    for k in 0..modes_n {
        let o = 2 + 4 * k;
        let (a, b, sigma, omega) = (params[o], params[o + 1], params[o + 2], params[o + 3]);
        let wn = sigma.hypot(omega);
        let amp = a.hypot(b);
        // Gradients of f_n, xi and amplitude with respect to (a, b, sigma, omega).
        let g_f = [0.0, 0.0, sigma / wn / TAU, omega / wn / TAU];
        let g_xi = [
            0.0,
            0.0,
            omega * omega / wn.powi(3),
            -sigma * omega / wn.powi(3),
        ];
        let g_amp = if amp > 0.0 {
            [a / amp, b / amp, 0.0, 0.0]
        } else {
            [0.0; 4]
        };
        let std_of = |g: &[f64; 4]| {
            cov.and_then(|c| {
                let mut v = 0.0;
                for i in 0..4 {
                    for j in 0..4 {
                        v += g[i] * c[(o + i, o + j)] * g[j];
                    }
                }
                (v.is_finite() && v >= 0.0).then(|| v.sqrt())
            })
        };
        modes.push(Mode {
            frequency_hz: wn / TAU,
            frequency_std_hz: std_of(&g_f),
            damping_ratio: if wn > 0.0 { sigma / wn } else { 0.0 },
            damping_std: std_of(&g_xi),
            damped_frequency_hz: omega / TAU,
            decay_rate_per_s: sigma,
            amplitude: amp,
            amplitude_std: std_of(&g_amp),
            phase_rad: (-b).atan2(a),
            reference_time_s: t_ref,
        });
    }
    modes
}

fn finish(
    t: &[f64],
    t_ref: f64,
    params: Vec<f64>,
    drift: bool,
    rss_value: f64,
    iterations: usize,
    converged: bool,
) -> Result<Fit> {
    let free = params.len() - usize::from(!drift);
    let n = t.len();
    let s2 = rss_value / (n - free) as f64;
    let cov = unscaled_covariance(t, t_ref, &params, drift).map(|c| c * s2);
    let modes = modes_from(&params, cov.as_ref(), t_ref);
    if modes.iter().any(|m| {
        !(m.frequency_hz.is_finite() && m.damping_ratio.is_finite() && m.amplitude.is_finite())
    }) {
        return Err(ModalError::Numerical {
            what: "the damped-sine fit",
        });
    }
    Ok(Fit {
        modes,
        offset: params[0],
        drift_per_s: params[1],
        params,
        residual_rms: (rss_value / n as f64).sqrt(),
        rss: rss_value,
        samples: n,
        parameters: free,
        iterations,
        converged,
    })
}

/// The Cramér–Rao bound of the model this crate fits: the standard deviations below which no
/// unbiased estimator of each mode's frequency and damping ratio can go, for white Gaussian
/// noise of `noise_std` at the samples `times_s`, the true `modes` (amplitude and phase at
/// `reference_time_s` of the first mode), and an offset (plus a drift when `drift`) that
/// are estimated too. Returns the bound as [`Mode`]s whose `*_std` fields hold it; `None`
/// when the information matrix is singular.
#[must_use]
pub fn cramer_rao_bound(
    times_s: &[f64],
    modes: &[Mode],
    noise_std: f64,
    drift: bool,
) -> Option<Vec<Mode>> {
    let t_ref = modes.first()?.reference_time_s;
    let mut params = vec![0.0; 2 + 4 * modes.len()];
    for (k, m) in modes.iter().enumerate() {
        let o = 2 + 4 * k;
        params[o] = m.amplitude * m.phase_rad.cos();
        params[o + 1] = -m.amplitude * m.phase_rad.sin();
        params[o + 2] = m.decay_rate_per_s;
        params[o + 3] = TAU * m.damped_frequency_hz;
    }
    let cov = unscaled_covariance(times_s, t_ref, &params, drift)? * (noise_std * noise_std);
    Some(modes_from(&params, Some(&cov), t_ref))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_noise_free_damped_sine_on_irregular_times() {
        let (f, xi, amp, phase) = (1.46, 0.086, 0.2, 0.4);
        let wn = TAU * f;
        let (sigma, omega) = (xi * wn, wn * (1.0 - xi * xi).sqrt());
        let t: Vec<f64> = (0..300)
            .map(|i| f64::from(i) / 30.0 + 0.002 * (f64::from(i) * 1.7).sin())
            .collect();
        let y: Vec<f64> = t
            .iter()
            .map(|&t| 0.05 + 0.01 * t + amp * (-sigma * t).exp() * (omega * t + phase).cos())
            .collect();
        let bounds = Bounds {
            omega_min: 0.1,
            omega_max: TAU * 15.0,
            sigma_over_omega_max: 2.0,
        };
        let guess = [ModeGuess {
            sigma: sigma * 1.3,
            omega: omega * 1.03,
        }];
        let fit = fit(&t, &y, 0.0, &guess, &bounds, true).unwrap();
        let m = fit.modes[0];
        assert!((m.frequency_hz - f).abs() < 1e-9, "{m:?}");
        assert!((m.damping_ratio - xi).abs() < 1e-9);
        assert!((m.amplitude - amp).abs() < 1e-9);
        assert!((m.phase_rad - phase).abs() < 1e-9);
        assert!((fit.drift_per_s - 0.01).abs() < 1e-9);
        assert!(fit.converged);
    }
}
