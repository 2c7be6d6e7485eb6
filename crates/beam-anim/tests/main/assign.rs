//! Dynamics files: explicit, measured (nearest branch), level fill, default; skeleton JSON.

use std::path::Path;

use beam_anim::{
    AnimError, BeamTree, DynamicsSource, DynamicsSpec, GREEN_WOOD_DENSITY_KG_M3, PAPER_DYNAMICS,
    procedural_tree, skeleton_from_json,
};
use nalgebra::{Point3, Vector3};
use proptest::prelude::*;

fn tree() -> BeamTree {
    let sk = procedural_tree(13, 5).unwrap();
    BeamTree::with_density(&sk, GREEN_WOOD_DENSITY_KG_M3, &Vector3::x()).unwrap()
}

fn spec(json: &str) -> beam_anim::Result<DynamicsSpec> {
    DynamicsSpec::from_json(json, Path::new("d.json"))
}

fn mid(tree: &BeamTree, i: usize) -> Point3<f64> {
    tree.branches()[i].points[2]
}

#[test]
fn explicit_measured_level_and_default_in_that_order() {
    let t = tree();
    let b = t.branches();
    // The trunk (order 0), one order-1 branch explicit, one order-2 branch measured near its
    // middle; other order-1 and order-2 branches take their level's values; order 0 none.
    let o1: Vec<usize> = (0..b.len()).filter(|&i| b[i].order == 1).collect();
    let o2: Vec<usize> = (0..b.len()).filter(|&i| b[i].order == 2).collect();
    assert!(o1.len() >= 2 && o2.len() >= 2);
    let p = mid(&t, o2[0]);
    let json = format!(
        r#"{{"default": {{"frequency_hz": 1.46, "damping_ratio": 0.086}},
            "branches": {{"{}": {{"frequency_hz": 2.0, "damping_ratio": 0.1}}}},
            "measured": [{{"position": [{}, {}, {}], "frequency_hz": 3.0, "damping_ratio": 0.2}}]}}"#,
        b[o1[0]].id, p.x, p.y, p.z
    );
    let a = spec(&json).unwrap().assign(&t).unwrap();
    assert_eq!(a.source[o1[0]], DynamicsSource::Explicit);
    assert_eq!(a.dynamics[o1[0]].frequency_hz, 2.0);
    assert_eq!(a.source[o2[0]], DynamicsSource::Measured(0));
    assert_eq!(a.dynamics[o2[0]].damping_ratio, 0.2);
    for &i in &o1[1..] {
        assert_eq!(a.source[i], DynamicsSource::Level(1));
        assert_eq!(a.dynamics[i].frequency_hz, 2.0);
    }
    for &i in &o2[1..] {
        assert_eq!(a.source[i], DynamicsSource::Level(2));
        assert_eq!(a.dynamics[i].frequency_hz, 3.0);
    }
    // The trunk has no level of its own: the nearest level (1) fills it.
    assert_eq!(a.source[0], DynamicsSource::Level(1));
    // Nothing given at all: the default everywhere.
    let d = spec(r#"{"default": {"frequency_hz": 0.9, "damping_ratio": 0.05}}"#)
        .unwrap()
        .assign(&t)
        .unwrap();
    assert!(d.source.iter().all(|s| *s == DynamicsSource::Default));
    assert!(d.dynamics.iter().all(|x| x.frequency_hz == 0.9));
}

#[test]
fn level_fill_takes_the_median() {
    let t = tree();
    let b = t.branches();
    let o1: Vec<usize> = (0..b.len()).filter(|&i| b[i].order == 1).collect();
    assert!(o1.len() >= 3);
    let measured: Vec<String> = o1[..3]
        .iter()
        .zip([1.0, 2.0, 10.0])
        .map(|(&i, f)| {
            let p = mid(&t, i);
            format!(
                r#"{{"position": [{}, {}, {}], "frequency_hz": {f}, "damping_ratio": 0.1}}"#,
                p.x, p.y, p.z
            )
        })
        .collect();
    let json = format!(
        r#"{{"default": {{"frequency_hz": 1.46, "damping_ratio": 0.086}}, "measured": [{}]}}"#,
        measured.join(",")
    );
    let a = spec(&json).unwrap().assign(&t).unwrap();
    for &i in &o1[3..] {
        assert_eq!(a.dynamics[i].frequency_hz, 2.0);
    }
    assert_eq!(a.dynamics[o1[2]].frequency_hz, 10.0);
}

