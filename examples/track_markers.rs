//! Track markers through a folder of frames from the windows a user drew on the first one.
//!
//! ```text
//! cargo run --release --example track_markers -- <FRAMES_DIR> <INIT_JSON> [--out tracks.json] [--model hue|hs|rgb|gray] [--window fixed|adaptive] [--paper]
//! ```
//!
//! `FRAMES_DIR` holds PNG or JPEG images, taken in name order. `INIT_JSON` is
//! `[{"id": "A", "x": 396, "y": 158, "w": 12, "h": 12}, ...]` (top-left corner and size of
//! each window on the first frame, pixels), or the capture's `markers.json` (docs/capture.md). The output (stdout, or `--out`) is
//! `{"frames": N, "markers": [{"id", "centers": [[x, y] | null, ...], "status": [...],
//! "confidence": [...]}], "timing": {"decode_s", "track_s"}}`, one entry per frame; `track_s`
//! covers tracking only. A summary per marker goes to stderr: frames tracked, recovered,
//! predicted and lost, and the longest loss. With a colour model (hue, hs, rgb), a marker
//! whose window has little colour (`meanshift_track::window_saturation` under the colour
//! mask's floor: a black-and-white target) gets a warning there first, pointing to
//! `--model gray`.
//!
//! With no arguments it renders a synthetic pull-and-release sequence with kinect-io's `synth`
//! (the demo tree, its red markers swinging), tracks it, and prints the error against the
//! truth next to plain mean-shift (the paper's tracker).

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Parser;
use serde::{Deserialize, Serialize};
use treemocap::image::RgbImage;
use treemocap::kinect_io::read_color_image;
use treemocap::kinect_io::synth::{self, SynthConfig};
use treemocap::meanshift_track::synthetic::score;
use treemocap::meanshift_track::{
    AppearanceModel, MarkerInit, PixelRect, Track, Tracker, TrackerConfig, WindowMode,
    window_saturation,
};
use treemocap::mocap_pipeline::MarkersFile;
use treemocap::nalgebra::{Point2, Vector3};

mod common;

/// Track every marker through a folder of frames from the windows drawn on the first one,
/// and write JSON tracks.
///
/// Frames are the PNG/JPEG images of FRAMES_DIR in name order. A summary per marker goes to
/// stderr. With no arguments: a synthetic Kinect V2 sequence, scored against its ground
/// truth.
#[derive(Parser, Debug)]
#[command(name = "track_markers", version, about)]
struct Cli {
    /// The frames: PNG or JPEG images, taken in name order
    #[arg(value_name = "FRAMES_DIR", requires = "init_json")]
    frames_dir: Option<PathBuf>,
    /// The windows on the first frame, [{"id": "A", "x": 396, "y": 158, "w": 12, "h": 12},
    /// ...] (top-left corner and size, pixels), or the capture's markers.json
    #[arg(value_name = "INIT_JSON")]
    init_json: Option<PathBuf>,
    /// Write the tracks here instead of stdout
    #[arg(long, value_name = "FILE", requires = "frames_dir")]
    out: Option<PathBuf>,
    /// Appearance model: hue (the paper's), hs, rgb or gray [default: hue]
    #[arg(long, value_name = "MODEL", value_parser = parse_model, requires = "frames_dir")]
    model: Option<AppearanceModel>,
    /// fixed keeps the first size; adaptive lets each window follow the marker's size
    /// (CamShift's second moments, between half and twice the first size) [default: fixed]
    #[arg(long, value_name = "MODE", value_parser = parse_window, requires = "frames_dir")]
    window: Option<WindowMode>,
    /// Plain mean-shift as the paper did (no prediction, recovery or exclusivity), for
    /// comparison
    #[arg(long, requires = "frames_dir")]
    paper: bool,
}

fn parse_model(text: &str) -> Result<AppearanceModel, String> {
    AppearanceModel::from_name(text).map_err(|e| e.to_string())
}

