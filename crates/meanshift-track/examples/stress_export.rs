//! Write stress sequences to disk, for trackers that are not ours (OpenCV's meanShift and
//! CamShift in `eval/stress_opencv.py`) and for `track_markers`.
//!
//! ```text
//! cargo run --release -p meanshift-track --example stress_export -- <OUT_DIR> <CONDITION> <SEED>
//! ```
//!
//! `OUT_DIR` receives `f0000.png`, `f0001.png`, ... (the frames, lossless: a JPEG condition's
//! artefacts are already in the pixels), `init.json` (the windows on the first frame, in
//! `track_markers`' format) and `truth.json`: `{"condition", "seed", "fps_hz", "ids",
//! "truth": [[[x, y] per marker] per frame], "visibility": [[0..1 per marker] per frame],
//! "fully_visible"}`. Conditions: the names of `stress::Condition` (`baseline`, `blur`, ...).

use std::path::PathBuf;
use std::process::ExitCode;

use meanshift_track::stress::{Condition, FULLY_VISIBLE, StressConfig, StressScene};
use serde::Serialize;

#[derive(Serialize)]
struct Window<'a> {
    id: &'a str,
    x: i32,
    y: i32,
    w: i32,
    h: i32,
}

#[derive(Serialize)]
struct Truth<'a> {
    condition: &'a str,
    seed: u64,
    fps_hz: f64,
    ids: Vec<&'a str>,
    truth: Vec<Vec<[f64; 2]>>,
    visibility: Vec<Vec<f64>>,
    fully_visible: f64,
}

const USAGE: &str = "usage: stress_export <OUT_DIR> <CONDITION> <SEED>";

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("stress_export: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [out, condition, seed] = args.as_slice() else {
        return Err(format!(
            "{USAGE}\nconditions: {}",
            Condition::ALL.map(|c| c.name()).join(", ")
        ));
    };
    let out = PathBuf::from(out);
    let condition = Condition::from_name(condition).ok_or_else(|| {
        format!(
            "unknown condition {condition:?}; one of {}",
            Condition::ALL.map(|c| c.name()).join(", ")
        )
    })?;
    let seed: u64 = seed.parse().map_err(|e| format!("seed {seed:?}: {e}"))?;
    let config = StressConfig::condition(condition, seed);
    let scene = StressScene::new(&config).map_err(|e| e.to_string())?;
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let mut truth = Vec::with_capacity(scene.frames());
    let mut visibility = Vec::with_capacity(scene.frames());
    for f in 0..scene.frames() {
        let frame = scene.frame(f).map_err(|e| e.to_string())?;
        let path = out.join(format!("f{f:04}.png"));
        frame
            .save(&path)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        truth.push(scene.truth(f).iter().map(|p| [p.x, p.y]).collect());
        visibility.push(scene.visibility(f));
    }
    let windows: Vec<Window<'_>> = scene
        .inits()
        .iter()
        .map(|m| Window {
            id: &m.id,
            x: m.window.x,
            y: m.window.y,
            w: m.window.width,
            h: m.window.height,
        })
        .collect();
    let record = Truth {
        condition: condition.name(),
        seed,
        fps_hz: config.fps_hz,
        ids: scene.inits().iter().map(|m| m.id.as_str()).collect(),
        truth,
        visibility,
        fully_visible: FULLY_VISIBLE,
    };
    let write = |name: &str, text: String| {
        let path = out.join(name);
        std::fs::write(&path, text + "\n").map_err(|e| format!("{}: {e}", path.display()))
    };
    write(
        "init.json",
        serde_json::to_string(&windows).map_err(|e| e.to_string())?,
    )?;
    write(
        "truth.json",
        serde_json::to_string(&record).map_err(|e| e.to_string())?,
    )?;
    Ok(())
}
