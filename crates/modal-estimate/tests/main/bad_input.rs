use modal_estimate::{EstimateConfig, ModalError, Signal, estimate};

fn uniform(values: Vec<Option<f64>>) -> Signal {
    Signal::uniform(30.0, values).unwrap()
}

#[test]
fn bad_records_are_typed_errors() {
    let cfg = EstimateConfig::default();
    assert!(matches!(
        estimate(&uniform(vec![None; 50]), &cfg),
        Err(ModalError::AllMissing { samples: 50 })
    ));
    assert!(matches!(
        estimate(&uniform(vec![Some(0.3); 50]), &cfg),
        Err(ModalError::Constant { .. })
    ));
    assert!(matches!(
        estimate(&uniform(vec![Some(0.1), Some(0.2), Some(0.1)]), &cfg),
        Err(ModalError::TooFewSamples { .. })
    ));
    assert!(matches!(
        Signal::new(vec![0.0, 1.0, 0.5], vec![Some(1.0); 3]),
        Err(ModalError::NonIncreasingTime { index: 2, .. })
    ));
    assert!(matches!(
        Signal::new(vec![0.0, 1.0], vec![Some(f64::NAN), Some(1.0)]),
        Err(ModalError::NonFiniteValue { index: 0, .. })
    ));
    let wave: Vec<Option<f64>> = (0..300).map(|i| Some((f64::from(i) * 0.3).sin())).collect();
    let beyond = EstimateConfig {
        band_hz: Some((0.5, 20.0)),
        ..EstimateConfig::default()
    };
    assert!(matches!(
        estimate(&uniform(wave.clone()), &beyond),
        Err(ModalError::BandAboveNyquist { .. })
    ));
    let backwards = EstimateConfig {
        band_hz: Some((3.0, 1.0)),
        ..EstimateConfig::default()
    };
    assert!(matches!(
        estimate(&uniform(wave), &backwards),
        Err(ModalError::InvalidBand { .. })
    ));
    // Half a cycle of a 0.1 Hz wave in 2 s: shorter than a cycle at the band's edge.
    let short = EstimateConfig {
        band_hz: Some((0.05, 0.2)),
        ..EstimateConfig::default()
    };
    let slow: Vec<Option<f64>> = (0..60)
        .map(|i| Some((f64::from(i) / 30.0 * 0.6).sin()))
        .collect();
    assert!(matches!(
        estimate(&uniform(slow), &short),
        Err(ModalError::RecordTooShort { .. })
    ));
}

mod never_panics {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Arbitrary records: an estimate or a typed error, and every number finite.
        #[test]
        fn estimates_are_finite_or_errors(
            values in proptest::collection::vec(proptest::option::weighted(0.9, -1e3f64..1e3), 0..120),
            gaps in proptest::collection::vec(0.001f64..0.2, 120),
        ) {
            let mut t = 0.0;
            let times: Vec<f64> = gaps.iter().take(values.len()).map(|g| { t += g; t }).collect();
            let signal = Signal::new(times, values).unwrap();
            for method in ["auto", "paper", "pencil", "ambient"] {
                let cfg = EstimateConfig { method: method.parse().unwrap(), ..EstimateConfig::default() };
                if let Ok(e) = estimate(&signal, &cfg) {
                    for m in &e.modes {
                        let numbers = [m.frequency_hz, m.damping_ratio, m.amplitude, m.phase_rad, m.damped_frequency_hz, m.decay_rate_per_s];
                        prop_assert!(numbers.iter().all(|v| v.is_finite()), "{m:?}");
                        for s in [m.frequency_std_hz, m.damping_std, m.amplitude_std].into_iter().flatten() {
                            prop_assert!(s.is_finite());
                        }
                    }
                }
            }
        }
    }
}

/// The paper's branch record with every value multiplied by `scale`.
fn scaled_branch(scale: f64) -> Signal {
    let s = modal_estimate::synthetic::DecaySpec::paper_branch()
        .generate()
        .unwrap();
    let values = s.values().iter().map(|v| v.map(|v| v * scale)).collect();
    Signal::new(s.times_s().to_vec(), values).unwrap()
}

