//! Every bad input is a typed error, never a panic or a NaN pose.

use beam_anim::{
    AnimConfig, AnimError, BeamTree, Dynamics, PAPER_DYNAMICS, Simulation, WindConfig, WindField,
    validate_nodes,
};
use nalgebra::{Point3, Vector3};
use proptest::prelude::*;
use space_colonize::SkeletonNode;

fn node(id: usize, parent: Option<usize>, z: f64) -> SkeletonNode {
    SkeletonNode {
        id,
        parent,
        position: Point3::new(0.0, 0.0, z),
        radius_m: 0.01,
    }
}

fn chain(n: usize) -> Vec<SkeletonNode> {
    (0..n)
        .map(|i| node(i, i.checked_sub(1), 0.2 * i as f64))
        .collect()
}

fn sim(dynamics: Dynamics, dt_s: f64) -> beam_anim::Result<Simulation> {
    let sk = validate_nodes(&chain(6))?;
    let config = AnimConfig::default();
    let tree = BeamTree::new(&sk, &config)?;
    let d = vec![dynamics; tree.branches().len()];
    Simulation::new(tree, &d, config, dt_s)
}

#[test]
fn skeleton_errors_are_named() {
    let mut cyc = chain(4);
    cyc[0].parent = Some(3);
    cyc.push(node(4, None, 5.0));
    assert!(matches!(validate_nodes(&cyc), Err(AnimError::Cycle { .. })));
    let mut two = chain(4);
    two[2].parent = None;
    assert!(matches!(
        validate_nodes(&two),
        Err(AnimError::Disconnected { node: 2 })
    ));
    let mut zero = chain(4);
    zero[3].position = zero[2].position;
    assert!(matches!(
        validate_nodes(&zero),
        Err(AnimError::ZeroLengthSegment { node: 3 })
    ));
    assert!(matches!(
        validate_nodes(&[]),
        Err(AnimError::InvalidSkeleton { .. })
    ));
    let mut dangling = chain(3);
    dangling[1].parent = Some(9);
    assert!(matches!(
        validate_nodes(&dangling),
        Err(AnimError::InvalidSkeleton { .. })
    ));
}

#[test]
fn dynamics_and_step_errors_are_named() {
    let f0 = Dynamics {
        frequency_hz: 0.0,
        ..PAPER_DYNAMICS
    };
    assert!(matches!(
        sim(f0, 0.03),
        Err(AnimError::InvalidFrequency { .. })
    ));
    let fneg = Dynamics {
        frequency_hz: -1.0,
        ..PAPER_DYNAMICS
    };
    assert!(matches!(
        sim(fneg, 0.03),
        Err(AnimError::InvalidFrequency { .. })
    ));
    for xi in [1.0, -0.1, f64::NAN] {
        let d = Dynamics {
            damping_ratio: xi,
            ..PAPER_DYNAMICS
        };
        assert!(
            matches!(sim(d, 0.03), Err(AnimError::InvalidDamping { .. })),
            "{xi}"
        );
    }
    for dt in [0.0, -1.0, f64::NAN] {
        assert!(matches!(
            sim(PAPER_DYNAMICS, dt),
            Err(AnimError::InvalidTimeStep { .. })
        ));
        assert!(matches!(
            WindField::new(WindConfig::default(), dt, 1.0),
            Err(AnimError::InvalidTimeStep { .. })
        ));
    }
}

