//! Turn 3D marker trajectories into the relative rotation angle of every branch.
//!
//! ```text
//! cargo run --release --example branch_angles -- <TRAJECTORIES_CSV> <HIERARCHY_JSON|MARKERS_JSON> [--out angles.csv] [--signed]
//! ```
//!
//! `TRAJECTORIES_CSV` has rows `t,id,x,y,z` (seconds, metres; empty x, y, z for a lost
//! frame). `HIERARCHY_JSON` is `{"markers": [{"id": "A", "parent": null}, {"id": "C",
//! "parent": "A"}, ...]}`, or the capture's `markers.json` (docs/capture.md). The output CSV (stdout, or `--out`) has the header
//! `t,<child id>,...`: per child marker the angle of its branch relative to its parent branch
//! (eq. 1 of the paper), in degrees, an empty cell where it is unknown; with `--signed` two
//! columns per child, `<id>_u` and `<id>_w`, the signed tilts from the rest pose. Gaps are
//! reported on stderr. Children of the root are measured against +Z (the tree frame's up).
//!
//! With no arguments it runs on a synthetic two-level hierarchy with known swinging angles and
//! prints the error of each output.

use std::path::{Path, PathBuf};

use clap::Parser;
use treemocap::branch_angles::csv::{
    angle_columns, angles_to_csv, read_text, read_trajectories_csv, write_text,
};
use treemocap::branch_angles::{
    AngleConfig, AngleSet, Hierarchy, MarkerNode, Series, branch_angles, synthetic,
};
use treemocap::mocap_pipeline::MarkersFile;

mod common;

/// The angle of every branch relative to its parent branch (eq. 1 of the paper, degrees),
/// from 3D marker trajectories and the marker hierarchy.
///
/// Short gaps (up to 3 frames) are filled with a cubic; longer ones stay empty and are
/// reported on stderr. The output CSV (`t,<child id>,...`) feeds `estimate_modal --column
/// <id>`. With no arguments: a synthetic two-level tree with known angles, and the error.
#[derive(Parser, Debug)]
#[command(name = "branch_angles", version, about)]
struct Args {
    /// Marker trajectories: CSV rows t,id,x,y,z (seconds, metres; empty x,y,z for a lost
    /// frame)
    #[arg(value_name = "TRAJECTORIES_CSV", requires = "hierarchy")]
    trajectories: Option<PathBuf>,
    /// The hierarchy ({"markers": [{"id": "A", "parent": null}, ...]}) or the capture's
    /// markers.json (docs/capture.md)
    #[arg(value_name = "HIERARCHY_JSON")]
    hierarchy: Option<PathBuf>,
    /// Write the CSV here instead of stdout
    #[arg(long, value_name = "FILE", requires = "trajectories")]
    out: Option<PathBuf>,
    /// Two columns per child, <id>_u and <id>_w: the signed tilts from the rest pose
    #[arg(long, requires = "trajectories")]
    signed: bool,
}

fn main() -> std::process::ExitCode {
    let args = Args::parse();
    common::run("branch_angles", || {
        match (&args.trajectories, &args.hierarchy) {
            (Some(t), Some(h)) => run(&args, t, h),
            _ => synthetic_demo(),
        }
    })
}

/// The hierarchy from its own JSON, or from the capture's markers file.
fn read_hierarchy(path: &Path) -> Result<Hierarchy, Box<dyn std::error::Error>> {
    let text = read_text(path)?;
    match Hierarchy::from_json(&text) {
        Ok(h) => Ok(h),
        Err(own) => match MarkersFile::parse(&text, path) {
            Ok(file) => Ok(Hierarchy::new(
                file.markers
                    .into_iter()
                    .map(|m| MarkerNode {
                        id: m.id,
                        parent: m.parent,
                    })
                    .collect(),
            )
            .map_err(|e| common::naming(path, e))?),
            // Not a markers file either: the hierarchy reader's message is the one to show
            // unless the file looks like a markers file (it has windows).
            Err(markers) if text.contains("\"x\"") => Err(markers.into()),
            Err(_) => Err(common::naming(path, own).into()),
        },
    }
}

