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

// ---------------------------------------------------------------------------------------------
// End to end on synthetic captures.

/// Lift error bound with Kinect V2 noise: the depth sigma is about 1.7 mm at 2.2 m and the
/// median over the few points of a marker leaves up to about 2 sigma; the lateral position comes
/// from the exact pixel.
const NOISY_LIFT_TOLERANCE_M: f64 = 0.005;
/// Without noise only the 1 mm depth quantisation and the marker disc's tilt remain.
const CLEAN_LIFT_TOLERANCE_M: f64 = 0.002;

fn lift_errors(config: &SynthConfig, on_color_plane: bool) -> Vec<f64> {
    let frame = synth::render(&synth::demo_tree(config.seed), config).expect("renders");
    let calibration = &config.calibration;
    let cloud = CloudBuilder::new(calibration, CloudConfig::default())
        .expect("valid")
        .build(&frame.depth, &frame.color)
        .expect("valid frame");
    let (camera, pose) = if on_color_plane {
        (
            calibration.color_camera,
            calibration.depth_to_color().expect("ok").expect("rigid"),
        )
    } else {
        (calibration.depth_camera, Isometry3::identity())
    };
    let projection =
        project_cloud(&cloud, &camera, &pose, &ProjectionConfig::default()).expect("valid");
    frame
        .markers
        .iter()
        .filter(|m| m.visible)
        .map(|m| {
            let pixel = camera
                .project(&(pose * m.depth_camera_m))
                .expect("in front");
            let p = projection
                .lift(&cloud, &pixel, &LiftConfig::default())
                .unwrap_or_else(|| panic!("marker {} lifts to a point", m.id));
            (p - m.depth_camera_m).norm()
        })
        .collect()
}

#[test]
fn markers_lift_back_to_their_true_position_with_sensor_noise() {
    for seed in [1, 2] {
        for on_color_plane in [false, true] {
            let errors = lift_errors(&small_synth(seed, SensorNoise::kinect_v2()), on_color_plane);
            assert!(errors.len() >= 8, "{} markers visible", errors.len());
            for e in &errors {
                assert!(*e < NOISY_LIFT_TOLERANCE_M, "seed {seed}: error {e} m");
            }
        }
    }
}

#[test]
fn markers_lift_back_exactly_without_noise() {
    let errors = lift_errors(&small_synth(4, SensorNoise::none()), false);
    assert!(
        errors.iter().all(|e| *e < CLEAN_LIFT_TOLERANCE_M),
        "{errors:?}"
    );
}

#[test]
fn the_projection_image_shows_red_markers_where_the_truth_says() {
    let config = small_synth(5, SensorNoise::kinect_v2());
    let frame = synth::render(&synth::demo_tree(5), &config).expect("renders");
    let cal = &config.calibration;
    let cloud = CloudBuilder::new(cal, CloudConfig::default())
        .expect("valid")
        .build(&frame.depth, &frame.color)
        .expect("ok");
    let projection = project_cloud(
        &cloud,
        &cal.depth_camera,
        &Isometry3::identity(),
        &ProjectionConfig::default(),
    )
    .expect("valid");
    let mut red = 0;
    for m in frame.markers.iter().filter(|m| m.visible) {
        let (u, v) = cal
            .depth_camera
            .pixel_at(&m.depth_pixel.expect("front"))
            .expect("on image");
        let px = projection.image().get_pixel(u, v).0;
        red += usize::from(px[0] > 140 && px[1] < 80 && px[2] < 80);
    }
    assert!(red >= 8, "{red} markers red on the projection image");
}

