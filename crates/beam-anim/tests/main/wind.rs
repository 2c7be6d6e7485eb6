//! The synthesized wind: spectral slope, variance, coherence.

use beam_anim::wind::{log_slope, welch_psd};
use beam_anim::{Spectrum, WindConfig, WindField};

#[test]
fn power_law_wind_has_the_slope_it_was_asked_for() {
    for beta in [5.0 / 3.0, 1.0, 2.0] {
        let config = WindConfig {
            spectrum: Spectrum::PowerLaw {
                beta,
                corner_hz: 0.05,
            },
            ..WindConfig::default()
        };
        let fs = 30.0;
        let mut w = WindField::new(config, 1.0 / fs, 5.0).unwrap();
        let x = w.along_wind_series(1 << 17);
        let (f, p) = welch_psd(&x, fs, 4096);
        // Well above the corner and below Nyquist.
        let slope = log_slope(&f, &p, 0.5, 10.0).unwrap();
        assert!((slope + beta).abs() < 0.05, "beta {beta}: slope {slope}");
        // σ_u = I U.
        let sd = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
        let want = config.turbulence_intensity * config.mean_speed_m_s;
        assert!((sd / want - 1.0).abs() < 0.2, "sd {sd} want {want}");
    }
}

#[test]
fn kaimal_and_von_karman_fall_at_five_thirds() {
    for spectrum in [
        Spectrum::Kaimal {
            length_scale_m: 50.0,
        },
        Spectrum::VonKarman {
            length_scale_m: 50.0,
        },
    ] {
        let config = WindConfig {
            spectrum,
            ..WindConfig::default()
        };
        let mut w = WindField::new(config, 1.0 / 30.0, 5.0).unwrap();
        let x = w.along_wind_series(1 << 17);
        let (f, p) = welch_psd(&x, 30.0, 4096);
        let slope = log_slope(&f, &p, 1.0, 10.0).unwrap();
        assert!((slope + 5.0 / 3.0).abs() < 0.1, "{spectrum:?}: {slope}");
    }
}

#[test]
fn frozen_turbulence_delays_gusts_downstream() {
    let config = WindConfig::default();
    let dt = 1.0 / 30.0;
    let mut w = WindField::new(config, dt, 10.0).unwrap();
    // A point 5 m downstream sees now what the upstream point saw 1 s (30 samples) ago.
    let mut upstream = Vec::new();
    let mut downstream = Vec::new();
    for _ in 0..200 {
        w.advance();
        upstream.push(w.velocity_at(0.0));
        downstream.push(w.velocity_at(5.0));
    }
    for k in 30..200 {
        assert!((downstream[k] - upstream[k - 30]).norm() < 1e-9, "{k}");
    }
}
