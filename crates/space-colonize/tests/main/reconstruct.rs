//! Reconstruction of synthetic trees against their known skeletons.

use nalgebra::{Point3, Vector3};
use space_colonize::synthetic::{SyntheticConfig, skeleton_error};
use space_colonize::{ColonizeConfig, ColonizeError, metrics, reconstruct};

fn small(seed: u64) -> SyntheticConfig {
    SyntheticConfig {
        seed,
        points: 10_000,
        ..Default::default()
    }
}

#[test]
fn recovers_a_synthetic_tree() {
    let truth = small(3).generate().unwrap();
    let model = reconstruct(&truth.points, &ColonizeConfig::default()).unwrap();
    let m = metrics(&truth.points, &model.skeleton);
    let e = skeleton_error(&model.skeleton, &truth.skeleton);
    // Surface within a few noise levels (1 mm) of the points, axes within a centimetre.
    assert!(m.mean_distance_m < 0.004, "{m:?}");
    assert!(m.within_2cm > 0.99, "{m:?}");
    assert!(e.mean_skeleton_error_m < 0.012, "{e:?}");
    assert!(e.truth_length_found > 0.97, "{e:?}");
    assert!((e.length_ratio - 1.0).abs() < 0.3, "{e:?}");
    assert!((e.volume_ratio - 1.0).abs() < 0.3, "{e:?}");
    assert!((e.base_radius_ratio - 1.0).abs() < 0.1, "{e:?}");
    // The trunk is order 0 and there are branches of higher orders.
    let by_order = model.branches_by_order();
    assert_eq!(by_order[0], 1);
    assert!(by_order.len() >= 3, "{by_order:?}");
}

#[test]
fn one_sided_view_is_centred() {
    let cfg = SyntheticConfig {
        view_direction: Some(Vector3::new(0.0, 1.0, 0.0)),
        ..small(5)
    };
    let truth = cfg.generate().unwrap();
    let centred = reconstruct(&truth.points, &ColonizeConfig::default()).unwrap();
    let raw = reconstruct(
        &truth.points,
        &ColonizeConfig {
            centring: false,
            ..Default::default()
        },
    )
    .unwrap();
    let ec = skeleton_error(&centred.skeleton, &truth.skeleton);
    let er = skeleton_error(&raw.skeleton, &truth.skeleton);
    // Centring moves the axes off the visible surface toward the true axis.
    assert!(
        ec.mean_skeleton_error_m < er.mean_skeleton_error_m,
        "centred {ec:?} raw {er:?}"
    );
    assert!(ec.mean_skeleton_error_m < 0.02, "{ec:?}");
}

#[test]
fn a_kinect_view_grows_one_chain_up_each_half_seen_branch() {
    use space_colonize::{ViewConfig, camera_view};
    // A Kinect v2 3.6 m from the trunk sees the near half of every branch, with 6 mm of
    // depth noise. With the full scan's kill distance (1.2 trunk radii) the half-seen trunk
    // grew as two chains side by side: axis error 13.8–15.9 mm and 1.29–1.37 times the true
    // length on these seeds.
    for seed in [31, 32, 33] {
        let truth = SyntheticConfig {
            seed,
            points: 20_000,
            ..Default::default()
        }
        .generate()
        .unwrap();
        let seen = camera_view(
            &truth.points,
            &ViewConfig::kinect(Point3::new(3.6, 0.5, 1.3)),
        )
        .unwrap();
        let model = reconstruct(&seen, &ColonizeConfig::default()).unwrap();
        assert!(
            model.parameters.one_sided,
            "seed {seed}: {:?}",
            model.parameters
        );
        let e = skeleton_error(&model.skeleton, &truth.skeleton);
        // Now 9.0–12.1 mm, 1.05–1.14 times the length, volume 0.98–1.00.
        assert!(e.mean_skeleton_error_m < 0.0125, "seed {seed}: {e:?}");
        assert!(e.length_ratio < 1.2, "seed {seed}: {e:?}");
        assert!((0.9..1.1).contains(&e.volume_ratio), "seed {seed}: {e:?}");
    }
    // A full scan is not taken for a view.
    let full = small(31).generate().unwrap();
    let model = reconstruct(&full.points, &ColonizeConfig::default()).unwrap();
    assert!(!model.parameters.one_sided, "{:?}", model.parameters);
}

#[test]
fn bridges_an_occluded_trunk_and_stays_one_tree() {
    let cfg = SyntheticConfig {
        gap_z_m: Some((0.6, 1.0)),
        ..small(11)
    };
    let truth = cfg.generate().unwrap();
    let model = reconstruct(&truth.points, &ColonizeConfig::default()).unwrap();
    assert!(model.growth.bridges >= 1, "{:?}", model.growth);
    assert_eq!(model.growth.unreached_points, 0);
    // One tree (a Skeleton has one root by construction) that covers the points.
    let m = metrics(&truth.points, &model.skeleton);
    assert!(m.within_5cm > 0.99, "{m:?}");
    // The bridge runs near where the trunk was (from a node to the nearest surface point
    // across the gap, so up to a trunk radius off the axis there).
    let e = skeleton_error(&model.skeleton, &truth.skeleton);
    assert!(e.truth_length_found > 0.9, "{e:?}");
    assert!(e.mean_skeleton_error_m < 0.01, "{e:?}");
}

