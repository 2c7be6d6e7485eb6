//! Angles on generated trees: accuracy, the fold of eq. (1), rigid-motion invariance, gaps.

use approx::assert_relative_eq;
use branch_angles::synthetic::{self, BranchSpec};
use branch_angles::{
    AngleConfig, AngleError, GapConfig, Hierarchy, MarkerNode, MarkerTrack, RestPose, Trajectories,
    branch_angles,
};
use nalgebra::{Point3, Rotation3, Vector3};
use proptest::prelude::*;

/// Rounding of unit vectors built from coordinates of order 1 m, radians.
const ROUNDING_RAD: f64 = 1e-12;
/// The accuracy goal on noise-free trajectories, degrees.
const GOAL_DEG: f64 = 0.01;

fn config_for(tree: &synthetic::SyntheticTree) -> AngleConfig {
    AngleConfig {
        rest: tree.rest,
        ..AngleConfig::default()
    }
}

fn max_err_deg(values: &[Option<f64>], truth: &[f64]) -> f64 {
    values
        .iter()
        .zip(truth)
        .map(|(v, t)| {
            (v.expect("no gaps in generated data") - t)
                .abs()
                .to_degrees()
        })
        .fold(0.0, f64::max)
}

#[test]
fn noise_free_angles_are_within_a_hundredth_of_a_degree() {
    let tree = synthetic::two_level();
    let set = branch_angles(&tree.hierarchy, &tree.trajectories, &config_for(&tree)).expect("ok");
    assert_eq!(set.branches.len(), 3);
    for (b, t) in set.branches.iter().zip(&tree.truth) {
        let s = b.signed.as_ref().expect("signed by default");
        for (what, v, truth) in [
            ("eq. 1", &b.angle_rad.values, &t.angle_rad),
            ("u", &s.u_rad.values, &t.u_rad),
            ("w", &s.w_rad.values, &t.w_rad),
        ] {
            let e = max_err_deg(v, truth);
            assert!(e < GOAL_DEG, "{} {what}: {e} deg", b.child);
        }
        assert!(b.angle_rad.measured.iter().all(|&m| m));
    }
    assert_eq!(set.branches[1].level, 2);
    assert_eq!(set.branches[1].grandparent.as_deref(), Some("A"));
    // The paper's preset gives the same eq. (1) and no signed angles.
    let paper =
        branch_angles(&tree.hierarchy, &tree.trajectories, &AngleConfig::paper()).expect("ok");
    assert!(paper.branches[1].signed.is_none());
    assert_eq!(paper.branches[1].angle_rad, set.branches[1].angle_rad);
}

/// Dominant frequency of `values` at `rate_hz` by a direct DFT scan (0.01 Hz steps).
fn dominant_hz(values: &[f64], rate_hz: f64) -> f64 {
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    let power = |f: f64| {
        let (mut re, mut im) = (0.0, 0.0);
        for (k, v) in values.iter().enumerate() {
            let ph = 2.0 * std::f64::consts::PI * f * k as f64 / rate_hz;
            re += (v - mean) * ph.cos();
            im += (v - mean) * ph.sin();
        }
        re * re + im * im
    };
    (10..=800)
        .map(|k| f64::from(k) * 0.01)
        .max_by(|a, b| power(*a).total_cmp(&power(*b)))
        .expect("non-empty")
}

#[test]
fn a_swing_through_the_rest_direction_keeps_its_frequency_in_the_signed_output() {
    // E is aligned with C at rest and swings ±5 degrees at 2 Hz.
    let tree = synthetic::two_level();
    let set = branch_angles(&tree.hierarchy, &tree.trajectories, &config_for(&tree)).expect("ok");
    let e = &set.branches[2];
    assert_eq!(e.child, "E");
    let after: Vec<usize> = (0..set.times_s.len())
        .filter(|&k| set.times_s[k] > 0.5)
        .collect();
    let pick = |v: &[Option<f64>]| {
        after
            .iter()
            .map(|&k| v[k].expect("known"))
            .collect::<Vec<_>>()
    };
    let u = pick(&e.signed.as_ref().expect("signed").u_rad.values);
    let unsigned = pick(&e.angle_rad.values);
    assert_relative_eq!(dominant_hz(&u, 30.0), 2.0, epsilon = 0.02);
    // The unsigned angle of eq. (1) folds the swing: twice the frequency.
    assert_relative_eq!(dominant_hz(&unsigned, 30.0), 4.0, epsilon = 0.02);
    assert!(unsigned.iter().all(|&a| a >= 0.0));
    assert!(u.iter().any(|&a| a < -0.08) && u.iter().any(|&a| a > 0.08));
}

