//! Skeleton validation, branches, JSON.

use std::path::Path;

use nalgebra::Point3;
use proptest::prelude::*;
use space_colonize::{ColonizeError, Skeleton, SkeletonNode};

fn node(id: usize, parent: Option<usize>, z: f64, x: f64) -> SkeletonNode {
    SkeletonNode {
        id,
        parent,
        position: Point3::new(x, 0.0, z),
        radius_m: 0.01,
    }
}

/// A trunk of 4 nodes with a long side branch at node 1 and a short one at node 2.
fn forked() -> Skeleton {
    Skeleton::new(vec![
        node(0, None, 0.0, 0.0),
        node(1, Some(0), 1.0, 0.0),
        node(2, Some(1), 2.0, 0.0),
        node(3, Some(2), 3.0, 0.0),
        node(4, Some(1), 1.5, 0.5),
        node(5, Some(4), 2.0, 1.0),
        node(6, Some(2), 2.2, -0.2),
    ])
    .unwrap()
}

#[test]
fn branches_follow_the_child_carrying_most() {
    let s = forked();
    let b = s.branches();
    assert_eq!(b.len(), 3);
    assert_eq!((b[0].id, b[0].order, b[0].parent), (0, 0, None));
    assert_eq!(b[0].nodes, vec![0, 1, 2, 3]);
    assert!((b[0].length_m - 3.0).abs() < 1e-12);
    let side = b.iter().find(|x| x.id == 4).unwrap();
    assert_eq!(
        (side.order, side.parent, side.base_node),
        (1, Some(0), Some(1))
    );
    assert_eq!(side.nodes, vec![4, 5]);
    assert!(
        (s.total_length_m() - (3.0 + 2.0 * 0.5f64.hypot(0.5) + 0.2f64.hypot(0.2))).abs() < 1e-12
    );
}

#[test]
fn json_round_trip() {
    let s = forked();
    let text = s.to_json().unwrap();
    assert!(text.contains("\"parent\": null"));
    let back = Skeleton::from_json(&text, Path::new("t.json")).unwrap();
    assert_eq!(back, s);
}

#[test]
fn invalid_skeletons_are_named() {
    let cycle = vec![
        node(0, None, 0.0, 0.0),
        node(1, Some(2), 1.0, 0.0),
        node(2, Some(1), 2.0, 0.0),
    ];
    let e = Skeleton::new(cycle).unwrap_err().to_string();
    assert!(e.contains("not connected") || e.contains("cycle"), "{e}");
    let two_roots = vec![node(0, None, 0.0, 0.0), node(1, None, 1.0, 0.0)];
    assert!(
        Skeleton::new(two_roots)
            .unwrap_err()
            .to_string()
            .contains("2 roots")
    );
    let dangling = vec![node(0, None, 0.0, 0.0), node(1, Some(7), 1.0, 0.0)];
    assert!(
        Skeleton::new(dangling)
            .unwrap_err()
            .to_string()
            .contains("does not exist")
    );
    let gap = vec![node(0, None, 0.0, 0.0), node(2, Some(0), 1.0, 0.0)];
    assert!(matches!(
        Skeleton::new(gap),
        Err(ColonizeError::InvalidSkeleton { .. })
    ));
    let mut bad_r = vec![node(0, None, 0.0, 0.0), node(1, Some(0), 1.0, 0.0)];
    bad_r[1].radius_m = -1.0;
    assert!(
        Skeleton::new(bad_r)
            .unwrap_err()
            .to_string()
            .contains("radius")
    );
    assert!(matches!(
        Skeleton::from_json("{\"nodes\": 3}", Path::new("x.json")),
        Err(ColonizeError::Format { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Arbitrary JSON-ish text and arbitrary parent links never panic the reader.
    #[test]
    fn skeleton_reader_never_panics(
        parents in prop::collection::vec(prop::option::of(0usize..12), 0..12),
        radius in -1.0f64..1.0,
        junk in "\\PC{0,40}",
    ) {
        let nodes: Vec<String> = parents
            .iter()
            .enumerate()
            .map(|(i, p)| format!(
                "{{\"id\": {i}, \"parent\": {}, \"position\": [0, 0, {i}], \"radius\": {radius}}}",
                p.map_or("null".to_string(), |p| p.to_string())
            ))
            .collect();
        let text = format!("{{\"nodes\": [{}]}}", nodes.join(","));
        if let Ok(s) = Skeleton::from_json(&text, Path::new("p.json")) {
            prop_assert_eq!(s.topological_order().len(), parents.len());
            let _ = s.branches();
        }
        let _ = Skeleton::from_json(&junk, Path::new("j.json"));
    }
}
