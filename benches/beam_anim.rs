//! Criterion bench of beam-anim: one frame of a procedural tree in turbulent wind.
//! `cargo test --benches` runs the 1,000-branch case once; `cargo bench` also runs 10,000
//! (the 40,000 segments) and 100,000 branches.
#![allow(missing_docs, clippy::expect_used, clippy::unwrap_used)]

use criterion::{Criterion, criterion_group, criterion_main};
use treemocap::beam_anim::{AnimConfig, BeamTree, PAPER_DYNAMICS, Simulation, procedural_tree};

fn beam_anim(c: &mut Criterion) {
    let full = std::env::args().any(|a| a == "--bench");
    let sizes: &[usize] = if full {
        &[1_000, 10_000, 100_000]
    } else {
        &[1_000]
    };
    let mut g = c.benchmark_group("beam_anim");
    for &n in sizes {
        let sk = procedural_tree(n, 7).unwrap();
        let config = AnimConfig::default();
        let tree = BeamTree::new(&sk, &config).unwrap();
        let dynamics = vec![PAPER_DYNAMICS; tree.branches().len()];
        let mut sim = Simulation::new(tree, &dynamics, config, 1.0 / 30.0).unwrap();
        let mut wind = sim.wind_field().unwrap();
        g.bench_function(format!("frame_{n}_branches"), |b| {
            b.iter(|| sim.step(&mut wind).unwrap());
        });
    }
    g.finish();
}

criterion_group!(benches, beam_anim);
criterion_main!(benches);
