//! Cylinder table and mesh.

use std::collections::HashMap;

use space_colonize::synthetic::SyntheticConfig;
use space_colonize::{ColonizeConfig, cylinders, cylinders_to_csv, reconstruct, tube_mesh};

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
    // Lengths and volume agree with the skeleton's.
    let len: f64 = cyl.iter().map(|c| c.length_m).sum();
    assert!((len - s.total_length_m()).abs() < 1e-9);
    let vol: f64 = cyl
        .iter()
        .map(|c| std::f64::consts::PI * c.radius_m.powi(2) * c.length_m)
        .sum();
    assert!((vol - s.volume_m3()).abs() < 1e-12);
    // Parents come first; each cylinder starts where its parent ends.
    for c in &cyl {
        if let Some(p) = c.parent {
            assert!(p < c.id);
            let q = &cyl[p];
            let end = q.start + q.axis * q.length_m;
            assert!((end - c.start).norm() < 1e-9);
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