#[test]
fn far_outliers_are_set_aside_and_reported() {
    let mut truth = small(2).generate().unwrap();
    let n = truth.points.len();
    for k in 0..5 {
        truth
            .points
            .push(Point3::new(100.0 + f64::from(k), -50.0, 20.0));
    }
    let model = reconstruct(&truth.points, &ColonizeConfig::default()).unwrap();
    assert_eq!(model.growth.outlier_points, 5);
    // The root is still at the base of the tree, not at the outliers.
    let root = model.skeleton.nodes()[model.skeleton.root()].position;
    assert!(root.coords.norm() < 0.1, "{root:?}");
    let m = metrics(&truth.points[..n], &model.skeleton);
    assert!(m.within_2cm > 0.99, "{m:?}");
}

#[test]
fn iteration_bound_is_reported() {
    let truth = small(1).generate().unwrap();
    let err = reconstruct(
        &truth.points,
        &ColonizeConfig {
            max_iterations: Some(20),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(
        matches!(err, ColonizeError::IterationLimit { iterations: 20, .. }),
        "{err}"
    );
    let err = reconstruct(
        &truth.points,
        &ColonizeConfig {
            max_nodes: Some(50),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(
        matches!(err, ColonizeError::NodeLimit { nodes: 50, .. }),
        "{err}"
    );
}

#[test]
fn pure_pipe_model_follows_the_pipe_rule() {
    let truth = small(4).generate().unwrap();
    let cfg = ColonizeConfig {
        radius_fits: false,
        ..Default::default()
    };
    let model = reconstruct(&truth.points, &cfg).unwrap();
    let s = &model.skeleton;
    let e = cfg.pipe_exponent;
    // r_in^e = Σ r_out^e at every fork (radii of the segments into and out of it).
    let carried = s.carried_length_m();
    let mut forks = 0;
    for node in s.nodes() {
        let kids = s.children(node.id);
        if kids.len() < 2 || node.parent.is_none() {
            continue;
        }
        forks += 1;
        let out: f64 = kids
            .iter()
            .map(|&c| {
                // The segment out of the fork carries its child's subtree and its own length.
                s.nodes()[c].radius_m.powf(e)
            })
            .sum();
        let inn = node.radius_m.powf(e);
        // The incoming segment also carries its own length: inn >= out, and larger by at
        // most its own share of the length it carries.
        let own = s.segment_length_m(node.id) / carried[node.id];
        assert!(inn >= out * (1.0 - 1e-9), "fork {}: {inn} < {out}", node.id);
        assert!(
            inn <= out / (1.0 - own) * (1.0 + 1e-6),
            "fork {}: {inn} vs {out}, own share {own}",
            node.id
        );
    }
    assert!(forks > 5);
    // Anchored at the fitted trunk base.
    let base = s
        .children(s.root())
        .iter()
        .map(|&c| s.nodes()[c].radius_m)
        .fold(0.0, f64::max);
    approx::assert_relative_eq!(base, model.parameters.trunk_radius_m, max_relative = 1e-9);
}

/// Points on the lateral surfaces of `(start, end, radius)` cylinders, `per_m2` per square
/// metre, with 1 mm of noise (seeded).
fn sample_cylinders(
    parts: &[([f64; 3], [f64; 3], f64)],
    per_m2: f64,
    seed: u64,
) -> Vec<Point3<f64>> {
    let mut state = seed;
    let mut uniform = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut out = Vec::new();
    for &(a, b, r) in parts {
        let (a, b) = (Vector3::from(a), Vector3::from(b));
        let d = b - a;
        let len = d.norm();
        let u = d / len;
        let e1 = u
            .cross(&Vector3::x())
            .try_normalize(1e-9)
            .unwrap_or_else(|| u.cross(&Vector3::y()).normalize());
        let e2 = u.cross(&e1);
        let n = (per_m2 * std::f64::consts::TAU * r * len).round() as usize;
        for _ in 0..n {
            let (s, phi) = (uniform() * len, uniform() * std::f64::consts::TAU);
            let noise = 0.001 * (uniform() + uniform() + uniform() - 1.5) * 2.0;
            let p = a + u * s + (e1 * phi.cos() + e2 * phi.sin()) * (r + noise);
            out.push(Point3::from(p));
        }
    }
    out
}

#[test]
fn growth_does_not_cut_the_corner_between_diverging_twigs() {
    // A 9 cm stem forking into two 1 cm twigs 20° apart: the stem sets a kill distance
    // of 5.4 cm, so the nodes at the fork are drawn by both twigs at once, and their mean
    // attraction points into the air between them (without the rule, 4 % of the model
    // was more than 2 cm from any point, up to 3.8 cm).
    let (s, c) = (10f64.to_radians().sin(), 10f64.to_radians().cos());
    let fork = [0.0, 0.0, 0.5];
    let parts = [
        ([0.0, 0.0, 0.0], fork, 0.045),
        (fork, [0.6 * s, 0.0, 0.5 + 0.6 * c], 0.005),
        (fork, [-0.6 * s, 0.0, 0.5 + 0.6 * c], 0.005),
    ];
    let pts = sample_cylinders(&parts, 20_000.0, 11);
    let model = reconstruct(&pts, &ColonizeConfig::default()).unwrap();
    let m = metrics(&pts, &model.skeleton);
    assert!(m.max_model_gap_m < 0.015, "{m:?}");
    assert!(m.length_near_cloud > 0.999, "{m:?}");
    assert!(m.within_2cm > 0.99, "{m:?}");
    // Both twigs are found whole (the stem continues into one of them).
    let lens: Vec<f64> = model.branches.iter().map(|b| b.length_m).collect();
    assert_eq!(lens.iter().filter(|&&l| l > 0.5).count(), 2, "{lens:?}");
    let true_m = 0.5 + 2.0 * 0.6;
    assert!((m.total_length_m / true_m - 1.0).abs() < 0.1, "{m:?}");
}

/// Level-set growth puts every node on a patch of points: on a synthetic tree the model
/// stays on the cloud (space colonization's chords through the air would not), every
/// point is near it, and the trunk's thin slices make rings on its axis, not parallel
/// chains on its surface (before arcs were merged: axis error 2.2 cm, length x2.3).
#[test]
fn level_sets_stay_on_the_points() {
    let truth = small(3).generate().unwrap();
    let config = ColonizeConfig {
        growth: space_colonize::Growth::LevelSets,
        ..ColonizeConfig::default()
    };
    let model = reconstruct(&truth.points, &config).unwrap();
    let f = space_colonize::fidelity(&truth.points, &model.skeleton);
    assert!(f.model_near_cloud > 0.99, "{f:?}");
    assert!(f.within_2cm > 0.99, "{f:?}");
    assert!(f.mean_distance_m < 0.003, "{f:?}");
    // Measured 7.9 mm, 98.7 %, x1.19.
    let e = skeleton_error(&model.skeleton, &truth.skeleton);
    assert!(e.mean_skeleton_error_m < 0.01, "{e:?}");
    assert!(e.truth_length_found > 0.97, "{e:?}");
    assert!((e.length_ratio - 1.0).abs() < 0.3, "{e:?}");
    assert_eq!(model.parameters.growth, space_colonize::Growth::LevelSets);
}

/// A dense scan (40k points, 2.6 mm spacing) grows its level sets on the cloud thinned to
/// 1 cm cubes (`THIN_BELOW_VOXEL`), and the model is as good as on 10k points.
#[test]
fn level_sets_on_a_dense_cloud_stay_on_the_points() {
    let truth = SyntheticConfig {
        points: 40_000,
        ..small(3)
    }
    .generate()
    .unwrap();
    let config = ColonizeConfig {
        growth: space_colonize::Growth::LevelSets,
        ..ColonizeConfig::default()
    };
    let model = reconstruct(&truth.points, &config).unwrap();
    let p = model.parameters;
    assert!(
        p.spacing_m < space_colonize::THIN_BELOW_VOXEL * space_colonize::LEVEL_VOXEL_BINS * p.bin_m,
        "{p:?}"
    );
    let f = space_colonize::fidelity(&truth.points, &model.skeleton);
    assert!(f.model_near_cloud > 0.99, "{f:?}");
    assert!(f.within_2cm > 0.99, "{f:?}");
    let e = skeleton_error(&model.skeleton, &truth.skeleton);
    println!("{f:?}\n{e:?}");
    assert!(e.mean_skeleton_error_m < 0.015, "{e:?}");
    assert!(e.truth_length_found > 0.97, "{e:?}");
}

/// A tree in leaf seen as a sparse scan sees it: the trunk, and above it leaf clumps
/// without the twigs that hold them (the wood of a synthetic tree above `crown_z_m` hidden,
/// its leaves kept).
fn leaf_clumps_over_a_trunk(seed: u64, crown_z_m: f64) -> Vec<Point3<f64>> {
    let config = SyntheticConfig {
        leaf_points: 1_500,
        ..small(seed)
    };
    let wood = SyntheticConfig {
        leaf_points: 0,
        ..config.clone()
    }
    .generate()
    .unwrap()
    .points
    .len();
    let all = config.generate().unwrap().points;
    all.iter()
        .enumerate()
        .filter(|(i, p)| *i >= wood || p.z < crown_z_m)
        .map(|(_, p)| *p)
        .collect()
}

/// The default grows by space colonization where that stays on the points (a leaf-off
/// tree: the same model as asking for colonization), and by level sets where colonization
/// runs through the air between leaf clumps, which leaves more of the model near the points
/// (measured on seeds 21 and 22: colonization's growth 0.75 and 0.67 near the points; model
/// near the cloud 82.7 → 87.9 % and 76.0 → 85.4 %, mean distance 1.42 → 1.39 mm and 1.89 →
/// 1.85 mm).
#[test]
fn the_default_grows_by_level_sets_only_where_colonization_runs_through_the_air() {
    let bare = small(3).generate().unwrap();
    let auto = reconstruct(&bare.points, &ColonizeConfig::default()).unwrap();
    let colonization = ColonizeConfig {
        growth: space_colonize::Growth::Colonization,
        ..ColonizeConfig::default()
    };
    let by_colonization = reconstruct(&bare.points, &colonization).unwrap();
    assert_eq!(auto.parameters.growth, space_colonize::Growth::Colonization);
    assert_eq!(
        auto.skeleton.nodes().len(),
        by_colonization.skeleton.nodes().len()
    );
    let share = auto.growth.colonization_near_cloud.unwrap();
    assert!(share >= space_colonize::AUTO_NEAR_SHARE, "{share}");
    assert_eq!(by_colonization.growth.colonization_near_cloud, None);

    for seed in [21, 22] {
        let pts = leaf_clumps_over_a_trunk(seed, 1.2);
        let auto = reconstruct(&pts, &ColonizeConfig::default()).unwrap();
        let by_colonization = reconstruct(&pts, &colonization).unwrap();
        let fa = space_colonize::fidelity(&pts, &auto.skeleton);
        let fc = space_colonize::fidelity(&pts, &by_colonization.skeleton);
        println!(
            "seed {seed}: {:?}\n auto {fa:?}\n colonization {fc:?}",
            auto.growth
        );
        assert_eq!(auto.parameters.growth, space_colonize::Growth::LevelSets);
        let share = auto.growth.colonization_near_cloud.unwrap();
        assert!(share < space_colonize::AUTO_NEAR_SHARE, "{share}");
        assert!(
            fa.model_near_cloud > fc.model_near_cloud + 0.03,
            "{fa:?} {fc:?}"
        );
        // Since forks are centred, colonization's surface is nearer the points here (seed
        // 22: 1.67 against level sets' 1.85 mm, 99.98 against 99.90 % within 2 cm); what
        // it loses is model drawn through the air, which is what the choice is made on.
        assert!(
            fa.mean_distance_m < 1.2 * fc.mean_distance_m,
            "{fa:?} {fc:?}"
        );
        assert!(fa.within_2cm >= fc.within_2cm - 0.002, "{fa:?} {fc:?}");
    }
}

#[test]
fn stray_points_around_a_tree_do_not_become_branches() {
    use rand_xoshiro::SplitMix64;
    use rand_xoshiro::rand_core::{RngCore, SeedableRng};
    let truth = small(3).generate().unwrap();
    let clean = reconstruct(&truth.points, &ColonizeConfig::default()).unwrap();
    // 300 stray returns (3 % of the points) spread through the tree's box grown by 30 cm.
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in &truth.points {
        for c in 0..3 {
            lo[c] = lo[c].min(p[c] - 0.3);
            hi[c] = hi[c].max(p[c] + 0.3);
        }
    }
    let mut rng = SplitMix64::seed_from_u64(41);
    let mut uniform = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    let mut points = truth.points.clone();
    for _ in 0..300 {
        points.push(Point3::new(
            lo[0] + (hi[0] - lo[0]) * uniform(),
            lo[1] + (hi[1] - lo[1]) * uniform(),
            lo[2] + (hi[2] - lo[2]) * uniform(),
        ));
    }
    let model = reconstruct(&points, &ColonizeConfig::default()).unwrap();
    // Nearly all of them set aside (a few land on the tree and are points of it).
    assert!(model.growth.outlier_points >= 250, "{:?}", model.growth);
    // The model of the tree is the clean cloud's: no branches through the air to them.
    let (e, ec) = (
        skeleton_error(&model.skeleton, &truth.skeleton),
        skeleton_error(&clean.skeleton, &truth.skeleton),
    );
    assert!(e.length_ratio < 1.1 * ec.length_ratio, "{e:?} clean {ec:?}");
    assert!(e.mean_skeleton_error_m < 0.012, "{e:?}");
    assert!(e.truth_length_found > 0.97, "{e:?}");
    let m = metrics(&truth.points, &model.skeleton);
    assert!(m.within_2cm > 0.99, "{m:?}");
}

#[test]
fn a_cloud_holding_every_point_twice_is_the_same_tree() {
    let truth = small(3).generate().unwrap();
    let once = reconstruct(&truth.points, &ColonizeConfig::default()).unwrap();
    let twice: Vec<_> = truth.points.iter().chain(&truth.points).copied().collect();
    // Before, the spacing saw only each point's copy (0 m) and the cloud was called
    // degenerate.
    let model = reconstruct(&twice, &ColonizeConfig::default()).unwrap();
    let (a, b) = (once.parameters.spacing_m, model.parameters.spacing_m);
    assert!((a - b).abs() < 0.05 * a, "spacing {a} once, {b} twice");
    let e = skeleton_error(&model.skeleton, &truth.skeleton);
    assert!(e.mean_skeleton_error_m < 0.012, "{e:?}");
    assert!(e.truth_length_found > 0.97, "{e:?}");
    // Seventeen copies of every point: told as what it is.
    let many: Vec<_> = truth.points[..500]
        .iter()
        .flat_map(|p| std::iter::repeat_n(*p, 17))
        .collect();
    let err = reconstruct(&many, &ColonizeConfig::default()).unwrap_err();
    assert!(err.to_string().contains("duplicate"), "{err}");
}

/// A disc of ground of `radius_m` around the trunk's foot, points `step_m` apart (jittered),
/// rising `slope` per metre along x, with Gaussian roughness `rough_m`.
pub(crate) fn ground_disc(
    tree: &[Point3<f64>],
    radius_m: f64,
    step_m: f64,
    slope: f64,
    rough_m: f64,
    seed: u64,
) -> Vec<Point3<f64>> {
    use rand_xoshiro::SplitMix64;
    use rand_xoshiro::rand_core::{RngCore, SeedableRng};
    let mut rng = SplitMix64::seed_from_u64(seed);
    let mut uniform = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    let z0 = tree.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    let foot: Vec<&Point3<f64>> = tree.iter().filter(|p| p.z < z0 + 0.1).collect();
    let n = foot.len() as f64;
    let (cx, cy) = (
        foot.iter().map(|p| p.x).sum::<f64>() / n,
        foot.iter().map(|p| p.y).sum::<f64>() / n,
    );
    let k = (radius_m / step_m).ceil() as i64;
    let mut out = Vec::new();
    for i in -k..=k {
        for j in -k..=k {
            let (x, y) = (
                (i as f64 + 0.6 * (uniform() - 0.5)) * step_m,
                (j as f64 + 0.6 * (uniform() - 0.5)) * step_m,
            );
            if x.hypot(y) > radius_m {
                continue;
            }
            // Box–Muller for the roughness.
            let g = (-2.0 * uniform().max(1e-300).ln()).sqrt()
                * (std::f64::consts::TAU * uniform()).cos();
            out.push(Point3::new(cx + x, cy + y, z0 + slope * x + rough_m * g));
        }
    }
    out
}

#[test]
fn a_ground_around_the_trunk_is_set_aside() {
    let truth = small(3).generate().unwrap();
    let clean = reconstruct(&truth.points, &ColonizeConfig::default()).unwrap();
    assert!(clean.ground.is_none(), "{:?}", clean.ground);
    let ec = skeleton_error(&clean.skeleton, &truth.skeleton);
    // Flat and smooth, sloping 8° and rough, and sampled four times more sparsely than the
    // tree (a ground seen from farther away).
    for (slope, rough_m, step_m) in [(0.0, 0.002, 0.01), (0.14, 0.008, 0.01), (0.0, 0.003, 0.04)] {
        let ground = ground_disc(&truth.points, 1.0, step_m, slope, rough_m, 5);
        let mut points = truth.points.clone();
        points.extend(&ground);
        // Grown from every point, the ground becomes branches.
        let kept = reconstruct(
            &points,
            &ColonizeConfig {
                remove_ground: false,
                ..ColonizeConfig::default()
            },
        )
        .unwrap();
        let ek = skeleton_error(&kept.skeleton, &truth.skeleton);
        assert!(ek.length_ratio > 2.0 * ec.length_ratio, "{ek:?}");
        let model = reconstruct(&points, &ColonizeConfig::default()).unwrap();
        let g = model.ground.as_ref().expect("a ground");
        let tree_points = truth.points.len();
        let of_ground = g.indices.iter().filter(|&&i| i >= tree_points).count();
        let of_tree = g.indices.len() - of_ground;
        assert!(
            of_ground as f64 > 0.99 * ground.len() as f64,
            "slope {slope}: {of_ground} of {} ground points",
            ground.len()
        );
        // The tree keeps all but the foot of its trunk.
        assert!(
            of_tree < tree_points / 100,
            "slope {slope}: {of_tree} tree points"
        );
        let e = skeleton_error(&model.skeleton, &truth.skeleton);
        assert!(
            e.length_ratio < 1.05 * ec.length_ratio,
            "slope {slope}: {e:?} clean {ec:?}"
        );
        assert!(e.mean_skeleton_error_m < 0.012, "slope {slope}: {e:?}");
        assert!(e.truth_length_found > 0.97, "slope {slope}: {e:?}");
    }
}

#[test]
fn no_ground_is_found_under_trees_cut_out_of_their_scene() {
    // Thin and thick trunks cut flat at their foot (a ring of points on a plane), one-sided
    // views, leafy crowns.
    for seed in 0..3 {
        for base_radius_m in [0.05, 0.3] {
            let cases = [
                SyntheticConfig {
                    base_radius_m,
                    ..small(seed)
                },
                SyntheticConfig {
                    base_radius_m,
                    view_direction: Some(Vector3::new(1.0, 0.0, 0.0)),
                    ..small(seed)
                },
                SyntheticConfig {
                    base_radius_m,
                    leaf_points: 10_000,
                    ..small(seed)
                },
            ];
            for config in cases {
                let tree = config.generate().unwrap();
                let model = reconstruct(&tree.points, &ColonizeConfig::default()).unwrap();
                assert!(
                    model.ground.is_none(),
                    "seed {seed}, base radius {base_radius_m} m: {:?}",
                    model.ground
                );
            }
        }
    }
}

#[test]
fn a_cloud_in_a_cameras_frame_is_flagged_and_can_be_turned_z_up() {
    use space_colonize::UpAxis;
    let truth = small(5).generate().unwrap();
    assert!(
        !reconstruct(&truth.points, &ColonizeConfig::default())
            .unwrap()
            .camera_frame_suspected
    );
    // The tree 3 m in front of a level camera 1.2 m above its base, in the camera's frame
    // (x right, y down, z forward), as kinect-io writes a capture.
    let camera = Vector3::new(0.0, -3.0, 1.2);
    let up = UpAxis::MinusY;
    let in_camera: Vec<Point3<f64>> = truth
        .points
        .iter()
        .map(|p| up.from_z_up(&(p - camera)))
        .collect();
    let read_z_up = reconstruct(&in_camera, &ColonizeConfig::default()).unwrap();
    assert!(read_z_up.camera_frame_suspected);
    // Turned Z up, it is the tree again, not flagged, and its model turned back lies on the
    // camera-frame cloud exactly as the Z-up model lies on the turned cloud.
    let turned: Vec<Point3<f64>> = in_camera.iter().map(|p| up.to_z_up(p)).collect();
    let model = reconstruct(&turned, &ColonizeConfig::default()).unwrap();
    assert!(!model.camera_frame_suspected);
    let shifted = truth.skeleton.map_positions(|p| p - camera).unwrap();
    let e = skeleton_error(&model.skeleton, &shifted);
    assert!(e.mean_skeleton_error_m < 0.012, "{e:?}");
    assert!(e.truth_length_found > 0.97, "{e:?}");
    let back = up.skeleton_from_z_up(&model.skeleton).unwrap();
    let (m_back, m_z_up) = (
        metrics(&in_camera, &back),
        metrics(&turned, &model.skeleton),
    );
    assert!(
        (m_back.mean_distance_m - m_z_up.mean_distance_m).abs() < 1e-9,
        "{m_back:?} {m_z_up:?}"
    );
    // Read as Z up, the camera-frame cloud gives a model that is not the tree.
    let wrong_in_tree_frame = read_z_up.skeleton.map_positions(|p| up.to_z_up(p)).unwrap();
    let e_wrong = skeleton_error(&wrong_in_tree_frame, &shifted);
    // (seed 5: 30 mm and 4.6 times the length, against 3.9 mm and 1.14 turned)
    assert!(
        e_wrong.mean_skeleton_error_m > 3.0 * e.mean_skeleton_error_m
            && e_wrong.length_ratio > 2.0 * e.length_ratio,
        "{e_wrong:?} {e:?}"
    );
}

#[test]
fn a_known_camera_makes_the_cloud_a_one_sided_view() {
    let truth = small(3).generate().unwrap();
    let full = reconstruct(&truth.points, &ColonizeConfig::default()).unwrap();
    assert!(!full.parameters.one_sided, "{:?}", full.parameters);
    let seen = reconstruct(
        &truth.points,
        &ColonizeConfig {
            camera_m: Some(Point3::new(3.0, 0.0, 1.0)),
            ..ColonizeConfig::default()
        },
    )
    .unwrap();
    let p = seen.parameters;
    assert!(p.one_sided, "{p:?}");
    assert_eq!(p.camera_m, Some([3.0, 0.0, 1.0]));
    approx::assert_relative_eq!(
        p.kill_distance_m,
        space_colonize::KILL_PER_TRUNK_RADIUS_ONE_SIDED * p.trunk_radius_m,
        max_relative = 1e-12
    );
}

/// A tree of the `one_sided_views` example's sets (seed, trunk radius, height, points, 1 or
/// 2 mm of noise) seen by a Kinect 2.5 m from the trunk at `azimuth_rad`, 0.45 of its height
/// up: the truth, the camera and the view.
fn one_sided_view(
    (seed, noise_m, base_radius_m, height_m, points): (u64, f64, f64, f64, usize),
    azimuth_rad: f64,
) -> (
    space_colonize::synthetic::SyntheticTree,
    Point3<f64>,
    Vec<Point3<f64>>,
) {
    use space_colonize::{ViewConfig, camera_view};
    let truth = SyntheticConfig {
        seed,
        noise_m,
        base_radius_m,
        height_m,
        points,
        ..Default::default()
    }
    .generate()
    .unwrap();
    let root = truth.skeleton.nodes()[truth.skeleton.root()].position;
    let camera = Point3::new(
        root.x + 2.5 * azimuth_rad.cos(),
        root.y + 2.5 * azimuth_rad.sin(),
        root.z + 0.45 * height_m,
    );
    let view = ViewConfig {
        seed,
        ..ViewConfig::kinect(camera)
    };
    let seen = camera_view(&truth.points, &view).unwrap();
    (truth, camera, seen)
}

/// A trunk hidden behind branches in front of it (the `one_sided_views` example's first
/// set, seed 64, camera at 2.4 rad: a tuning view) is continued through the hidden stretch
/// with the camera's rays as evidence, instead of along what hides it.
#[test]
fn a_trunk_hidden_behind_branches_is_continued_through_them() {
    use space_colonize::fidelity;
    let (truth, camera, seen) = one_sided_view((64, 0.001, 0.04, 3.5, 20_000), 2.4);
    let rebuild = |hidden_wood| {
        reconstruct(
            &seen,
            &ColonizeConfig {
                camera_m: Some(camera),
                hidden_wood,
                ..ColonizeConfig::default()
            },
        )
        .unwrap()
    };
    let (with, without) = (rebuild(true), rebuild(false));
    assert!(with.growth.hidden_stretches >= 1, "{:?}", with.growth);
    assert_eq!(without.growth.hidden_stretches, 0);
    // Measured against the whole cloud: 93.8 % within 2 cm without, 96.1 % with.
    let (fw, fo) = (
        fidelity(&truth.points, &with.skeleton),
        fidelity(&truth.points, &without.skeleton),
    );
    assert!(fw.within_2cm > 0.955, "{fw:?}");
    assert!(fw.within_2cm > fo.within_2cm + 0.015, "{fw:?} {fo:?}");
    let (ew, eo) = (
        skeleton_error(&with.skeleton, &truth.skeleton),
        skeleton_error(&without.skeleton, &truth.skeleton),
    );
    assert!(
        ew.mean_skeleton_error_m < eo.mean_skeleton_error_m,
        "{ew:?} {eo:?}"
    );
    // Without a camera there is no evidence to go on.
    let blind = reconstruct(&seen, &ColonizeConfig::default()).unwrap();
    assert_eq!(blind.growth.hidden_stretches, 0);
}

/// A trunk stretch the camera hardly saw (the example's second set, seed 63, camera at
/// 4.5 rad: a tuning view) is measured on the few points of what hid it; it is held as thick
/// as the trunk above it, up to the pipe model (before: 85.2 % of the whole cloud within
/// 2 cm and 0.82 of the true volume).
#[test]
fn a_hardly_seen_trunk_stretch_is_as_thick_as_the_trunk_above_it() {
    use space_colonize::fidelity;
    let (truth, camera, seen) = one_sided_view((63, 0.001, 0.07, 4.0, 30_000), 4.5);
    let model = reconstruct(
        &seen,
        &ColonizeConfig {
            camera_m: Some(camera),
            ..ColonizeConfig::default()
        },
    )
    .unwrap();
    let f = fidelity(&truth.points, &model.skeleton);
    let e = skeleton_error(&model.skeleton, &truth.skeleton);
    // Now 96.5 % and 1.04.
    assert!(f.within_2cm > 0.95, "{f:?}");
    assert!((e.volume_ratio - 1.0).abs() < 0.1, "{e:?}");
}

#[test]
fn a_noisy_scan_is_measured_and_its_volume_not_trusted() {
    let truth = small(4).generate().unwrap();
    let clean = reconstruct(&truth.points, &ColonizeConfig::default()).unwrap();
    let quiet = clean.surface_noise_m.unwrap();
    assert!(quiet < 0.002, "{quiet}");
    assert!(clean.volume_trusted());
    // The same tree with 5 mm of Gaussian noise per axis.
    let noisy = SyntheticConfig {
        noise_m: 0.005,
        ..small(4)
    }
    .generate()
    .unwrap()
    .points;
    let model = reconstruct(&noisy, &ColonizeConfig::default()).unwrap();
    let n = model.surface_noise_m.unwrap();
    // The radial spread is the added noise and the scan's own, less what the fits absorb.
    assert!((0.003..0.007).contains(&n), "{n}");
    assert!(!model.volume_trusted());
}

/// Growth splits a branch late, so a fork sits beside the axis and the nodes next to it
/// stayed there; with `centre_forks` (the default) they go onto their own branch's axis and
/// the fork onto its parent's. On bare synthetic trees (seeds 40 and 41, 20,000 points,
/// 1 mm noise) the axes come nearer the true skeleton and the surface nearer the points
/// than with the forks as grown (both without the last stage's cylinder fits, which move
/// the nodes again).
#[test]
fn centring_by_forks_brings_axes_nearer_the_truth() {
    for seed in [40, 41] {
        let t = SyntheticConfig {
            seed,
            points: 20_000,
            ..Default::default()
        }
        .generate()
        .unwrap();
        let smooth = ColonizeConfig {
            cylinder_fits: false,
            ..ColonizeConfig::default()
        };
        let as_grown = ColonizeConfig {
            centre_forks: false,
            ..smooth.clone()
        };
        let plain = reconstruct(&t.points, &as_grown).unwrap();
        let centred = reconstruct(&t.points, &smooth).unwrap();
        let (ep, ec) = (
            skeleton_error(&plain.skeleton, &t.skeleton),
            skeleton_error(&centred.skeleton, &t.skeleton),
        );
        let (mp, mc) = (
            metrics(&t.points, &plain.skeleton),
            metrics(&t.points, &centred.skeleton),
        );
        println!("seed {seed}: {ep:?} {ec:?}\n {mp:?}\n {mc:?}");
        assert!(
            ec.mean_skeleton_error_m < 0.9 * ep.mean_skeleton_error_m,
            "{ep:?} {ec:?}"
        );
        assert!(
            mc.mean_distance_m < 0.95 * mp.mean_distance_m,
            "{mp:?} {mc:?}"
        );
        assert!(ec.truth_length_found > 0.97, "{ec:?}");
        assert!(mc.length_near_cloud > 0.99, "{mc:?}");
    }
}

/// Median of |model radius / true radius − 1| over the model's segments that lie on a true
/// segment (midpoint within that segment's radius, or 1 cm, of its axis).
fn median_radius_error(model: &space_colonize::Skeleton, truth: &space_colonize::Skeleton) -> f64 {
    let tn = truth.nodes();
    let segs: Vec<(Point3<f64>, Point3<f64>, f64)> = tn
        .iter()
        .filter_map(|n| Some((tn[n.parent?].position, n.position, n.radius_m)))
        .collect();
    let mn = model.nodes();
    let mut err: Vec<f64> = mn
        .iter()
        .filter_map(|n| {
            let a = mn[n.parent?].position;
            let m = Point3::from((a.coords + n.position.coords) * 0.5);
            let (d, r) = segs
                .iter()
                .map(|(s, e, r)| {
                    let v = e - s;
                    let t = ((m - s).dot(&v) / v.norm_squared().max(1e-24)).clamp(0.0, 1.0);
                    ((m - (s + v * t)).norm(), *r)
                })
                .min_by(|x, y| x.0.total_cmp(&y.0))?;
            (d <= r.max(0.01)).then(|| (n.radius_m / r - 1.0).abs())
        })
        .collect();
    err.sort_by(f64::total_cmp);
    err[err.len() / 2]
}

/// The last stage fits each segment's cylinder to its own points: on bare synthetic trees
/// (1 and 3 mm of noise) the surface comes nearer the points and the radii nearer the true
/// ones, and the axes stay as near the true skeleton (within 5 %: under 3 mm of noise the
/// fits follow some of it, 3.82 → 3.95 mm on seed 41; over seeds 40–51 the mean axis error
/// went 6.66 → 6.30 mm).
#[test]
fn cylinders_fitted_to_their_points_come_nearer_the_points_and_the_true_radii() {
    for (seed, noise_m) in [(40, 0.001), (41, 0.003)] {
        let t = SyntheticConfig {
            seed,
            noise_m,
            points: 20_000,
            ..Default::default()
        }
        .generate()
        .unwrap();
        let smooth = reconstruct(
            &t.points,
            &ColonizeConfig {
                cylinder_fits: false,
                ..ColonizeConfig::default()
            },
        )
        .unwrap();
        let fitted = reconstruct(&t.points, &ColonizeConfig::default()).unwrap();
        assert_eq!(smooth.growth.fitted_segments, 0);
        assert!(fitted.growth.fitted_segments > 100, "{:?}", fitted.growth);
        let (ms, mf) = (
            metrics(&t.points, &smooth.skeleton),
            metrics(&t.points, &fitted.skeleton),
        );
        assert!(
            mf.mean_distance_m < 0.9 * ms.mean_distance_m,
            "{ms:?}\n{mf:?}"
        );
        let (es, ef) = (
            skeleton_error(&smooth.skeleton, &t.skeleton),
            skeleton_error(&fitted.skeleton, &t.skeleton),
        );
        assert!(
            ef.mean_skeleton_error_m <= 1.05 * es.mean_skeleton_error_m,
            "{es:?}\n{ef:?}"
        );
        let (rs, rf) = (
            median_radius_error(&smooth.skeleton, &t.skeleton),
            median_radius_error(&fitted.skeleton, &t.skeleton),
        );
        println!("seed {seed}: radius error {rs:.4} -> {rf:.4}; {ms:?}\n{mf:?}");
        assert!(rf < rs, "median radius error {rs} -> {rf}");
    }
}
