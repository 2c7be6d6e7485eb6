//! Unit tests of `refine`.
#![allow(clippy::unwrap_used)]
use super::*;

/// A straight 1 m trunk up z in 10 cm steps, with a 6 cm side stub in +x from 50 cm.
fn trunk_with_stub() -> Graph {
    let mut pos: Vec<Vector3<f64>> = (0..=10)
        .map(|k| Vector3::new(0.0, 0.0, 0.1 * f64::from(k)))
        .collect();
    let mut parent: Vec<Option<usize>> = (0_usize..=10).map(|k| k.checked_sub(1)).collect();
    pos.push(Vector3::new(0.03, 0.0, 0.5));
    parent.push(Some(5));
    pos.push(Vector3::new(0.06, 0.0, 0.5));
    parent.push(Some(11));
    let bridge = vec![false; pos.len()];
    Graph {
        pos,
        parent,
        bridge,
    }
}

#[test]
fn fits_far_from_the_pipe_model_are_not_used() {
    let g = trunk_with_stub();
    let (pipe, _) = g.to_skeleton(2.5, 0.05, None).unwrap();
    let scaled = |k: f64| -> Vec<Option<f64>> {
        pipe.nodes().iter().map(|n| Some(k * n.radius_m)).collect()
    };
    let (near, used) = g.to_skeleton(2.5, 0.05, Some(&scaled(1.3))).unwrap();
    assert!(used);
    assert!((near.nodes()[3].radius_m / pipe.nodes()[3].radius_m - 1.3).abs() < 1e-9);
    // Five times the pipe radius at the median: leaf clumps, not wood.
    let (far, used) = g.to_skeleton(2.5, 0.05, Some(&scaled(5.0))).unwrap();
    assert!(!used);
    assert_eq!(far, pipe);
}

#[test]
fn twig_ends_in_the_air_are_found_from_their_first_far_segment() {
    // Trunk nodes every 10 cm up z with a side twig at 50 cm: 3 cm, 6 cm, then 10 cm
    // and 14 cm out along +x. Points lie along the trunk and the twig's first 6 cm.
    let mut g = trunk_with_stub();
    g.pos.push(Vector3::new(0.10, 0.0, 0.5));
    g.parent.push(Some(12));
    g.pos.push(Vector3::new(0.14, 0.0, 0.5));
    g.parent.push(Some(13));
    g.bridge.extend([false, false]);
    let (sk, _) = g.to_skeleton(2.5, 0.02, None).unwrap();
    let mut pts: Vec<[f64; 3]> = (0..=100).map(|k| [0.0, 0.0, 0.01 * f64::from(k)]).collect();
    pts.extend((0..=6).map(|k| [0.01 * f64::from(k), 0.0, 0.5]));
    let tree: PointTree = PointTree::new_from_slice(&pts);
    // The segment 6 -> 10 cm has its middle 2 cm beyond the last point, its surface
    // 1.3 cm (pipe radius 7 mm): with 2.5 cm allowed only the last segment is in
    // the air, with 1 cm both are, from the first far one to the tip.
    assert_eq!(far_tails(&sk, &tree, 0.025), vec![vec![14]]);
    assert_eq!(far_tails(&sk, &tree, 0.01), vec![vec![13, 14]]);
    // The trunk's top is no tail: its points reach it.
    assert!(far_tails(&sk, &tree, 0.005).iter().all(|t| t[0] > 10));
    // Onto the cloud: the tail's nodes go to their radius from their nearest point (the
    // twig's last point, 6 cm out), and no segment is in the air any more; as a bridge,
    // the same tail stays where it is.
    let r: Vec<f64> = sk.nodes().iter().map(|n| n.radius_m).collect();
    let tails = far_tails(&sk, &tree, 0.01);
    let mut bridged = g.clone();
    bridged.bridge[13] = true;
    bridged.bridge[14] = true;
    assert_eq!(bridged.onto_cloud(&tails, &tree, &pts, &r), 0);
    assert_eq!(bridged.pos, g.pos);
    assert_eq!(g.onto_cloud(&tails, &tree, &pts, &r), 2);
    for v in [13, 14] {
        assert!((g.pos[v] - Vector3::new(0.06 + r[v], 0.0, 0.5)).norm() < 1e-12);
    }
    let (moved, _) = g.to_skeleton(2.5, 0.02, None).unwrap();
    assert!(far_tails(&moved, &tree, 0.01).is_empty());
}

#[test]
fn a_stub_is_kept_only_when_a_point_needs_it() {
    let g = trunk_with_stub();
    let (sk, _) = g.to_skeleton(2.5, 0.02, None).unwrap();
    let stubs = twig_stubs(&sk, 0.1);
    assert_eq!(stubs, vec![vec![11, 12]]);
    let trunk_r = sk.nodes()[5].radius_m;
    // Distance of a point in the y = 0 plane at height 0.5 m to the trunk's surface.
    let off_trunk = |x: f64| x.abs() - trunk_r;
    // A point 30 cm out, beyond the stub's tip: only the stub comes near it.
    let far = [[0.3, 0.0, 0.5]];
    let remove = unneeded_stubs(&far, &[true], &sk, &stubs, &[off_trunk(0.3)], 0.02);
    assert_eq!(remove, vec![false]);
    // A point on the trunk's far side: the trunk alone holds it.
    let near = [[-0.03, 0.0, 0.5]];
    let remove = unneeded_stubs(&near, &[true], &sk, &stubs, &[off_trunk(-0.03)], 0.02);
    assert_eq!(remove, vec![true]);
    // Points outside the main cluster do not count.
    let remove = unneeded_stubs(&far, &[false], &sk, &stubs, &[off_trunk(0.3)], 0.02);
    assert_eq!(remove, vec![true]);
}
