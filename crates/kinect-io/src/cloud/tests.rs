//! Unit tests of `cloud`.
use super::*;
use crate::calibration::Calibration;
use approx::assert_relative_eq;

fn flat_wall(calibration: &Calibration, depth_raw: u16) -> (DepthImage, RgbImage) {
    let d = calibration.depth_camera;
    let c = calibration.color_camera;
    let depth = DepthImage::new(
        d.width,
        d.height,
        calibration.depth_unit_m,
        vec![depth_raw; d.pixel_count()],
    )
    .expect("size");
    let color = RgbImage::from_fn(c.width, c.height, |u, v| {
        image::Rgb([(u % 256) as u8, (v % 256) as u8, 7])
    });
    (depth, color)
}

#[test]
fn wall_points_have_the_wall_depth_and_the_colour_of_their_projection() {
    let calibration = Calibration::kinect_v2();
    let (depth, color) = flat_wall(&calibration, 2000);
    let mut builder = CloudBuilder::new(&calibration, CloudConfig::default()).expect("valid");
    let cloud = builder.build(&depth, &color).expect("valid depth");
    assert_eq!(cloud.valid_count(), calibration.depth_camera.pixel_count());
    let p = cloud.get(256, 207).expect("centre");
    assert_relative_eq!(p.position_m.z, 2.0, epsilon = 1e-12);
    // Its colour is the colour pixel it projects to.
    let t = calibration.depth_to_color().expect("rigid").expect("some");
    let px = calibration
        .color_camera
        .project(&(t * p.position_m))
        .expect("front");
    let expected = color.get_pixel((px.x + 0.5).floor() as u32, (px.y + 0.5).floor() as u32);
    assert_eq!(p.rgb, Some(expected.0));
}

#[test]
fn all_zero_depth_is_an_error() {
    let calibration = Calibration::kinect_v2();
    let (depth, color) = flat_wall(&calibration, 0);
    let mut builder = CloudBuilder::new(&calibration, CloudConfig::default()).expect("valid");
    assert!(matches!(
        builder.build(&depth, &color),
        Err(KinectError::NoValidDepth { .. })
    ));
}

#[test]
fn mismatched_sizes_are_errors() {
    let calibration = Calibration::kinect_v2();
    let (_, color) = flat_wall(&calibration, 1000);
    let depth = DepthImage::new(640, 480, 0.001, vec![1000; 640 * 480]).expect("size");
    let mut builder = CloudBuilder::new(&calibration, CloudConfig::default()).expect("valid");
    assert!(matches!(
        builder.build(&depth, &color),
        Err(KinectError::SizeMismatch {
            expected_width: 512,
            found_width: 640,
            ..
        })
    ));
}

#[test]
fn occluded_background_loses_its_colour() {
    let calibration = Calibration::kinect_v2();
    let (mut depth, color) = flat_wall(&calibration, 3000);
    // A near post in front of the wall.
    for v in 0..424 {
        for u in 240..260 {
            depth.values_mut()[v * 512 + u] = 1000;
        }
    }
    let mut filtered = CloudBuilder::new(&calibration, CloudConfig::default()).expect("ok");
    let mut plain = CloudBuilder::new(
        &calibration,
        CloudConfig {
            occlusion_filter: None,
            ..CloudConfig::default()
        },
    )
    .expect("ok");
    let a = filtered.build(&depth, &color).expect("ok");
    let b = plain.build(&depth, &color).expect("ok");
    let coloured = |c: &TexturedCloud| c.iter_valid().filter(|(_, p)| p.rgb.is_some()).count();
    assert!(
        coloured(&a) < coloured(&b),
        "{} vs {}",
        coloured(&a),
        coloured(&b)
    );
    assert!(
        a.get(250, 200).and_then(|p| p.rgb).is_some(),
        "the post keeps its colour"
    );
}

