//! The main job: capture a tree's motion, measure each marked branch's natural frequency and
//! damping, rebuild the static tree and animate it in wind with what was measured.
//!
//! ```text
//! cargo run --release --example pipeline                     # the synthetic twin
//! cargo run --release --example pipeline -- --recording DIR --markers markers.json
//! ```
//!
//! With no arguments it runs on a digital twin whose every true value is known (a procedural
//! tree with per-branch dynamics, red markers on chains of levels 1–3, a pull and release
//! simulated with beam-anim, rendered as a Kinect V2 capture at 30 fps) and prints the
//! paper's Table 1 with the truth, ours and the paper's method side by side. Everything is
//! written under `target/treemocap-demo/`: `report.md`, `report.json`, one SVG pair per
//! branch under `figures/`, `projection.png`, `tree.glb`, `tree.bvh`, `skeleton.json`,
//! `tracks.csv` and `angles.csv`. `docs/capture.md` describes the capture protocol and the
//! files of a real recording.

mod chain;
mod report;
mod twin;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};
use treemocap::beam_anim::{
    AnimConfig, BeamTree, DynamicsSpec, GlbOptions, MeasuredDynamics, PAPER_DYNAMICS, Pose,
    Simulation, write_bvh, write_glb,
};
use treemocap::kinect_io::synth::Renderer;
use treemocap::kinect_io::{ColorFormat, Recording, RecordingWriter, camera_to_world_z_up};
use treemocap::nalgebra::{Isometry3, Point2, Point3, Vector3};
use treemocap::space_colonize::synthetic::skeleton_error;
use treemocap::space_colonize::{ColonizeConfig, cylinders, reconstruct};

use chain::{BranchResult, Capture, CaptureSetup, MarkerSpec, RawFrame};
use report::{BranchRow, write_atomic};
use twin::{Twin, TwinConfig};

const USAGE: &str = "usage: pipeline [--out-dir DIR] [--threads N]
                [--seed N] [--fps HZ] [--distance M] [--marker-radius M]
                [--noise SCALE] [--chains N] [--window-error PX]
       pipeline --recording DIR --markers markers.json [--out-dir DIR] [--threads N]
       pipeline --write-recording DIR [twin options]

With no recording: the synthetic twin (a tree with known dynamics, filmed by a simulated
Kinect V2), measured and compared with the truth. With --recording: a real recording in the
native or TUM layout (docs/recording-format.md) and the markers of markers.json
(docs/capture.md). Results go to DIR (default target/treemocap-demo). --write-recording saves
the twin's capture as a native recording with its markers.json, to try the --recording path
on.";

/// Share of the colour camera's resolution the projection image is drawn at when the colour
/// image is wider than this many pixels (the Kinect V2's 1920 → 960: markers of 3 cm are then
/// 7 px wide at 2.2 m, and the image holds every depth pixel without holes).
const PLANE_MAX_WIDTH_PX: u32 = 1920;
/// A tracked centre within this distance of the truth is on the marker (pixels of the
/// tracking plane; the tracker's own accuracy goal, meanshift-track).
const TRACK_TOLERANCE_PX: f64 = 3.0;
/// Frames of the still tree accumulated for the static reconstruction.
const STATIC_FRAMES: usize = 5;
/// Points lower than this above the ground are the ground (metres).
const GROUND_CLEARANCE_M: f64 = 0.04;
/// Points kept for the reconstruction lie within this distance (metres, along the camera's
/// view) of the nearest and furthest marker.
const CROP_MARGIN_M: f64 = 0.5;
/// Length of the wind animation, seconds, and its mean wind speed, m/s.
const ANIMATION_S: f64 = 10.0;
const WIND_SPEED_M_S: f64 = 4.0;

struct Args {
    out_dir: PathBuf,
    threads: usize,
    twin: TwinConfig,
    recording: Option<PathBuf>,
    markers: Option<PathBuf>,
    write_recording: Option<PathBuf>,
}

