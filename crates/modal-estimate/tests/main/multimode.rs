use modal_estimate::synthetic::{DecaySpec, SecondMode};
use modal_estimate::{EstimateConfig, estimate};

/// A branch like the paper's J: the stem's mode at 1.46 Hz and a second mode near 2.4 Hz at
/// a third of its amplitude. The automatic model order finds both; one mode is asked for, one
/// is returned.
#[test]
fn a_second_mode_near_2_4_hz_is_found() {
    let spec = DecaySpec {
        second_mode: Some(SecondMode {
            frequency_ratio: 2.4 / 1.46,
            amplitude_ratio: 0.35,
            damping_ratio: 0.05,
        }),
        snr_db: 30.0,
        ..DecaySpec::paper_branch()
    };
    let signal = spec.generate().unwrap();
    let e = estimate(&signal, &EstimateConfig::default()).unwrap();
    assert_eq!(e.modes.len(), 2, "{:?}", e.modes);
    // Largest amplitude first.
    assert!(e.modes[0].amplitude > e.modes[1].amplitude);
    let (m1, m2) = (e.modes[0], e.modes[1]);
    assert!(
        (m1.frequency_hz - 1.46).abs() < 3.0 * m1.frequency_std_hz.unwrap(),
        "{m1:?}"
    );
    assert!(
        (m2.frequency_hz - 2.4).abs() < 3.0 * m2.frequency_std_hz.unwrap(),
        "{m2:?}"
    );
    assert!(
        (m1.damping_ratio - 0.086).abs() < 3.0 * m1.damping_std.unwrap(),
        "{m1:?}"
    );
    assert!(
        (m2.damping_ratio - 0.05).abs() < 3.0 * m2.damping_std.unwrap(),
        "{m2:?}"
    );
    let one = EstimateConfig {
        modes: Some(1),
        ..EstimateConfig::default()
    };
    assert_eq!(estimate(&signal, &one).unwrap().modes.len(), 1);
    // A single-mode record gets a single mode.
    let single = DecaySpec::paper_branch().generate().unwrap();
    assert_eq!(
        estimate(&single, &EstimateConfig::default())
            .unwrap()
            .modes
            .len(),
        1
    );
}
