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

/// A chain through `pos` in order, each node the previous one's child.
fn chain(pos: Vec<Vector3<f64>>) -> Graph {
    let parent: Vec<Option<usize>> = (0..pos.len()).map(|k| k.checked_sub(1)).collect();
    Graph {
        bridge: vec![false; pos.len()],
        pos,
        parent,
    }
}

/// A straight chain up z from the origin in 2 cm steps, `n` nodes.
fn straight_up(n: u32) -> Graph {
    chain(
        (0..n)
            .map(|k| Vector3::new(0.0, 0.0, 0.02 * f64::from(k)))
            .collect(),
    )
}

#[test]
fn fits_far_from_the_pipe_model_are_not_used() {
    let g = trunk_with_stub();
    let (pipe, _) = g.to_skeleton(2.5, 0.05, None, None).unwrap();
    let scaled = |k: f64| -> Vec<Option<f64>> {
        pipe.nodes().iter().map(|n| Some(k * n.radius_m)).collect()
    };
    let (near, used) = g.to_skeleton(2.5, 0.05, Some(&scaled(1.3)), None).unwrap();
    assert!(used);
    assert!((near.nodes()[3].radius_m / pipe.nodes()[3].radius_m - 1.3).abs() < 1e-9);
    // Five times the pipe radius at the median: leaf clumps, not wood.
    let (far, used) = g.to_skeleton(2.5, 0.05, Some(&scaled(5.0)), None).unwrap();
    assert!(!used);
    assert_eq!(far, pipe);
}

#[test]
fn one_fit_far_off_the_pipe_model_is_no_anchor_when_asked() {
    let g = trunk_with_stub();
    let (pipe, _) = g.to_skeleton(2.5, 0.05, None, None).unwrap();
    // Every node measured at 1.3 times the pipe model, the stub's tip at 10 times.
    let fits: Vec<Option<f64>> = pipe
        .nodes()
        .iter()
        .map(|n| Some(if n.id == 12 { 10.0 } else { 1.3 } * n.radius_m))
        .collect();
    let ratio = |sk: &Skeleton, i: usize| sk.nodes()[i].radius_m / pipe.nodes()[i].radius_m;
    let (taken, _) = g.to_skeleton(2.5, 0.05, Some(&fits), None).unwrap();
    assert!((ratio(&taken, 12) - 10.0).abs() < 1e-9);
    let (bounded, used) = g
        .to_skeleton(2.5, 0.05, Some(&fits), Some(MAX_FIT_PER_PIPE_MEDIAN))
        .unwrap();
    assert!(used);
    // The tip takes its parent's ratio; every other node keeps its fit.
    assert!((ratio(&bounded, 12) - 1.3).abs() < 1e-9);
    assert!((ratio(&bounded, 11) - 1.3).abs() < 1e-9);
    assert!((ratio(&bounded, 3) - 1.3).abs() < 1e-9);
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
    let (sk, _) = g.to_skeleton(2.5, 0.02, None, None).unwrap();
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
    let (moved, _) = g.to_skeleton(2.5, 0.02, None, None).unwrap();
    assert!(far_tails(&moved, &tree, 0.01).is_empty());
}