fn parse_args() -> Result<Option<Args>, String> {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target"));
    let mut args = Args {
        out_dir: target.join("treemocap-demo"),
        threads: std::thread::available_parallelism().map_or(2, |n| n.get()),
        twin: TwinConfig::default(),
        recording: None,
        markers: None,
        write_recording: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or(format!("{name} needs a value\n\n{USAGE}"));
        let number = |name: &str, v: String| -> Result<f64, String> {
            v.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or(format!("{name} {v:?} is not a number"))
        };
        match a.as_str() {
            "-h" | "--help" => return Ok(None),
            "--out-dir" => args.out_dir = value(&a)?.into(),
            "--recording" => args.recording = Some(value(&a)?.into()),
            "--markers" => args.markers = Some(value(&a)?.into()),
            "--write-recording" => args.write_recording = Some(value(&a)?.into()),
            "--threads" => {
                let v = value(&a)?;
                args.threads = v
                    .parse()
                    .ok()
                    .filter(|n| *n > 0)
                    .ok_or(format!("--threads {v:?} is not a positive whole number"))?;
            }
            "--seed" => {
                let v = value(&a)?;
                args.twin.seed = v
                    .parse()
                    .map_err(|_| format!("--seed {v:?} is not a number"))?;
            }
            "--chains" => {
                let v = value(&a)?;
                args.twin.chains = v
                    .parse()
                    .map_err(|_| format!("--chains {v:?} is not a number"))?;
            }
            "--fps" => args.twin.fps_hz = number(&a, value(&a)?)?,
            "--distance" => args.twin.distance_m = number(&a, value(&a)?)?,
            "--marker-radius" => args.twin.marker_radius_m = number(&a, value(&a)?)?,
            "--noise" => args.twin.noise_scale = number(&a, value(&a)?)?,
            "--window-error" => args.twin.window_error_px = number(&a, value(&a)?)?,
            other => return Err(format!("unknown argument {other:?}\n\n{USAGE}")),
        }
    }
    if args.recording.is_some() != args.markers.is_some() {
        return Err(format!(
            "--recording and --markers go together (one names the frames, the other the markers)\n\n{USAGE}"
        ));
    }
    Ok(Some(args))
}

/// Progress of a long stage on stderr, one line rewritten in place.
struct Progress {
    stage: &'static str,
    last: Instant,
}

impl Progress {
    fn new(stage: &'static str) -> Self {
        Self {
            stage,
            last: Instant::now(),
        }
    }
    fn update(&mut self, done: usize, total: usize) {
        if done == total || self.last.elapsed().as_secs_f64() > 0.5 {
            self.last = Instant::now();
            eprint!(
                "\r{:<12} {done}/{total} ({:.0} %)   ",
                self.stage,
                100.0 * done as f64 / total.max(1) as f64
            );
            if done == total {
                eprintln!();
            }
        }
    }
}

fn main() {
    let started = Instant::now();
    let args = match parse_args() {
        Ok(Some(args)) => args,
        Ok(None) => {
            println!("{USAGE}");
            return;
        }
        Err(e) => {
            eprintln!("pipeline: {e}");
            std::process::exit(2);
        }
    };
    let result = match (&args.recording, &args.write_recording) {
        (None, Some(dir)) => write_recording(&args, dir),
        (None, None) => run_twin(&args, started),
        (Some(dir), _) => run_recording(
            &args,
            dir,
            args.markers.as_deref().unwrap_or(Path::new("")),
            started,
        ),
    };
    if let Err(e) = result {
        eprintln!("pipeline: {e}");
        std::process::exit(1);
    }
}

/// What the chain measured, ready for the report.
struct Measured {
    capture: Capture,
    branches: Vec<BranchResult>,
    dropped: Vec<(String, String)>,
    cloud_to_tree: Isometry3<f64>,
}

fn measure(
    setup: &CaptureSetup,
    frames: usize,
    produce: &(dyn Fn(usize) -> Result<RawFrame, String> + Sync),
    cloud_to_tree: Isometry3<f64>,
    windows_s: &BTreeMap<String, (f64, f64)>,
) -> Result<Measured, String> {
    let mut progress = Progress::new("capture");
    let capture = chain::capture(setup, frames, produce, &mut |d, n| progress.update(d, n))?;
    let mut dropped = capture.dropped.clone();
    let hierarchy = chain::hierarchy(&setup.markers, &capture.ids, &mut dropped)?;
    let trajectories = chain::trajectories(&capture, &hierarchy, &cloud_to_tree)?;
    let branches = chain::analyse(
        &hierarchy,
        &trajectories,
        Vector3::z(),
        windows_s,
        &chain::tracked_fractions(&capture),
    )?;
    Ok(Measured {
        capture,
        branches,
        dropped,
        cloud_to_tree,
    })
}