#[test]
fn the_unit_of_a_record_does_not_change_its_frequency_or_damping() {
    // Issue 20: a decay scaled by 1e155 hung in the matrix pencil's SVD (its Gram matrix
    // overflowed); scaled by 1e-160 the squares underflow. Frequency and damping must not
    // depend on the unit, and the amplitude must scale with it.
    for method in [modal_estimate::Method::Auto, modal_estimate::Method::Paper] {
        let config = if method == modal_estimate::Method::Paper {
            EstimateConfig::paper()
        } else {
            EstimateConfig::default()
        };
        let reference = estimate(&scaled_branch(1.0), &config).unwrap();
        let m0 = reference.modes[0];
        for exponent in [-300, -200, -160, -100, -10, 10, 100, 154, 155, 200, 300] {
            let scale = 10f64.powi(exponent);
            let e = estimate(&scaled_branch(scale), &config)
                .unwrap_or_else(|err| panic!("{method:?} at 1e{exponent}: {err}"));
            let m = e.modes[0];
            assert!(
                (m.frequency_hz / m0.frequency_hz - 1.0).abs() < 1e-6,
                "{method:?} 1e{exponent}: {m:?} vs {m0:?}"
            );
            assert!(
                (m.damping_ratio / m0.damping_ratio - 1.0).abs() < 1e-6,
                "{method:?} 1e{exponent}: {m:?} vs {m0:?}"
            );
            let amplitude = m.amplitude / scale;
            assert!(
                (amplitude / m0.amplitude - 1.0).abs() < 1e-6,
                "{method:?} 1e{exponent}: amplitude {} vs {}",
                m.amplitude,
                m0.amplitude
            );
        }
    }
}

#[test]
fn one_absurd_sample_is_named_not_fitted() {
    // Issue 20: one sample of 1e308 hung the estimator, one of 1e200 panicked.
    for bad in [1e308, 1e200, -1e300, 1e30] {
        let s = scaled_branch(1.0);
        let mut values = s.values().to_vec();
        values[57] = Some(bad);
        let signal = Signal::new(s.times_s().to_vec(), values).unwrap();
        match estimate(&signal, &EstimateConfig::default()) {
            Err(ModalError::Outlier { index, value, .. }) => {
                assert_eq!(index, 57);
                assert_eq!(value, bad);
            }
            other => panic!("{bad}: {other:?}"),
        }
    }
}

#[test]
fn timestamps_that_would_need_a_huge_grid_are_refused() {
    // Two samples a nanosecond apart and the rest a second apart: a uniform grid at the
    // median interval is fine, but one sample per nanosecond over 1e6 s is not.
    let mut times: Vec<f64> = (0..20).map(|i| f64::from(i) * 1e-9).collect();
    times.push(1e6);
    let values = (0..21).map(|i| Some(f64::from(i % 3))).collect();
    let signal = Signal::new(times, values).unwrap();
    assert!(matches!(
        signal.resample_uniform(None),
        Err(ModalError::TooLarge { .. })
    ));
    assert!(estimate(&signal, &EstimateConfig::default()).is_err());
}

#[test]
fn spectra_and_the_paper_method_do_not_depend_on_the_unit() {
    use modal_estimate::{Scaling, SpectrumConfig, paper_half_power, spectrum};
    let reference = scaled_branch(1.0);
    let hp0 = paper_half_power(&reference, 0.2, 15.0).unwrap();
    for scaling in [Scaling::Amplitude, Scaling::PowerSpectralDensity] {
        let config = SpectrumConfig {
            scaling,
            ..SpectrumConfig::default()
        };
        let s0 = spectrum(&reference, &config).unwrap();
        let peak0 = s0.peaks(0.1)[0].refined_frequency_hz;
        for exponent in [-300, -160, -100, 0, 100, 154, 155, 200, 300] {
            let scale = 10f64.powi(exponent);
            match spectrum(&scaled_branch(scale), &config) {
                Ok(s) => {
                    assert!(s.values.iter().all(|v| v.is_finite()), "1e{exponent}");
                    let peak = s.peaks(0.1)[0].refined_frequency_hz;
                    assert!((peak / peak0 - 1.0).abs() < 1e-9, "1e{exponent}: {peak}");
                }
                // A PSD in unit^2/Hz of a record in units of 1e300 is beyond f64, and an
                // amplitude spectrum of 1e-300 units is at the edge of underflow: said so.
                Err(ModalError::Numerical { .. }) => {
                    let representable = match scaling {
                        Scaling::Amplitude => -200..=300,
                        _ => -100..=100,
                    };
                    assert!(!representable.contains(&exponent), "1e{exponent}");
                }
                Err(e) => panic!("1e{exponent}: {e}"),
            }
        }
    }
    for exponent in [-200, -100, 100, 300] {
        let hp = paper_half_power(&scaled_branch(10f64.powi(exponent)), 0.2, 15.0).unwrap();
        assert_eq!(hp.bin, hp0.bin, "1e{exponent}");
        let (xi, xi0) = (hp.damping_ratio.unwrap(), hp0.damping_ratio.unwrap());
        assert!((xi / xi0 - 1.0).abs() < 1e-9, "1e{exponent}: {xi} vs {xi0}");
    }
}
