//! Cylinder table and mesh.

use std::collections::HashMap;

use nalgebra::Point3;
use space_colonize::synthetic::SyntheticConfig;
use space_colonize::{
    ColonizeConfig, Skeleton, SkeletonNode, cylinders, cylinders_to_csv, reconstruct, tube_mesh,
};

#[test]
fn cylinders_and_mesh_of_a_model() {
    let truth = SyntheticConfig {
        points: 6_000,
        max_order: 2,
        ..Default::default()
    }
    .generate()
    .unwrap();
    let model = reconstruct(&truth.points, &ColonizeConfig::default()).unwrap();
    let s = &model.skeleton;
    let cyl = cylinders(s);
    // Lengths and volume are the skeleton's less the stretches inside parents.
    let inside = s.inside_parent_m();
    let inside_m: f64 = inside.iter().sum();
    assert!(inside_m > 0.0);
    let len: f64 = cyl.iter().map(|c| c.length_m).sum();
    assert!((len - (s.total_length_m() - inside_m)).abs() < 1e-9);
    let inside_m3: f64 = s
        .nodes()
        .iter()
        .map(|n| std::f64::consts::PI * n.radius_m.powi(2) * inside[n.id])
        .sum();
    let vol: f64 = cyl
        .iter()
        .map(|c| std::f64::consts::PI * c.radius_m.powi(2) * c.length_m)
        .sum();
    assert!((vol - (s.volume_m3() - inside_m3)).abs() < 1e-12);
    // Parents come first; a cylinder of the same branch starts where its parent ends, the
    // first of a branch off its parent's axis.
    for c in &cyl {
        if let Some(p) = c.parent {
            assert!(p < c.id);
            let q = &cyl[p];
            let end = q.start + q.axis * q.length_m;
            if q.branch == c.branch {
                assert!((end - c.start).norm() < 1e-9);
            } else {
                assert!((end - c.start).norm() > 0.5 * q.radius_m.min(c.length_m));
            }
        }
        assert!((c.axis.norm() - 1.0).abs() < 1e-12);
    }
    let csv = cylinders_to_csv(&cyl);
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "id,parent,start_x,start_y,start_z,axis_x,axis_y,axis_z,length,radius,branch,order"
    );
    assert_eq!(lines.count(), cyl.len());

    let sides = 8;
    let mesh = tube_mesh(s, sides).unwrap();
    // Every edge is shared by exactly two triangles, in opposite directions: closed,
    // consistently oriented tubes.
    let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *edges.entry((a, b)).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &edges {
        assert_eq!(n, 1, "edge {a}-{b} used {n} times one way");
        assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} has no twin");
    }
    // Outward orientation: the enclosed volume is positive and near the cylinders' (the
    // 8-gon has 90 % of the circle's area; tubes overlap at joints).
    let v = mesh.volume_m3();
    assert!(
        v > 0.8 * vol && v < 1.2 * vol,
        "mesh {v} vs cylinders {vol}"
    );
    assert!(
        mesh.to_obj()
            .lines()
            .filter(|l| l.starts_with("f "))
            .count()
            == mesh.triangles.len()
    );
    let ply = mesh.to_ply();
    assert!(ply.starts_with(b"ply\nformat binary_little_endian 1.0\n"));
    assert!(tube_mesh(s, 2).is_err());
}

/// A trunk up z (radius 4 cm) with a branch leaving it at 90° and one at 30° from the axis.
fn trunk_with_two_branches() -> Skeleton {
    let at = |id: usize, parent: Option<usize>, p: [f64; 3], r: f64| SkeletonNode {
        id,
        parent,
        position: Point3::from(p),
        radius_m: r,
    };
    let (s30, c30) = (30f64.to_radians().sin(), 30f64.to_radians().cos());
    Skeleton::new(vec![
        at(0, None, [0.0, 0.0, 0.0], 0.04),
        at(1, Some(0), [0.0, 0.0, 0.5], 0.04),
        at(2, Some(1), [0.0, 0.0, 1.0], 0.04),
        at(3, Some(2), [0.0, 0.0, 1.5], 0.03),
        // Level: 1 cm steps, so the crossing is inside the fifth segment.
        at(4, Some(1), [0.01, 0.0, 0.5], 0.01),
        at(5, Some(4), [0.02, 0.0, 0.5], 0.01),
        at(6, Some(5), [0.035, 0.0, 0.5], 0.01),
        at(7, Some(6), [0.045, 0.0, 0.5], 0.01),
        at(8, Some(7), [0.2, 0.0, 0.5], 0.01),
        // 30° off the axis, 5 cm steps: crosses at 8 cm from the fork (0.04 / sin 30°).
        at(9, Some(2), [0.05 * s30, 0.0, 1.0 + 0.05 * c30], 0.01),
        at(10, Some(9), [0.1 * s30, 0.0, 1.0 + 0.1 * c30], 0.01),
        at(11, Some(10), [0.3 * s30, 0.0, 1.0 + 0.3 * c30], 0.01),
    ])
    .unwrap()
}

#[test]
fn branches_start_on_their_parents_surface() {
    let s = trunk_with_two_branches();
    let inside = s.inside_parent_m();
    let expect = [
        0.0, 0.0, 0.0, 0.0, 0.01, 0.01, 0.015, 0.005, 0.0, 0.05, 0.03, 0.0,
    ];
    for (i, (&got, &want)) in inside.iter().zip(&expect).enumerate() {
        assert!((got - want).abs() < 1e-12, "node {i}: {got} vs {want}");
    }
    let cyl = cylinders(&s);
    // The level branch's first cylinder starts on the trunk's surface, 4 cm out; the
    // segments wholly inside are left out.
    let level: Vec<_> = cyl.iter().filter(|c| c.branch == 4).collect();
    assert_eq!(level.len(), 2);
    assert!((level[0].start - Point3::new(0.04, 0.0, 0.5)).norm() < 1e-12);
    assert!((level[0].length_m - 0.005).abs() < 1e-12);
    // The 30° branch leaves the trunk 8 cm from the fork.
    let steep: Vec<_> = cyl.iter().filter(|c| c.branch == 9).collect();
    assert_eq!(steep.len(), 2);
    assert!((steep[0].start.x - 0.04).abs() < 1e-12);
    assert!((steep[0].length_m - 0.02).abs() < 1e-12);
    let total: f64 = cyl.iter().map(|c| c.length_m).sum();
    assert!((total - (s.total_length_m() - 0.04 - 0.08)).abs() < 1e-12);
}