fn run_twin(args: &Args, started: Instant) -> Result<(), String> {
    let t = Instant::now();
    let twin = Twin::build(&args.twin)?;
    println!(
        "twin      {} skeleton nodes, {} markers ({} branches of levels 1-3), {} frames at {} fps, release at {} s ({:.1} s)",
        twin.skeleton.nodes().len(),
        twin.markers.len(),
        twin.markers.len() - 1,
        twin.times_s.len(),
        twin.config.fps_hz,
        twin.release_s,
        t.elapsed().as_secs_f64()
    );
    let renderer = Renderer::new(&twin.synth).map_err(|e| format!("renderer: {e}"))?;
    let setup = twin.capture_setup(
        &renderer,
        plane_scale(twin.synth.calibration.color_camera.width),
        STATIC_FRAMES,
        args.threads,
    )?;
    let produce = |i: usize| twin.frame(&renderer, i);
    let tree_to_depth = twin.synth.world_to_depth;
    let windows_s = twin.windows_s();
    let measured = measure(
        &setup,
        twin.times_s.len(),
        &produce,
        tree_to_depth.inverse(),
        &windows_s,
    )?;
    // Lift error against the truth.
    let mut errors_mm = Vec::new();
    for (k, id) in measured.capture.ids.iter().enumerate() {
        let Some(m) = twin.scenes[0].markers.iter().position(|m| m.id == *id) else {
            continue;
        };
        for (f, p) in measured.capture.positions_m[k].iter().enumerate() {
            if let Some(p) = p {
                let truth = tree_to_depth * twin.scenes[f].markers[m].center_m;
                errors_mm.push((p - truth).norm() * 1e3);
            }
        }
    }
    // The tracked centre against the marker's true centre on the tracking plane.
    let mut within_3px = BTreeMap::new();
    for (k, id) in measured.capture.ids.iter().enumerate() {
        let Some(m) = twin.scenes[0].markers.iter().position(|m| m.id == *id) else {
            continue;
        };
        let near = measured.capture.centers[k]
            .iter()
            .enumerate()
            .filter(|(f, c)| {
                let p =
                    setup.cloud_to_plane * (tree_to_depth * twin.scenes[*f].markers[m].center_m);
                match (c, setup.plane.project(&p)) {
                    (Some(c), Some(t)) => (c - t).norm() <= TRACK_TOLERANCE_PX,
                    _ => false,
                }
            })
            .count();
        within_3px.insert(
            id.clone(),
            near as f64 / measured.capture.times_s.len().max(1) as f64,
        );
    }
    let truth = |id: &str| {
        twin.markers
            .iter()
            .find(|m| m.id == id)
            .map(|m| (m.truth.frequency_hz, m.truth.damping_ratio))
    };
    finish(
        args,
        started,
        &measured,
        &within_3px,
        Some(&twin.skeleton),
        &truth,
        median(errors_mm),
    )
}

/// The twin's capture as a native recording (JPEG colour at quality 95, as the Kinect V2
/// delivers it; 16-bit depth) and its
/// `markers.json` (windows on the first colour image, each branch's test window).
fn write_recording(args: &Args, dir: &Path) -> Result<(), String> {
    let twin = Twin::build(&args.twin)?;
    let renderer = Renderer::new(&twin.synth).map_err(|e| format!("renderer: {e}"))?;
    let windows = twin.windows(&renderer, 1.0)?;
    let mut writer = RecordingWriter::create(
        dir,
        &twin.synth.calibration,
        ColorFormat::Jpeg { quality: 95 },
    )
    .map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut progress = Progress::new("record");
    for i in 0..twin.scenes.len() {
        let frame = twin.frame(&renderer, i)?;
        writer
            .write_frame(frame.time_s, &frame.color, &frame.depth)
            .map_err(|e| format!("{}: frame {i}: {e}", dir.display()))?;
        progress.update(i + 1, twin.scenes.len());
    }
    let markers: Vec<serde_json::Value> = twin
        .markers
        .iter()
        .zip(&windows)
        .map(|(m, w)| {
            let half = f64::from(w.size_px) / 2.0;
            let mut v = serde_json::json!({
                "id": m.id,
                "parent": m.parent,
                "x": (w.center.x - half).round(),
                "y": (w.center.y - half).round(),
                "w": w.size_px,
                "h": w.size_px,
            });
            if m.level > 0 {
                v["window_s"] = serde_json::json!([m.window_s.0, m.window_s.1]);
            }
            v
        })
        .collect();
    let camera = twin.synth.world_to_depth.inverse() * Point3::origin();
    let file = serde_json::json!({
        "camera_height_m": camera.z,
        "pitch_down_deg": 0.0,
        "markers": markers,
    });
    let text = serde_json::to_string_pretty(&file).map_err(|e| e.to_string())? + "\n";
    write_atomic(&dir.join("markers.json"), text.as_bytes())?;
    println!(
        "wrote     {} ({} frames, native layout) and its markers.json; run it with\n          cargo run --release --example pipeline -- --recording {} --markers {}",
        dir.display(),
        twin.scenes.len(),
        dir.display(),
        dir.join("markers.json").display()
    );
    Ok(())
}