#[test]
fn bad_dynamics_files_are_named() {
    let t = tree();
    let ok = r#""default": {"frequency_hz": 1.46, "damping_ratio": 0.086}"#;
    assert!(matches!(spec("{"), Err(AnimError::Format { .. })));
    assert!(matches!(
        spec(&format!(r#"{{{ok}, "extra": 1}}"#)),
        Err(AnimError::Format { .. })
    ));
    let unknown = spec(&format!(
        r#"{{{ok}, "branches": {{"99999": {{"frequency_hz": 1, "damping_ratio": 0.1}}}}}}"#
    ))
    .unwrap();
    assert!(matches!(
        unknown.assign(&t),
        Err(AnimError::UnknownBranch { id: 99999 })
    ));
    let not_id = spec(&format!(
        r#"{{{ok}, "branches": {{"trunk": {{"frequency_hz": 1, "damping_ratio": 0.1}}}}}}"#
    ))
    .unwrap();
    assert!(matches!(
        not_id.assign(&t),
        Err(AnimError::InvalidParameter { .. })
    ));
    let zero_f = spec(r#"{"default": {"frequency_hz": 0, "damping_ratio": 0.1}}"#).unwrap();
    assert!(matches!(
        zero_f.assign(&t),
        Err(AnimError::InvalidFrequency { .. })
    ));
    let xi_one = spec(&format!(
        r#"{{{ok}, "measured": [{{"position": [0, 0, 1], "frequency_hz": 1, "damping_ratio": 1.0}}]}}"#
    ))
    .unwrap();
    assert!(matches!(
        xi_one.assign(&t),
        Err(AnimError::InvalidDamping { .. })
    ));
    let mut far = DynamicsSpec::default();
    far.measured.push(beam_anim::MeasuredDynamics {
        position: [f64::NAN, 0.0, 0.0],
        frequency_hz: 1.0,
        damping_ratio: 0.1,
    });
    assert!(matches!(
        far.assign(&t),
        Err(AnimError::InvalidParameter { .. })
    ));
    assert_eq!(DynamicsSpec::default().default, PAPER_DYNAMICS);
}

#[test]
fn skeleton_json_errors_are_typed() {
    let p = Path::new("s.json");
    let node = |id: usize, parent: &str, z: f64| {
        format!(r#"{{"id": {id}, "parent": {parent}, "position": [0, 0, {z}], "radius": 0.01}}"#)
    };
    let doc = |nodes: &[String]| format!(r#"{{"nodes": [{}]}}"#, nodes.join(","));
    let good = doc(&[node(0, "null", 0.0), node(1, "0", 1.0), node(2, "1", 2.0)]);
    assert_eq!(skeleton_from_json(&good, p).unwrap().nodes().len(), 3);
    let cycle = doc(&[node(0, "null", 0.0), node(1, "2", 1.0), node(2, "1", 2.0)]);
    assert!(matches!(
        skeleton_from_json(&cycle, p),
        Err(AnimError::Cycle { .. })
    ));
    let two_roots = doc(&[node(0, "null", 0.0), node(1, "null", 1.0)]);
    assert!(matches!(
        skeleton_from_json(&two_roots, p),
        Err(AnimError::Disconnected { .. })
    ));
    let zero = doc(&[node(0, "null", 0.0), node(1, "0", 0.0)]);
    assert!(matches!(
        skeleton_from_json(&zero, p),
        Err(AnimError::ZeroLengthSegment { .. })
    ));
    assert!(matches!(
        skeleton_from_json("[]", p),
        Err(AnimError::Format { .. })
    ));
}

proptest! {
    /// Arbitrary text never panics the parsers.
    #[test]
    fn parsers_never_panic(text in "\\PC{0,200}") {
        let _ = spec(&text);
        let _ = skeleton_from_json(&text, Path::new("s.json"));
    }
}
