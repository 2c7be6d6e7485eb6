//! Recordings: the native and TUM layouts, iai_kinect2 calibration folders, and their errors.

use super::*;

#[test]
fn native_recording_round_trip() {
    let dir = temp_dir("native");
    let config = small_synth(8, SensorNoise::kinect_v2());
    let scene = synth::demo_tree(8);
    let mut writer =
        RecordingWriter::create(&dir, &config.calibration, ColorFormat::Png).expect("create");
    let mut frames = Vec::new();
    for (k, t) in [0.0, 0.0334, 0.0667].into_iter().enumerate() {
        let mut c = config.clone();
        c.seed = k as u64;
        let frame = synth::render(&scene, &c).expect("renders");
        writer
            .write_frame(t, &frame.color, &frame.depth)
            .expect("write");
        frames.push((t, frame));
    }
    // Timestamps must increase.
    let f = &frames[0].1;
    assert!(writer.write_frame(0.05, &f.color, &f.depth).is_err());
    drop(writer);
    let recording = Recording::open(&dir).expect("open");
    assert_eq!(recording.layout(), Layout::Native);
    assert_eq!(recording.len(), 3);
    assert_eq!(recording.calibration(), &config.calibration);
    for (loaded, (t, original)) in recording.frames().zip(&frames) {
        let loaded = loaded.expect("frame");
        assert_eq!(loaded.timestamp_s, *t);
        assert_eq!(loaded.depth, original.depth);
        assert_eq!(loaded.color, original.color);
    }
    assert!(matches!(
        recording.frame(3),
        Err(KinectError::FrameOutOfRange {
            index: 3,
            count: 3,
            ..
        })
    ));
    // A recording is not overwritten.
    assert!(RecordingWriter::create(&dir, &config.calibration, ColorFormat::Png).is_err());
}

#[test]
fn recording_errors_name_the_file() {
    let dir = temp_dir("broken");
    let config = small_synth(9, SensorNoise::none());
    let frame = synth::render(&synth::demo_tree(9), &config).expect("renders");
    let mut writer =
        RecordingWriter::create(&dir, &config.calibration, ColorFormat::Jpeg { quality: 90 })
            .expect("create");
    writer
        .write_frame(1.0, &frame.color, &frame.depth)
        .expect("write");
    writer
        .write_frame(2.0, &frame.color, &frame.depth)
        .expect("write");
    drop(writer);
    // Truncate the first depth PNG.
    let depth0 = dir.join("depth/000000.png");
    let bytes = std::fs::read(&depth0).expect("read");
    std::fs::write(&depth0, &bytes[..bytes.len() / 2]).expect("write");
    let recording = Recording::open(&dir).expect("open");
    let err = recording.frame(0).expect_err("truncated");
    assert!(err.to_string().contains("000000.png"), "{err}");
    // An 8-bit depth image.
    let gray = image::GrayImage::new(frame.depth.width(), frame.depth.height());
    gray.save(dir.join("depth/000001.png")).expect("save");
    assert!(matches!(
        recording.frame(1),
        Err(KinectError::DepthNot16Bit { .. })
    ));
    // A missing colour file.
    std::fs::remove_file(dir.join("color/000001.jpg")).expect("rm");
    let err = recording.frame(1).expect_err("missing");
    assert!(matches!(err, KinectError::Io { .. }), "{err}");
    assert!(err.to_string().contains("000001.jpg"), "{err}");
    // A malformed calibration.
    std::fs::write(dir.join(CALIBRATION_FILE), "{\"format\": 3}").expect("write");
    assert!(matches!(
        Recording::open(&dir),
        Err(KinectError::Calibration { .. })
    ));
    // Not a recording at all.
    let empty = temp_dir("empty");
    assert!(matches!(
        Recording::open(&empty),
        Err(KinectError::UnknownLayout { .. })
    ));
}