fn plane_scale(color_width: u32) -> f64 {
    if color_width > PLANE_MAX_WIDTH_PX {
        f64::from(PLANE_MAX_WIDTH_PX) / f64::from(color_width)
    } else {
        1.0
    }
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

/// The markers file of a real recording.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MarkersFile {
    markers: Vec<MarkerEntry>,
    /// Camera height above the ground, metres (for the Z-up tree frame). Default 1.0.
    #[serde(default)]
    camera_height_m: Option<f64>,
    /// Camera pitch below the horizon, degrees. Default 0 (level).
    #[serde(default)]
    pitch_down_deg: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MarkerEntry {
    id: String,
    parent: Option<String>,
    /// Window on the first colour image: top-left corner and size, pixels.
    x: f64,
    y: f64,
    w: f64,
    h: f64,
    /// The branch's own pull-and-release test, seconds from the first frame: the branch is
    /// measured inside it only. Default: the whole recording.
    #[serde(default)]
    window_s: Option<[f64; 2]>,
}

fn read_markers(path: &Path) -> Result<MarkersFile, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let file: MarkersFile =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    if file.markers.is_empty() {
        return Err(format!("{}: no markers", path.display()));
    }
    let roots: Vec<&str> = file
        .markers
        .iter()
        .filter(|m| m.parent.is_none())
        .map(|m| m.id.as_str())
        .collect();
    if roots.len() != 1 {
        let found = if roots.is_empty() {
            "none has".to_string()
        } else {
            format!("{} have ({})", roots.len(), roots.join(", "))
        };
        return Err(format!(
            "{}: exactly one marker must have \"parent\": null (the trunk's, the root of the hierarchy); {found}",
            path.display()
        ));
    }
    for m in &file.markers {
        if m.id.trim().is_empty() || m.id.contains([',', '"', '\n', '\r']) {
            return Err(format!(
                "{}: marker id {:?} is empty or holds a comma, quote or line break",
                path.display(),
                m.id
            ));
        }
        if file.markers.iter().filter(|q| q.id == m.id).count() > 1 {
            return Err(format!(
                "{}: marker id {:?} appears twice",
                path.display(),
                m.id
            ));
        }
        if let Some(p) = &m.parent
            && !file.markers.iter().any(|q| q.id == *p)
        {
            return Err(format!(
                "{}: marker {} names parent {p:?}, which is not in the file",
                path.display(),
                m.id
            ));
        }
        if let Some([start, end]) = m.window_s
            && !(start.is_finite() && end.is_finite() && start >= 0.0 && start < end)
        {
            return Err(format!(
                "{}: marker {}: window_s [{start}, {end}] must be [start, end] in seconds from the first frame, 0 <= start < end",
                path.display(),
                m.id
            ));
        }
        if ![m.x, m.y, m.w, m.h].iter().all(|v| v.is_finite()) || m.w < 3.0 || m.h < 3.0 {
            return Err(format!(
                "{}: marker {}: window x {}, y {}, w {}, h {} must be finite and at least 3 px wide",
                path.display(),
                m.id,
                m.x,
                m.y,
                m.w,
                m.h
            ));
        }
    }
    Ok(file)
}

