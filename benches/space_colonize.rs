//! Reconstruction speed on synthetic clouds of 10k, 100k and 1M points (the sizes).
//! `cargo test --benches` runs the 10k case once; `cargo bench` runs all three.
#![allow(missing_docs, clippy::expect_used, clippy::unwrap_used)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use treemocap::space_colonize::synthetic::SyntheticConfig;
use treemocap::space_colonize::{ColonizeConfig, reconstruct};

fn bench(c: &mut Criterion) {
    let full = std::env::args().any(|a| a == "--bench");
    let sizes: &[usize] = if full {
        &[10_000, 100_000, 1_000_000]
    } else {
        &[10_000]
    };
    let mut g = c.benchmark_group("space_colonize");
    g.sample_size(10);
    for &n in sizes {
        let tree = SyntheticConfig {
            points: n,
            ..Default::default()
        }
        .generate()
        .unwrap();
        g.bench_function(format!("reconstruct_{}k", n / 1000), |b| {
            b.iter(|| reconstruct(black_box(&tree.points), &ColonizeConfig::default()).unwrap());
        });
    }
    g.finish();
}

criterion_group!(space_colonize, bench);
criterion_main!(space_colonize);
