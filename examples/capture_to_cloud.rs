//! Turns one frame of a recording (native or TUM layout) into a textured PLY point cloud.
//!
//! ```text
//! cargo run --release --example capture_to_cloud -- <RECORDING_DIR> [--frame N] [--calibration FILE] [--out cloud.ply]
//! ```
//!
//! Prints one JSON object to stdout: `{"points": <valid points>, "width": W, "height": H,
//! "bbox_min": [x,y,z], "bbox_max": [x,y,z]}` in metres, in the depth camera frame. Errors go
//! to stderr with a non-zero exit. With no arguments it writes a small synthetic native
//! recording under `target/treemocap-demo/recording` and converts its first frame.

use std::path::PathBuf;
use std::process::ExitCode;

use treemocap::kinect_io::synth::{self, SynthConfig};
use treemocap::kinect_io::{
    Calibration, CloudBuilder, CloudConfig, ColorFormat, PlyFormat, PointCloud, Recording,
    RecordingWriter, write_ply,
};

mod common;

const USAGE: &str =
    "usage: capture_to_cloud <RECORDING_DIR> [--frame N] [--calibration FILE] [--out cloud.ply]

RECORDING_DIR   a native recording (frames.csv + calibration.json) or a TUM RGB-D folder
                (rgb.txt + depth.txt; TUM's default intrinsics when it has no calibration)
--frame N       frame index, default 0
--calibration   our calibration JSON, or an iai_kinect2 folder / calib_*.yaml file
--out FILE      PLY to write, default cloud.ply

Prints {\"points\", \"width\", \"height\", \"bbox_min\", \"bbox_max\"} (metres, camera frame).
With no arguments, runs on a synthetic recording it writes under target/treemocap-demo.";

/// Colour written for points the colour camera does not see (PLY has no 'no colour').
const UNSEEN_RGB: [u8; 3] = [128, 128, 128];

/// The JSON printed to stdout (fields in this order).
#[derive(serde::Serialize)]
struct Summary {
    points: usize,
    width: u32,
    height: u32,
    bbox_min: [f64; 3],
    bbox_max: [f64; 3],
}

struct Args {
    dir: PathBuf,
    frame: usize,
    calibration: Option<PathBuf>,
    out: PathBuf,
}

fn parse_args(raw: Vec<String>) -> Result<Option<Args>, String> {
    let mut dir = None;
    let mut frame = 0;
    let mut calibration = None;
    let mut out = PathBuf::from("cloud.ply");
    let mut it = raw.into_iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "-h" | "--help" => return Ok(None),
            "--frame" => {
                let v = it.next().ok_or("--frame needs a value")?;
                frame = v
                    .parse()
                    .map_err(|_| format!("--frame {v:?} is not a frame index"))?;
            }
            "--calibration" => {
                calibration = Some(it.next().ok_or("--calibration needs a file")?.into())
            }
            "--out" => out = it.next().ok_or("--out needs a file")?.into(),
            s if s.starts_with("--") => return Err(format!("unknown option {s:?}\n\n{USAGE}")),
            s => {
                if dir.replace(PathBuf::from(s)).is_some() {
                    return Err(format!("more than one RECORDING_DIR\n\n{USAGE}"));
                }
            }
        }
    }
    let dir = dir.ok_or_else(|| format!("missing RECORDING_DIR\n\n{USAGE}"))?;
    Ok(Some(Args {
        dir,
        frame,
        calibration,
        out,
    }))
}

/// Write a two-frame synthetic native recording and return its directory.
fn demo_recording() -> Result<PathBuf, Box<dyn std::error::Error>> {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target"));
    let dir = target.join("treemocap-demo").join("recording");
    if dir.exists() {
        std::fs::remove_dir_all(&dir)?;
    }
    let scene = synth::demo_tree(3);
    let mut writer: Option<RecordingWriter> = None;
    for k in 0..2u64 {
        let config = SynthConfig::kinect_v2(2.2, 1.1, k);
        let frame = synth::render(&scene, &config)?;
        let w = match writer.as_mut() {
            Some(w) => w,
            None => writer.insert(RecordingWriter::create(
                &dir,
                &config.calibration,
                ColorFormat::Png,
            )?),
        };
        w.write_frame(k as f64 / 30.0, &frame.color, &frame.depth)?;
    }
    eprintln!("wrote a synthetic recording to {}", dir.display());
    Ok(dir)
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let raw: Vec<String> = std::env::args().skip(1).collect();
    let args = if raw.is_empty() {
        let dir = demo_recording()?;
        let out = dir.join("cloud.ply");
        Args {
            dir,
            frame: 0,
            calibration: None,
            out,
        }
    } else {
        match parse_args(raw)? {
            Some(a) => a,
            None => {
                println!("{USAGE}");
                return Ok(());
            }
        }
    };
    let recording = match &args.calibration {
        Some(path) => Recording::open_with_calibration(&args.dir, Calibration::read(path)?)?,
        None => Recording::open(&args.dir)?,
    };
    let frame = recording.frame(args.frame)?;
    let mut builder = CloudBuilder::new(recording.calibration(), CloudConfig::default())?;
    let cloud = builder.build(&frame.depth, &frame.color)?;
    write_ply(
        &PointCloud::from_textured(&cloud, UNSEEN_RGB),
        &args.out,
        PlyFormat::BinaryLittleEndian,
    )?;
    let (lo, hi) = cloud.bounding_box().ok_or("the cloud has no valid point")?;
    let summary = Summary {
        points: cloud.valid_count(),
        width: cloud.width(),
        height: cloud.height(),
        bbox_min: [lo.x, lo.y, lo.z],
        bbox_max: [hi.x, hi.y, hi.z],
    };
    println!("{}", serde_json::to_string(&summary)?);
    eprintln!("wrote {}", args.out.display());
    Ok(())
}

fn main() -> ExitCode {
    common::run("capture_to_cloud", run)
}
