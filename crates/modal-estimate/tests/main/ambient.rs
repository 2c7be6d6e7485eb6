use modal_estimate::synthetic::ambient;
use modal_estimate::{EstimateConfig, Estimator, Method, Warning, estimate};

#[test]
fn an_hour_of_wind_sway_gives_frequency_and_damping() {
    let (f, xi) = (0.9, 0.04);
    let signal = ambient(f, xi, 10.0, 3600.0, 20.0, 7).unwrap();
    let e = estimate(&signal, &EstimateConfig::default()).unwrap();
    assert_eq!(e.estimator, Estimator::RandomDecrement, "{:?}", e.warnings);
    let m = e.modes[0];
    eprintln!(
        "ambient: f {:.4} xi {:.4} +- {:.4}",
        m.frequency_hz,
        m.damping_ratio,
        m.damping_std.unwrap()
    );
    assert!((m.frequency_hz / f - 1.0).abs() < 0.01, "{m:?}");
    assert!((m.damping_ratio / xi - 1.0).abs() < 0.3, "{m:?}");
    assert!(
        !e.warnings
            .iter()
            .any(|w| matches!(w, Warning::DampingUncertain { .. }))
    );
}

#[test]
fn a_short_wind_record_warns_that_damping_is_untrustworthy() {
    let signal = ambient(1.2, 0.015, 20.0, 60.0, 20.0, 3).unwrap();
    let config = EstimateConfig {
        method: Method::Ambient,
        ..EstimateConfig::default()
    };
    let e = estimate(&signal, &config).unwrap();
    let warning = e
        .warnings
        .iter()
        .find_map(|w| match w {
            Warning::DampingUncertain { cov, cycles, .. } => Some((*cov, *cycles)),
            _ => None,
        })
        .expect("Au's rule warning");
    // Au: c.o.v. = 1 / sqrt(2 pi xi N) with N = 72 cycles.
    let xi = e.modes[0].damping_ratio;
    assert!((warning.0 - 1.0 / (std::f64::consts::TAU * xi * warning.1).sqrt()).abs() < 1e-9);
    assert!(warning.0 > 0.3);
}
