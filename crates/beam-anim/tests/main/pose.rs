//! Poses: rigid segments, children on their parents' deformed frames.

use beam_anim::{AnimConfig, BeamTree, PAPER_DYNAMICS, SEGMENTS, Simulation, procedural_tree};

#[test]
fn segment_frames_keep_segments_rigid_and_children_attached() {
    let sk = procedural_tree(40, 3).unwrap();
    let mut config = AnimConfig::default();
    config.wind.mean_speed_m_s = 20.0;
    let tree = BeamTree::new(&sk, &config).unwrap();
    let rest = tree.clone();
    let dynamics = vec![PAPER_DYNAMICS; tree.branches().len()];
    let mut sim = Simulation::new(tree, &dynamics, config, 1.0 / 30.0).unwrap();
    let mut wind = sim.wind_field().unwrap();
    for _ in 0..45 {
        sim.step(&mut wind).unwrap();
    }
    let frames = sim.segment_frames();
    let mut largest_turn = 0.0f64;
    for (bi, b) in rest.branches().iter().enumerate() {
        for j in 0..SEGMENTS {
            let s = bi * SEGMENTS + j;
            let (g, start) = frames[s];
            largest_turn = largest_turn.max(g.angle());
            let end = start + g * (b.points[j + 1] - b.points[j]);
            if j + 1 < SEGMENTS {
                let next = frames[s + 1].1;
                assert!((end - next).norm() < 1e-12, "branch {} segment {j}", b.id);
            }
        }
        if let Some(ps) = b.parent_segment {
            // The child's base keeps its rest offset in its parent segment's frame.
            let (g, start) = frames[ps];
            let expected = start + g * (b.points[0] - rest.segment_start(ps));
            let got = frames[bi * SEGMENTS].1;
            assert!((expected - got).norm() < 1e-12, "branch {}", b.id);
        }
    }
    // The wind did bend the tree (the checks above are not about a rest pose).
    assert!(largest_turn > 1e-3, "largest rotation {largest_turn} rad");
}
