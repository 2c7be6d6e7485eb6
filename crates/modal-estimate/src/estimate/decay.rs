//! Free decay: the part after the release, skipped and trimmed; starting poles from the
//! matrix pencil and the spectrum; 1..=k modes fitted and the best kept by BIC.

use super::*;

/// Free decay from `release_s` (or the record's start): skip, fit, trim the tail, refit.
pub(super) fn free_decay(
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

pub(super) fn bounds(part: &Signal, band: (f64, f64)) -> Bounds {
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
pub(super) fn starting_poles(
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
pub(super) fn fit_modes(
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