fn run_recording(
    args: &Args,
    dir: &Path,
    markers_path: &Path,
    started: Instant,
) -> Result<(), String> {
    let file = read_markers(markers_path)?;
    let recording = Recording::open(dir).map_err(|e| {
        format!(
            "{}: {e} (a native recording needs calibration.json; see docs/recording-format.md)",
            dir.display()
        )
    })?;
    if recording.len() < 2 {
        return Err(format!(
            "{}: {} frames; a capture needs at least 2",
            dir.display(),
            recording.len()
        ));
    }
    let calibration = recording.calibration().clone();
    let color = calibration.color_camera;
    // Each window on the first colour image, and each measuring window inside the recording.
    let t_first = recording.entries()[0].timestamp_s;
    let duration_s = recording
        .entries()
        .last()
        .map_or(0.0, |e| e.timestamp_s - t_first);
    let frame_s = duration_s / (recording.len() - 1) as f64;
    for m in &file.markers {
        let (w, h) = (f64::from(color.width), f64::from(color.height));
        if m.x < 0.0 || m.y < 0.0 || m.x + m.w > w || m.y + m.h > h {
            return Err(format!(
                "{}: marker {}: window x {}, y {}, w {}, h {} is not inside the {}x{} px colour image",
                markers_path.display(),
                m.id,
                m.x,
                m.y,
                m.w,
                m.h,
                color.width,
                color.height
            ));
        }
        if let Some([start, end]) = m.window_s
            && (start >= duration_s || end > duration_s + frame_s)
        {
            return Err(format!(
                "{}: marker {}: window_s [{start}, {end}] s is not inside the recording (0 to {duration_s:.3} s)",
                markers_path.display(),
                m.id
            ));
        }
    }
    let plane_scale = plane_scale(color.width);
    let plane = color
        .scaled(plane_scale)
        .map_err(|e| format!("projection plane: {e}"))?;
    let cloud_to_plane = calibration
        .depth_to_color()
        .map_err(|e| format!("{}: calibration: {e}", dir.display()))?
        .ok_or_else(|| {
            format!(
                "{}: the calibration has no rigid depth-to-colour transform (libfreenect2's model): the projection image needs one",
                dir.display()
            )
        })?;
    let markers: Vec<MarkerSpec> = file
        .markers
        .iter()
        .map(|m| MarkerSpec {
            id: m.id.clone(),
            parent: m.parent.clone(),
            center: Point2::new(
                (m.x + 0.5 * m.w) * plane_scale,
                (m.y + 0.5 * m.h) * plane_scale,
            ),
            size_px: (0.5 * (m.w + m.h) * plane_scale).round() as i32,
        })
        .collect();
    println!(
        "recording {} ({:?} layout): {} frames, {} markers",
        dir.display(),
        recording.layout(),
        recording.len(),
        markers.len()
    );
    let setup = CaptureSetup {
        calibration,
        plane,
        cloud_to_plane,
        markers,
        static_frames: STATIC_FRAMES,
        threads: args.threads,
    };
    let t0 = recording.entries()[0].timestamp_s;
    let produce = |i: usize| -> Result<RawFrame, String> {
        let frame = recording
            .frame(i)
            .map_err(|e| format!("{}: frame {i}: {e}", dir.display()))?;
        Ok(RawFrame {
            time_s: frame.timestamp_s - t0,
            depth: frame.depth,
            color: frame.color,
        })
    };
    let height = file.camera_height_m.unwrap_or(1.0);
    let pitch = file.pitch_down_deg.unwrap_or(0.0).to_radians();
    let windows_s: BTreeMap<String, (f64, f64)> = file
        .markers
        .iter()
        .filter_map(|m| m.window_s.map(|w| (m.id.clone(), (w[0], w[1]))))
        .collect();
    let duration_s = recording
        .entries()
        .last()
        .map_or(0.0, |e| e.timestamp_s - t0);
    for (id, (start, _)) in &windows_s {
        if *start >= duration_s {
            return Err(format!(
                "{}: marker {id}: window_s starts at {start} s, after the recording ends ({duration_s:.3} s)",
                markers_path.display()
            ));
        }
    }
    let measured = measure(
        &setup,
        recording.len(),
        &produce,
        camera_to_world_z_up(height, pitch),
        &windows_s,
    )?;
    finish(
        args,
        started,
        &measured,
        &BTreeMap::new(),
        None,
        &|_| None,
        None,
    )
}

