//! The main job, on an embedded default: a synthetic Kinect V2 capture of a tree with red
//! markers, its textured cloud and projection image, and the markers lifted back to 3D.
//!
//! ```text
//! cargo run --release --example pipeline [-- --seed N] [--out-dir DIR]
//! ```
//!
//! Writes `cloud.ply` (binary PLY, metres, depth camera frame) and `projection.png` (the
//! projection image on the colour camera's plane) under `target/treemocap-demo/`, and prints
//! the lift error of every visible marker against the ground truth. Later stages (tracking,
//! angles, modal estimation, reconstruction, animation) join this program as they land.

use std::path::PathBuf;
use std::time::Instant;

use treemocap::kinect_io::synth::{self, SynthConfig};
use treemocap::kinect_io::{
    CloudBuilder, CloudConfig, LiftConfig, PlyFormat, PointCloud, ProjectionConfig, project_cloud,
    write_ply,
};

const USAGE: &str = "usage: pipeline [--seed N] [--out-dir DIR]

Renders a synthetic Kinect V2 capture of a small tree with red markers, builds the textured
point cloud and its projection image, lifts each marker's true pixel back to 3D and prints the
error against the ground truth. Writes cloud.ply and projection.png to DIR (default
target/treemocap-demo).";

/// Colour written for points the colour camera does not see (PLY has no 'no colour').
const UNSEEN_RGB: [u8; 3] = [128, 128, 128];
/// Distance of the camera from the tree, metres.
const CAMERA_DISTANCE_M: f64 = 2.2;
/// Height of the camera above the ground, metres.
const CAMERA_HEIGHT_M: f64 = 1.1;

struct Args {
    seed: u64,
    out_dir: PathBuf,
}

fn parse_args() -> Result<Option<Args>, String> {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target"));
    let mut args = Args {
        seed: 7,
        out_dir: target.join("treemocap-demo"),
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "-h" | "--help" => return Ok(None),
            "--seed" => {
                let v = it.next().ok_or("--seed needs a value")?;
                args.seed = v
                    .parse()
                    .map_err(|_| format!("--seed {v:?} is not a number"))?;
            }
            "--out-dir" => args.out_dir = it.next().ok_or("--out-dir needs a value")?.into(),
            other => return Err(format!("unknown argument {other:?}\n\n{USAGE}")),
        }
    }
    Ok(Some(args))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let Some(args) = parse_args()? else {
        println!("{USAGE}");
        return Ok(());
    };
    std::fs::create_dir_all(&args.out_dir)?;

    let t = Instant::now();
    let scene = synth::demo_tree(args.seed);
    let config = SynthConfig::kinect_v2(CAMERA_DISTANCE_M, CAMERA_HEIGHT_M, args.seed);
    let frame = synth::render(&scene, &config)?;
    println!(
        "capture   synthetic Kinect V2 frame: depth {}x{}, colour {}x{}, {} markers, seed {} ({:.0} ms)",
        frame.depth.width(),
        frame.depth.height(),
        frame.color.width(),
        frame.color.height(),
        frame.markers.len(),
        args.seed,
        t.elapsed().as_secs_f64() * 1e3
    );

    let calibration = &config.calibration;
    let t = Instant::now();
    let mut builder = CloudBuilder::new(calibration, CloudConfig::default())?;
    let cloud = builder.build(&frame.depth, &frame.color)?;
    let coloured = cloud.iter_valid().filter(|(_, p)| p.rgb.is_some()).count();
    println!(
        "cloud     {} points with depth, {} with colour ({:.1} ms)",
        cloud.valid_count(),
        coloured,
        t.elapsed().as_secs_f64() * 1e3
    );

    // The paper's projection image: the textured cloud seen from the colour camera.
    let t = Instant::now();
    let depth_to_color = calibration
        .depth_to_color()?
        .ok_or("the demo calibration is rigid")?;
    let projection = project_cloud(
        &cloud,
        &calibration.color_camera,
        &depth_to_color,
        &ProjectionConfig::default(),
    )?;
    println!(
        "project   {}x{} projection image, {} pixels show a point ({:.1} ms)",
        projection.image().width(),
        projection.image().height(),
        projection.covered_pixels(),
        t.elapsed().as_secs_f64() * 1e3
    );

    println!("lift      marker  pixel (colour image)     error_mm");
    let mut errors_mm = Vec::new();
    for marker in &frame.markers {
        let Some(pixel) = marker.color_pixel.filter(|_| marker.visible) else {
            println!("          {:<6}  not visible", marker.id);
            continue;
        };
        match projection.lift(&cloud, &pixel, &LiftConfig::default()) {
            Some(p) => {
                let e = (p - marker.depth_camera_m).norm() * 1e3;
                errors_mm.push(e);
                println!(
                    "          {:<6}  ({:7.2}, {:7.2})      {e:6.2}",
                    marker.id, pixel.x, pixel.y
                );
            }
            None => println!("          {:<6}  no point near the marker", marker.id),
        }
    }
    if errors_mm.is_empty() {
        return Err("no marker could be lifted".into());
    }
    let mean = errors_mm.iter().sum::<f64>() / errors_mm.len() as f64;
    let max = errors_mm.iter().copied().fold(0.0, f64::max);
    println!(
        "lift error against ground truth: mean {mean:.2} mm, max {max:.2} mm over {} markers",
        errors_mm.len()
    );

    let ply = args.out_dir.join("cloud.ply");
    write_ply(
        &PointCloud::from_textured(&cloud, UNSEEN_RGB),
        &ply,
        PlyFormat::BinaryLittleEndian,
    )?;
    let png = args.out_dir.join("projection.png");
    projection.image().save(&png)?;
    println!("wrote     {}", ply.display());
    println!("wrote     {}", png.display());
    Ok(())
}
