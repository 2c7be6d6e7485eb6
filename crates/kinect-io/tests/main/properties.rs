//! Property tests: camera round trips, and no parser panics on random or damaged input.

use super::*;

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

pub(crate) fn damage(mut bytes: Vec<u8>, cut: usize, flips: &[(usize, u8)]) -> Vec<u8> {
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

pub(crate) fn must_not_panic<T>(result: Result<T, KinectError>) {
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
