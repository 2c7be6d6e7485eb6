//! The whole method through the library (`treemocap::mocap_pipeline`), as a downstream crate
//! calls it: a smaller twin (one marked chain of levels 1–3, shorter tests) measured in
//! memory against its truth, and a twin written as a recording and measured through the
//! recording path, which must give the same branches as the in-memory path.
#![allow(missing_docs, clippy::expect_used, clippy::unwrap_used, clippy::panic)]

use std::path::PathBuf;

use treemocap::kinect_io::{ColorFormat, Recording};
use treemocap::mocap_pipeline::twin::{Twin, TwinConfig};
use treemocap::mocap_pipeline::{MarkersFile, Pipeline, PipelineConfig, Report};

fn small_twin() -> TwinConfig {
    TwinConfig {
        seed: 8,
        chains: 1,
        // Colour at full resolution, as the example: at half, the twig's tracking noise
        // puts its frequency 2 % off.
        color_scale: 1.0,
        decay_s: [3.0, 3.0, 3.0],
        ..TwinConfig::default()
    }
}

fn pipeline() -> Pipeline {
    Pipeline::new(PipelineConfig {
        threads: 2,
        // A short animation: this test is about the measurement.
        animation_s: 1.0,
        ..PipelineConfig::default()
    })
    .expect("valid config")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("treemocap-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn small_twin_recovers_frequency_damping_and_skeleton() {
    let twin = Twin::build(&small_twin()).expect("twin builds");
    assert_eq!(twin.markers.len(), 4, "trunk and one chain of levels 1-3");
    let report: Report = pipeline().run_twin(&twin).expect("runs");
    assert_eq!(report.tracking.frames, twin.times_s.len());
    assert!(
        report.dropped_markers.is_empty(),
        "{:?}",
        report.dropped_markers
    );
    let lift_mm = report.tracking.median_lift_error_mm.expect("twin truth");
    assert!(lift_mm < 5.0, "median lift error {lift_mm} mm");

    assert_eq!(report.branches.len(), 3);
    for b in &report.branches {
        eprintln!(
            "{} level {}: tracked {:.3}, f {:?} (true {:?}), xi {:?} (true {:?}), paper {:?} {:?}; {:?}",
            b.id,
            b.level,
            b.tracked_fraction,
            b.frequency_hz,
            b.true_frequency_hz,
            b.damping_ratio,
            b.true_damping_ratio,
            b.paper_frequency_hz,
            b.paper_damping_ratio,
            b.notes
        );
    }
    for b in &report.branches {
        let (_id, f, xi): (&str, Option<f64>, Option<f64>) =
            (&b.id, b.frequency_hz, b.damping_ratio);
        assert!(
            b.tracked_fraction >= 0.99,
            "{}: tracked {}",
            b.id,
            b.tracked_fraction
        );
        let f = f.unwrap_or_else(|| panic!("{}: no mode; {:?}", b.id, b.notes));
        let xi = xi.expect("a mode has a damping ratio");
        let (f_true, xi_true) = (b.true_frequency_hz.unwrap(), b.true_damping_ratio.unwrap());
        // The goals: f within 1 %, xi within 15 %, on every level.
        assert!(
            (f - f_true).abs() / f_true < 0.01,
            "{} level {}: f {f} vs {f_true}",
            b.id,
            b.level
        );
        assert!(
            (xi - xi_true).abs() / xi_true < 0.15,
            "{} level {}: xi {xi} vs {xi_true}",
            b.id,
            b.level
        );
        // The paper's FFT reads a bin: a multiple of its bin width.
        let bins = b.paper_frequency_hz.expect("paper method ran") / b.paper_bin_width_hz.unwrap();
        assert!((bins - bins.round()).abs() < 1e-6, "{}: {bins} bins", b.id);
    }

    check_reconstruction(&report.reconstruction);
    assert_eq!(
        report.animation.frames, 31,
        "1 s at 30 fps and the rest pose"
    );

    // The report's files, and the JSON keys of the contract.
    let dir = scratch("report");
    report.write_all(&dir).expect("writes");
    let json = std::fs::read_to_string(dir.join("report.json")).expect("report.json");
    for key in [
        "branches",
        "id",
        "level",
        "tracked_fraction",
        "true_frequency_hz",
        "frequency_hz",
        "paper_frequency_hz",
        "true_damping_ratio",
        "damping_ratio",
        "paper_damping_ratio",
        "reconstruction",
        "mean_skeleton_error_m",
        "seconds",
    ] {
        assert!(
            json.contains(&format!("\"{key}\":")),
            "report.json lacks {key}"
        );
    }
    for file in [
        "report.md",
        "tree.glb",
        "tree.bvh",
        "skeleton.json",
        "projection.png",
    ] {
        assert!(dir.join(file).is_file(), "{file} not written");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_recording_path_gives_the_in_memory_result_on_the_same_frames() {
    // A short twin (1 s tests at 15 fps, half-size colour) keeps the PNG recording small.
    let config = TwinConfig {
        seed: 11,
        chains: 1,
        fps_hz: 15.0,
        color_scale: 0.5,
        decay_s: [1.5, 1.5, 1.5],
        ..TwinConfig::default()
    };
    let twin = Twin::build(&config).expect("twin builds");
    let pipeline = pipeline();
    let memory = pipeline.run_twin(&twin).expect("in memory");
    let dir = scratch("recording");
    let written = pipeline
        .write_twin_recording(&twin, &dir, ColorFormat::Png)
        .expect("writes the recording");
    let markers = MarkersFile::read(&dir.join("markers.json")).expect("markers file");
    assert_eq!(markers.markers, written.markers);
    let recording = Recording::open(&dir).expect("opens");
    let from_file = pipeline.run(&recording, &markers).expect("recording path");
    let _ = std::fs::remove_dir_all(&dir);

    assert_eq!(memory.branches.len(), from_file.branches.len());
    assert_eq!(memory.tracking.frames, from_file.tracking.frames);
    for (a, b) in memory.branches.iter().zip(&from_file.branches) {
        assert_eq!(a.id, b.id);
        assert_eq!(a.tracked_fraction, b.tracked_fraction, "{}", a.id);
        assert_eq!(a.lifted_fraction, b.lifted_fraction, "{}", a.id);
        let close = |x: Option<f64>, y: Option<f64>, what: &str| match (x, y) {
            (Some(x), Some(y)) => assert!(
                (x - y).abs() <= 1e-6 * x.abs().max(1e-9),
                "{} {what}: {x} in memory, {y} from the recording",
                a.id
            ),
            (None, None) => {}
            _ => panic!("{} {what}: {x:?} in memory, {y:?} from the recording", a.id),
        };
        close(a.frequency_hz, b.frequency_hz, "f");
        close(a.damping_ratio, b.damping_ratio, "xi");
        close(a.paper_frequency_hz, b.paper_frequency_hz, "paper f");
        close(a.paper_damping_ratio, b.paper_damping_ratio, "paper xi");
    }
}

/// The static tree from the still frames, against the true skeleton, with the same crop as
/// the example (the library's): its axes, its length, and its volume (x1.02 by luck before
/// quarter arcs of one-sided views were measured; seeds 8-10 then x0.49-0.73, now
/// x0.91-0.94), from a scan quiet enough for the volume to be trusted.
fn check_reconstruction(rec: &treemocap::mocap_pipeline::report::ReconstructionSummary) {
    let mean = rec.mean_skeleton_error_m.expect("twin truth");
    assert!(mean < 0.015, "mean skeleton error {mean} m");
    let found = rec.truth_length_found.expect("twin truth");
    assert!(found > 0.7, "{found} of the true length found");
    let volume = rec.volume_ratio.expect("twin truth");
    assert!(
        (volume - 1.0).abs() < 0.1,
        "volume {volume} of the true one"
    );
    assert!(rec.volume_trusted, "{:?}", rec.surface_noise_m);
}
