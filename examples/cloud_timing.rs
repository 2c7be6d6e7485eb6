//! Times the textured-cloud step on the real frames the `kinect_io` bench uses, printed in the
//! format of `crates/kinect-io/fixtures/open3d_cloud_timing.py`, so that a script can
//! alternate the two in short turns and compare them under the same load
//! (`crates/kinect-io/fixtures/interleaved_cloud_timing.py`; issue 23).
//!
//! ```text
//! cargo run --release --example cloud_timing -- [--frame tum|azure|azure-registered] [--no-filter] [--runs N] [--data DIR]
//! cargo run --release --example cloud_timing -- --write-registered-depth depth.png
//! ```
//!
//! Prints one line: `ours_<frame>: median M ms (quartiles Q1-Q3, fastest F)`. The images are
//! read before timing; each run is `CloudBuilder::build_into` into one reused cloud.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::{Parser, ValueEnum};
use treemocap::image::RgbImage;
use treemocap::kinect_io::{
    Calibration, CloudBuilder, CloudConfig, DEPTH_UNIT_MM_M, DEPTH_UNIT_TUM_M, DepthImage,
    Extrinsics, read_color_image, read_depth_image, read_npy_transform, register_to_color,
    write_depth_png,
};

mod common;

/// Which real frame to build.
#[derive(Debug, Clone, Copy, ValueEnum)]
enum Which {
    /// The TUM frame (640x480, already registered).
    Tum,
    /// The Azure Kinect frame (512x512 WFOV binned depth, 720p colour, rigid registration).
    Azure,
    /// The Azure Kinect frame with its depth registered to the colour camera (1280x720, as
    /// the Azure Kinect SDK's transformation gives it; made from the raw frame).
    AzureRegistered,
}

/// Time the textured cloud of a real frame (TUM or Azure Kinect) like Open3D's timing script.
#[derive(Parser, Debug)]
#[command(name = "cloud_timing", version, about)]
struct Args {
    /// The frame
    #[arg(long, value_enum, default_value = "azure")]
    frame: Which,
    /// Without the occlusion filter (two-camera frames)
    #[arg(long = "no-filter")]
    no_filter: bool,
    /// Timed runs (after one untimed)
    #[arg(long, default_value_t = 300, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    runs: u32,
    /// Write the registered Azure frame's depth (16-bit PNG, mm) here and stop: the input
    /// of Open3D's side of `--frame azure-registered`
    #[arg(long = "write-registered-depth", value_name = "FILE.png")]
    write_registered_depth: Option<PathBuf>,
    /// The folder holding `slambook_ch7_tum/` and `cameramodels_azure_kinect/`
    /// (default: `../shared/data/kinect` next to the workspace)
    #[arg(long, value_name = "DIR")]
    data: Option<PathBuf>,
}

fn main() -> std::process::ExitCode {
    let args = Args::parse();
    common::run("cloud_timing", || run(&args))
}

/// One frame: its calibration, depth and colour.
type Frame = (Calibration, DepthImage, RgbImage);

/// The Azure Kinect frame (`cameramodels_azure_kinect/`): its ROS camera infos, and the
/// file named `depth_to_rgb_transformation.npy`, which maps colour to depth (inverted here;
/// see `benches/kinect_io.rs`).
fn azure(data: &Path) -> Result<Frame, Box<dyn std::error::Error>> {
    let dir = data.join("cameramodels_azure_kinect");
    let color_to_depth = read_npy_transform(&dir.join("depth_to_rgb_transformation.npy"))?;
    let calibration = Calibration::from_ros_camera_infos(
        &dir.join("k4a_depth_camera_info.yaml"),
        &dir.join("k4a_rgb_camera_info.yaml"),
        Extrinsics::from_isometry(&color_to_depth.to_isometry()?.inverse()),
        DEPTH_UNIT_MM_M,
    )?;
    Ok((
        calibration,
        read_depth_image(&dir.join("k4a_depth_image_raw.png"), DEPTH_UNIT_MM_M)?,
        read_color_image(&dir.join("k4a_rgb_image_raw.jpg"))?,
    ))
}

/// The Azure Kinect frame with its depth registered to the colour camera.
fn azure_registered(data: &Path) -> Result<Frame, Box<dyn std::error::Error>> {
    let (calibration, depth, color) = azure(data)?;
    let cloud = CloudBuilder::new(&calibration, CloudConfig::default())?.build(&depth, &color)?;
    let (registered, depth) = register_to_color(&cloud, &calibration, DEPTH_UNIT_MM_M)?;
    Ok((registered, depth, color))
}

/// The TUM frame with TUM's default calibration.
fn tum(data: &Path) -> Result<Frame, Box<dyn std::error::Error>> {
    let dir = data.join("slambook_ch7_tum");
    Ok((
        Calibration::tum_default(),
        read_depth_image(&dir.join("1_depth.png"), DEPTH_UNIT_TUM_M)?,
        read_color_image(&dir.join("1.png"))?,
    ))
}

fn run(args: &Args) -> Result<(), Box<dyn std::error::Error>> {
    let data = match &args.data {
        Some(dir) => dir.clone(),
        None => {
            let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kinect");
            if !dir.is_dir() {
                return Err(format!("{} is absent; give --data DIR", dir.display()).into());
            }
            dir
        }
    };
    if let Some(path) = &args.write_registered_depth {
        let (_, depth, _) = azure_registered(&data)?;
        write_depth_png(&depth, path)?;
        eprintln!("wrote {}", path.display());
        return Ok(());
    }
    let (label, (calibration, depth, color)) = match args.frame {
        Which::Tum => ("ours_tum_640x480", tum(&data)?),
        Which::Azure => ("ours_azure_wfov_512x512", azure(&data)?),
        Which::AzureRegistered => ("ours_azure_registered_1280x720", azure_registered(&data)?),
    };
    let config = CloudConfig {
        occlusion_filter: if args.no_filter {
            None
        } else {
            CloudConfig::default().occlusion_filter
        },
        ..CloudConfig::default()
    };
    let mut builder = CloudBuilder::new(&calibration, config)?;
    let mut cloud = builder.build(&depth, &color)?;
    let mut times_ms: Vec<f64> = Vec::with_capacity(args.runs as usize);
    for _ in 0..args.runs {
        let t = Instant::now();
        builder.build_into(&depth, &color, &mut cloud)?;
        times_ms.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times_ms.sort_by(f64::total_cmp);
    // The statistics module's default quantiles ("exclusive", n = 4), as the Python script.
    let quantile = |p: f64| {
        let n = times_ms.len();
        let h = (n as f64 + 1.0) * p - 1.0;
        let (lo, frac) = (h.floor().clamp(0.0, (n - 1) as f64) as usize, h - h.floor());
        let hi = (lo + 1).min(n - 1);
        times_ms[lo] + (times_ms[hi] - times_ms[lo]) * frac.clamp(0.0, 1.0)
    };
    let suffix = if args.no_filter { "_no_filter" } else { "" };
    println!(
        "{label}{suffix}: median {:.3} ms (quartiles {:.3}-{:.3}, fastest {:.3}), {} points",
        quantile(0.5),
        quantile(0.25),
        quantile(0.75),
        times_ms[0],
        cloud.valid_count()
    );
    Ok(())
}