fn node(id: &str, parent: Option<&str>) -> MarkerNode {
    MarkerNode {
        id: id.into(),
        parent: parent.map(Into::into),
    }
}

fn still(id: &str, n: usize, p: Point3<f64>) -> MarkerTrack {
    MarkerTrack {
        id: id.into(),
        positions_m: vec![Some(p); n],
    }
}

#[test]
fn a_child_aligned_with_its_parent_gives_zero() {
    let h = Hierarchy::new(vec![
        node("A", None),
        node("B", Some("A")),
        node("C", Some("B")),
    ])
    .expect("valid");
    let t = Trajectories::new(
        vec![0.0, 0.1],
        vec![
            still("A", 2, Point3::new(0.0, 0.0, 0.0)),
            still("B", 2, Point3::new(0.3, 0.2, 0.5)),
            still("C", 2, Point3::new(0.9, 0.6, 1.5)),
        ],
    )
    .expect("valid");
    let set = branch_angles(&h, &t, &AngleConfig::default()).expect("ok");
    for v in &set.branches[1].angle_rad.values {
        assert!(v.expect("known").abs() < ROUNDING_RAD, "{v:?}");
    }
    // Anti-parallel: exactly pi, where acos of a rounded ratio can give NaN.
    let t = t.map_positions(|p| {
        if p.x > 0.5 {
            Point3::new(-0.3, -0.2, -0.5)
        } else {
            p
        }
    });
    let set = branch_angles(&h, &t, &AngleConfig::default()).expect("ok");
    let v = set.branches[1].angle_rad.values[0].expect("known");
    assert_relative_eq!(v, std::f64::consts::PI, epsilon = 1e-12);
}

#[test]
fn coincident_markers_and_long_gaps_are_explicit_gaps_and_short_ones_are_filled() {
    let h = Hierarchy::new(vec![
        node("A", None),
        node("B", Some("A")),
        node("C", Some("B")),
    ])
    .expect("valid");
    let n = 12;
    let times: Vec<f64> = (0..n).map(|k| k as f64 / 30.0).collect();
    let mut c = still("C", n, Point3::new(0.5, 0.0, 1.0));
    // Lost at 2 (short, filled) and 5..=9 (long, a gap); coincident with B at 11.
    c.positions_m[2] = None;
    for k in 5..=9 {
        c.positions_m[k] = None;
    }
    c.positions_m[11] = Some(Point3::new(0.0, 0.0, 0.5));
    let t = Trajectories::new(
        times,
        vec![
            still("A", n, Point3::origin()),
            still("B", n, Point3::new(0.0, 0.0, 0.5)),
            c,
        ],
    )
    .expect("valid");
    let set = branch_angles(&h, &t, &AngleConfig::default()).expect("ok");
    let b = &set.branches[1];
    let known: Vec<bool> = b.angle_rad.values.iter().map(Option::is_some).collect();
    let mut expected = vec![true; n];
    for k in [5, 6, 7, 8, 9, 11] {
        expected[k] = false;
    }
    assert_eq!(known, expected);
    assert!(!b.angle_rad.measured[2] && b.angle_rad.measured[1]);
    assert_eq!(b.degenerate_samples, 1);
    assert!(b.angle_rad.values.iter().flatten().all(|v| v.is_finite()));
    let s = b.signed.as_ref().expect("signed");
    assert!(s.u_rad.values.iter().flatten().all(|v| v.is_finite()));
    assert_eq!(set.gaps.len(), 2);
    assert!(set.gaps[0].filled && !set.gaps[1].filled);
    assert_eq!(b.angle_rad.segments(), vec![0..5, 10..11]);
    // Without filling, the short gap stays a gap.
    let none = AngleConfig {
        gaps: GapConfig::NONE,
        ..AngleConfig::default()
    };
    let set = branch_angles(&h, &t, &none).expect("ok");
    assert!(set.branches[1].angle_rad.values[2].is_none());
}

#[test]
fn bad_configs_and_missing_markers_are_named() {
    let tree = synthetic::two_level();
    let bad = AngleConfig {
        root_direction: Vector3::zeros(),
        ..AngleConfig::default()
    };
    assert!(matches!(
        branch_angles(&tree.hierarchy, &tree.trajectories, &bad),
        Err(AngleError::InvalidParameter {
            name: "root_direction",
            ..
        })
    ));
    let empty_rest = AngleConfig {
        rest: RestPose::Interval {
            start_s: 100.0,
            end_s: 101.0,
        },
        ..AngleConfig::default()
    };
    assert!(matches!(
        branch_angles(&tree.hierarchy, &tree.trajectories, &empty_rest),
        Err(AngleError::InvalidParameter { name: "rest", .. })
    ));
    let h = Hierarchy::new(vec![node("A", None), node("Z", Some("A"))]).expect("valid");
    assert!(matches!(
        branch_angles(&h, &tree.trajectories, &AngleConfig::default()),
        Err(AngleError::UnknownMarker { .. })
    ));
}