#[test]
fn a_world_frame_cloud_is_z_up_and_lifts_in_world_coordinates() {
    let mut config = small_synth(6, SensorNoise::none());
    let world_to_depth = config.world_to_depth;
    config.noise = SensorNoise::none();
    let frame = synth::render(&synth::demo_tree(6), &config).expect("renders");
    let cloud_config = CloudConfig {
        camera_to_world: Some(world_to_depth.inverse()),
        ..CloudConfig::default()
    };
    let cloud = CloudBuilder::new(&config.calibration, cloud_config)
        .expect("valid")
        .build(&frame.depth, &frame.color)
        .expect("ok");
    // The ground is at z = 0 in the world frame.
    let (lo, _) = cloud.bounding_box().expect("points");
    assert!(lo.z.abs() < 0.01, "lowest point {lo}");
    let camera = config.calibration.depth_camera;
    let projection = project_cloud(
        &cloud,
        &camera,
        &world_to_depth,
        &ProjectionConfig::default(),
    )
    .expect("valid");
    let m = frame.markers.iter().find(|m| m.visible).expect("visible");
    let p = projection
        .lift(
            &cloud,
            &m.depth_pixel.expect("front"),
            &LiftConfig::default(),
        )
        .expect("a point");
    assert!(
        (p - m.world_m).norm() < CLEAN_LIFT_TOLERANCE_M,
        "{p} vs {}",
        m.world_m
    );
}

// ---------------------------------------------------------------------------------------------
// Recordings.

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
    assert_eq!(recording.entries()[1].color_timestamp_s, 10.030);
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

// ---------------------------------------------------------------------------------------------
// Property tests: round trips.

fn camera_strategy() -> impl Strategy<Value = CameraModel> {
    (
        400.0..1200.0f64,
        0.9..1.1f64,
        -0.05..0.1f64,
        -0.1..0.05f64,
        -0.02..0.02f64,
        -0.002..0.002f64,
        -0.002..0.002f64,
    )
        .prop_map(|(f, aspect, k1, k2, k3, p1, p2)| CameraModel {
            width: 640,
            height: 480,
            fx: f,
            fy: f * aspect,
            cx: 319.5,
            cy: 239.5,
            distortion: Distortion {
                k1,
                k2,
                k3,
                p1,
                p2,
                ..Distortion::default()
            },
        })
}