#[test]
fn occlusion_filter_matches_a_brute_force_reference() {
    use crate::synth;
    let mut config = synth::SynthConfig::kinect_v2(2.2, 1.1, 3);
    config.calibration.color_camera = config.calibration.color_camera.scaled(0.5).expect("valid");
    let frame = synth::render(&synth::demo_tree(3), &config).expect("renders");
    let calibration = &config.calibration;
    let filter = OcclusionFilter::default();
    let mut builder = CloudBuilder::new(calibration, CloudConfig::default()).expect("ok");
    // A first frame leaves stale cells behind; the second must not be misled by them.
    let d = calibration.depth_camera;
    let near_wall =
        DepthImage::new(d.width, d.height, 0.001, vec![900; d.pixel_count()]).expect("size");
    builder.build(&near_wall, &frame.color).expect("ok");
    let cloud = builder.build(&frame.depth, &frame.color).expect("ok");
    // Reference: every point's colour pixel and colour-camera depth, then for each point
    // the nearest depth of any point whose colour pixel is within the window.
    let t = calibration.depth_to_color().expect("ok").expect("rigid");
    let cam = calibration.color_camera;
    let projected: Vec<Option<(i64, i64, f64)>> = (0..cloud.len())
        .map(|i| {
            let pc = t * cloud.position_m(i)?;
            let px = cam.project(&pc)?;
            let (u, v) = cam.pixel_at(&px)?;
            Some((i64::from(u), i64::from(v), pc.z))
        })
        .collect();
    let mut nearest = std::collections::HashMap::<(i64, i64), f64>::new();
    for &(u, v, z) in projected.iter().flatten() {
        let e = nearest.entry((u, v)).or_insert(f64::INFINITY);
        *e = e.min(z);
    }
    let (hw, hh) = (
        i64::from(filter.half_width_px),
        i64::from(filter.half_height_px),
    );
    let (mut checked, mut hidden) = (0, 0);
    for (i, proj) in projected.iter().enumerate() {
        let (Some(p), Some((u, v, z))) = (cloud.point(i), proj) else {
            continue;
        };
        let mut m = f64::INFINITY;
        for y in v - hh..=v + hh {
            for x in u - hw..=u + hw {
                m = m.min(nearest.get(&(x, y)).copied().unwrap_or(f64::INFINITY));
            }
        }
        let occluded = (z - m) / z > filter.tolerance;
        // Skip razor-edge cases where 0.1 mm quantisation may decide.
        if ((z - m) / z - filter.tolerance).abs() < 1e-4 {
            continue;
        }
        assert_eq!(
            p.rgb.is_none(),
            occluded,
            "point at {u},{v} z {z} nearest {m}"
        );
        checked += 1;
        hidden += usize::from(occluded);
    }
    assert!(checked > 10_000, "{checked}");
    // The frame has occlusion to find, and most points are seen.
    assert!(
        hidden > 100 && hidden < checked / 4,
        "{hidden} of {checked}"
    );
}

#[test]
fn freenect2_pinhole_model_matches_the_rigid_model() {
    use crate::freenect2::{Freenect2ColorParams, Freenect2IrParams};
    let ir = Freenect2IrParams {
        k1: 0.0,
        k2: 0.0,
        k3: 0.0,
        ..Freenect2IrParams::kinect_v2_typical()
    };
    let color = Freenect2ColorParams::from_pinhole_baseline(&ir, 1081.37, 959.5, 539.5, 52.0);
    let f2 = Calibration::freenect2(ir, color);
    let mut rigid = f2.clone();
    rigid.registration =
        crate::calibration::RegistrationModel::Rigid(crate::calibration::Extrinsics {
            translation_m: [0.052, 0.0, 0.0],
            ..crate::calibration::Extrinsics::identity()
        });
    let (depth, colour) = flat_wall(&f2, 1500);
    let config = CloudConfig {
        occlusion_filter: None,
        ..CloudConfig::default()
    };
    let a = CloudBuilder::new(&f2, config)
        .expect("ok")
        .build(&depth, &colour)
        .expect("ok");
    let b = CloudBuilder::new(&rigid, config)
        .expect("ok")
        .build(&depth, &colour)
        .expect("ok");
    let mut same = 0;
    let mut total = 0;
    for i in 0..a.len() {
        if let (Some(pa), Some(pb)) = (a.point(i), b.point(i)) {
            assert_relative_eq!(pa.position_m, pb.position_m, epsilon = 1e-9);
            total += 1;
            same += usize::from(pa.rgb == pb.rgb);
        }
    }
    // Rounding of f32 vs f64 may move a colour pixel at exact half-pixel ties only.
    assert!(same * 1000 >= total * 999, "{same} of {total}");
}