fn parse_window(text: &str) -> Result<WindowMode, String> {
    WindowMode::from_name(text).map_err(|e| e.to_string())
}

/// Accuracy goal of the tracker: a centre within this distance of the truth (pixels).
const TOLERANCE_PX: f64 = 3.0;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InitWindow {
    id: String,
    x: i32,
    y: i32,
    w: i32,
    h: i32,
}

#[derive(Serialize)]
struct Output {
    frames: usize,
    markers: Vec<MarkerOut>,
    timing: Timing,
}

#[derive(Serialize)]
struct MarkerOut {
    id: String,
    centers: Vec<Option<[f64; 2]>>,
    status: Vec<&'static str>,
    confidence: Vec<f64>,
}

#[derive(Serialize)]
struct Timing {
    decode_s: f64,
    track_s: f64,
}

struct Args {
    frames_dir: PathBuf,
    init_json: PathBuf,
    out: Option<PathBuf>,
    model: AppearanceModel,
    window: WindowMode,
    paper: bool,
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    common::run("track_markers", || match (cli.frames_dir, cli.init_json) {
        (Some(frames_dir), Some(init_json)) => track_folder(&Args {
            frames_dir,
            init_json,
            out: cli.out,
            model: cli.model.unwrap_or(AppearanceModel::PAPER),
            window: cli.window.unwrap_or_default(),
            paper: cli.paper,
        }),
        _ => synthetic_demo(),
    })
}

/// Image files of `dir` in name order.
fn frame_paths(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut paths = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| format!("{}: {e}", dir.display()))?.path();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if matches!(ext.as_deref(), Some("png" | "jpg" | "jpeg")) {
            paths.push(path);
        }
    }
    if paths.is_empty() {
        return Err(format!("{}: no PNG or JPEG frames", dir.display()));
    }
    paths.sort();
    Ok(paths)
}

/// A frame, strictly decoded (a truncated JPEG is an error, not grey pixels).
fn decode(path: &Path) -> Result<RgbImage, String> {
    let image = read_color_image(path).map_err(|e| e.to_string())?;
    if image.width() == 0 || image.height() == 0 {
        return Err(format!("{}: empty image", path.display()));
    }
    Ok(image)
}

fn read_inits(path: &Path) -> Result<Vec<MarkerInit>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let windows: Vec<InitWindow> = if text.trim_start().starts_with('{') {
        // The capture's markers file: its windows, to whole pixels.
        let file = MarkersFile::parse(&text, path).map_err(|e| e.to_string())?;
        file.markers
            .into_iter()
            .map(|m| InitWindow {
                id: m.id,
                x: m.x.round() as i32,
                y: m.y.round() as i32,
                w: m.w.round() as i32,
                h: m.h.round() as i32,
            })
            .collect()
    } else {
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?
    };
    if windows.is_empty() {
        return Err(format!("{}: no windows", path.display()));
    }
    if let Some(w) = windows
        .iter()
        .find(|w| w.id.trim().is_empty() || w.id.contains([',', '"', '\n', '\r']))
    {
        return Err(format!(
            "{}: window id {:?} is empty or holds a comma, quote or line break",
            path.display(),
            w.id
        ));
    }
    Ok(windows
        .into_iter()
        .map(|w| MarkerInit {
            id: w.id,
            window: PixelRect::new(w.x, w.y, w.w, w.h),
        })
        .collect())
}

