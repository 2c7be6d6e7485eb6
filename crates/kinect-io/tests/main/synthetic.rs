//! End to end on synthetic captures: lifts, the projection image, world-frame clouds.

use super::*;

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
