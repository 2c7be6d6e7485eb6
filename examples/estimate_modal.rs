//! Natural frequency and damping ratio of a signal (a branch's angle series, a strain record).
//!
//! ```text
//! cargo run --release --example estimate_modal -- <SIGNAL_CSV> [--method auto|paper|pencil] [--modes K]
//! ```
//!
//! `SIGNAL_CSV`: a header line, then `t,value` rows (seconds, any unit); an empty value is a
//! missing sample. Prints one JSON object:
//! `{"method": "...", "modes": [{"frequency_hz", "damping_ratio", "frequency_std_hz",
//! "damping_std", "amplitude"}, ...], "warnings": [...]}`, modes by amplitude, largest first
//! (a standard error the method cannot give is `null`). Also in the object: `"estimator"`
//! (what ran) and `"segment"` (release, start and end of the part used, seconds).
//!
//! With no arguments it runs on a synthetic decay with known f and xi and prints both
//! methods' errors side by side.

use std::path::PathBuf;

use serde_json::{Value, json};
use treemocap::modal_estimate::csv::read_signal_csv;
use treemocap::modal_estimate::synthetic::DecaySpec;
use treemocap::modal_estimate::{Estimate, EstimateConfig, Method, estimate};

const USAGE: &str = "usage: estimate_modal <SIGNAL_CSV> [--method auto|paper|pencil] [--modes K]

Estimates the natural frequency and damping ratio of each mode of a record (CSV with a header
line, then t,value rows in seconds and any unit; an empty value is a missing sample) and prints
one JSON object. auto (default) finds a pull-and-release's decay, or treats a long wind record
as ambient; pencil fits the free decay (matrix pencil + Levenberg-Marquardt); paper is the
paper's FFT peak and half-power band. --modes K fixes the number of modes.
With no arguments: a synthetic decay with known f and xi, and both methods' errors.";

struct Args {
    signal: PathBuf,
    method: Method,
    modes: Option<usize>,
}

fn parse_args() -> Result<Option<Option<Args>>, String> {
    let mut positional = Vec::new();
    let (mut method, mut modes) = (None, None);
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "-h" | "--help" => return Ok(None),
            "--method" => {
                let m = it.next().ok_or("--method needs auto, paper or pencil")?;
                method = Some(match m.as_str() {
                    "auto" => Method::Auto,
                    "paper" => Method::Paper,
                    "pencil" => Method::Pencil,
                    other => {
                        return Err(format!(
                            "unknown method {other:?}: expected auto, paper or pencil"
                        ));
                    }
                });
            }
            "--modes" => {
                let k = it.next().ok_or("--modes needs a number")?;
                let k: usize = k
                    .parse()
                    .map_err(|_| format!("--modes {k:?} is not a whole number"))?;
                modes = Some(k);
            }
            other if other.starts_with('-') => {
                return Err(format!("unknown option {other:?}\n\n{USAGE}"));
            }
            _ => positional.push(PathBuf::from(a)),
        }
    }
    match positional.as_slice() {
        [] if method.is_none() && modes.is_none() => Ok(Some(None)),
        [p] => Ok(Some(Some(Args {
            signal: p.clone(),
            method: method.unwrap_or(Method::Auto),
            modes,
        }))),
        other => Err(format!(
            "expected one SIGNAL_CSV, got {} paths\n\n{USAGE}",
            other.len()
        )),
    }
}

fn config(method: Method, modes: Option<usize>) -> EstimateConfig {
    let base = match method {
        Method::Paper => EstimateConfig::paper(),
        m => EstimateConfig {
            method: m,
            ..EstimateConfig::default()
        },
    };
    EstimateConfig {
        modes: modes.or(base.modes),
        ..base
    }
}

fn to_json(method: Method, e: &Estimate) -> Value {
    let modes: Vec<Value> = e
        .modes
        .iter()
        .map(|m| {
            json!({
                "frequency_hz": m.frequency_hz,
                "damping_ratio": m.damping_ratio,
                "frequency_std_hz": m.frequency_std_hz,
                "damping_std": m.damping_std,
                "amplitude": m.amplitude,
                "damped_frequency_hz": m.damped_frequency_hz,
                "phase_rad": m.phase_rad,
            })
        })
        .collect();
    let warnings: Vec<String> = e.warnings.iter().map(ToString::to_string).collect();
    json!({
        "method": method.name(),
        "modes": modes,
        "warnings": warnings,
        "estimator": e.estimator,
        "segment": e.segment.map(|s| json!({
            "release_s": s.release.map(|r| r.time_s),
            "start_s": s.start_s,
            "end_s": s.end_s,
        })),
    })
}

/// Errors are printed as their messages (and the causes under them), not as debug dumps.
fn main() -> std::process::ExitCode {
    match run_main() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("estimate_modal: {e}");
            // Causes the message does not already say.
            let mut said = e.to_string();
            let mut cause = e.source();
            while let Some(c) = cause {
                let text = c.to_string();
                if !said.contains(&text) {
                    eprintln!("  caused by: {text}");
                    said.push_str(&text);
                }
                cause = c.source();
            }
            std::process::ExitCode::FAILURE
        }
    }
}

fn run_main() -> Result<(), Box<dyn std::error::Error>> {
    match parse_args()? {
        None => {
            println!("{USAGE}");
            Ok(())
        }
        Some(None) => demo(),
        Some(Some(args)) => {
            let signal = read_signal_csv(&args.signal)?;
            let e = estimate(&signal, &config(args.method, args.modes))?;
            println!(
                "{}",
                serde_json::to_string_pretty(&to_json(args.method, &e))?
            );
            Ok(())
        }
    }
}

fn demo() -> Result<(), Box<dyn std::error::Error>> {
    let spec = DecaySpec::paper_branch();
    let signal = spec.generate()?;
    println!(
        "synthetic pull-and-release: f = {} Hz, xi = {}, {} samples at {} Hz (+-{} ms jitter, {:.0} % dropped),",
        spec.frequency_hz,
        spec.damping_ratio,
        spec.samples,
        spec.sample_rate_hz,
        spec.jitter_s * 1e3,
        spec.drop_fraction * 100.0
    );
    println!(
        "held still {} s before the release, offset {} rad, drift {} rad/s, {} dB\n",
        spec.held_s, spec.offset, spec.drift_per_s, spec.snr_db
    );
    println!(
        "{:<8} {:>10} {:>10} {:>9} {:>8} {:>10} {:>9}",
        "method", "f (Hz)", "+-", "error", "xi", "+-", "error"
    );
    for method in [Method::Auto, Method::Paper] {
        let e = estimate(&signal, &config(method, None))?;
        let Some(m) = e.modes.first() else {
            println!("{:<8} no mode: {:?}", method.name(), e.warnings);
            continue;
        };
        let fmt_std = |s: Option<f64>| s.map_or("-".to_owned(), |s| format!("{s:.4}"));
        println!(
            "{:<8} {:>10.4} {:>10} {:>8.2}% {:>8.4} {:>10} {:>8.1}%",
            method.name(),
            m.frequency_hz,
            fmt_std(m.frequency_std_hz),
            100.0 * (m.frequency_hz / spec.frequency_hz - 1.0),
            m.damping_ratio,
            fmt_std(m.damping_std),
            100.0 * (m.damping_ratio / spec.damping_ratio - 1.0)
        );
        for w in &e.warnings {
            println!("         note: {w}");
        }
    }
    Ok(())
}
