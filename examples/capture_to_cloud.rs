//! Turns one frame of a recording (native or TUM folder, Azure Kinect / Orbbec Femto `.mkv`,
//! RealSense or Orbbec `.bag`) into a textured PLY point cloud.
//!
//! ```text
//! cargo run --release --example capture_to_cloud -- <RECORDING> [--frame N] [--calibration FILE] [--out cloud.ply]
//! ```
//!
//! Prints one JSON object to stdout: `{"points": <valid points>, "width": W, "height": H,
//! "bbox_min": [x,y,z], "bbox_max": [x,y,z]}` in metres, in the depth camera frame. Errors go
//! to stderr with a non-zero exit. With no arguments it writes a small synthetic native
//! recording under `target/treemocap-demo/capture_to_cloud/` and converts its first frame.
//! The cloud stays in the depth camera's frame (y down): `reconstruct_tree CLOUD --up -y`
//! grows a tree model from it (for a level camera; a capture's background is grown too,
//! so crop the tree first).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use treemocap::kinect_io::synth::{self, SynthConfig};
use treemocap::kinect_io::{
    Calibration, CloudBuilder, CloudConfig, ColorFormat, PlyFormat, PointCloud, Recording,
    RecordingWriter, write_ply,
};

mod common;

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

/// One frame of a recording (native or TUM folder, Azure Kinect .mkv, RealSense/Orbbec .bag) as a
/// textured PLY point cloud.
///
/// Prints {"points", "width", "height", "bbox_min", "bbox_max"} (metres, depth camera
/// frame). With no arguments, runs on a synthetic recording it writes under
/// target/treemocap-demo/capture_to_cloud.
#[derive(Parser, Debug)]
#[command(name = "capture_to_cloud", version, about)]
struct Args {
    /// A native recording (frames.csv + calibration.json), a TUM RGB-D folder (rgb.txt +
    /// depth.txt; TUM's default intrinsics when it has no calibration), an Azure Kinect /
    /// Orbbec Femto .mkv or a RealSense / Orbbec SDK v2 .bag (calibration read from the file)
    #[arg(value_name = "RECORDING")]
    dir: Option<PathBuf>,
    /// Frame index
    #[arg(long, value_name = "N", default_value_t = 0, requires = "dir")]
    frame: usize,
    /// Our calibration JSON, or an iai_kinect2 folder / calib_*.yaml file
    #[arg(long, value_name = "FILE", requires = "dir")]
    calibration: Option<PathBuf>,
    /// PLY to write [default: cloud.ply, or the demo folder's]
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
}

/// Write a two-frame synthetic native recording and return its directory.
fn demo_recording() -> Result<PathBuf, Box<dyn std::error::Error>> {
    let dir = common::demo_dir("capture_to_cloud").join("recording");
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

fn run(args: Args) -> Result<(), Box<dyn std::error::Error>> {
    let (dir, out) = match args.dir {
        Some(dir) => (dir, args.out.unwrap_or_else(|| PathBuf::from("cloud.ply"))),
        None => {
            let dir = demo_recording()?;
            let out = args
                .out
                .unwrap_or_else(|| common::demo_dir("capture_to_cloud").join("cloud.ply"));
            (dir, out)
        }
    };
    let recording = match &args.calibration {
        Some(path) => Recording::open_with_calibration(&dir, Calibration::read(path)?)?,
        None => Recording::open(&dir)?,
    };
    let frame = recording.frame(args.frame)?;
    let mut builder = CloudBuilder::new(recording.calibration(), CloudConfig::default())?;
    let cloud = builder.build(&frame.depth, &frame.color)?;
    write_ply(
        &PointCloud::from_textured(&cloud, UNSEEN_RGB),
        &out,
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
    eprintln!(
        "wrote {} (the depth camera's frame: x right, y down, z forward; for a tree model \
         of it, `reconstruct_tree {} --up -y`)",
        out.display(),
        out.display()
    );
    Ok(())
}

fn main() -> ExitCode {
    let args = Args::parse();
    common::run("capture_to_cloud", || run(args))
}
