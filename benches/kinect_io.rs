//! kinect-io speed on realistic sizes: a Kinect V2 frame (512x424 depth, 1920x1080 colour) to
//! an organized textured cloud (rigid and libfreenect2 registration), to projection images on
//! the depth and colour planes, and lifting markers; and real frames (TUM, Azure Kinect; read
//! from `../shared/data/kinect`, skipped when absent) to compare with Open3D. Figures:
//! `docs/benchmarks.md`.

// A bench that cannot set up its data has nothing to measure: failing loudly is right here.
#![allow(clippy::expect_used, clippy::missing_panics_doc)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};

#[path = "common/real_frames.rs"]
mod real_frames;
use treemocap::kinect_io::synth::{self, SynthConfig};
use treemocap::kinect_io::{
    Calibration, CloudBuilder, CloudConfig, DepthImage, Freenect2ColorParams, Freenect2IrParams,
    LiftConfig, ProjectionConfig, project_cloud,
};
use treemocap::nalgebra::Isometry3;

#[allow(clippy::too_many_lines)] // longer than 100 lines; to be split by concept (issue 21)
fn kinect_io(c: &mut Criterion) {
    let config = SynthConfig::kinect_v2(2.2, 1.1, 7);
    let frame = synth::render(&synth::demo_tree(7), &config).expect("demo scene renders");
    let calibration = config.calibration.clone();
    let mut group = c.benchmark_group("kinect_io");

    let mut builder = CloudBuilder::new(&calibration, CloudConfig::default()).expect("valid");
    let mut cloud = builder
        .build(&frame.depth, &frame.color)
        .expect("valid frame");
    group.bench_function("cloud_rigid_registration_512x424", |b| {
        b.iter(|| {
            builder
                .build_into(black_box(&frame.depth), black_box(&frame.color), &mut cloud)
                .expect("valid frame")
        })
    });

    // Worst case: every depth pixel valid (a wall at 2 m filling the view).
    let wall = DepthImage::new(
        frame.depth.width(),
        frame.depth.height(),
        frame.depth.unit_m(),
        vec![2000; frame.depth.values().len()],
    )
    .expect("valid size");
    let mut wall_cloud = builder.build(&wall, &frame.color).expect("valid frame");
    group.bench_function("cloud_rigid_registration_all_pixels_valid_512x424", |b| {
        b.iter(|| {
            builder
                .build_into(black_box(&wall), black_box(&frame.color), &mut wall_cloud)
                .expect("valid frame")
        })
    });

    let mut plain = CloudBuilder::new(
        &calibration,
        CloudConfig {
            occlusion_filter: None,
            ..CloudConfig::default()
        },
    )
    .expect("valid");
    group.bench_function("cloud_rigid_registration_no_filter_512x424", |b| {
        b.iter(|| {
            plain
                .build_into(black_box(&frame.depth), black_box(&frame.color), &mut cloud)
                .expect("valid frame")
        })
    });
    group.bench_function(
        "cloud_rigid_registration_no_filter_all_pixels_valid_512x424",
        |b| {
            b.iter(|| {
                plain
                    .build_into(black_box(&wall), black_box(&frame.color), &mut cloud)
                    .expect("valid frame")
            })
        },
    );

    let ir = Freenect2IrParams::kinect_v2_typical();
    let color = Freenect2ColorParams::from_pinhole_baseline(&ir, 1081.37, 959.5, 539.5, 52.0);
    let f2 = Calibration::freenect2(ir, color);
    let mut f2_builder = CloudBuilder::new(&f2, CloudConfig::default()).expect("valid");
    let mut f2_cloud = f2_builder
        .build(&frame.depth, &frame.color)
        .expect("valid frame");
    group.bench_function("cloud_freenect2_registration_512x424", |b| {
        b.iter(|| {
            f2_builder
                .build_into(
                    black_box(&frame.depth),
                    black_box(&frame.color),
                    &mut f2_cloud,
                )
                .expect("valid frame")
        })
    });

    let proj_config = ProjectionConfig::default();
    let mut on_depth = project_cloud(
        &cloud,
        &calibration.depth_camera,
        &Isometry3::identity(),
        &proj_config,
    )
    .expect("valid camera");
    group.bench_function("projection_depth_plane_512x424", |b| {
        b.iter(|| {
            on_depth
                .update(black_box(&cloud), &proj_config)
                .expect("small cloud")
        })
    });

    let mut on_depth_wall = on_depth.clone();
    group.bench_function("projection_depth_plane_all_pixels_valid_512x424", |b| {
        b.iter(|| {
            on_depth_wall
                .update(black_box(&wall_cloud), &proj_config)
                .expect("small cloud")
        })
    });

    let depth_to_color = calibration.depth_to_color().expect("valid").expect("rigid");
    let mut on_color = project_cloud(
        &cloud,
        &calibration.color_camera,
        &depth_to_color,
        &proj_config,
    )
    .expect("valid camera");
    group.bench_function("projection_color_plane_1920x1080", |b| {
        b.iter(|| {
            on_color
                .update(black_box(&cloud), &proj_config)
                .expect("small cloud")
        })
    });

    let pixels: Vec<_> = frame.markers.iter().filter_map(|m| m.color_pixel).collect();
    let lift = LiftConfig::default();
    let mut scratch = Vec::new();
    group.bench_function("lift_10_markers", |b| {
        b.iter(|| {
            for p in &pixels {
                black_box(on_color.lift_with(&cloud, p, &lift, &mut scratch));
            }
        })
    });
    group.finish();
}

