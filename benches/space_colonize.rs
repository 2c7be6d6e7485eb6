//! Reconstruction speed on synthetic clouds of 10k, 100k and 1M points (the sizes),
//! by space colonization and by level sets, and on the real AdTree clouds when
//! `../shared/data/pointclouds/adtree/` is present (issue 22: at most half of AdTree's
//! 1.8 s on tree7 and 3.3 s on Paris_Luxembourg_1), and wood/leaf separation. `cargo test --benches` runs the 10k
//! cases once; `cargo bench` runs all.
#![allow(missing_docs, clippy::expect_used, clippy::unwrap_used)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use treemocap::space_colonize::synthetic::SyntheticConfig;
use treemocap::space_colonize::{ColonizeConfig, Growth, WoodConfig, reconstruct, separate_wood};

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
        g.bench_function(format!("reconstruct_levels_{}k", n / 1000), |b| {
            b.iter(|| reconstruct(black_box(&tree.points), &levels()).unwrap());
        });
        // Wood/leaf separation on the same tree in leaf (half as many leaf points again);
        // the 1M case is timed once in `docs/benchmarks.md` (about a minute a run).
        if n <= 100_000 {
            let leafy = SyntheticConfig {
                points: n,
                leaf_points: n / 2,
                ..Default::default()
            }
            .generate()
            .unwrap();
            g.bench_function(format!("separate_wood_{}k_plus_leaves", n / 1000), |b| {
                b.iter(|| separate_wood(black_box(&leafy.points), &WoodConfig::default()).unwrap());
            });
        }
    }
    if full {
        // The leaf-off coffee tree, a full scan: the default (which fits each segment's
        // cylinder to its points last) beside the smooth model without that stage.
        if let Some(points) = real_cloud("rtwig_gymnocladus/cloud.txt") {
            g.bench_function("coffee_default", |b| {
                b.iter(|| reconstruct(black_box(&points), &ColonizeConfig::default()).unwrap());
            });
            let smooth = ColonizeConfig {
                cylinder_fits: false,
                ..ColonizeConfig::default()
            };
            g.bench_function("coffee_without_cylinder_fits", |b| {
                b.iter(|| reconstruct(black_box(&points), &smooth).unwrap());
            });
        }
        for name in ["tree7", "tree13", "Paris_Luxembourg_1"] {
            let Some(points) = real_cloud(&format!("adtree/{name}.xyz")) else {
                continue;
            };
            g.bench_function(format!("adtree_{name}_levels"), |b| {
                b.iter(|| reconstruct(black_box(&points), &levels()).unwrap());
            });
            // The default (`Growth::Auto`) chooses level sets on these clouds after
            // colonization's first growth: the time a user gets.
            g.bench_function(format!("adtree_{name}_default"), |b| {
                b.iter(|| reconstruct(black_box(&points), &ColonizeConfig::default()).unwrap());
            });
        }
    }
    g.finish();
}

/// A real cloud of `../shared/data/pointclouds/`, read by path with the workspace's point-cloud
/// reader; `None`, with a message, when absent or unreadable.
fn real_cloud(rel: &str) -> Option<Vec<treemocap::nalgebra::Point3<f64>>> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/pointclouds")
        .join(rel);
    match treemocap::kinect_io::read_point_cloud(&path) {
        Ok(cloud) => Some(cloud.valid_points().map(|(p, _)| p).collect()),
        Err(e) => {
            println!("skipped {rel}: {e}");
            None
        }
    }
}

fn levels() -> ColonizeConfig {
    ColonizeConfig {
        growth: Growth::LevelSets,
        ..ColonizeConfig::default()
    }
}

criterion_group!(space_colonize, bench);
criterion_main!(space_colonize);
