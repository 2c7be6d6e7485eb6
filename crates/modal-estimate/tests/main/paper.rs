use modal_estimate::synthetic::DecaySpec;
use modal_estimate::{EstimateConfig, Method, estimate, paper_half_power};

/// The paper's 1.39 and 1.46 Hz are bins 19 and 20 of a 409-sample FFT at 30 Hz: its
/// method reports the bin, whatever the true frequency between bins.
#[test]
fn paper_method_lands_on_bins_19_and_20_for_409_samples_at_30_hz() {
    let bin_hz = 30.0 / 409.0;
    for (true_hz, bin) in [(1.39, 19), (1.46, 20), (1.37, 19), (1.48, 20)] {
        let spec = DecaySpec {
            frequency_hz: true_hz,
            held_s: 0.0,
            jitter_s: 0.0,
            drop_fraction: 0.0,
            snr_db: 40.0,
            ..DecaySpec::paper_branch()
        };
        let signal = spec.generate().unwrap();
        let hp = paper_half_power(&signal, 0.3, 15.0).unwrap();
        assert_eq!(hp.bin, bin, "{true_hz} Hz");
        assert!((hp.frequency_hz - bin as f64 * bin_hz).abs() < 1e-12);
        assert!((hp.bin_width_hz - bin_hz).abs() < 1e-12);
        // Eq. (6) from the interpolated half-power band.
        let (lo, hi) = (hp.lower_hz.unwrap(), hp.upper_hz.unwrap());
        assert!((hp.damping_ratio.unwrap() - (hi - lo) / (2.0 * hp.frequency_hz)).abs() < 1e-12);
        // Through the estimator, with the bin quantisation as its uncertainty.
        let e = estimate(&signal, &EstimateConfig::paper()).unwrap();
        assert_eq!(e.method, Method::Paper);
        assert!((e.modes[0].frequency_hz - bin as f64 * bin_hz).abs() < 1e-12);
        assert!((e.modes[0].frequency_std_hz.unwrap() - bin_hz / 12f64.sqrt()).abs() < 1e-12);
        assert!(e.modes[0].damping_std.is_none());
    }
}

/// A half-power band only a few bins wide overestimates the damping of a lightly damped
/// branch; the parametric fit does not.
#[test]
fn half_power_band_overestimates_light_damping() {
    let (mut paper_err, mut our_err) = (0.0, 0.0);
    let cases: u32 = 11;
    for k in 0..cases {
        let k: u32 = k;
        let spec = DecaySpec {
            frequency_hz: 1.40 + 0.01 * f64::from(k),
            damping_ratio: 0.03,
            held_s: 0.0,
            snr_db: 35.0,
            seed: k.into(),
            ..DecaySpec::paper_branch()
        };
        let signal = spec.generate().unwrap();
        let paper = estimate(&signal, &EstimateConfig::paper()).unwrap();
        let ours = estimate(&signal, &EstimateConfig::default()).unwrap();
        paper_err += (paper.modes[0].damping_ratio / spec.damping_ratio - 1.0) / f64::from(cases);
        our_err +=
            (ours.modes[0].damping_ratio / spec.damping_ratio - 1.0).abs() / f64::from(cases);
    }
    eprintln!("xi 0.03: paper bias {paper_err:+.3}, ours mean |error| {our_err:.3}");
    assert!(paper_err > 0.2, "{paper_err}");
    assert!(our_err < 0.05, "{our_err}");
}
