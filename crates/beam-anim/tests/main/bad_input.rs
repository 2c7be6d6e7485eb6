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
    let tree = BeamTree::new(&sk, config.wood_density_kg_m3, &config.wind.direction)?;
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
            if let Ok(tree) = BeamTree::new(&sk, config.wood_density_kg_m3, &config.wind.direction) {
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