/// Pixel round-trip tolerance: Newton's undistortion converges to 1e-12 normalised units.
const ROUND_TRIP_PX: f64 = 1e-6;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn pixel_point_pixel_round_trip(
        camera in camera_strategy(),
        u in 0.0..639.0f64,
        v in 0.0..479.0f64,
        z in 0.3..8.0f64,
        distorted in any::<bool>(),
    ) {
        let camera = if distorted { camera } else { CameraModel { distortion: Distortion::default(), ..camera } };
        let pixel = Point2::new(u, v);
        let point = camera.unproject(&pixel, z).expect("invertible inside the image");
        prop_assert!((point.z - z).abs() < 1e-12);
        let back = camera.project(&point).expect("in front");
        prop_assert!((back - pixel).norm() < ROUND_TRIP_PX, "{} -> {}", pixel, back);
    }

    #[test]
    fn point_pixel_point_round_trip(
        camera in camera_strategy(),
        x in -0.5..0.5f64,
        y in -0.4..0.4f64,
        z in 0.5..6.0f64,
    ) {
        let point = Point3::new(x * z, y * z, z);
        let pixel = camera.project(&point).expect("in front");
        let back = camera.unproject(&pixel, z).expect("invertible");
        prop_assert!((back - point).norm() < 1e-9 * z.max(1.0), "{} -> {}", point, back);
    }

    #[test]
    fn ply_round_trip(
        points in prop::collection::vec((-1e3..1e3f64, -1e3..1e3f64, -1e3..1e3f64), 1..200),
        colors in any::<bool>(),
        ascii in any::<bool>(),
    ) {
        let cloud = PointCloud {
            width: points.len() as u32,
            height: 1,
            points: points.iter().map(|&(x, y, z)| Some(Point3::new(x, y, z))).collect(),
            colors: colors.then(|| points.iter().enumerate().map(|(i, _)| [i as u8, (i * 7) as u8, 255]).collect()),
        };
        let format = if ascii { PlyFormat::Ascii } else { PlyFormat::BinaryLittleEndian };
        let back = parse_ply(&encode_ply(&cloud, format).expect("valid")).expect("parses");
        prop_assert_eq!(back, cloud);
    }

    #[test]
    fn pcd_round_trip(
        width in 1u32..20,
        height in 1u32..6,
        seed in any::<u64>(),
        colors in any::<bool>(),
        ascii in any::<bool>(),
        double in any::<bool>(),
    ) {
        let n = (width * height) as usize;
        let mut state = seed;
        let mut next = || { state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407); (state >> 11) as f64 / (1u64 << 53) as f64 };
        let points: Vec<Option<Point3<f64>>> = (0..n)
            .map(|_| (next() > 0.2).then(|| Point3::new(next() * 10.0 - 5.0, next() * 4.0, next() * 8.0)))
            .collect();
        let cloud = PointCloud {
            width,
            height,
            points,
            colors: colors.then(|| (0..n).map(|i| [(i * 3) as u8, 9, (i * 5) as u8]).collect()),
        };
        let options = PcdWriteOptions {
            data: if ascii { PcdData::Ascii } else { PcdData::Binary },
            precision: if double { PcdPrecision::Float64 } else { PcdPrecision::Float32 },
        };
        let back = parse_pcd(&encode_pcd(&cloud, options).expect("valid")).expect("parses");
        prop_assert_eq!(back.width, width);
        prop_assert_eq!(back.height, height);
        prop_assert_eq!(&back.colors, &cloud.colors);
        for (a, b) in cloud.points.iter().zip(&back.points) {
            match (a, b) {
                (Some(a), Some(b)) if double => prop_assert_eq!(a, b),
                // f32 keeps 24 bits: relative error below 6e-8.
                (Some(a), Some(b)) => prop_assert!((a - b).norm() <= 1e-6 * a.coords.norm().max(1.0)),
                (None, None) => {}
                _ => prop_assert!(false, "validity changed: {:?} vs {:?}", a, b),
            }
        }
    }

    #[test]
    fn xyz_round_trip(
        points in prop::collection::vec((-1e4..1e4f64, -1e4..1e4f64, -1e4..1e4f64), 1..100),
        colors in any::<bool>(),
    ) {
        let dir = temp_dir("xyz");
        let cloud = PointCloud {
            width: points.len() as u32,
            height: 1,
            points: points.iter().map(|&(x, y, z)| Some(Point3::new(x, y, z))).collect(),
            colors: colors.then(|| points.iter().map(|_| [1, 2, 3]).collect()),
        };
        let path = dir.join("c.xyz");
        write_xyz(&cloud, &path).expect("write");
        prop_assert_eq!(read_point_cloud(&path).expect("read"), cloud);
    }

    #[test]
    fn depth_png_and_pgm_round_trip(
        width in 1u32..40,
        height in 1u32..30,
        seed in any::<u16>(),
    ) {
        let dir = temp_dir("depth");
        let values: Vec<u16> = (0..width * height).map(|i| (i as u16).wrapping_mul(seed) ^ seed).collect();
        let depth = DepthImage::new(width, height, DEPTH_UNIT_MM_M, values).expect("ok");
        write_depth_png(&depth, &dir.join("d.png")).expect("png");
        write_depth_pgm(&depth, &dir.join("d.pgm")).expect("pgm");
        prop_assert_eq!(&read_depth_image(&dir.join("d.png"), DEPTH_UNIT_MM_M).expect("png"), &depth);
        prop_assert_eq!(&read_depth_image(&dir.join("d.pgm"), DEPTH_UNIT_MM_M).expect("pgm"), &depth);
    }

    #[test]
    fn calibration_json_round_trip(
        fx in 300.0..1200.0f64,
        k1 in -0.3..0.3f64,
        angle in -0.1..0.1f64,
        tx in -0.1..0.1f64,
    ) {
        let mut c = Calibration::kinect_v2();
        c.depth_camera.fx = fx;
        c.depth_camera.distortion.k1 = k1;
        let iso = Isometry3::new(nalgebra::Vector3::new(tx, 0.001, -0.002), nalgebra::Vector3::new(0.0, angle, 0.0));
        c.registration = RegistrationModel::Rigid(Extrinsics::from_isometry(&iso));
        prop_assert_eq!(Calibration::from_json(&c.to_json()).expect("parses"), c);
    }
}

