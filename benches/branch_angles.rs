//! Criterion benches of branch-angles: the paper's record (409 samples at 30 Hz) of a
//! two-level tree, and CSV parsing of it.
#![allow(missing_docs, clippy::expect_used, clippy::unwrap_used)]

use std::hint::black_box;

use branch_angles::csv::{read_trajectories_csv, trajectories_to_csv};
use branch_angles::{AngleConfig, branch_angles, synthetic};
use criterion::{Criterion, criterion_group, criterion_main};

fn bench(c: &mut Criterion) {
    let tree = synthetic::two_level();
    let config = AngleConfig {
        rest: tree.rest,
        ..AngleConfig::default()
    };
    let mut group = c.benchmark_group("branch_angles");
    group.bench_function("angles_3_branches_409_samples", |b| {
        b.iter(|| {
            branch_angles(
                black_box(&tree.hierarchy),
                black_box(&tree.trajectories),
                &config,
            )
            .expect("valid")
        });
    });
    let text = trajectories_to_csv(&tree.trajectories);
    group.bench_function("read_trajectories_csv_4_markers_409_samples", |b| {
        b.iter(|| read_trajectories_csv(black_box(&text)).expect("valid"));
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
