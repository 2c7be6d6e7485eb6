//! Ambient records: the sway peak of a wind record and random decrement around it.

use super::*;

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
pub(super) fn sway_peak(
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

pub(super) fn ambient_estimate(
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