#[test]
fn a_transform_in_the_config_or_afterwards_moves_every_point_the_same() {
    let calibration = Calibration::kinect_v2();
    let (mut depth, color) = flat_wall(&calibration, 1800);
    // A hole and a nearer patch, so that not every entry is the same.
    let w = calibration.depth_camera.width as usize;
    for (i, d) in depth.values_mut().iter_mut().enumerate() {
        if i % w < 40 {
            *d = 0;
        } else if (i / w) % 50 < 10 {
            *d = 1200;
        }
    }
    let world = Isometry3::new(Vector3::new(0.3, -1.2, 2.0), Vector3::new(0.2, -0.4, 1.1));
    let plain = CloudBuilder::new(&calibration, CloudConfig::default())
        .expect("ok")
        .build(&depth, &color)
        .expect("ok");
    let config = CloudConfig {
        camera_to_world: Some(world),
        ..CloudConfig::default()
    };
    let moved = CloudBuilder::new(&calibration, config)
        .expect("ok")
        .build(&depth, &color)
        .expect("ok");
    let after = plain.transformed(&world);
    assert_eq!(moved.valid_count(), plain.valid_count());
    assert!(plain.valid_count() < plain.len());
    let mut checked = 0;
    for i in 0..plain.len() {
        let (Some(p), Some(m), Some(a)) = (plain.point(i), moved.point(i), after.point(i)) else {
            assert!(plain.point(i).is_none() && moved.point(i).is_none());
            assert!(after.point(i).is_none());
            continue;
        };
        assert_relative_eq!(m.position_m, world * p.position_m, epsilon = 1e-12);
        assert_relative_eq!(a.position_m, m.position_m, epsilon = 1e-12);
        assert_eq!((m.rgb, a.rgb), (p.rgb, p.rgb));
        // The packed depth is the point's z in its own camera.
        assert_relative_eq!(moved.depths_m()[i], p.position_m.z, epsilon = 1e-12);
        checked += 1;
    }
    assert_eq!(checked, plain.valid_count());
    // iter_valid, point, get and position_m agree.
    for (i, p) in moved.iter_valid() {
        let (u, v) = ((i % w) as u32, (i / w) as u32);
        assert_eq!(moved.get(u, v), Some(p));
        assert_eq!(moved.position_m(i), Some(p.position_m));
        assert_eq!(moved.color(i), p.rgb);
    }
    assert_eq!(moved.point(moved.len()), None);
    assert_eq!(moved.get(moved.width(), 0), None);
}

#[test]
fn a_hand_made_cloud_checks_its_inputs_and_keeps_them() {
    let camera = Calibration::kinect_v2().depth_camera;
    let n = camera.pixel_count();
    let mut depths = vec![0.0; n];
    let mut colours = vec![None; n];
    depths[1000] = 2.5;
    colours[1000] = Some([1, 2, 3]);
    depths[2000] = 1.5;
    // A colour where there is no point is not a point.
    colours[3000] = Some([9, 9, 9]);
    let cloud =
        TexturedCloud::new(camera, depths.clone(), &colours, Isometry3::identity()).expect("valid");
    assert_eq!(cloud.valid_count(), 2);
    let p = cloud.point(1000).expect("point");
    assert_eq!(p.rgb, Some([1, 2, 3]));
    assert_relative_eq!(p.position_m.z, 2.5, epsilon = 1e-12);
    // On its pixel's ray: it projects back onto its own pixel.
    let px = camera.project(&p.position_m).expect("in front");
    let w = camera.width as usize;
    assert_eq!(
        camera.pixel_at(&px),
        Some(((1000 % w) as u32, (1000 / w) as u32))
    );
    assert_eq!(cloud.point(2000).and_then(|p| p.rgb), None);
    assert_eq!(cloud.point(3000), None);
    assert_eq!(cloud.color(3000), None);
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        let mut d = depths.clone();
        d[5] = bad;
        let err = TexturedCloud::new(camera, d, &colours, Isometry3::identity());
        assert!(
            matches!(err, Err(KinectError::InvalidParameter { .. })),
            "{bad}: {err:?}"
        );
    }
    let short = TexturedCloud::new(camera, vec![1.0; n - 1], &colours, Isometry3::identity());
    assert!(matches!(short, Err(KinectError::SizeMismatch { .. })));
    let short = TexturedCloud::new(camera, depths, &colours[1..], Isometry3::identity());
    assert!(matches!(short, Err(KinectError::SizeMismatch { .. })));
}

#[test]
fn filter_settings_out_of_range_are_refused_by_name() {
    let calibration = Calibration::kinect_v2();
    let with = |filter: OcclusionFilter| CloudConfig {
        occlusion_filter: Some(filter),
        ..CloudConfig::default()
    };
    let widest = OcclusionFilter {
        half_width_px: MAX_OCCLUSION_HALF_WINDOW_PX,
        half_height_px: MAX_OCCLUSION_HALF_WINDOW_PX,
        ..OcclusionFilter::default()
    };
    assert!(CloudBuilder::new(&calibration, with(widest)).is_ok());
    for bad in [
        OcclusionFilter {
            half_width_px: MAX_OCCLUSION_HALF_WINDOW_PX + 1,
            ..OcclusionFilter::default()
        },
        OcclusionFilter {
            half_height_px: u32::MAX,
            ..OcclusionFilter::default()
        },
        OcclusionFilter {
            tolerance: f64::NAN,
            ..OcclusionFilter::default()
        },
    ] {
        match CloudBuilder::new(&calibration, with(bad)) {
            Err(KinectError::InvalidParameter { name, .. }) => {
                assert!(name.starts_with("occlusion filter"), "{name}");
            }
            other => panic!("{bad:?}: {:?}", other.err()),
        }
    }
}
