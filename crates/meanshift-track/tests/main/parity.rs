//! Bit-for-bit parity with OpenCV (fixtures made by `fixtures/generate.py`).

use std::path::PathBuf;

use image::{GrayImage, RgbImage};
use meanshift_track::{
    BackProjector, ChannelOrder, ChannelRange, Histogram, HistogramSpec, HsvImage, ImageView,
    PixelRect, TermCriteria, cam_shift, gray_image, in_range, mean_shift,
};
use serde_json::Value;

fn fixture_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures")
}

fn rgb(name: &str) -> RgbImage {
    image::open(fixture_dir().join(name)).expect(name).to_rgb8()
}

fn gray(name: &str) -> GrayImage {
    image::open(fixture_dir().join(name))
        .expect(name)
        .to_luma8()
}

fn fixtures() -> Value {
    let text = std::fs::read_to_string(fixture_dir().join("fixtures.json")).expect("fixtures");
    serde_json::from_str(&text).expect("json")
}

fn f32s(v: &Value) -> Vec<f32> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|s| s.as_str().expect("string").parse::<f64>().expect("number") as f32)
        .collect()
}

fn usizes(v: &Value) -> Vec<usize> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_u64().expect("int") as usize)
        .collect()
}

fn rect(v: &Value) -> PixelRect {
    let a: Vec<i32> = v
        .as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_i64().expect("int") as i32)
        .collect();
    PixelRect::new(a[0], a[1], a[2], a[3])
}

fn count_diff(a: &[u8], b: &[u8]) -> usize {
    a.iter().zip(b).filter(|(x, y)| x != y).count()
}

#[test]
fn hsv_and_gray_match_opencv_on_the_colour_grid() {
    let grid = rgb("colour_grid.png");
    let rgb2hsv = HsvImage::from_image(&grid, ChannelOrder::Rgb);
    let expected = rgb("colour_grid_rgb2hsv.png");
    assert_eq!(count_diff(rgb2hsv.as_raw(), expected.as_raw()), 0);
    let bgr2hsv = HsvImage::from_image(&grid, ChannelOrder::Bgr);
    let expected = rgb("colour_grid_bgr2hsv.png");
    assert_eq!(count_diff(bgr2hsv.as_raw(), expected.as_raw()), 0);
    let g = gray_image(&grid, ChannelOrder::Rgb);
    assert_eq!(
        count_diff(g.as_raw(), gray("colour_grid_rgb2gray.png").as_raw()),
        0
    );
}

#[test]
fn in_range_matches_opencv() {
    let scene = rgb("scene.png");
    let hsv = HsvImage::from_image(&scene, ChannelOrder::Rgb);
    let range = ChannelRange {
        lower: [0, 60, 32],
        upper: [180, 255, 255],
    };
    let mask = in_range(ImageView::from(&hsv), &range).expect("3 channels");
    assert_eq!(
        count_diff(mask.as_raw(), gray("scene_mask.png").as_raw()),
        0
    );
}

#[test]
fn histograms_normalisation_and_back_projection_match_opencv() {
    let all = fixtures();
    let scene = rgb("scene.png");
    let hsv = HsvImage::from_image(&scene, ChannelOrder::Rgb);
    let scene_gray = gray("scene_gray.png");
    let mask = gray("scene_mask.png");
    let hists = all["histograms"].as_object().expect("object");
    assert!(hists.len() >= 8);
    for (name, h) in hists {
        let view = match h["image"].as_str().expect("image") {
            "hsv" => ImageView::from(&hsv),
            "gray" => ImageView::from(&scene_gray),
            _ => ImageView::from(&scene),
        };
        let ranges_flat = f32s(&Value::Array(
            h["ranges"]
                .as_array()
                .expect("ranges")
                .iter()
                .map(|v| Value::String(v.to_string()))
                .collect(),
        ));
        let spec = HistogramSpec {
            channels: usizes(&h["channels"]),
            bins: usizes(&h["bins"]),
            ranges: ranges_flat.chunks(2).map(|r| [r[0], r[1]]).collect(),
        };
        let roi = (!h["roi"].is_null()).then(|| rect(&h["roi"]));
        let use_mask = h["mask"].as_bool().expect("bool");
        let mut hist =
            Histogram::calc(view, spec, use_mask.then_some(&mask), roi).expect("valid hist");
        assert_eq!(
            hist.values(),
            f32s(&h["raw"]).as_slice(),
            "{name}: raw counts"
        );
        hist.normalize_min_max(0.0, 255.0).expect("finite");
        let norm = f32s(&h["normalized"]);
        for (k, (a, b)) in hist.values().iter().zip(&norm).enumerate() {
            assert_eq!(
                a.to_bits(),
                b.to_bits(),
                "{name}: normalised bin {k}: {a} vs {b}"
            );
        }
        if !h["backproject"].as_bool().expect("bool") {
            continue;
        }
        let bp = BackProjector::new(hist, 1.0)
            .expect("finite")
            .project(view)
            .expect("projects");
        let expected = gray(&format!("backproject_{name}.png"));
        assert_eq!(
            count_diff(bp.as_raw(), expected.as_raw()),
            0,
            "{name}: back-projection"
        );
    }
}

