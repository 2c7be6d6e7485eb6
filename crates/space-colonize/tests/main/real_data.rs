//! The real clouds in `../shared/data/pointclouds/`, when present (GPL data: read by path,
//! never copied). Skips with a printed reason when absent.

use std::path::PathBuf;

use space_colonize::{AUTO_NEAR_SHARE, ColonizeConfig, Growth, metrics, reconstruct};

fn cloud(rel: &str) -> Option<Vec<nalgebra::Point3<f64>>> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/pointclouds")
        .join(rel);
    let Ok(text) = std::fs::read_to_string(&path) else {
        println!("skipped: {} not found", path.display());
        return None;
    };
    Some(
        text.lines()
            .filter_map(|l| {
                let v: Vec<f64> = l
                    .split_whitespace()
                    .filter_map(|x| x.parse().ok())
                    .collect();
                (v.len() >= 3).then(|| nalgebra::Point3::new(v[0], v[1], v[2]))
            })
            .collect(),
    )
}

#[test]
fn coffee_tree_is_close_to_its_cloud() {
    let Some(pts) = cloud("rtwig_gymnocladus/cloud.txt") else {
        return;
    };
    let model = reconstruct(&pts, &ColonizeConfig::default()).unwrap();
    let m = metrics(&pts, &model.skeleton);
    println!("{m:?} {:?}", model.growth);
    // A leaf-off scan of wood: the default keeps space colonization (0.996 of its growth
    // near the points).
    assert_eq!(model.parameters.growth, Growth::Colonization);
    assert!(
        model
            .growth
            .colonization_near_cloud
            .is_some_and(|s| s > 0.98),
        "{:?}",
        model.growth
    );
    // Figures in docs/validation.md. Issue 22's goal: at most 2.2 mm by the cylinder
    // table, better than TreeQSM (2.17 mm since each segment's cylinder is fitted to its
    // points; 2.58 mm before, 2.97 mm before forks were centred).
    assert!(m.mean_distance_m <= 0.0022, "{m:?}");
    assert!(model.growth.radius_fits_used);
    assert!(model.growth.fitted_segments > 500, "{:?}", model.growth);
    assert!(m.within_2cm > 0.99, "{m:?}");
    // Issue 22's goals against TreeQSM's published model of this cloud (32.80 m, 21.57 L,
    // `qsm_treeqsm_summary.json`): length and volume within 5 % (+3.1 % and +4.6 %
    // measured), every model part within 2 cm of the cloud.
    assert!((m.total_length_m / 32.80 - 1.0).abs() < 0.05, "{m:?}");
    assert!((m.volume_l / 21.57 - 1.0).abs() < 0.05, "{m:?}");
    assert!(m.length_near_cloud > 0.9999, "{m:?}");
    assert!(m.max_model_gap_m <= space_colonize::NEAR_CLOUD_M, "{m:?}");
}

#[test]
fn gappy_tree13_stays_one_tree() {
    let Some(pts) = cloud("adtree/tree13.xyz") else {
        return;
    };
    let config = ColonizeConfig {
        growth: Growth::Colonization,
        ..ColonizeConfig::default()
    };
    let model = reconstruct(&pts, &config).unwrap();
    println!("{:?}", model.growth);
    assert!(model.growth.bridges > 0);
    // Leaf clumps are reached, and circle fits to them are not taken for wood.
    let m = metrics(&pts, &model.skeleton);
    assert!(m.within_5cm > 0.95, "{m:?}");
    assert!(!model.growth.radius_fits_used);
    assert_eq!(model.growth.unreached_points, 0);
    // Only stray points are set aside (fewer than 3 others within 15 spacings): 26 of
    // 6,992, no cluster of the tree.
    assert!(
        model.growth.outlier_points <= pts.len() / 200,
        "{:?}",
        model.growth
    );
}

