//! The main job: capture a tree's motion, measure each marked branch's natural frequency and
//! damping, rebuild the static tree and animate it in wind with what was measured. A thin
//! program over `treemocap::mocap_pipeline`; everything it computes, a library user can call.
//!
//! ```text
//! cargo run --release --example pipeline                     # the synthetic twin
//! cargo run --release --example pipeline -- --recording DIR|FILE.mkv|FILE.bag --markers markers.json [--calibration FILE]
//! cargo run --release --example pipeline -- --write-recording DIR   # the twin, saved
//! ```
//!
//! With no arguments it runs on a digital twin whose every true value is known (a procedural
//! tree with per-branch dynamics, red markers on chains of levels 1–3, a pull and release
//! simulated with beam-anim, rendered as a Kinect V2 capture at 30 fps) and prints the
//! paper's Table 1 with the truth, ours and the paper's method side by side. Everything is
//! written under `target/treemocap-demo/pipeline/`: `report.md`, `report.json`, one SVG pair
//! per branch under `figures/`, `projection.png`, `tree.glb`, `tree.bvh` and
//! `skeleton.json`. `docs/capture.md` describes the capture protocol and the files of a real
//! recording. Exit status: 0 when at least one branch was measured, 1 on an error or when
//! none was (the report is still written), 2 for a usage error.

mod common;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

use clap::Parser;
use treemocap::kinect_io::{Calibration, ColorFormat, Recording};
use treemocap::mocap_pipeline::twin::{TRACK_TOLERANCE_PX, TWIN_JPEG_QUALITY, Twin, TwinConfig};
use treemocap::mocap_pipeline::{MarkersFile, Pipeline, PipelineConfig, Report, report};

const PROGRAM: &str = "pipeline";

/// Measure a tree's branches from an RGB-D capture (or the synthetic twin), rebuild the tree
/// and animate it in wind.
///
/// With no recording: the synthetic twin (a tree with known dynamics, filmed by a simulated
/// Kinect V2), measured and compared with the truth. With --recording: a recording in the
/// native or TUM layout, an Azure Kinect .mkv or a RealSense / Orbbec .bag (docs/recording-format.md)
/// and the markers of its markers file
/// (docs/capture.md).
#[derive(Parser, Debug)]
#[command(name = PROGRAM, version, about, allow_negative_numbers = true)]
struct Args {
    /// Folder for the report, figures, skeleton and animation [default:
    /// target/treemocap-demo/pipeline]
    #[arg(long, value_name = "DIR")]
    out_dir: Option<PathBuf>,
    /// Worker threads for frames and clouds [default: the machine's]
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// A recording to measure instead of the twin: a folder (native or TUM layout), an Azure
    /// Kinect / Orbbec Femto .mkv or a RealSense / Orbbec SDK v2 .bag
    #[arg(
        long,
        value_name = "DIR",
        requires = "markers",
        conflicts_with = "write_recording"
    )]
    recording: Option<PathBuf>,
    /// The recording's markers file (markers.json, docs/capture.md)
    #[arg(long, value_name = "FILE", requires = "recording")]
    markers: Option<PathBuf>,
    /// A calibration to use instead of the recording's own (our calibration JSON, or an
    /// iai_kinect2 folder / calib_*.yaml file)
    #[arg(long, value_name = "FILE", requires = "recording")]
    calibration: Option<PathBuf>,
    /// Save the twin's capture as a native recording with its markers.json, then stop
    #[arg(long, value_name = "DIR")]
    write_recording: Option<PathBuf>,
    #[command(flatten)]
    twin: TwinArgs,
}

/// The twin's options.
#[derive(clap::Args, Debug)]
struct TwinArgs {
    /// Seed of the twin's tree, dynamics, windows and sensor noise
    #[arg(long, default_value_t = TwinConfig::default().seed)]
    seed: u64,
    /// Frame rate, hertz
    #[arg(long, value_name = "HZ", default_value_t = TwinConfig::default().fps_hz)]
    fps: f64,
    /// Camera distance from the trunk, metres
    #[arg(long, value_name = "M", default_value_t = TwinConfig::default().distance_m)]
    distance: f64,
    /// Marker radius, metres
    #[arg(long, value_name = "M", default_value_t = TwinConfig::default().marker_radius_m)]
    marker_radius: f64,
    /// Scale of the sensor noise (1: a Kinect V2, 0: exact)
    #[arg(long, value_name = "SCALE", default_value_t = TwinConfig::default().noise_scale)]
    noise: f64,
    /// Limbs with a marked chain of levels 1-3
    #[arg(long, value_name = "N", default_value_t = TwinConfig::default().chains)]
    chains: usize,
    /// Standard deviation of the user's window placement, colour pixels
    #[arg(long, value_name = "PX", default_value_t = TwinConfig::default().window_error_px)]
    window_error: f64,
}

impl TwinArgs {
    fn config(&self) -> TwinConfig {
        TwinConfig {
            seed: self.seed,
            fps_hz: self.fps,
            distance_m: self.distance,
            marker_radius_m: self.marker_radius,
            noise_scale: self.noise,
            chains: self.chains,
            window_error_px: self.window_error,
            ..TwinConfig::default()
        }
    }
}

fn main() -> ExitCode {
    let args = Args::parse();
    let mut measured_none = false;
    let code = common::run(PROGRAM, || run(&args, &mut measured_none));
    if code == ExitCode::SUCCESS && measured_none {
        return ExitCode::FAILURE;
    }
    code
}

