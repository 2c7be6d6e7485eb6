//! Integration tests of kinect-io: round trips, bad input, fuzz-style parser tests, end-to-end
//! synthetic captures, and checks on the real data in `../shared/data` (skipped with a printed
//! reason when it is absent).

// Helpers here are test code too: a failed expectation is a failed test.
#![allow(clippy::expect_used, clippy::unwrap_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use image::RgbImage;
use kinect_io::synth::{self, SensorNoise, SynthConfig};
use kinect_io::*;
use nalgebra::{Isometry3, Point2, Point3};
use proptest::prelude::*;

mod containers;
mod jpeg;
mod properties;
mod real_data;
mod recording;
mod synthetic;

/// A fresh, empty directory under the system's temporary directory, removed when dropped.
struct TempDir(PathBuf);

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn temp_dir(tag: &str) -> TempDir {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "kinect-io-test-{}-{tag}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    TempDir(dir)
}

/// `../shared/data/kinect`, or `None` (with the reason printed) when it is not there.
fn shared_kinect_data() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/kinect");
    if dir.is_dir() {
        Some(dir)
    } else {
        println!("skipped: real data folder {} is absent", dir.display());
        None
    }
}

fn small_synth(seed: u64, noise: SensorNoise) -> SynthConfig {
    let mut config = SynthConfig::kinect_v2(2.2, 1.1, seed);
    config.calibration.color_camera = config.calibration.color_camera.scaled(0.5).expect("valid");
    config.noise = noise;
    config
}

/// A plausible iai_kinect2 calibration folder (values of the kind the tool writes).
fn write_iai(dir: &Path) {
    let matrix = |name: &str, rows: usize, cols: usize, data: &[f64]| {
        let list: Vec<String> = data.iter().map(|v| format!("{v:e}")).collect();
        format!(
            "{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {} ]\n",
            list.join(",\n       ")
        )
    };
    let camera = |f: f64, cx: f64, cy: f64| {
        format!(
            "%YAML:1.0\n{}{}",
            matrix(
                "cameraMatrix",
                3,
                3,
                &[f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0]
            ),
            matrix(
                "distortionCoefficients",
                1,
                5,
                &[0.1, -0.3, 0.001, -0.001, 0.1]
            )
        )
    };
    std::fs::write(dir.join("calib_color.yaml"), camera(1060.0, 955.0, 530.0)).expect("write");
    std::fs::write(dir.join("calib_ir.yaml"), camera(365.0, 255.0, 205.0)).expect("write");
    std::fs::write(
        dir.join("calib_pose.yaml"),
        format!(
            "%YAML:1.0\n{}{}",
            matrix(
                "rotation",
                3,
                3,
                &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
            ),
            matrix("translation", 3, 1, &[-0.052, 0.0, 0.0])
        ),
    )
    .expect("write");
    std::fs::write(
        dir.join("calib_depth.yaml"),
        "%YAML:1.0\ndepthShift: -12.5\n",
    )
    .expect("write");
}