// ---------------------------------------------------------------------------------------------
// Fuzz-style property tests: no parser panics on random or damaged input.

fn valid_ply() -> Vec<u8> {
    let cloud = PointCloud {
        width: 3,
        height: 1,
        points: vec![Some(Point3::new(1.0, 2.0, 3.0)); 3],
        colors: Some(vec![[1, 2, 3]; 3]),
    };
    encode_ply(&cloud, PlyFormat::BinaryLittleEndian).expect("valid")
}

fn valid_pcd(ascii: bool) -> Vec<u8> {
    let cloud = PointCloud {
        width: 2,
        height: 2,
        points: vec![
            Some(Point3::new(1.0, 2.0, 3.0)),
            None,
            Some(Point3::new(0.0, 0.0, 1.0)),
            None,
        ],
        colors: Some(vec![[9, 8, 7]; 4]),
    };
    let data = if ascii {
        PcdData::Ascii
    } else {
        PcdData::Binary
    };
    encode_pcd(
        &cloud,
        PcdWriteOptions {
            data,
            precision: PcdPrecision::Float32,
        },
    )
    .expect("valid")
}

fn damage(mut bytes: Vec<u8>, cut: usize, flips: &[(usize, u8)]) -> Vec<u8> {
    for &(at, value) in flips {
        if !bytes.is_empty() {
            let n = bytes.len();
            bytes[at % n] = value;
        }
    }
    let keep = cut % (bytes.len() + 1);
    bytes.truncate(keep);
    bytes
}