fn run(args: &Args, measured_none: &mut bool) -> Result<(), Box<dyn std::error::Error>> {
    let out = args
        .out_dir
        .clone()
        .unwrap_or_else(|| common::demo_dir(PROGRAM));
    let mut config = PipelineConfig::default();
    if let Some(n) = args.threads {
        config.threads = usize::from(n);
    }
    let line = Arc::new(common::ProgressLine::new());
    let pipeline = Pipeline::new(config)?.with_progress({
        let line = Arc::clone(&line);
        move |p| line.show(p.stage.name(), p.done, p.total)
    });
    let report = match (&args.recording, &args.markers, &args.write_recording) {
        (Some(dir), Some(markers), _) => {
            let markers = MarkersFile::read(markers)?;
            let recording = match &args.calibration {
                Some(path) => Recording::open_with_calibration(dir, Calibration::read(path)?)?,
                None => Recording::open(dir)?,
            };
            println!(
                "recording {} ({:?} layout): {} frames, {} markers",
                dir.display(),
                recording.layout(),
                recording.len(),
                markers.markers.len()
            );
            if recording.unpaired_depth_frames() > 0 {
                println!(
                    "          {} depth frames had no colour image close enough in time and are left out",
                    recording.unpaired_depth_frames()
                );
            }
            pipeline.run(&recording, &markers)?
        }
        (_, _, Some(dir)) => return write_recording(&pipeline, &args.twin.config(), dir),
        _ => {
            let twin = Twin::build(&args.twin.config())?;
            println!(
                "twin      {} skeleton nodes, {} markers ({} branches of levels 1-3), {} frames at {} fps, release at {} s",
                twin.skeleton.nodes().len(),
                twin.markers.len(),
                twin.markers.len() - 1,
                twin.times_s.len(),
                twin.config.fps_hz,
                twin.release_s
            );
            pipeline.run_twin(&twin)?
        }
    };
    std::fs::create_dir_all(&out).map_err(|e| common::naming(&out, e))?;
    report.write_all(&out)?;
    print_summary(&report, &out);
    if !report.measured_any() {
        eprintln!(
            "{PROGRAM}: no branch could be measured (every row of the table is `-`; {} says why for each)",
            out.join("report.md").display()
        );
        *measured_none = true;
    }
    Ok(())
}

fn write_recording(
    pipeline: &Pipeline,
    config: &TwinConfig,
    dir: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let twin = Twin::build(config)?;
    let color = ColorFormat::Jpeg {
        quality: TWIN_JPEG_QUALITY,
    };
    pipeline.write_twin_recording(&twin, dir, color)?;
    println!(
        "wrote     {} ({} frames, native layout) and its markers.json; run it with\n          cargo run --release --example pipeline -- --recording {} --markers {}",
        dir.display(),
        twin.scenes.len(),
        dir.display(),
        dir.join("markers.json").display()
    );
    Ok(())
}

fn print_summary(report: &Report, out: &Path) {
    println!("\n{}", report::table(&report.branches));
    for d in &report.dropped_markers {
        println!("marker {} left out: {}", d.id, d.reason);
    }
    for r in &report.branches {
        for n in &r.notes {
            println!("branch {}: {n}", r.id);
        }
    }
    let t = &report.tracking;
    let worst = |v: &mut dyn Iterator<Item = f64>| v.fold(1.0, f64::min) * 100.0;
    let within: Vec<f64> = t
        .markers
        .iter()
        .filter_map(|m| m.within_3px_fraction)
        .collect();
    println!(
        "tracking  {} markers over {} frames: worst marker tracked on {:.1} % of frames{}, lifted to 3D on {:.1} %{}",
        t.markers.len(),
        t.frames,
        worst(&mut t.markers.iter().map(|m| m.tracked_fraction)),
        if within.is_empty() {
            String::new()
        } else {
            format!(
                ", within {TRACK_TOLERANCE_PX} px of the truth on {:.1} %",
                worst(&mut within.into_iter())
            )
        },
        worst(&mut report.branches.iter().map(|r| r.lifted_fraction)),
        t.median_lift_error_mm
            .map_or(String::new(), |e| format!(", median lift error {e:.2} mm"))
    );
    let r = &report.reconstruction;
    println!(
        "rebuild   {} points -> {} nodes, {} branches, {:.2} m of wood, {:.2} L{}{} ({:.2} s)",
        r.points,
        r.nodes,
        r.branches,
        r.total_length_m,
        r.volume_l,
        if r.volume_trusted {
            ""
        } else {
            " (noisy scan: the volume may run high)"
        },
        match (
            r.mean_skeleton_error_m,
            r.p95_skeleton_error_m,
            r.truth_length_found
        ) {
            (Some(mean), Some(p95), Some(found)) => format!(
                ", mean skeleton error {:.1} mm (p95 {:.1} mm), {:.0} % of the true length found, volume {:.2} times the true one",
                mean * 1e3,
                p95 * 1e3,
                100.0 * found,
                r.volume_ratio.unwrap_or(f64::NAN)
            ),
            _ => String::new(),
        },
        r.seconds
    );
    let a = &report.animation;
    println!(
        "animate   {} branches of the rebuilt tree with measured dynamics, the rest by level or default; {} frames in {} m/s wind",
        a.measured_branches, a.frames, a.wind_speed_m_s
    );
    println!(
        "wrote     {} (report.md, report.json, figures/, tree.glb, tree.bvh, skeleton.json, projection.png)",
        out.display()
    );
    let tm = &report.timing;
    println!(
        "timing    capture {:.1} s (frames and clouds {:.1} s of CPU, tracking and lifting {:.1} s), reconstruction {:.2} s",
        tm.capture_s, tm.frames_and_clouds_cpu_s, tm.tracking_and_lifting_s, r.seconds
    );
    println!("seconds   {:.1}", report.seconds);
}