/// AdTree's figures on the same clouds by the same measure (issue 22): mean point-to-surface
/// (metres), share of points within 2 cm, share of model length near the cloud.
const ADTREE: [(&str, f64, f64, f64); 3] = [
    ("adtree/tree7.xyz", 0.0052, 0.95, 0.93),
    ("adtree/tree13.xyz", 0.0270, 0.88, 0.50),
    ("adtree/Paris_Luxembourg_1.xyz", 0.0102, 0.92, 0.70),
];

/// The default against AdTree's figures: it grows these leafy clouds by level sets (space
/// colonization's first growth lies near the points on 0.68, 0.16 and 0.28 of its length),
/// and is better on all three figures on every cloud (issue 22's goal; the margins are thin
/// on tree13's and Paris's model near the cloud, 50.9 % and 71.0 % against 50 % and 70 %,
/// see docs/validation.md).
#[test]
fn the_default_beats_adtree_on_its_clouds() {
    for (rel, mean, within, near) in ADTREE {
        let Some(pts) = cloud(rel) else {
            continue;
        };
        let model = reconstruct(&pts, &ColonizeConfig::default()).unwrap();
        let f = space_colonize::fidelity(&pts, &model.skeleton);
        println!("{rel}: {f:?} {:?}", model.growth);
        assert_eq!(model.parameters.growth, Growth::LevelSets, "{rel}");
        assert!(
            model
                .growth
                .colonization_near_cloud
                .is_some_and(|s| s < AUTO_NEAR_SHARE),
            "{rel}: {:?}",
            model.growth
        );
        assert!(f.mean_distance_m < mean, "{rel}: {f:?}");
        assert!(f.within_2cm > within, "{rel}: {f:?}");
        assert!(f.model_near_cloud > near, "{rel}: {f:?}");
    }
}

/// One-sided Kinect-like views of the coffee tree (`camera_view`, 6 mm depth noise) with
/// the camera known: thin branches are measured across the rays, and the volume is within
/// 10 % of TreeQSM's full-scan model on every view (without the camera, the second view
/// gave +13 %: its branches under 1 cm 1.16 times as thick as TreeQSM's).
#[test]
fn coffee_views_with_their_camera_keep_their_volume() {
    use space_colonize::{ViewConfig, camera_view};
    let Some(pts) = cloud("rtwig_gymnocladus/cloud.txt") else {
        return;
    };
    for camera in [
        [-2.74, -16.36, 255.7],
        [0.97, -19.85, 255.7],
        [3.97, -14.5, 255.0],
    ] {
        let camera = nalgebra::Point3::from(camera);
        let view = camera_view(&pts, &ViewConfig::kinect(camera)).unwrap();
        let config = ColonizeConfig {
            camera_m: Some(camera),
            ..ColonizeConfig::default()
        };
        let model = reconstruct(&view, &config).unwrap();
        let m = metrics(&pts, &model.skeleton);
        println!("{camera:?}: {:.1} L", m.volume_l);
        assert!((m.volume_l / 21.6 - 1.0).abs() < 0.1, "{camera:?}: {m:?}");
        assert_eq!(
            model.parameters.camera_m,
            Some([camera.x, camera.y, camera.z])
        );
    }
}

/// Leaf-off, separation keeps the wood: the coffee tree is all wood.
#[test]
fn the_leaf_off_coffee_tree_keeps_its_wood_when_leaves_are_separated() {
    use space_colonize::{WoodConfig, separate_wood};
    let Some(points) = cloud("rtwig_gymnocladus/cloud.txt") else {
        return;
    };
    let split = separate_wood(&points, &WoodConfig::default()).unwrap();
    let kept = split.wood_points() as f64 / points.len() as f64;
    assert!(kept > 0.95, "{kept}");
    let model = reconstruct(&points, &crate::wood::leaves_set_aside()).unwrap();
    let m = metrics(&points, &model.skeleton);
    println!("kept {kept:.3}; {m:?}");
    assert!(m.within_2cm > 0.98, "{m:?}");
}