#[derive(Serialize)]
struct ReportJson {
    branches: Vec<BranchRow>,
    dropped_markers: Vec<Dropped>,
    tracking: TrackingJson,
    reconstruction: ReconstructionJson,
    animation: AnimationJson,
    timing: TimingJson,
    seconds: f64,
}

#[derive(Serialize)]
struct Dropped {
    id: String,
    reason: String,
}

#[derive(Serialize)]
struct TrackingJson {
    frames: usize,
    markers: Vec<MarkerTracking>,
    median_lift_error_mm: Option<f64>,
}

#[derive(Serialize)]
struct MarkerTracking {
    id: String,
    tracked_fraction: f64,
    lifted_fraction: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    within_3px_fraction: Option<f64>,
}

#[derive(Serialize)]
struct ReconstructionJson {
    points: usize,
    nodes: usize,
    branches: usize,
    total_length_m: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    mean_skeleton_error_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    p95_skeleton_error_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    truth_length_found: Option<f64>,
    seconds: f64,
}

#[derive(Serialize)]
struct AnimationJson {
    frames: usize,
    wind_speed_m_s: f64,
    measured_branches: usize,
    glb: String,
    bvh: String,
}

#[derive(Serialize)]
struct TimingJson {
    capture_s: f64,
    frames_and_clouds_cpu_s: f64,
    tracking_and_lifting_s: f64,
}

