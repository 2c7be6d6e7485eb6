use super::*;
use crate::hsv::rgb_to_hsv;

#[test]
fn frames_are_reproducible_and_truth_matches_the_motion() {
    let cfg = StressConfig::condition(Condition::Baseline, 3);
    let scene = StressScene::new(&cfg).expect("valid");
    assert_eq!(scene.frames(), 120);
    let a = scene.frame(40).expect("in range");
    let b = scene.frame(40).expect("in range");
    assert_eq!(a, b);
    assert!(scene.frame(120).is_err());
    // At rest before the pull, every marker is where its window is.
    for (c, init) in scene.truth(0).iter().zip(scene.inits()) {
        assert!((c - init.window.center()).norm() < 2.5);
    }
    assert!(scene.visibility(0).iter().all(|&v| v >= FULLY_VISIBLE));
}

/// The release condition matches the clip it stands for: a streak of about 2.5 marker
/// widths, about a third less saturation, about 2.5 widths per frame at the fastest.
#[test]
fn release_at_240_fps_blurs_and_pales_as_the_real_clip() {
    let cfg = StressConfig::condition(Condition::Release240, 1);
    let scene = StressScene::new(&cfg).expect("valid");
    let d = scene.markers()[0].diameter_px;
    let (mut fastest, mut at) = (0.0, 0);
    for f in 1..scene.frames() {
        let step = (scene.truth(f)[0] - scene.truth(f - 1)[0]).norm();
        if step > fastest {
            (fastest, at) = (step, f);
        }
    }
    assert!(
        (2.2..=2.8).contains(&(fastest / d)),
        "{fastest} px / {d} px"
    );
    let max_sat = |img: &RgbImage, c: Point2<f64>| {
        let mut best = 0u8;
        for y in (c.y - 20.0) as u32..(c.y + 20.0) as u32 {
            for x in (c.x - 40.0) as u32..(c.x + 40.0) as u32 {
                if let Some(p) = img.get_pixel_checked(x, y) {
                    let hsv = rgb_to_hsv(p.0);
                    if hsv[0] < 10 || hsv[0] > 170 {
                        best = best.max(hsv[1]);
                    }
                }
            }
        }
        best
    };
    let still = max_sat(&scene.frame(0).expect("frame"), scene.truth(0)[0]);
    let moving = max_sat(&scene.frame(at).expect("frame"), scene.truth(at)[0]);
    let loss = 1.0 - f64::from(moving) / f64::from(still);
    assert!(
        (0.2..=0.45).contains(&loss),
        "saturation {still} -> {moving}"
    );
}

#[test]
fn jumps_are_two_to_five_windows_and_reentries_leave_the_frame() {
    let scene = StressScene::new(&StressConfig::condition(Condition::Jumps, 2)).expect("valid");
    let mut widest = 0.0f64;
    for k in 0..scene.markers().len() {
        let w = f64::from(scene.inits()[k].window.width);
        for f in 1..scene.frames() {
            let step = (scene.truth(f)[k] - scene.truth(f - 1)[k]).norm();
            widest = widest.max(step / w);
        }
    }
    assert!((2.0..=5.5).contains(&widest), "{widest}");
    let scene = StressScene::new(&StressConfig::condition(Condition::Reentry, 2)).expect("valid");
    let hidden = (0..scene.frames())
        .filter(|&f| scene.visibility(f).contains(&0.0))
        .count();
    assert!(hidden > 5, "{hidden}");
}

#[test]
fn occlusions_hide_markers_for_their_frames() {
    let scene = StressScene::new(&StressConfig::condition(Condition::Occlusion, 4)).expect("valid");
    for e in &scene.occlusions {
        for f in e.start..e.start + e.frames {
            assert_eq!(scene.visibility(f)[e.marker], 0.0, "{e:?} frame {f}");
        }
        let before = scene.visibility(e.start - 1)[e.marker];
        assert!(before > 0.0 && before < 1.0, "{before}");
    }
}

