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
