//! Wood and leaves told apart (`separate_wood`, `ColonizeConfig::separate_leaves`). The
//! constants were chosen on synthetic leafy trees of seeds 0–2; these tests use others.

use nalgebra::Point3;
use space_colonize::synthetic::{SyntheticConfig, skeleton_error};
use space_colonize::{
    ColonizeConfig, ColonizeError, WoodConfig, fidelity, reconstruct, separate_wood,
};

use crate::reconstruct::ground_disc;

/// The default reconstruction with the leaves set aside.
pub(crate) fn leaves_set_aside() -> ColonizeConfig {
    ColonizeConfig {
        separate_leaves: true,
        ..ColonizeConfig::default()
    }
}

fn leafy(seed: u64, leaf_points: usize) -> SyntheticConfig {
    SyntheticConfig {
        seed,
        points: 15_000,
        leaf_points,
        ..Default::default()
    }
}

/// Shares of the wood kept and of the leaves set aside.
fn shares(seed: u64, leaf_points: usize) -> (f64, f64) {
    let tree = leafy(seed, leaf_points).generate().unwrap();
    let split = separate_wood(&tree.points, &WoodConfig::default()).unwrap();
    assert_eq!(split.wood.len(), tree.points.len());
    assert_eq!(split.off_axis_share.len(), tree.points.len());
    let (wood, leaves) = split.wood.split_at(tree.wood_points);
    let kept = wood.iter().filter(|&&w| w).count() as f64 / wood.len() as f64;
    let dropped = if leaves.is_empty() {
        1.0
    } else {
        leaves.iter().filter(|&&w| !w).count() as f64 / leaves.len() as f64
    };
    (kept, dropped)
}

#[test]
fn leaves_are_told_from_wood() {
    for seed in [200, 201] {
        let (kept, dropped) = shares(seed, 8_000);
        println!("seed {seed}: wood kept {kept:.3}, leaves set aside {dropped:.3}");
        assert!(kept > 0.7, "seed {seed}: {kept}");
        assert!(dropped > 0.85, "seed {seed}: {dropped}");
        // Leaf-off, most of the wood stays.
        let (kept, _) = shares(seed, 0);
        assert!(kept > 0.8, "seed {seed} leaf-off: {kept}");
    }
}

/// Measured on seeds 100–103 (`docs/validation.md`, "Wood and leaves"): the model's
/// length 3–7 times the truth without separation, 0.8–1.7 times with it.
#[test]
fn a_leafy_tree_gives_a_wood_skeleton() {
    let tree = leafy(202, 10_000).generate().unwrap();
    let wood = &tree.points[..tree.wood_points];
    let truth_m = tree.skeleton.total_length_m();
    let run = |separate_leaves| {
        let model = reconstruct(
            &tree.points,
            &ColonizeConfig {
                separate_leaves,
                ..ColonizeConfig::default()
            },
        )
        .unwrap();
        let f = fidelity(wood, &model.skeleton);
        let e = skeleton_error(&model.skeleton, &tree.skeleton);
        println!(
            "separate {separate_leaves}: length {:.2} m (truth {truth_m:.2}), {f:?}, {e:?}",
            model.skeleton.total_length_m()
        );
        (model, f, e)
    };
    let (all, f_all, e_all) = run(false);
    let (sep, f_sep, e_sep) = run(true);
    assert!(all.leaves.is_none());
    let leaves = sep.leaves.as_ref().expect("leaves reported");
    assert_eq!(leaves.points, leaves.indices.len());
    // Most of what was set aside is leaves (the leaves are the points after the wood's).
    let on_leaves = leaves
        .indices
        .iter()
        .filter(|&&i| i >= tree.wood_points)
        .count();
    assert!(
        on_leaves as f64 > 0.7 * leaves.points as f64,
        "{on_leaves} of {}",
        leaves.points
    );
    // Without separation the model chases the leaves through the air.
    assert!(f_all.model_near_cloud < 0.8, "{f_all:?}");
    assert!(all.skeleton.total_length_m() > 2.5 * truth_m);
    // With it the model lies on the wood and is about the tree's length.
    assert!(f_sep.model_near_cloud > 0.9, "{f_sep:?}");
    assert!(sep.skeleton.total_length_m() < 2.0 * truth_m);
    assert!(e_sep.mean_skeleton_error_m < 0.5 * e_all.mean_skeleton_error_m);
    assert!(e_sep.truth_length_found > 0.55, "{e_sep:?}");
}