#[test]
fn a_stub_is_kept_only_when_a_point_needs_it() {
    let g = trunk_with_stub();
    let (sk, _) = g.to_skeleton(2.5, 0.02, None, None).unwrap();
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

/// A half ring of radius `r` facing a camera far along -x (rays along +x), as a view's
/// cross-section across a branch up z: `lateral` positions (y) with `depth_noise_m` along
/// the ray, in the node's plane basis (u = x, v = y).
fn half_ring(r: f64, lateral: &[f64], depth_noise_m: f64, seed: u64) -> Vec<[f64; 2]> {
    let mut rng = crate::synthetic::Rng::new(seed);
    lateral
        .iter()
        .map(|&y| {
            [
                -(r * r - y * y).max(0.0).sqrt() + depth_noise_m * rng.normal(),
                y,
            ]
        })
        .collect()
}

#[test]
fn depth_noise_widens_a_thin_branchs_circle_but_not_its_width_across_the_ray() {
    let r = 0.006;
    // A laser scan's points kept by the view: spread evenly around the near half.
    let lateral: Vec<f64> = (0..60)
        .map(|k| r * (std::f64::consts::PI * (f64::from(k) + 0.5) / 60.0).cos())
        .collect();
    let plane = half_ring(r, &lateral, 0.006, 3);
    let fit = crate::circle::fit_circle(&plane).unwrap();
    assert!(fit.radius_m > 1.1 * r, "{fit:?}");
    let (u, v) = (Vector3::x(), Vector3::y());
    let camera = [-3.0, 0.0, 0.0];
    let across =
        across_ray_radius(&plane, Vector3::zeros(), u.cross(&v), (u, v), camera, 0.004).unwrap();
    assert!((across / r - 1.0).abs() < 0.08, "{across}");
    // A camera's pixels: columns 6 mm apart (a Kinect v2 at 2.5 m), three rows each, on a
    // 6 mm branch: two columns, whose centres span half the width.
    let columns: Vec<f64> = [-0.003, 0.003].iter().flat_map(|&y| [y, y, y]).collect();
    let plane = half_ring(r, &columns, 0.006, 5);
    let across =
        across_ray_radius(&plane, Vector3::zeros(), u.cross(&v), (u, v), camera, 0.006).unwrap();
    assert!((across / r - 1.0).abs() < 0.1, "{across}");
    // A ray along the branch has no across.
    assert!(
        across_ray_radius(&plane, Vector3::zeros(), u, (v, u.cross(&v)), camera, 0.006).is_none()
    );
}

/// Two branches up z, 2 cm nodes: at x = 0 a 2.5 cm branch seen over ±45° from -y (a
/// camera whose silhouette pixels are lost), at x = 0.5 m a 1 cm branch seen all round,
/// both with `noise_m` of noise; hung from one root.
fn arc_and_ring(noise_m: f64) -> (Graph, Vec<[f64; 3]>) {
    let mut pos = Vec::new();
    let mut parent = Vec::new();
    for k in 0..=30_u32 {
        pos.push(Vector3::new(0.0, 0.0, 0.02 * f64::from(k)));
        parent.push(k.checked_sub(1).map(|p| p as usize));
    }
    for k in 0..=30_u32 {
        pos.push(Vector3::new(0.5, 0.0, 0.02 * f64::from(k)));
        parent.push(Some(if k == 0 { 0 } else { 30 + k as usize }));
    }
    let bridge = vec![false; pos.len()];
    let mut rng = crate::synthetic::Rng::new(7);
    let mut pts = Vec::new();
    for zk in 0..300 {
        let z = 0.002 * f64::from(zk);
        for ak in -9..=9 {
            // Facing -y: the normal within 45° of it.
            let a = (-90.0 + 5.0 * f64::from(ak)).to_radians();
            let r = 0.025 + noise_m * rng.normal();
            pts.push([r * a.cos(), r * a.sin(), z]);
        }
        for ak in 0..12 {
            let a = (30.0 * f64::from(ak)).to_radians();
            let r = 0.01 + noise_m * rng.normal();
            pts.push([0.5 + r * a.cos(), r * a.sin(), z]);
        }
    }
    (
        Graph {
            pos,
            parent,
            bridge,
        },
        pts,
    )
}

fn arc_parameters(one_sided: bool) -> Parameters {
    Parameters {
        growth: crate::config::Growth::Colonization,
        bin_m: 0.015,
        patch_m: 0.03,
        spacing_m: 0.002,
        trunk_radius_m: 0.025,
        trunk_radius_fitted: true,
        trunk_coverage: 0.3,
        one_sided,
        kill_distance_m: 0.04,
        twig_kill_distance_m: 0.006,
        step_m: 0.02,
        influence_m: 0.11,
        max_gap_m: 1.0,
        root_m: [0.0; 3],
        camera_m: None,
        pipe_exponent: 2.5,
        min_twig_m: 0.004,
        max_iterations: 1000,
        max_nodes: 1000,
    }
}

#[test]
fn a_one_sided_views_short_arcs_measure_where_the_noise_is_small_against_them() {
    // Mid-branch nodes of the arc branch (away from the root fork and the tip).
    let arc_radii = |fits: &[Option<f64>]| -> Vec<Option<f64>> { fits[5..25].to_vec() };
    let (g, pts) = arc_and_ring(0.0005);
    let keep = vec![true; pts.len()];
    // A full scan's rule: a ±45° arc covers a quarter of its circle, too little.
    let full = g.fit_radii(&pts, &keep, &arc_parameters(false));
    assert!(arc_radii(&full).iter().all(Option::is_none), "{full:?}");
    // The ring branch tells the scan's noise (0.5 mm, a fiftieth of the arc's radius).
    let seen = g.fit_radii(&pts, &keep, &arc_parameters(true));
    for r in arc_radii(&seen) {
        let r = r.unwrap();
        assert!((r / 0.025 - 1.0).abs() < 0.05, "{r}");
    }
    // With 5 mm of noise a short arc's radius is not measured.
    let (g, pts) = arc_and_ring(0.005);
    let seen = g.fit_radii(&pts, &keep, &arc_parameters(true));
    assert!(arc_radii(&seen).iter().all(Option::is_none), "{seen:?}");
}

#[test]
fn a_chains_taper_is_not_carried_past_its_measured_stretch() {
    // A straight chain up z in 2 cm steps, measured only on nodes 10..=15, where the radius
    // falls from 30 to 20 mm.
    let g = straight_up(21);
    let raw: Vec<Option<f64>> = (0..=20_u32)
        .map(|k| {
            (10..=15)
                .contains(&k)
                .then(|| 0.030 - 0.002 * f64::from(k - 10))
        })
        .collect();
    let out = g.taper_fit(&raw, &g.children());
    // The line itself is kept where it was measured ...
    assert!((out[10].unwrap() - 0.030).abs() < 1e-9, "{out:?}");
    assert!((out[15].unwrap() - 0.020).abs() < 1e-9, "{out:?}");
    // ... and held at its ends beyond: extrapolated, the base would be 50 mm and the tip
    // would vanish.
    assert!((out[0].unwrap() - 0.030).abs() < 1e-9, "{out:?}");
    assert!((out[20].unwrap() - 0.020).abs() < 1e-9, "{out:?}");
}

#[test]
fn a_longer_span_sees_the_branch_past_a_sideways_wander() {
    // A chain up z that steps 4.5 cm sideways over three nodes while rising 1.5 cm, as a
    // chain drawn along the seen half of a thick branch can.
    let at = [
        (0.0, 0.0),
        (0.0, 0.02),
        (0.0, 0.04),
        (0.0, 0.06),
        (0.015, 0.065),
        (0.03, 0.07),
        (0.045, 0.075),
        (0.045, 0.10),
        (0.045, 0.12),
        (0.045, 0.14),
    ];
    let g = chain(at.iter().map(|&(x, z)| Vector3::new(x, 0.0, z)).collect());
    let children = g.children();
    let off_z = |span: usize| {
        g.tangent(5, &children, span)
            .unwrap()
            .z
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    };
    assert!(off_z(1) > 60.0, "{}", off_z(1));
    assert!(off_z(ONE_SIDED_TANGENT_SPAN) < 35.0, "{}", off_z(3));
    // Near the chain's ends the span is cut short, not carried past them.
    let end = g.tangent(8, &children, ONE_SIDED_TANGENT_SPAN).unwrap();
    assert!(end.x > 0.0 && end.z > 0.9, "{end:?}");
}

#[test]
fn a_loop_across_a_thick_branch_is_put_on_its_chord_and_a_thin_one_is_left() {
    // Up z in 2 cm steps, swinging 5 cm sideways and back while rising 2.5 cm.
    let xz = [
        (0.0, 0.0),
        (0.0, 0.02),
        (0.0, 0.04),
        (0.0, 0.06),
        (0.0, 0.08),
        (0.03, 0.085),
        (0.05, 0.09),
        (0.05, 0.095),
        (0.03, 0.10),
        (0.0, 0.105),
        (0.0, 0.125),
        (0.0, 0.145),
        (0.0, 0.165),
        (0.0, 0.185),
    ];
    let build = || chain(xz.iter().map(|&(x, z)| Vector3::new(x, 0.0, z)).collect());
    let n = xz.len();
    let mut thick = build();
    let before = thick.pos.clone();
    assert!(thick.straighten_loops(&vec![0.03; n]) > 0);
    let widest = |g: &Graph| g.pos.iter().map(|p| p.x.abs()).fold(0.0, f64::max);
    assert!(widest(&thick) < 0.01, "{:?}", thick.pos);
    assert_eq!(thick.pos[0], before[0]);
    assert_eq!(thick.pos[n - 1], before[n - 1]);
    // A thin twig's swing is left as it is.
    let mut thin = build();
    assert_eq!(thin.straighten_loops(&vec![0.004; n]), 0);
    assert_eq!(thin.pos, before);
    // A straight chain has no loop.
    let mut straight = straight_up(u32::try_from(n).unwrap());
    assert_eq!(straight.straighten_loops(&vec![0.03; n]), 0);
}

#[test]
fn centring_moves_the_chain_onto_its_axis_and_leaves_the_root() {
    // A 3 cm trunk whose axis is 1 cm off the grown chain (up z from the origin, 2 cm
    // steps), scanned all round from 1 cm below the root.
    let mut g = straight_up(16);
    let mut pts = Vec::new();
    for zk in -5..150 {
        for ak in 0..24 {
            let a = (15.0 * f64::from(ak)).to_radians();
            pts.push([0.01 + 0.03 * a.cos(), 0.03 * a.sin(), 0.002 * f64::from(zk)]);
        }
    }
    let keep = vec![true; pts.len()];
    let how = Centring {
        centroid_fallback: true,
        near_forks: false,
        span: 1,
    };
    g.centre(&pts, &keep, &arc_parameters(false), 0, how);
    assert_eq!(g.pos[0], Vector3::zeros());
    for k in 3..13 {
        assert!((g.pos[k].x - 0.01).abs() < 1e-3, "{k}: {:?}", g.pos[k]);
        assert!(
            (g.pos[k].z - 0.02 * k as f64).abs() < 1e-3,
            "{k}: {:?}",
            g.pos[k]
        );
    }
    g.centre_on_radius(&pts, &keep, &[0.03; 16], 1);
    assert_eq!(g.pos[0], Vector3::zeros());
}

#[test]
fn a_twig_running_inside_its_parent_is_a_candidate_and_one_growing_out_is_not() {
    let node = |id: usize, parent: Option<usize>, p: [f64; 3], r: f64| SkeletonNode {
        id,
        parent,
        position: Point3::from(p),
        radius_m: r,
    };
    // A 5 cm trunk up z in 5 cm steps to 1 m.
    let mut nodes: Vec<SkeletonNode> = (0..=20)
        .map(|k| node(k, k.checked_sub(1), [0.0, 0.0, 0.05 * k as f64], 0.05))
        .collect();
    // From 0.2 m, a twig up along the trunk 3 cm off its axis for 30 cm ...
    for k in 0..6 {
        let parent = if k == 0 { 4 } else { 20 + k };
        nodes.push(node(
            21 + k,
            Some(parent),
            [0.03, 0.0, 0.25 + 0.05 * k as f64],
            0.005,
        ));
    }
    // ... and from 0.6 m a branch out to 30 cm from the axis.
    for k in 0..6 {
        let parent = if k == 0 { 12 } else { 26 + k };
        nodes.push(node(
            27 + k,
            Some(parent),
            [0.05 * (k + 1) as f64, 0.0, 0.62],
            0.005,
        ));
    }
    let skeleton = Skeleton::new(nodes).unwrap();
    let inside = inside_parent_twigs(&skeleton, 0.01);
    assert_eq!(inside, vec![(21..27).collect::<Vec<usize>>()]);
    // The tip-distance rule of `twig_stubs` misses it: its tip is 32 cm from the fork.
    assert!(twig_stubs(&skeleton, 0.01).is_empty());
}
