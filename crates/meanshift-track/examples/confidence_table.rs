//! What a confidence value is worth: over every frame the tracker reports found (`tracked` or
//! `recovered`) in the stress sequences of the given conditions and seeds, how often the
//! centre was within 3 px of the marker's true centre and how often more than 8 px off, by
//! status and confidence band. The table in `docs/validation.md` ("What a confidence value
//! means") comes from this program.
//!
//! ```text
//! cargo run --release -p meanshift-track --example confidence_table -- <CONDITIONS|all> <FIRST_SEED> <LAST_SEED>
//! ```
//!
//! `CONDITIONS`: names of `stress::Condition` separated by commas (`baseline,blur`), or
//! `all`. Seeds from `FIRST_SEED` to `LAST_SEED`, both included (tuning seeds are 0..8,
//! evaluation seeds 1000 and up). Progress goes to stderr, the Markdown table to stdout.

use std::process::ExitCode;

use meanshift_track::stress::{Condition, StressConfig, StressScene};
use meanshift_track::{TrackStatus, Tracker, TrackerConfig};

const USAGE: &str = "usage: confidence_table <CONDITIONS|all> <FIRST_SEED> <LAST_SEED>";
/// Confidence bands, lower bounds included (the last band holds 1).
const BANDS: [(f64, f64); 4] = [(0.0, 0.6), (0.6, 0.8), (0.8, 0.95), (0.95, 1.0)];
/// Within this distance of the truth a centre is right (the stress evaluation's tolerance).
const RIGHT_PX: f64 = 3.0;
/// Beyond this distance a found frame is a false report (the issue's 8 px).
const WRONG_PX: f64 = 8.0;

/// Frames, within [`RIGHT_PX`], beyond [`WRONG_PX`].
type Counts = [usize; 3];

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("confidence_table: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [conditions, first, last] = args.as_slice() else {
        return Err(format!(
            "{USAGE}\nconditions: {}",
            Condition::ALL.map(|c| c.name()).join(", ")
        ));
    };
    let conditions: Vec<Condition> = if conditions == "all" {
        Condition::ALL.to_vec()
    } else {
        conditions
            .split(',')
            .map(|name| {
                Condition::from_name(name).ok_or_else(|| {
                    format!(
                        "unknown condition {name:?}; one of {}",
                        Condition::ALL.map(|c| c.name()).join(", ")
                    )
                })
            })
            .collect::<Result<_, _>>()?
    };
    let seed = |s: &String| s.parse::<u64>().map_err(|e| format!("seed {s:?}: {e}"));
    let (first, last) = (seed(first)?, seed(last)?);
    if first > last {
        return Err(format!("first seed {first} after last seed {last}"));
    }
    // [tracked, recovered] x band.
    let mut counts = [[[0usize; 3]; BANDS.len()]; 2];
    for condition in conditions {
        for seed in first..=last {
            eprintln!("{} seed {seed}", condition.name());
            tally(condition, seed, &mut counts)?;
        }
    }
    println!("| status | confidence | frames | within 3 px | more than 8 px off |");
    println!("| --- | --- | --- | --- | --- |");
    for (status, bands) in ["tracked", "recovered"].iter().zip(&counts) {
        for ((lo, hi), &[n, right, wrong]) in BANDS.iter().zip(bands) {
            let share = |k: usize| 100.0 * k as f64 / n.max(1) as f64;
            println!(
                "| {status} | {lo:.2}–{hi:.2} | {n} | {right} ({:.1} %) | {wrong} ({:.1} %) |",
                share(right),
                share(wrong)
            );
        }
    }
    Ok(())
}

/// Track one stress sequence with the default tracker and add its found frames to `counts`.
fn tally(
    condition: Condition,
    seed: u64,
    counts: &mut [[Counts; BANDS.len()]; 2],
) -> Result<(), String> {
    let scene =
        StressScene::new(&StressConfig::condition(condition, seed)).map_err(|e| e.to_string())?;
    let first = scene.frame(0).map_err(|e| e.to_string())?;
    let mut tracker = Tracker::new(TrackerConfig::default(), &first, None, scene.inits())
        .map_err(|e| e.to_string())?;
    for f in 1..scene.frames() {
        let frame = scene.frame(f).map_err(|e| e.to_string())?;
        tracker.update(&frame, None).map_err(|e| e.to_string())?;
    }
    // Read after the last frame: swap repairs revise earlier frames.
    for f in 1..scene.frames() {
        let truth = scene.truth(f);
        for (track, t) in tracker.tracks().iter().zip(&truth) {
            let o = &track.observations[f];
            let status = match o.status {
                TrackStatus::Tracked => 0,
                TrackStatus::Recovered => 1,
                _ => continue,
            };
            let Some(center) = o.center else { continue };
            let band = BANDS
                .iter()
                .rposition(|&(lo, _)| o.confidence >= lo)
                .unwrap_or(0);
            let error = (center - t).norm();
            let c = &mut counts[status][band];
            c[0] += 1;
            c[1] += usize::from(error <= RIGHT_PX);
            c[2] += usize::from(error > WRONG_PX);
        }
    }
    Ok(())
}