#[allow(clippy::too_many_arguments)]
fn finish(
    args: &Args,
    started: Instant,
    measured: &Measured,
    within_3px: &BTreeMap<String, f64>,
    truth_skeleton: Option<&treemocap::space_colonize::Skeleton>,
    truth: &dyn Fn(&str) -> Option<(f64, f64)>,
    median_lift_error_mm: Option<f64>,
) -> Result<(), String> {
    let capture = &measured.capture;
    let tracked = chain::tracked_fractions(capture);
    let capture_s = started.elapsed().as_secs_f64();
    let out = &args.out_dir;
    std::fs::create_dir_all(out.join("figures")).map_err(|e| format!("{}: {e}", out.display()))?;

    // Reconstruction from the still frames' clouds.
    let t = Instant::now();
    eprintln!(
        "reconstruct  {} points of {} still frames",
        capture.static_points_m.len(),
        STATIC_FRAMES.min(capture.times_s.len())
    );
    // The tree stands within reach of its markers: points further in front or behind (the
    // ground beyond, a wall, flying pixels mixing a branch with the background) are not it.
    let marker_depths: Vec<f64> = capture
        .positions_m
        .iter()
        .filter_map(|track| track.iter().take(STATIC_FRAMES).flatten().next())
        .map(|p| (measured.cloud_to_tree * p).y)
        .collect();
    let near = marker_depths.iter().copied().fold(f64::INFINITY, f64::min) - CROP_MARGIN_M;
    let far = marker_depths
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max)
        + CROP_MARGIN_M;
    let points: Vec<Point3<f64>> = capture
        .static_points_m
        .iter()
        .map(|p| measured.cloud_to_tree * p)
        .filter(|p| p.z > GROUND_CLEARANCE_M && (near..=far).contains(&p.y))
        .collect();
    let recon = reconstruct(&points, &ColonizeConfig::default())
        .map_err(|e| format!("reconstruction from {} points: {e}", points.len()))?;
    let recon_s = t.elapsed().as_secs_f64();
    let error = truth_skeleton.map(|s| skeleton_error(&recon.skeleton, s));

    // Measured dynamics onto the reconstruction, then wind.
    let t = Instant::now();
    let rest_position = |id: &str| -> Option<[f64; 3]> {
        let k = capture.ids.iter().position(|x| x == id)?;
        let known: Vec<Point3<f64>> = capture.positions_m[k]
            .iter()
            .take(STATIC_FRAMES.max(1))
            .flatten()
            .map(|p| measured.cloud_to_tree * p)
            .collect();
        let n = known.len();
        (n > 0).then(|| {
            let c = known.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n as f64;
            [c.x, c.y, c.z]
        })
    };
    let measured_dynamics: Vec<MeasuredDynamics> = measured
        .branches
        .iter()
        .filter_map(|b| {
            let m = b.ours?;
            Some(MeasuredDynamics {
                position: rest_position(&b.id)?,
                frequency_hz: m.frequency_hz,
                damping_ratio: m.damping_ratio,
            })
        })
        .collect();
    let spec = DynamicsSpec {
        default: PAPER_DYNAMICS,
        measured: measured_dynamics.clone(),
        ..DynamicsSpec::default()
    };
    let config = AnimConfig {
        wind: treemocap::beam_anim::WindConfig {
            mean_speed_m_s: WIND_SPEED_M_S,
            ..AnimConfig::default().wind
        },
        ..AnimConfig::default()
    };
    let beam = BeamTree::new(
        &recon.skeleton,
        config.wood_density_kg_m3,
        &config.wind.direction,
    )
    .map_err(|e| format!("animation beams: {e}"))?;
    let assignment = spec.assign(&beam).map_err(|e| format!("dynamics: {e}"))?;
    let fps = 30.0;
    let mut sim = Simulation::new(beam, &assignment.dynamics, config, 1.0 / fps)
        .map_err(|e| format!("animation: {e}"))?;
    let mut wind = sim.wind_field().map_err(|e| format!("wind: {e}"))?;
    let frames = (ANIMATION_S * fps) as usize;
    let mut poses: Vec<Pose> = Vec::with_capacity(frames + 1);
    poses.push(sim.pose().clone());
    let mut progress = Progress::new("animate");
    for k in 0..frames {
        sim.step(&mut wind).map_err(|e| format!("animation: {e}"))?;
        poses.push(sim.pose().clone());
        progress.update(k + 1, frames);
    }
    let glb = out.join("tree.glb");
    let bvh = out.join("tree.bvh");
    write_glb(&glb, &sim, &poses, &GlbOptions::default()).map_err(|e| e.to_string())?;
    write_bvh(&bvh, &sim, &poses).map_err(|e| e.to_string())?;
    let anim_s = t.elapsed().as_secs_f64();

    // Report.
    let rows: Vec<BranchRow> = measured
        .branches
        .iter()
        .map(|b| BranchRow::new(b, truth(&b.id)))
        .collect();
    for (b, row) in measured.branches.iter().zip(&rows) {
        let base = out.join("figures").join(format!("branch_{}", b.id));
        write_atomic(
            &base.with_extension("angle.svg"),
            report::series_svg(b).as_bytes(),
        )?;
        write_atomic(
            &base.with_extension("spectrum.svg"),
            report::spectrum_svg(b, row.true_frequency_hz).as_bytes(),
        )?;
    }
    let table = report::table(&rows);
    println!("\n{table}");
    for (id, reason) in &measured.dropped {
        println!("marker {id} left out: {reason}");
    }
    for r in &rows {
        for n in &r.notes {
            println!("branch {}: {n}", r.id);
        }
    }
    let worst = |v: &mut dyn Iterator<Item = f64>| v.fold(1.0, f64::min) * 100.0;
    let min_tracked = worst(&mut tracked.values().copied());
    let min_lifted = worst(&mut rows.iter().map(|r| r.lifted_fraction));
    let near = if within_3px.is_empty() {
        String::new()
    } else {
        format!(
            ", within {TRACK_TOLERANCE_PX} px of the truth on {:.1} %",
            worst(&mut within_3px.values().copied())
        )
    };
    println!(
        "tracking  {} markers over {} frames: worst marker tracked on {min_tracked:.1} % of frames{near}, lifted to 3D on {min_lifted:.1} %{}",
        capture.ids.len(),
        capture.times_s.len(),
        median_lift_error_mm.map_or(String::new(), |e| format!(", median lift error {e:.2} mm"))
    );
    // Wood length as TreeQSM counts it: each branch from its parent's surface.
    let wood_m: f64 = cylinders(&recon.skeleton).iter().map(|c| c.length_m).sum();
    println!(
        "rebuild   {} points -> {} nodes, {} branches, {wood_m:.2} m of wood{} ({recon_s:.2} s)",
        points.len(),
        recon.skeleton.nodes().len(),
        recon.branches.len(),
        error.map_or(String::new(), |e| format!(
            ", mean skeleton error {:.1} mm (p95 {:.1} mm), {:.0} % of the true length found",
            e.mean_skeleton_error_m * 1e3,
            e.p95_skeleton_error_m * 1e3,
            100.0 * e.truth_length_found
        ))
    );
    println!(
        "animate   {} of {} branches measured, the rest by level or default; {} frames in {WIND_SPEED_M_S} m/s wind ({anim_s:.2} s)",
        assignment
            .source
            .iter()
            .filter(|s| matches!(s, treemocap::beam_anim::DynamicsSource::Measured(_)))
            .count(),
        assignment.source.len(),
        poses.len()
    );
    let seconds = started.elapsed().as_secs_f64();
    let json = ReportJson {
        branches: rows.clone(),
        dropped_markers: measured
            .dropped
            .iter()
            .map(|(id, reason)| Dropped {
                id: id.clone(),
                reason: reason.clone(),
            })
            .collect(),
        tracking: TrackingJson {
            frames: capture.times_s.len(),
            markers: capture
                .ids
                .iter()
                .enumerate()
                .map(|(k, id)| MarkerTracking {
                    id: id.clone(),
                    tracked_fraction: tracked.get(id).copied().unwrap_or(0.0),
                    // After the jump filter, as the angles saw them (the root's as lifted).
                    lifted_fraction: rows.iter().find(|r| r.id == *id).map_or_else(
                        || {
                            capture.positions_m[k]
                                .iter()
                                .filter(|p| p.is_some())
                                .count() as f64
                                / capture.times_s.len().max(1) as f64
                        },
                        |r| r.lifted_fraction,
                    ),
                    within_3px_fraction: within_3px.get(id).copied(),
                })
                .collect(),
            median_lift_error_mm,
        },
        reconstruction: ReconstructionJson {
            points: points.len(),
            nodes: recon.skeleton.nodes().len(),
            branches: recon.branches.len(),
            total_length_m: wood_m,
            mean_skeleton_error_m: error.map(|e| e.mean_skeleton_error_m),
            p95_skeleton_error_m: error.map(|e| e.p95_skeleton_error_m),
            truth_length_found: error.map(|e| e.truth_length_found),
            seconds: recon_s,
        },
        animation: AnimationJson {
            frames: poses.len(),
            wind_speed_m_s: WIND_SPEED_M_S,
            measured_branches: measured_dynamics.len(),
            glb: glb.display().to_string(),
            bvh: bvh.display().to_string(),
        },
        timing: TimingJson {
            capture_s,
            frames_and_clouds_cpu_s: capture.produce_s,
            tracking_and_lifting_s: capture.track_s,
        },
        seconds,
    };
    let json_text = serde_json::to_string_pretty(&json).map_err(|e| e.to_string())? + "\n";
    write_atomic(&out.join("report.json"), json_text.as_bytes())?;
    let mut md = String::from("# treemocap pipeline report\n\n");
    md.push_str(&table);
    md.push('\n');
    for (id, reason) in &measured.dropped {
        md.push_str(&format!("- marker {id} left out: {reason}\n"));
    }
    md.push_str(&format!(
        "\nFrames: {}. Reconstruction: {} nodes, {} branches{}. Whole run: {seconds:.1} s.\n\nFigures: `figures/branch_<id>.angle.svg`, `figures/branch_<id>.spectrum.svg`.\n",
        capture.times_s.len(),
        recon.skeleton.nodes().len(),
        recon.branches.len(),
        error.map_or(String::new(), |e| format!(
            ", mean skeleton error {:.1} mm",
            e.mean_skeleton_error_m * 1e3
        ))
    ));
    write_atomic(&out.join("report.md"), md.as_bytes())?;
    capture
        .first_projection
        .save(out.join("projection.png"))
        .map_err(|e| format!("projection.png: {e}"))?;
    recon
        .skeleton
        .write_json(&out.join("skeleton.json"))
        .map_err(|e| e.to_string())?;
    println!(
        "wrote     {} (report.md, report.json, figures/, tree.glb, tree.bvh, skeleton.json, projection.png)",
        out.display()
    );
    println!(
        "timing    capture {capture_s:.1} s (frames and clouds {:.1} s of CPU on {} threads, tracking and lifting {:.1} s), reconstruction {recon_s:.2} s, animation and export {anim_s:.2} s",
        capture.produce_s, args.threads, capture.track_s
    );
    println!("seconds   {seconds:.1}");
    if rows.iter().all(|r| r.frequency_hz.is_none()) {
        return Err(format!(
            "no branch could be measured (every row of the table is `-`; the report in {} says why for each)",
            out.display()
        ));
    }
    Ok(())
}