#[test]
fn nan_wind_is_refused_and_the_pose_stays_finite() {
    let mut s = sim(PAPER_DYNAMICS, 1.0 / 30.0).unwrap();
    let n = s.tree().segment_count();
    let mut v = vec![Vector3::new(5.0, 0.0, 0.0); n];
    s.step_with(&v).unwrap();
    v[2].y = f64::NAN;
    assert!(matches!(
        s.step_with(&v),
        Err(AnimError::NonFiniteWind { .. })
    ));
    assert!(s.pose().angle_rad.iter().all(|a| a.is_finite()));
    let bad = WindConfig {
        mean_speed_m_s: f64::NAN,
        ..WindConfig::default()
    };
    assert!(matches!(
        WindField::new(bad, 0.03, 1.0),
        Err(AnimError::InvalidParameter { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn random_parent_links_never_panic(parents in proptest::collection::vec(proptest::option::of(0usize..12), 1..12),
                                       zs in proptest::collection::vec(-1.0f64..1.0, 12)) {
        let nodes: Vec<SkeletonNode> = parents.iter().enumerate()
            .map(|(i, p)| node(i, *p, zs[i] + i as f64))
            .collect();
        if let Ok(sk) = validate_nodes(&nodes) {
            let config = AnimConfig::default();
            if let Ok(tree) = BeamTree::new(&sk, &config) {
                let d = vec![PAPER_DYNAMICS; tree.branches().len()];
                let mut s = Simulation::new(tree, &d, config, 1.0 / 30.0).unwrap();
                let mut w = s.wind_field().unwrap();
                for _ in 0..10 {
                    s.step(&mut w).unwrap();
                }
                prop_assert!(s.pose().angle_rad.iter().all(|a| a.is_finite()));
            }
        }
    }
}

/// Issue 20: values outside the range where the model means anything are errors, and sizes
/// are checked before anything is allocated.
#[test]
fn values_beyond_the_model_and_sizes_beyond_memory_are_refused() {
    // Nothing of a tree sways at 1e12 Hz, and a 20 Hz branch cannot be shown by frames
    // 1/30 s apart.
    let absurd = Dynamics {
        frequency_hz: 1e12,
        ..PAPER_DYNAMICS
    };
    assert!(matches!(
        sim(absurd, 1.0 / 30.0),
        Err(AnimError::InvalidFrequency { .. })
    ));
    let fast = Dynamics {
        frequency_hz: 20.0,
        ..PAPER_DYNAMICS
    };
    let e = sim(fast, 1.0 / 30.0)
        .err()
        .expect("20 Hz at 30 fps refused");
    assert!(
        matches!(
            e,
            AnimError::InvalidParameter {
                name: "dynamics",
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("Nyquist"), "{e}");
    assert!(sim(fast, 1.0 / 60.0).is_ok());
    assert!(
        sim(
            Dynamics {
                frequency_hz: 14.9,
                ..PAPER_DYNAMICS
            },
            1.0 / 30.0
        )
        .is_ok()
    );
    // Pulls beyond a right angle.
    let mut s = sim(PAPER_DYNAMICS, 1.0 / 30.0).unwrap();
    let id = s.tree().branches()[0].id;
    for deg in [1000.0_f64, -91.0, f64::INFINITY] {
        assert!(
            matches!(
                s.pull(id, deg.to_radians()),
                Err(AnimError::InvalidParameter {
                    name: "angle_rad",
                    ..
                })
            ),
            "{deg}"
        );
    }
    assert!(s.pull(id, 20f64.to_radians()).is_ok());
    // Wind beyond any measured gust.
    let mut w = WindConfig {
        mean_speed_m_s: 1e6,
        ..WindConfig::default()
    };
    assert!(matches!(
        w.validate(),
        Err(AnimError::InvalidParameter {
            name: "mean_speed_m_s",
            ..
        })
    ));
    w.mean_speed_m_s = beam_anim::MAX_WIND_SPEED_M_S;
    assert!(w.validate().is_ok());
    // Frames: counted, then checked against the frame and memory limits.
    assert_eq!(beam_anim::frame_count(10.0, 30.0, 80, 20).unwrap(), 300);
    assert_eq!(beam_anim::frame_count(1e-6, 30.0, 80, 20).unwrap(), 1);
    for (seconds, fps) in [(1e9, 30.0), (10.0, 1e9), (1e300, 1e300)] {
        assert!(
            matches!(
                beam_anim::frame_count(seconds, fps, 80, 20),
                Err(AnimError::TooLarge { .. })
            ),
            "{seconds} {fps}"
        );
    }
    // 3 million frames fit the frame limit but not the memory limit for 80 segments.
    assert!(matches!(
        beam_anim::frame_count(100_000.0, 30.0, 80, 20),
        Err(AnimError::TooLarge { .. })
    ));
    for (seconds, fps) in [
        (0.0, 30.0),
        (-1.0, 30.0),
        (f64::NAN, 30.0),
        (10.0, f64::INFINITY),
    ] {
        assert!(
            matches!(
                beam_anim::frame_count(seconds, fps, 80, 20),
                Err(AnimError::InvalidParameter { .. })
            ),
            "{seconds} {fps}"
        );
    }
}