fn track_folder(args: &Args) -> Result<(), Box<dyn std::error::Error>> {
    let paths = frame_paths(&args.frames_dir)?;
    let inits = read_inits(&args.init_json)?;
    let (mut decode_s, mut track_s) = (0.0, 0.0);
    let t = Instant::now();
    let first = decode(&paths[0])?;
    decode_s += t.elapsed().as_secs_f64();
    let t = Instant::now();
    let config = if args.paper {
        TrackerConfig {
            model: args.model,
            window: args.window,
            ..TrackerConfig::paper()
        }
    } else {
        TrackerConfig {
            window: args.window,
            ..TrackerConfig::for_model(args.model)
        }
    };
    let floor = config.hsv_mask.lower[1];
    let colour = !matches!(config.model, AppearanceModel::Gray { .. });
    // A colour model on a target without colour runs badly or not at all: say so first.
    for init in inits.iter().filter(|_| colour) {
        if let Some(s) = window_saturation(&first, init.window).filter(|&s| s < floor) {
            eprintln!(
                "warning: marker {}'s window has little colour (median saturation {s} of 255, \
                 under the colour mask's {floor}); the {} model tells it from gray \
                 surroundings poorly: --model gray is for black-and-white targets",
                init.id,
                args.model.name()
            );
        }
    }
    let mut tracker = Tracker::new(config, &first, None, &inits)
        .map_err(|e| format!("{}: {e}", paths[0].display()))?;
    track_s += t.elapsed().as_secs_f64();
    for (k, path) in paths.iter().enumerate().skip(1) {
        let t = Instant::now();
        let frame = decode(path)?;
        decode_s += t.elapsed().as_secs_f64();
        let t = Instant::now();
        // The tracker keeps this frame (no copy) and hands back the one before, dropped
        // here outside the timing as a borrowed frame would be.
        let spare = tracker
            .update_owned(frame, None)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        track_s += t.elapsed().as_secs_f64();
        drop(spare);
        if (k + 1) % 50 == 0 {
            eprintln!("tracked {} of {} frames", k + 1, paths.len());
        }
    }
    let output = Output {
        frames: paths.len(),
        markers: tracker.tracks().iter().map(marker_out).collect(),
        timing: Timing { decode_s, track_s },
    };
    let id_width = tracker
        .tracks()
        .iter()
        .map(|t| t.id.chars().count())
        .max()
        .unwrap_or(0)
        .max("marker".len());
    eprintln!(
        "{:<id_width$}  tracked  recovered  predicted  lost  longest loss (frames)",
        "marker"
    );
    for track in tracker.tracks() {
        let s = track.summary();
        eprintln!(
            "{:<id_width$}  {:>7}  {:>9}  {:>9}  {:>4}  {:>12}",
            track.id, s.tracked, s.recovered, s.predicted, s.lost, s.longest_loss_frames
        );
    }
    let json = serde_json::to_string_pretty(&output)?;
    match &args.out {
        Some(path) => {
            std::fs::write(path, json + "\n").map_err(|e| format!("{}: {e}", path.display()))?
        }
        None => println!("{json}"),
    }
    Ok(())
}

fn marker_out(track: &Track) -> MarkerOut {
    MarkerOut {
        id: track.id.clone(),
        centers: track
            .observations
            .iter()
            .map(|o| o.center.map(|c| [c.x, c.y]))
            .collect(),
        status: track.observations.iter().map(|o| o.status.name()).collect(),
        confidence: track.observations.iter().map(|o| o.confidence).collect(),
    }
}

/// Frames of the synthetic demo (1.5 s at 30 Hz: rest, pull, release, free swing).
const DEMO_FRAMES: usize = 45;
/// Kinect V2 colour frame rate, hertz.
const FPS_HZ: f64 = 30.0;
/// Pull from 0.1 s to the release at 0.4 s.
const PULL_S: [f64; 2] = [0.1, 0.4];
/// The colour camera at half resolution (960x540) keeps the demo quick; the paper's markers
/// are then 7–9 px wide.
const COLOR_SCALE: f64 = 0.5;