fn run(
    args: &Args,
    trajectories_path: &Path,
    hierarchy_path: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let trajectories = read_trajectories_csv(&read_text(trajectories_path)?)
        .map_err(|e| common::naming(trajectories_path, e))?;
    let hierarchy = read_hierarchy(hierarchy_path)?;
    let config = AngleConfig {
        signed: args.signed,
        ..AngleConfig::default()
    };
    let set = branch_angles(&hierarchy, &trajectories, &config)?;
    report(&set);
    let columns = angle_columns(&set, args.signed);
    if columns.iter().all(|c| c.values.iter().all(Option::is_none)) {
        return Err(format!(
            "{}: no angle could be computed for any branch at any time (every marker pair lost or too close: see above)",
            trajectories_path.display()
        )
        .into());
    }
    let text = angles_to_csv(&set.times_s, &columns);
    match &args.out {
        Some(path) => write_text(path, &text)?,
        None => print!("{text}"),
    }
    Ok(())
}

/// Gaps and degenerate samples on stderr.
fn report(set: &AngleSet) {
    for g in &set.gaps {
        eprintln!(
            "gap: marker {} lost for {} frame(s), {} s .. {} s, {}",
            g.marker,
            g.samples,
            g.start_s,
            g.end_s,
            if g.filled { "filled" } else { "left empty" }
        );
    }
    for b in &set.branches {
        if b.degenerate_samples > 0 {
            eprintln!(
                "branch {}: {} sample(s) with a segment too short for a direction, left empty",
                b.child, b.degenerate_samples
            );
        }
    }
}

/// Largest |estimate - truth| in degrees over the known samples.
fn max_error_deg(series: &Series, truth: &[f64]) -> f64 {
    series
        .values
        .iter()
        .zip(truth)
        .filter_map(|(v, t)| v.map(|v| (v - t).abs().to_degrees()))
        .fold(0.0, f64::max)
}

/// Swing frequency from the mean-crossings of the series after `from_s` (hertz).
fn crossing_frequency_hz(series: &Series, from_s: f64) -> f64 {
    let pts: Vec<(f64, f64)> = series
        .times_s
        .iter()
        .zip(&series.values)
        .filter_map(|(&t, v)| v.filter(|_| t > from_s).map(|v| (t, v)))
        .collect();
    if pts.len() < 3 {
        return 0.0;
    }
    let mean = pts.iter().map(|p| p.1).sum::<f64>() / pts.len() as f64;
    let crossings: Vec<f64> = pts
        .windows(2)
        .filter(|w| (w[0].1 - mean) * (w[1].1 - mean) < 0.0)
        .map(|w| w[0].0 + (w[1].0 - w[0].0) * (mean - w[0].1) / (w[1].1 - w[0].1))
        .collect();
    match (crossings.first(), crossings.last()) {
        (Some(a), Some(b)) if crossings.len() > 2 => (crossings.len() - 1) as f64 / (2.0 * (b - a)),
        _ => 0.0,
    }
}

fn synthetic_demo() -> Result<(), Box<dyn std::error::Error>> {
    let tree = synthetic::two_level();
    let config = AngleConfig {
        rest: tree.rest,
        ..AngleConfig::default()
    };
    let set = branch_angles(&tree.hierarchy, &tree.trajectories, &config)?;
    println!(
        "synthetic two-level tree: {} markers, {} samples at {} Hz, release at 0.5 s",
        tree.hierarchy.markers().len(),
        tree.trajectories.times_s().len(),
        synthetic::PAPER_RATE_HZ
    );
    println!(
        "branch  parent  max error eq.(1)  max error u  max error w  true f   f from eq.(1)  f from u"
    );
    for (b, t) in set.branches.iter().zip(&tree.truth) {
        let signed = b.signed.as_ref().ok_or("signed angles are on by default")?;
        println!(
            "{:6}  {:6}  {:14.2e}°  {:9.2e}°  {:9.2e}°  {:4.2} Hz  {:10.2} Hz  {:5.2} Hz",
            b.child,
            b.parent,
            max_error_deg(&b.angle_rad, &t.angle_rad),
            max_error_deg(&signed.u_rad, &t.u_rad),
            max_error_deg(&signed.w_rad, &t.w_rad),
            t.frequency_hz,
            crossing_frequency_hz(&b.angle_rad, 0.5),
            crossing_frequency_hz(&signed.u_rad, 0.5),
        );
    }
    println!(
        "E is aligned with its parent at rest: eq. (1) folds its ±5° swing to twice the frequency; the signed u keeps it."
    );
    Ok(())
}
