//! The valid inputs every case starts from, generated here (seeded): one directory per
//! kind of input.

use super::*;

pub(super) fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        let p = e.path();
        let q = to.join(e.file_name());
        if p.is_dir() {
            copy_dir(&p, &q);
        } else {
            std::fs::copy(&p, &q).unwrap();
        }
    }
}

pub(super) fn os(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Vec<OsString> {
    args.iter().map(|a| a.as_ref().to_os_string()).collect()
}

/// Valid inputs, each in its own base directory.
pub(super) struct Bases {
    pub(super) signal: PathBuf,
    pub(super) angles: PathBuf,
    pub(super) frames: PathBuf,
    pub(super) recording: PathBuf,
    pub(super) clouds: PathBuf,
    pub(super) animation: PathBuf,
}

pub(super) fn make_bases(root: &Path) -> Bases {
    Bases {
        signal: signal_base(root),
        angles: angles_base(root),
        frames: frames_base(root),
        recording: recording_base(root),
        clouds: clouds_base(root),
        animation: animation_base(root),
    }
}

/// A pull-and-release record.
fn signal_base(root: &Path) -> PathBuf {
    let signal = root.join("base_signal");
    std::fs::create_dir_all(&signal).unwrap();
    let record = DecaySpec::paper_branch().generate().unwrap();
    std::fs::write(signal.join("signal.csv"), signal_to_csv(&record)).unwrap();
    signal
}

/// Marker trajectories and their hierarchy.
fn angles_base(root: &Path) -> PathBuf {
    let angles = root.join("base_angles");
    std::fs::create_dir_all(&angles).unwrap();
    let tree = treemocap::branch_angles::synthetic::two_level();
    std::fs::write(
        angles.join("trajectories.csv"),
        trajectories_to_csv(&tree.trajectories),
    )
    .unwrap();
    let markers: Vec<serde_json::Value> = tree
        .hierarchy
        .markers()
        .iter()
        .map(|m| serde_json::json!({"id": m.id, "parent": m.parent}))
        .collect();
    std::fs::write(
        angles.join("hierarchy.json"),
        serde_json::json!({ "markers": markers }).to_string(),
    )
    .unwrap();
    angles
}

/// Frames of a red marker moving on a textured background, and its window.
fn frames_base(root: &Path) -> PathBuf {
    let frames = root.join("base_frames");
    std::fs::create_dir_all(frames.join("frames")).unwrap();
    for k in 0..6u32 {
        let (cx, cy) = (20 + 3 * k, 24);
        let img = RgbImage::from_fn(64, 48, |x, y| {
            if x.abs_diff(cx) <= 4 && y.abs_diff(cy) <= 4 {
                Rgb([220, 30, 30])
            } else {
                Rgb([
                    (90 + (x * 7 + y * 3) % 40) as u8,
                    110,
                    (100 + (x ^ y) % 30) as u8,
                ])
            }
        });
        let mut bytes = Vec::new();
        treemocap::image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 90)
            .encode_image(&img)
            .unwrap();
        std::fs::write(frames.join("frames").join(format!("f{k:03}.jpg")), bytes).unwrap();
    }
    std::fs::write(
        frames.join("init.json"),
        r#"[{"id": "A", "x": 16, "y": 20, "w": 9, "h": 9}]"#,
    )
    .unwrap();
    frames
}

/// A tiny native recording: a wall at 1.5 m with a red patch, 8 frames, and its markers.
fn recording_base(root: &Path) -> PathBuf {
    let recording = root.join("base_recording");
    let rec_dir = recording.join("rec");
    let mut calibration = Calibration::kinect_v2();
    calibration.depth_camera = CameraModel::kinect_v2_depth().scaled(0.125).unwrap();
    calibration.color_camera = CameraModel::kinect_v2_color().scaled(0.05).unwrap();
    let mut writer =
        RecordingWriter::create(&rec_dir, &calibration, ColorFormat::Jpeg { quality: 90 }).unwrap();
    let (dw, dh) = (
        calibration.depth_camera.width,
        calibration.depth_camera.height,
    );
    let (cw, ch) = (
        calibration.color_camera.width,
        calibration.color_camera.height,
    );
    for k in 0..8u32 {
        let depth = DepthImage::new(
            dw,
            dh,
            calibration.depth_unit_m,
            (0..dw * dh)
                .map(|i| 1500 + ((i * 7 + k) % 13) as u16)
                .collect(),
        )
        .unwrap();
        let color = RgbImage::from_fn(cw, ch, |x, y| {
            if x.abs_diff(48 + k % 3) <= 3 && y.abs_diff(27) <= 3 {
                Rgb([220, 30, 30])
            } else {
                Rgb([(80 + (x * 5 + y * 3) % 50) as u8, 120, 100])
            }
        });
        writer
            .write_frame(f64::from(k) / 30.0, &color, &depth)
            .unwrap();
    }
    std::fs::write(
        recording.join("markers.json"),
        serde_json::json!({
            "markers": [
                {"id": "A", "parent": null, "x": 40, "y": 20, "w": 12, "h": 12},
                {"id": "B", "parent": "A", "x": 44, "y": 23, "w": 8, "h": 8, "window_s": [0.0, 0.2]}
            ]
        })
        .to_string(),
    )
    .unwrap();
    recording
}

/// The small synthetic tree (cloud and skeleton) of the cloud and animation bases.
fn small_tree() -> treemocap::space_colonize::synthetic::SyntheticTree {
    SyntheticConfig {
        seed: 5,
        points: 2_000,
        ..Default::default()
    }
    .generate()
    .unwrap()
}

/// A point cloud of a small tree in three formats.
fn clouds_base(root: &Path) -> PathBuf {
    let clouds = root.join("base_clouds");
    std::fs::create_dir_all(&clouds).unwrap();
    let cloud = PointCloud::from_points(small_tree().points);
    write_xyz(&cloud, &clouds.join("tree.xyz")).unwrap();
    write_ply(&cloud, &clouds.join("tree.ply"), PlyFormat::Ascii).unwrap();
    write_ply(
        &cloud,
        &clouds.join("tree_binary.ply"),
        PlyFormat::BinaryLittleEndian,
    )
    .unwrap();
    write_pcd(&cloud, &clouds.join("tree.pcd"), PcdWriteOptions::default()).unwrap();
    clouds
}

/// A skeleton and dynamics for the animation.
fn animation_base(root: &Path) -> PathBuf {
    let animation = root.join("base_animation");
    std::fs::create_dir_all(&animation).unwrap();
    std::fs::write(
        animation.join("skeleton.json"),
        small_tree().skeleton.to_json().unwrap(),
    )
    .unwrap();
    std::fs::write(
        animation.join("dynamics.json"),
        serde_json::json!({
            "default": {"frequency_hz": 1.46, "damping_ratio": 0.086},
            "branches": {"0": {"frequency_hz": 1.2, "damping_ratio": 0.05}},
            "measured": []
        })
        .to_string(),
    )
    .unwrap();
    animation
}
