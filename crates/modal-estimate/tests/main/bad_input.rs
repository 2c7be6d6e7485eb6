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