/// The leaves' indices are into the points given, with a ground set aside before them.
#[test]
fn leaves_and_ground_are_indexed_in_the_points_given() {
    let tree = leafy(203, 4_000).generate().unwrap();
    let ground = ground_disc(&tree.points[..tree.wood_points], 1.0, 0.02, 0.0, 0.002, 9);
    // Ground first, so the tree's indices shift.
    let mut points = ground.clone();
    points.extend(&tree.points);
    let model = reconstruct(&points, &leaves_set_aside()).unwrap();
    let g = model.ground.as_ref().expect("a ground");
    let l = model.leaves.as_ref().expect("leaves");
    let mut seen = vec![0u8; points.len()];
    for &i in g.indices.iter().chain(&l.indices) {
        seen[i] += 1;
    }
    assert!(seen.iter().all(|&s| s <= 1), "a point both ground and leaf");
    // They are what `separate_wood` finds on the points above the ground, in the indices of
    // the points given.
    let above: Vec<usize> = (0..points.len())
        .filter(|&i| seen[i] == 0 || !g.indices.contains(&i))
        .collect();
    let split = separate_wood(
        &above.iter().map(|&i| points[i]).collect::<Vec<_>>(),
        &WoodConfig::default(),
    )
    .unwrap();
    let expected: Vec<usize> = above
        .iter()
        .zip(&split.wood)
        .filter(|(_, w)| !**w)
        .map(|(&i, _)| i)
        .collect();
    assert_eq!(l.indices, expected);
    assert!(l.indices.iter().all(|&i| i >= ground.len() / 2));
}

#[test]
fn a_cloud_of_nothing_but_leaves_is_an_error_not_a_tree() {
    // Random points in a ball: every normal points its own way.
    let mut state = 12_345u64;
    let mut uniform = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut points = Vec::new();
    while points.len() < 3_000 {
        let p = Point3::new(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5);
        if p.coords.norm() < 0.5 {
            points.push(p + nalgebra::Vector3::new(0.0, 0.0, 2.0));
        }
    }
    let split = separate_wood(&points, &WoodConfig::default()).unwrap();
    assert!(split.wood_points() < 30, "{}", split.wood_points());
    let err = reconstruct(
        &points,
        &ColonizeConfig {
            remove_ground: false,
            ..leaves_set_aside()
        },
    );
    match err {
        Err(ColonizeError::InvalidParameter { name, reason }) => {
            assert_eq!(name, "separate_leaves", "{reason}");
        }
        other => panic!("{:?}", other.map(|m| m.skeleton.nodes().len())),
    }
}

#[test]
fn bad_wood_input_is_named() {
    let tree = leafy(204, 0).generate().unwrap();
    let shares = [0.0, 1.0, -0.1, f64::NAN, f64::INFINITY].map(|max_off_axis_share| {
        let config = WoodConfig {
            max_off_axis_share,
            ..WoodConfig::default()
        };
        (config, "max_off_axis_share")
    });
    let spacings = [0.0, -1.0, f64::NAN].map(|s| {
        let config = WoodConfig {
            spacing_m: Some(s),
            ..WoodConfig::default()
        };
        (config, "spacing_m")
    });
    for (config, field) in shares.into_iter().chain(spacings) {
        match separate_wood(&tree.points, &config) {
            Err(ColonizeError::InvalidParameter { name, .. }) => {
                assert_eq!(name, field, "{config:?}");
            }
            other => panic!("{config:?}: {:?}", other.map(|s| s.wood_points())),
        }
    }
    let mut bad = tree.points.clone();
    bad[7].y = f64::NAN;
    assert!(matches!(
        separate_wood(&bad, &WoodConfig::default()),
        Err(ColonizeError::NonFinitePoint { index: 7, .. })
    ));
    assert!(matches!(
        separate_wood(&tree.points[..5], &WoodConfig::default()),
        Err(ColonizeError::TooFewPoints { points: 5, .. })
    ));
    // Copies of one point: no spacing to measure.
    let same = vec![Point3::new(1.0, 2.0, 3.0); 40];
    assert!(separate_wood(&same, &WoodConfig::default()).is_err());
}