fn must_not_panic<T>(result: Result<T, KinectError>) {
    // Either outcome is fine; an error must render as text naming what is wrong.
    if let Err(e) = result {
        assert!(!e.to_string().is_empty());
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn parsers_survive_random_bytes(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        let path = Path::new("<fuzz>");
        must_not_panic(parse_ply(&bytes));
        must_not_panic(parse_pcd(&bytes));
        must_not_panic(parse_xyz(&bytes, path));
        must_not_panic(decode_depth_image(&bytes, path, DEPTH_UNIT_MM_M));
        must_not_panic(decode_color_image(&bytes, path));
        must_not_panic(Calibration::from_json(&String::from_utf8_lossy(&bytes)));
    }

    #[test]
    fn parsers_survive_headers_with_random_bodies(
        body in prop::collection::vec(any::<u8>(), 0..256),
        count in 0usize..1_000_000_000,
    ) {
        let mut ply = format!("ply\nformat binary_little_endian 1.0\nelement vertex {count}\nproperty float x\nproperty float y\nproperty float z\nproperty list uchar int idx\nend_header\n").into_bytes();
        ply.extend_from_slice(&body);
        must_not_panic(parse_ply(&ply));
        let mut pcd = format!("VERSION .7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\nWIDTH {count}\nHEIGHT 1\nPOINTS {count}\nDATA binary_compressed\n").into_bytes();
        pcd.extend_from_slice(&body);
        must_not_panic(parse_pcd(&pcd));
        let mut pgm = format!("P5 {count} 1 65535\n").into_bytes();
        pgm.extend_from_slice(&body);
        must_not_panic(decode_depth_image(&pgm, Path::new("<fuzz>"), DEPTH_UNIT_MM_M));
    }

    #[test]
    fn parsers_survive_damaged_valid_files(
        cut in any::<usize>(),
        flips in prop::collection::vec((any::<usize>(), any::<u8>()), 0..4),
    ) {
        must_not_panic(parse_ply(&damage(valid_ply(), cut, &flips)));
        must_not_panic(parse_pcd(&damage(valid_pcd(true), cut, &flips)));
        must_not_panic(parse_pcd(&damage(valid_pcd(false), cut, &flips)));
        let json = Calibration::kinect_v2().to_json().into_bytes();
        must_not_panic(Calibration::from_json(&String::from_utf8_lossy(&damage(json, cut, &flips))));
    }

    #[test]
    fn recording_index_readers_survive_random_text(
        frames in prop::collection::vec(any::<u8>(), 0..300),
        rgb in prop::collection::vec(any::<u8>(), 0..200),
        depth in prop::collection::vec(any::<u8>(), 0..200),
    ) {
        // Native: a valid calibration with a random frames.csv (after the right header, so the
        // rows are what gets exercised).
        let native = temp_dir("frames-fuzz");
        Calibration::kinect_v2().write_json(&native.join(CALIBRATION_FILE)).expect("write");
        let mut text = format!("{FRAMES_HEADER}\n").into_bytes();
        text.extend_from_slice(&frames);
        std::fs::write(native.join(FRAMES_FILE), text).expect("write");
        if let Ok(recording) = Recording::open(&native) {
            for frame in recording.frames() {
                must_not_panic(frame);
            }
        }
        // TUM: random rgb.txt and depth.txt.
        let tum = temp_dir("tum-fuzz");
        std::fs::write(tum.join("rgb.txt"), &rgb).expect("write");
        std::fs::write(tum.join("depth.txt"), &depth).expect("write");
        if let Ok(recording) = Recording::open(&tum) {
            for frame in recording.frames() {
                must_not_panic(frame);
            }
        }
    }

    #[test]
    fn iai_kinect2_reader_survives_damaged_yaml(
        cut in any::<usize>(),
        flips in prop::collection::vec((any::<usize>(), any::<u8>()), 0..4),
    ) {
        let dir = temp_dir("iai-fuzz");
        write_iai(&dir);
        let path = dir.join("calib_ir.yaml");
        let text = std::fs::read(&path).expect("read");
        std::fs::write(&path, damage(text, cut, &flips)).expect("write");
        must_not_panic(Calibration::read_iai_kinect2(&dir));
    }
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

// ---------------------------------------------------------------------------------------------
// Real data (skipped when ../shared/data is absent).

/// The (upper) median of depths in metres.
fn median_m(mut z: Vec<f64>) -> f64 {
    z.sort_by(f64::total_cmp);
    z[z.len() / 2]
}

#[test]
fn real_iai_kinect2_calibrations() {
    let Some(data) = shared_kinect_data() else {
        return;
    };
    for serial in ["196605135147", "299150235147"] {
        let c = Calibration::read_iai_kinect2(&data.join("iai_kinect2_calib").join(serial))
            .expect("real calibration reads");
        let t = c.depth_to_color().expect("ok").expect("rigid");
        // Real Kinect V2 baselines are about 52 mm along x.
        let baseline_m = t.translation.vector.norm();
        assert!(
            (0.045..0.06).contains(&baseline_m),
            "{serial}: baseline {baseline_m} m"
        );
        assert!((350.0..380.0).contains(&c.depth_camera.fx), "{serial}");
        assert!((1000.0..1120.0).contains(&c.color_camera.fx), "{serial}");
    }
}

#[test]
fn real_tum_frame_gives_the_documented_share_of_valid_points() {
    let Some(data) = shared_kinect_data() else {
        return;
    };
    let dir = temp_dir("real-tum");
    let src = data.join("slambook_ch7_tum");
    std::fs::write(
        dir.join("rgb.txt"),
        format!("1.0 {}\n", src.join("1.png").display()),
    )
    .expect("w");
    std::fs::write(
        dir.join("depth.txt"),
        format!("1.0 {}\n", src.join("1_depth.png").display()),
    )
    .expect("w");
    let recording = Recording::open(&dir).expect("open");
    let frame = recording.frame(0).expect("real frame reads");
    let cloud = CloudBuilder::new(recording.calibration(), CloudConfig::default())
        .expect("ok")
        .build(&frame.depth, &frame.color)
        .expect("ok");
    // PROVENANCE: 33-34 % of each TUM frame is invalid; median valid depth about 1.5 m.
    let share = cloud.valid_count() as f64 / (640.0 * 480.0);
    assert!((0.64..0.68).contains(&share), "valid share {share}");
    let median = median_m(cloud.iter_valid().map(|(_, p)| p.position_m.z).collect());
    assert!((1.2..1.8).contains(&median), "median depth {median} m");
}

#[test]
fn real_pgm_depth_is_big_endian_millimetres() {
    let Some(data) = shared_kinect_data() else {
        return;
    };
    let depth = read_depth_image(
        &data.join("slambook_ch5_joinmap/depth/1.pgm"),
        DEPTH_UNIT_MM_M,
    )
    .expect("real PGM reads");
    assert_eq!((depth.width(), depth.height()), (640, 480));
    let median = median_m(
        (0..480)
            .flat_map(|v| (0..640).map(move |u| (u, v)))
            .filter_map(|(u, v)| depth.depth_m(u, v))
            .collect(),
    );
    // PROVENANCE: median valid depth 2.7-3.2 m in the joinMap frames.
    assert!((2.5..3.4).contains(&median), "median depth {median} m");
}

#[test]
fn real_azure_and_kinect_v2_images_decode() {
    let Some(data) = shared_kinect_data() else {
        return;
    };
    let depth = read_depth_image(
        &data.join("cameramodels_azure_kinect/k4a_depth_image_raw.png"),
        DEPTH_UNIT_MM_M,
    )
    .expect("Azure depth reads");
    assert_eq!((depth.width(), depth.height()), (512, 512));
    assert!(depth.valid_count() > 10_000);
    let hd = read_color_image(&data.join("cameramodels_kinect_v2/hd.jpg")).expect("HD colour");
    assert_eq!(hd.dimensions(), (1920, 1080));
    // A colour JPEG is not a depth image.
    assert!(
        read_depth_image(&data.join("cameramodels_kinect_v2/hd.jpg"), DEPTH_UNIT_MM_M).is_err()
    );
}

/// A JPEG of a textured scene (so the compressed data is long enough to cut anywhere).
fn textured_jpeg() -> Vec<u8> {
    let image = RgbImage::from_fn(160, 120, |x, y| {
        image::Rgb([
            (x * 7 % 256) as u8,
            (y * 13 % 256) as u8,
            ((x ^ y) % 256) as u8,
        ])
    });
    let mut bytes = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 90)
        .encode_image(&image)
        .unwrap();
    bytes
}

/// Issue 20: a colour JPEG cut to a quarter or a tenth decoded as grey without a word.
#[test]
fn a_truncated_jpeg_is_an_error_naming_the_file_not_grey_pixels() {
    let whole = textured_jpeg();
    let path = Path::new("frame_0007.jpg");
    assert!(decode_color_image(&whole, path).is_ok());
    // Data after the end-of-image marker (some cameras append metadata) is allowed.
    let mut appended = whole.clone();
    appended.extend_from_slice(b"trailing metadata");
    assert!(decode_color_image(&appended, path).is_ok());
    let n = whole.len();
    let mut cuts: Vec<usize> = (1..20).map(|k| n * k / 20).collect();
    cuts.extend([2, 3, 4, n - 2, n - 1]);
    for cut in cuts {
        let e = decode_color_image(&whole[..cut], path)
            .err()
            .unwrap_or_else(|| panic!("cut at {cut} of {n} bytes decoded"));
        assert!(e.to_string().contains("frame_0007.jpg"), "{e}");
    }
}

/// The structure check accepts every real JPEG in `../shared/data` (different encoders:
/// phones, Kinect v2 and Azure Kinect), when present.
#[test]
fn real_jpegs_pass_the_structure_check() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if !root.exists() {
        eprintln!("skipped: {} is not there", root.display());
        return;
    }
    let mut stack = vec![root];
    let mut checked = 0;
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let p = entry.path();
            if p.is_dir() {
                stack.push(p);
            } else if p
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("jpg") || e.eq_ignore_ascii_case("jpeg"))
            {
                let bytes = std::fs::read(&p).unwrap();
                if let Err(e) = decode_color_image(&bytes, &p) {
                    assert!(
                        !e.to_string().contains("corrupt JPEG"),
                        "{}: {e}",
                        p.display()
                    );
                }
                checked += 1;
            }
        }
    }
    eprintln!("{checked} real JPEGs checked");
}