fn synthetic_demo() -> Result<(), Box<dyn std::error::Error>> {
    let seed = 11;
    let base = synth::demo_tree(seed);
    let mut config = SynthConfig::kinect_v2(2.2, 1.1, seed);
    config.calibration.color_camera = config.calibration.color_camera.scaled(COLOR_SCALE)?;
    // Each marker swings sideways (world x) with its own amplitude and frequency.
    let swings: Vec<(f64, f64, f64)> = (0..base.markers.len())
        .map(|k| {
            let u = k as f64 / base.markers.len().max(1) as f64;
            (
                0.02 + 0.05 * u,
                1.0 + 2.0 * ((k * 7) % 10) as f64 / 10.0,
                0.04,
            )
        })
        .collect();
    let displacement = |k: usize, t: f64| {
        let (amp, f_hz, zeta) = swings[k];
        if t <= PULL_S[0] {
            0.0
        } else if t <= PULL_S[1] {
            let u = (t - PULL_S[0]) / (PULL_S[1] - PULL_S[0]);
            amp * u * u * (3.0 - 2.0 * u)
        } else {
            let w = 2.0 * std::f64::consts::PI * f_hz;
            let wd = w * (1.0 - zeta * zeta).sqrt();
            let tr = t - PULL_S[1];
            amp * (-zeta * w * tr).exp() * ((wd * tr).cos() + zeta * w / wd * (wd * tr).sin())
        }
    };
    let t0 = Instant::now();
    let mut frames = Vec::with_capacity(DEMO_FRAMES);
    let mut truth: Vec<Vec<Option<Point2<f64>>>> = Vec::with_capacity(DEMO_FRAMES);
    for f in 0..DEMO_FRAMES {
        let t = f as f64 / FPS_HZ;
        let mut scene = base.clone();
        for (k, m) in scene.markers.iter_mut().enumerate() {
            m.center_m += Vector3::x() * displacement(k, t);
        }
        config.seed = seed.wrapping_add(f as u64);
        let frame = synth::render(&scene, &config)?;
        truth.push(
            frame
                .markers
                .iter()
                .map(|m| m.color_pixel.filter(|_| m.visible))
                .collect(),
        );
        frames.push(frame.color);
    }
    println!(
        "rendered  {DEMO_FRAMES} frames {}x{} of {} swinging markers ({:.1} s)",
        frames[0].width(),
        frames[0].height(),
        base.markers.len(),
        t0.elapsed().as_secs_f64()
    );
    // The user's windows: a square a little larger than each visible marker on frame 0.
    let size = 11;
    let tracked: Vec<usize> = (0..base.markers.len())
        .filter(|&k| truth.iter().all(|f| f[k].is_some()))
        .collect();
    let inits: Vec<MarkerInit> = tracked
        .iter()
        .filter_map(|&k| {
            let c = truth[0][k]?;
            Some(MarkerInit {
                id: base.markers[k].id.clone(),
                window: PixelRect::centered_at(c, size, size),
            })
        })
        .collect();
    let truth_tracked: Vec<Vec<Point2<f64>>> = truth
        .iter()
        .map(|f| tracked.iter().filter_map(|&k| f[k]).collect())
        .collect();
    for (name, tracker_config) in [
        ("ours", TrackerConfig::default()),
        ("paper", TrackerConfig::paper()),
    ] {
        let t = Instant::now();
        let mut tracker = Tracker::new(tracker_config, &frames[0], None, &inits)?;
        for frame in &frames[1..] {
            tracker.update(frame, None)?;
        }
        let track_s = t.elapsed().as_secs_f64();
        let s = score(tracker.tracks(), &truth_tracked, TOLERANCE_PX)?;
        println!(
            "{name:<6} {:.1} % of {} marker-frames within {TOLERANCE_PX} px, mean error {:.2} px, {} identity swaps, {} lost ({:.1} µs per marker and frame)",
            100.0 * s.fraction_within(),
            s.marker_frames,
            s.mean_error_px,
            s.identity_swaps,
            s.lost,
            track_s * 1e6 / s.marker_frames.max(1) as f64
        );
    }
    Ok(())
}