#[test]
fn bad_configs_are_errors() {
    let good = StressConfig::condition(Condition::Baseline, 0);
    for bad in [
        StressConfig {
            width: 10,
            ..good.clone()
        },
        StressConfig {
            width: 100_000,
            ..good.clone()
        },
        StressConfig {
            fps_hz: 0.0,
            ..good.clone()
        },
        StressConfig {
            duration_s: 1e12,
            ..good.clone()
        },
        StressConfig {
            markers: 0,
            ..good.clone()
        },
        StressConfig {
            markers: 1000,
            ..good.clone()
        },
        StressConfig {
            amplitude_px: [5.0, 1.0],
            ..good.clone()
        },
        StressConfig {
            damping_ratio: [0.0, 1.5],
            ..good.clone()
        },
        StressConfig {
            release_s: 0.1,
            ..good.clone()
        },
        StressConfig {
            flicker: f64::NAN,
            ..good.clone()
        },
        StressConfig {
            jpeg_quality: Some([0, 50]),
            ..good.clone()
        },
        StressConfig {
            crossing_pairs: 5,
            ..good.clone()
        },
        StressConfig {
            occlusion_frames: [0, 3],
            ..good.clone()
        },
    ] {
        assert!(StressScene::new(&bad).is_err(), "{bad:?}");
    }
    for c in Condition::ALL {
        assert_eq!(Condition::from_name(c.name()), Some(c));
        StressConfig::condition(c, 0)
            .validate()
            .expect("presets are valid");
    }
}

/// Where the motion changes within the exposure (a swing turning, a release, the start of a
/// camera shake), the truth is the centre of the streak the frame shows, not the marker's
/// place at mid-exposure: at 30 fps with the whole frame exposed, a swing's turn draws a
/// streak out and back whose centre lies inside the turning point.
#[test]
fn the_truth_of_a_blurred_frame_is_the_streaks_centre() {
    let cfg = StressConfig {
        stems: false,
        fps_hz: 30.0,
        duration_s: 1.5,
        release_s: 10.0 / 30.0,
        amplitude_px: [40.0, 50.0],
        frequency_hz: [2.0, 2.5],
        exposure_fraction: 1.0,
        shake_px: 12.0,
        ..StressConfig::condition(Condition::Release240, 1)
    };
    let scene = StressScene::new(&cfg).expect("valid");
    let apart = |f: usize| (scene.truth(f)[0] - scene.mid_exposure(f)[0]).norm();
    let f = (1..scene.frames())
        .max_by(|&a, &b| apart(a).total_cmp(&apart(b)))
        .expect("frames");
    assert!(apart(f) > 2.0, "frame {f}: {} px", apart(f));
    // The streak's centre: pixels weighed by how much of the exposure the marker covered
    // them, against the wall's colour (the median of the frame).
    let frame = scene.frame(f).expect("frame");
    let median = |c: usize| {
        let mut v: Vec<u8> = frame.pixels().map(|p| p.0[c]).collect();
        let mid = v.len() / 2;
        f64::from(*v.select_nth_unstable(mid).1)
    };
    let g = [median(0), median(1), median(2)];
    let m = scene.markers()[0].rgb.map(f64::from);
    let d = [m[0] - g[0], m[1] - g[1], m[2] - g[2]];
    let dd = d.iter().map(|v| v * v).sum::<f64>();
    let (mut sum, mut weight) = (Vector2::zeros(), 0.0);
    for (x, y, p) in frame.enumerate_pixels() {
        let e = [0, 1, 2].map(|c| f64::from(p.0[c]) - g[c]);
        let a = (e.iter().zip(&d).map(|(e, d)| e * d).sum::<f64>() / dd).clamp(0.0, 1.0);
        if a > 0.1 {
            sum += Vector2::new(f64::from(x), f64::from(y)) * a;
            weight += a;
        }
    }
    let centre = Point2::from(sum / weight);
    let c = scene.truth(f)[0];
    let (to_truth, to_mid) = (
        (centre - c).norm(),
        (centre - scene.mid_exposure(f)[0]).norm(),
    );
    assert!(
        to_truth < 0.5 && to_mid > 2.0,
        "streak centre {centre}: {to_truth} px from the truth, {to_mid} px from mid-exposure"
    );
}