prop_compose! {
    fn rigid_motion()(
        axis in prop::array::uniform3(-1.0f64..1.0),
        angle in -3.1f64..3.1,
        shift in prop::array::uniform3(-5.0f64..5.0),
    ) -> (Rotation3<f64>, Vector3<f64>) {
        let axis = Vector3::from(axis);
        let r = if axis.norm() > 1e-3 {
            Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle)
        } else {
            Rotation3::identity()
        };
        (r, Vector3::from(shift))
    }
}

/// Tolerance of the invariance: rounding of positions of order 10 m, radians.
const INVARIANCE_RAD: f64 = 1e-9;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn rigid_motions_leave_every_relative_angle_unchanged(
        (r, shift) in rigid_motion(),
        tilt_deg in 5.0f64..80.0,
        freq in 0.5f64..3.0,
    ) {
        let deg = f64::to_radians;
        let spec = |id: &str, parent: &str, tilt: f64, az: f64, f: f64| BranchSpec {
            id: id.into(),
            parent: parent.into(),
            length_m: 0.6,
            rest_tilt_rad: deg(tilt),
            azimuth_rad: deg(az),
            u_amplitude_rad: deg(6.0),
            w_amplitude_rad: deg(4.0),
            frequency_hz: f,
            w_phase_rad: 0.4,
            decay_per_s: 0.2,
        };
        let specs = [
            spec("B", "A", 30.0, 20.0, 1.2),
            spec("C", "B", tilt_deg, 70.0, freq),
            spec("D", "C", 0.0, 0.0, 2.0),
        ];
        let times: Vec<f64> = (0..90).map(|k| f64::from(k) / 30.0).collect();
        let tree = synthetic::generate(&specs, &times, 0.3).unwrap();
        let config = config_for(&tree);
        let before = branch_angles(&tree.hierarchy, &tree.trajectories, &config).unwrap();
        let moved = tree.trajectories.map_positions(|p| r * p + shift);
        // The fixed reference of the root's children moves with the marker set.
        let moved_config = AngleConfig { root_direction: r * config.root_direction, ..config };
        let after = branch_angles(&tree.hierarchy, &moved, &moved_config).unwrap();
        for (a, b) in before.branches.iter().zip(&after.branches) {
            let sa = a.signed.as_ref().unwrap();
            let sb = b.signed.as_ref().unwrap();
            for (x, y) in [
                (&a.angle_rad, &b.angle_rad),
                (&sa.u_rad, &sb.u_rad),
                (&sa.w_rad, &sb.w_rad),
            ] {
                for (u, v) in x.values.iter().zip(&y.values) {
                    let (u, v) = (u.unwrap(), v.unwrap());
                    prop_assert!((u - v).abs() < INVARIANCE_RAD, "{} {u} {v}", a.child);
                }
            }
        }
        for (a, b) in before.displacements_m.iter().zip(&after.displacements_m) {
            for (u, v) in a.values.iter().zip(&b.values) {
                prop_assert!((u.unwrap() - v.unwrap()).abs() < 1e-9);
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn any_positions_give_finite_angles_or_gaps(
        cells in prop::collection::vec(
            prop::option::of(prop::array::uniform3(prop_oneof![Just(0.0f64), -1.0f64..1.0])),
            24,
        )
    ) {
        // Three markers (A, B, C) over 8 samples, positions often coincident or lost.
        let h = Hierarchy::new(vec![node("A", None), node("B", Some("A")), node("C", Some("B"))])
            .unwrap();
        let track = |k: usize, id: &str| MarkerTrack {
            id: id.into(),
            positions_m: (0..8).map(|i| cells[k * 8 + i].map(Point3::from)).collect(),
        };
        let t = Trajectories::new(
            (0..8).map(|i| f64::from(i) * 0.1).collect(),
            vec![track(0, "A"), track(1, "B"), track(2, "C")],
        )
        .unwrap();
        for config in [AngleConfig::default(), AngleConfig::paper()] {
            match branch_angles(&h, &t, &config) {
                Ok(set) => {
                    for b in &set.branches {
                        prop_assert!(b.angle_rad.values.iter().flatten().all(|v| v.is_finite()));
                        if let Some(s) = &b.signed {
                            prop_assert!(s.u_rad.values.iter().flatten().all(|v| v.is_finite()));
                            prop_assert!(s.w_rad.values.iter().flatten().all(|v| v.is_finite()));
                        }
                    }
                }
                Err(e) => prop_assert!(matches!(e, AngleError::InvalidParameter { .. }), "{e}"),
            }
        }
    }
}