fn blob_frames(all: &Value) -> Vec<GrayImage> {
    let blobs = &all["blobs"];
    let (w, h) = (
        blobs["width"].as_u64().expect("w") as u32,
        blobs["height"].as_u64().expect("h") as u32,
    );
    let n = blobs["frames"].as_u64().expect("n") as u32;
    let stacked = gray("blobs.png");
    assert_eq!(stacked.dimensions(), (w, h * n));
    (0..n)
        .map(|k| image::imageops::crop_imm(&stacked, 0, k * h, w, h).to_image())
        .collect()
}

fn criteria(v: &Value) -> TermCriteria {
    TermCriteria {
        max_iterations: Some(v[0].as_u64().expect("count") as u32),
        epsilon_px: Some(v[1].as_f64().expect("eps")),
    }
}

#[test]
fn mean_shift_and_cam_shift_windows_equal_opencv() {
    let all = fixtures();
    let frames = blob_frames(&all);
    for run in all["blobs"]["runs"].as_array().expect("runs") {
        let mode = run["mode"].as_str().expect("mode");
        let start = rect(&run["start"]);
        let crit = criteria(&run["criteria"]);
        let mut window = start;
        for (k, (frame, step)) in frames
            .iter()
            .zip(run["steps"].as_array().expect("steps"))
            .enumerate()
        {
            if mode == "meanshift" {
                let r = mean_shift(frame, window, crit).expect("valid");
                assert_eq!(r.window, rect(&step["window"]), "meanShift frame {k}");
                assert_eq!(
                    u64::from(r.iterations),
                    step["iterations"].as_u64().expect("iters"),
                    "meanShift iterations frame {k}"
                );
                window = r.window;
            } else {
                let r = cam_shift(frame, window, crit).expect("valid");
                assert_eq!(r.window, rect(&step["window"]), "CamShift frame {k}");
                let b = f32s(&step["box"]);
                let got = [
                    r.rotated.center.x,
                    r.rotated.center.y,
                    r.rotated.width,
                    r.rotated.height,
                    r.rotated.angle_deg,
                ];
                for (g, e) in got.iter().zip(&b) {
                    // The box is derived from second moments in floating point; OpenCV may
                    // take them from IPP, so allow a few float ulps, not more.
                    assert!(
                        (*g as f32 - e).abs() <= 1e-4 * e.abs().max(1.0),
                        "CamShift box frame {k}: {got:?} vs {b:?}"
                    );
                }
                window = r.window;
            }
            if window.is_empty() {
                window = start;
            }
        }
    }
    for single in all["blobs"]["singles"].as_array().expect("singles") {
        let frame = &frames[single["frame"].as_u64().expect("frame") as usize];
        let r = mean_shift(frame, rect(&single["start"]), criteria(&single["criteria"]))
            .expect("valid");
        assert_eq!(r.window, rect(&single["window"]), "{single}");
        assert_eq!(
            u64::from(r.iterations),
            single["iterations"].as_u64().expect("iters"),
            "{single}"
        );
    }
}
