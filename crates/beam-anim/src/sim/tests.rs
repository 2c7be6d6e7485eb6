//! Unit tests of `sim`.
#![allow(clippy::unwrap_used)]
use super::*;

#[test]
fn branches_bent_in_pairs_match_branches_bent_one_by_one() {
    let sk = crate::procedural_tree(60, 11).unwrap();
    let mut config = AnimConfig::default();
    config.wind.mean_speed_m_s = 25.0;
    let tree = BeamTree::new(&sk, &config).unwrap();
    let d = vec![crate::PAPER_DYNAMICS; tree.branches().len()];
    let mut paired = Simulation::new(tree, &d, config, 1.0 / 30.0).unwrap();
    let mut single = Simulation::new(paired.tree().clone(), &d, config, 1.0 / 30.0).unwrap();
    single.pairable.fill(false);
    assert!(paired.pairable.iter().filter(|&&p| p).count() > 10);
    let mut wind = paired.wind_field().unwrap();
    let mut worst = 0.0f64;
    let mut largest = 0.0f64;
    for _ in 0..60 {
        let v: Vec<Vector3<f64>> = paired
            .downstream_m
            .iter()
            .map(|&x| wind.velocity_at(x))
            .collect();
        wind.advance();
        paired.step_with(&v).unwrap();
        single.step_with(&v).unwrap();
        for (a, b) in paired.pose.local.iter().zip(&single.pose.local) {
            worst = worst.max((a.coords - b.coords).amax());
            largest = largest.max(a.angle());
        }
        for (a, b) in paired.dir.iter().zip(&single.dir) {
            worst = worst.max((a - b).amax());
        }
    }
    // Both paths ran through bends of all series tiers, and agree to rounding.
    assert!(largest > 0.0625, "largest segment rotation {largest}");
    assert!(worst < 1e-13, "worst difference {worst}");
}

#[test]
fn rotation_matches_the_exact_axis_angle_quaternion_on_both_sides_of_the_series() {
    for &angle in &[
        0.0, 1e-9, 1e-3, 0.0199, 0.0201, 0.1, 0.2499, 0.2501, 1.0, 3.0,
    ] {
        let phi = Vector3::new(0.3, -0.5, 0.8).normalize() * angle;
        let ours = rotation(&phi);
        let exact = UnitQuaternion::from_scaled_axis(phi);
        let d = (ours.coords - exact.coords).amax();
        assert!(d < 2e-16, "angle {angle}: off by {d}");
    }
}
