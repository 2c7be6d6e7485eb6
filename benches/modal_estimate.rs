//! Criterion benches of modal-estimate: the paper's record (409 samples at 30 Hz, held still
//! for 1 s, then a pull-and-release decay) by each method, a Monte Carlo record with a
//! second mode, and an hour of wind sway.
#![allow(missing_docs, clippy::expect_used, clippy::unwrap_used)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use modal_estimate::synthetic::{DecaySpec, ambient};
use modal_estimate::{EstimateConfig, Method, SpectrumConfig, estimate, spectrum};

fn bench(c: &mut Criterion) {
    let signal = DecaySpec::paper_branch().generate().unwrap();
    let mut group = c.benchmark_group("modal_estimate");
    group.bench_function("auto_409_samples", |b| {
        b.iter(|| estimate(black_box(&signal), &EstimateConfig::default()).unwrap());
    });
    let one_mode = EstimateConfig {
        method: Method::Pencil,
        modes: Some(1),
        ..EstimateConfig::default()
    };
    group.bench_function("pencil_one_mode_409_samples", |b| {
        b.iter(|| estimate(black_box(&signal), &one_mode).unwrap());
    });
    group.bench_function("paper_409_samples", |b| {
        b.iter(|| estimate(black_box(&signal), &EstimateConfig::paper()).unwrap());
    });
    group.bench_function("spectrum_409_samples", |b| {
        b.iter(|| spectrum(black_box(&signal), &SpectrumConfig::default()).unwrap());
    });
    // Seed 1 of the Monte Carlo: 469 samples at 26 Hz with a second mode.
    let two_modes = DecaySpec::monte_carlo(1).generate().unwrap();
    group.bench_function("auto_monte_carlo_seed_1", |b| {
        b.iter(|| estimate(black_box(&two_modes), &EstimateConfig::default()).unwrap());
    });
    group.sample_size(10);
    let wind = ambient(0.9, 0.04, 10.0, 3600.0, 20.0, 7).unwrap();
    group.bench_function("ambient_1_hour_at_10_hz", |b| {
        b.iter(|| estimate(black_box(&wind), &EstimateConfig::default()).unwrap());
    });
    group.finish();
}

criterion_group!(modal_estimate, bench);
criterion_main!(modal_estimate);