#[test]
fn mismatched_sizes_in_a_recording_are_reported() {
    let dir = temp_dir("sizes");
    let calibration = Calibration::tum_default();
    let colour = RgbImage::new(640, 480);
    let depth = DepthImage::new(320, 240, DEPTH_UNIT_TUM_M, vec![5000; 320 * 240]).expect("ok");
    colour.save(dir.join("c.png")).expect("save");
    write_depth_png(&depth, &dir.join("d.png")).expect("save");
    std::fs::write(dir.join("rgb.txt"), "1.0 c.png\n").expect("write");
    std::fs::write(dir.join("depth.txt"), "1.0 d.png\n").expect("write");
    let recording = Recording::open(&dir).expect("open");
    assert_eq!(recording.calibration(), &calibration);
    let err = recording.frame(0).expect_err("sizes");
    assert!(
        matches!(
            err,
            KinectError::SizeMismatch {
                expected_width: 640,
                found_width: 320,
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("d.png"), "{err}");
}

#[test]
fn tum_layout_associates_and_converts_units() {
    let dir = temp_dir("tum");
    let colour = RgbImage::from_pixel(640, 480, image::Rgb([10, 20, 30]));
    // 1.5 m everywhere except a zero (invalid) row.
    let mut values = vec![7500u16; 640 * 480];
    values[..640].fill(0);
    let depth = DepthImage::new(640, 480, DEPTH_UNIT_TUM_M, values).expect("ok");
    std::fs::create_dir_all(dir.join("rgb")).expect("dir");
    std::fs::create_dir_all(dir.join("depth")).expect("dir");
    for k in 0..3 {
        colour.save(dir.join(format!("rgb/{k}.png"))).expect("save");
        write_depth_png(&depth, &dir.join(format!("depth/{k}.png"))).expect("save");
    }
    std::fs::write(
        dir.join("rgb.txt"),
        "# color images\n# file: 'x'\n# timestamp filename\n10.000 rgb/0.png\n10.030 rgb/1.png\n10.300 rgb/2.png\n",
    )
    .expect("write");
    std::fs::write(
        dir.join("depth.txt"),
        "# depth maps\n10.010 depth/0.png\n10.035 depth/1.png\n10.200 depth/2.png\n",
    )
    .expect("write");
    let recording = Recording::open(&dir).expect("open");
    assert_eq!(recording.layout(), Layout::Tum);
    // 10.200 has no colour within 0.02 s.
    assert_eq!(recording.len(), 2);
    assert_eq!(recording.unpaired_depth_frames(), 1);
    assert_eq!(
        recording.entries().expect("a folder")[1].color_timestamp_s,
        10.030
    );
    assert_eq!(recording.color_timestamps_s().nth(1), Some(10.030));
    assert_eq!(recording.timestamps_s().nth(1), Some(10.035));
    let frame = recording.frame(0).expect("frame");
    let cloud = CloudBuilder::new(recording.calibration(), CloudConfig::default())
        .expect("valid")
        .build(&frame.depth, &frame.color)
        .expect("ok");
    assert_eq!(cloud.valid_count(), 640 * 479);
    let p = cloud.get(320, 240).expect("valid");
    assert!((p.position_m.z - 1.5).abs() < 1e-12);
    // TUM defaults: cx = 319.5, so pixel 320 is half a pixel right of the axis.
    assert!((p.position_m.x - 0.5 / 525.0 * 1.5).abs() < 1e-12);
    assert_eq!(p.rgb, Some([10, 20, 30]));
}

#[test]
fn all_invalid_depth_is_an_error_not_an_empty_cloud() {
    let calibration = Calibration::tum_default();
    let colour = RgbImage::new(640, 480);
    let depth = DepthImage::zeros(640, 480, DEPTH_UNIT_TUM_M).expect("ok");
    let mut builder = CloudBuilder::new(&calibration, CloudConfig::default()).expect("ok");
    assert!(matches!(
        builder.build(&depth, &colour),
        Err(KinectError::NoValidDepth { .. })
    ));
    // Out of the configured range everywhere is the same.
    let depth = DepthImage::new(640, 480, DEPTH_UNIT_TUM_M, vec![50_000; 640 * 480]).expect("ok");
    let mut near_only = CloudBuilder::new(
        &calibration,
        CloudConfig {
            max_depth_m: 5.0,
            ..CloudConfig::default()
        },
    )
    .expect("ok");
    assert!(near_only.build(&depth, &colour).is_err());
}

#[test]
fn iai_kinect2_folder_is_read() {
    let dir = temp_dir("iai");
    write_iai(&dir);
    let c = Calibration::read(&dir.join("calib_pose.yaml")).expect("valid");
    assert_eq!((c.depth_camera.width, c.color_camera.width), (512, 1920));
    assert_eq!(c.depth_camera.fx, 365.0);
    assert_eq!(c.depth_camera.distortion.p1, 0.001);
    assert_eq!(c.depth_offset_m, -0.0125);
    let t = c.depth_to_color().expect("ok").expect("rigid");
    assert!((t.translation.vector.x + 0.052).abs() < 1e-15);
    // A missing file is named.
    std::fs::remove_file(dir.join("calib_pose.yaml")).expect("rm");
    let err = Calibration::read_iai_kinect2(&dir).expect_err("missing");
    assert!(err.to_string().contains("calib_pose.yaml"), "{err}");
}