/// Issue 23: the textured cloud of real frames, side by side with Open3D
/// (`crates/kinect-io/fixtures/open3d_cloud_timing.py` times the same frames).
fn real_frames(c: &mut Criterion) {
    let Some(data) = real_frames::shared_kinect_data() else {
        println!("skipped real-frame cloud benches: ../shared/data/kinect is absent");
        return;
    };
    let mut group = c.benchmark_group("kinect_io");
    let tum = real_frames::tum(&data).expect("TUM frame");
    let (color, depth) = (&tum.color, &tum.depth);
    let mut builder = CloudBuilder::new(&tum.calibration, CloudConfig::default()).expect("valid");
    let mut cloud = builder.build(depth, color).expect("valid frame");
    group.bench_function("cloud_tum_registered_640x480", |b| {
        b.iter(|| builder.build_into(depth, color, &mut cloud).expect("ok"));
    });
    group.bench_function("cloud_tum_registered_new_cloud_640x480", |b| {
        b.iter(|| black_box(builder.build(depth, color).expect("ok")));
    });
    // Azure Kinect frame with its depth registered to the colour camera (1280x720), as the
    // Azure Kinect SDK's transformation gives it and Open3D takes it.
    let registered = real_frames::azure_registered(&data).expect("registered Azure frame");
    let (color_r, depth_r) = (&registered.color, &registered.depth);
    let mut builder =
        CloudBuilder::new(&registered.calibration, CloudConfig::default()).expect("valid");
    let mut cloud = builder.build(depth_r, color_r).expect("valid frame");
    group.bench_function("cloud_azure_registered_1280x720", |b| {
        b.iter(|| {
            builder
                .build_into(depth_r, color_r, &mut cloud)
                .expect("ok")
        });
    });
    // Azure Kinect, WFOV 2x2 binned depth (512x512) and 720p colour, rational distortion
    // on both cameras, rigid registration.
    let azure = real_frames::azure(&data).expect("Azure Kinect frame");
    let (calibration, color, depth) = (&azure.calibration, &azure.color, &azure.depth);
    for (name, config) in [
        ("cloud_azure_wfov_rigid_512x512", CloudConfig::default()),
        (
            "cloud_azure_wfov_rigid_no_filter_512x512",
            CloudConfig {
                occlusion_filter: None,
                ..CloudConfig::default()
            },
        ),
    ] {
        let mut builder = CloudBuilder::new(calibration, config).expect("valid");
        let mut cloud = builder.build(depth, color).expect("valid frame");
        group.bench_function(name, |b| {
            b.iter(|| builder.build_into(depth, color, &mut cloud).expect("ok"));
        });
    }
    group.finish();
}

criterion_group!(benches, kinect_io, real_frames);
criterion_main!(benches);
