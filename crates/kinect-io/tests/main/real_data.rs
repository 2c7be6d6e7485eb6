//! Real data (skipped with a printed reason when ../shared/data is absent).

use super::*;

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
