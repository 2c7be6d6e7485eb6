//! Natural frequency and damping ratio of a signal (a branch's angle series, a strain record).
//!
//! ```text
//! cargo run --release --example estimate_modal -- <SIGNAL_CSV> [--method auto|paper|pencil|ambient]
//!     [--modes K] [--column N] [--rate HZ] [--band LO:HI]
//! ```
//!
//! `SIGNAL_CSV`: `t,value` rows (seconds, any unit) after an optional header line; an empty
//! value is a missing sample. `--column N` takes the values from column N (0-based, default
//! 1); `--rate HZ` says the file has no time column and its rows are samples at HZ (the
//! value column then defaults to 0). `--band LO:HI` limits the frequencies searched, hertz. Prints one JSON object:
//! `{"method": "...", "modes": [{"frequency_hz", "damping_ratio", "frequency_std_hz",
//! "damping_std", "amplitude"}, ...], "warnings": [...]}`, modes by amplitude, largest first
//! (a standard error the method cannot give is `null`). Also in the object: `"estimator"`
//! (what ran) and `"segment"` (release, start and end of the part used, seconds).
//!
//! With no arguments it runs on a synthetic decay with known f and xi and prints both
//! methods' errors side by side.

use std::path::PathBuf;

use serde_json::{Value, json};
use treemocap::modal_estimate::csv::{CsvLayout, read_signal_csv_with};
use treemocap::modal_estimate::synthetic::DecaySpec;
use treemocap::modal_estimate::{Estimate, EstimateConfig, Method, ModalError, estimate};

mod common;

const USAGE: &str =
    "usage: estimate_modal <SIGNAL_CSV> [--method auto|paper|pencil|ambient] [--modes K]
                      [--column N] [--rate HZ] [--band LO:HI]

Estimates the natural frequency and damping ratio of each mode of a record (CSV of t,value rows
in seconds and any unit after an optional header line; an empty value is a missing sample) and
prints one JSON object. auto (default) finds a pull-and-release's decay, or treats a long wind
record as ambient; pencil fits the free decay (matrix pencil + Levenberg-Marquardt); ambient is
random decrement on a wind record; paper is the paper's FFT peak and half-power band.
  --modes K     fix the number of modes (1 to 8)
  --column N    the values are in column N (0-based; default 1, or 0 with --rate)
  --rate HZ     the file has no time column: its rows are samples HZ apart
  --band LO:HI  search LO..HI hertz only (default: 1.5 cycles per record to Nyquist)
With no arguments: a synthetic decay with known f and xi, and both methods' errors.";

struct Args {
    signal: PathBuf,
    method: Method,
    modes: Option<usize>,
    layout: CsvLayout,
    band_hz: Option<(f64, f64)>,
}

/// A positive finite number from an option's value.
fn positive(option: &str, text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("{option} {text:?} is not a positive number")),
    }
}

/// `LO:HI` in hertz.
fn parse_band(text: &str) -> Result<(f64, f64), String> {
    let (lo, hi) = text
        .split_once(':')
        .ok_or_else(|| format!("--band {text:?} is not LO:HI (hertz, e.g. 0.1:2)"))?;
    let lo: f64 = lo
        .trim()
        .parse()
        .map_err(|_| format!("--band {text:?}: {lo:?} is not a number"))?;
    let hi = positive("--band", hi.trim())?;
    if !(lo.is_finite() && lo >= 0.0 && lo < hi) {
        return Err(format!("--band {text:?} is not a band: need 0 <= LO < HI"));
    }
    Ok((lo, hi))
}

fn parse_args() -> Result<Option<Option<Args>>, String> {
    let mut positional = Vec::new();
    let (mut method, mut modes) = (None, None);
    let (mut column, mut rate, mut band_hz) = (None, None, None);
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "-h" | "--help" => return Ok(None),
            "--method" => {
                let m = it
                    .next()
                    .ok_or("--method needs auto, paper, pencil or ambient")?;
                method = Some(match m.as_str() {
                    "auto" => Method::Auto,
                    "paper" => Method::Paper,
                    "pencil" => Method::Pencil,
                    "ambient" => Method::Ambient,
                    other => {
                        return Err(format!(
                            "unknown method {other:?}: expected auto, paper, pencil or ambient"
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
            "--column" => {
                let c = it.next().ok_or("--column needs a number")?;
                column = Some(
                    c.parse::<usize>()
                        .map_err(|_| format!("--column {c:?} is not a column number (0-based)"))?,
                );
            }
            "--rate" => {
                let r = it.next().ok_or("--rate needs a sample rate in hertz")?;
                rate = Some(positive("--rate", &r)?);
            }
            "--band" => {
                let b = it.next().ok_or("--band needs LO:HI in hertz")?;
                band_hz = Some(parse_band(&b)?);
            }
            other if other.starts_with('-') => {
                return Err(format!("unknown option {other:?}\n\n{USAGE}"));
            }
            _ => positional.push(PathBuf::from(a)),
        }
    }
    match positional.as_slice() {
        [] if method.is_none() && modes.is_none() && column.is_none() && rate.is_none() => {
            Ok(Some(None))
        }
        [p] => {
            let layout = match rate {
                Some(r) => CsvLayout::sampled(r, column.unwrap_or(0)),
                None => CsvLayout {
                    value_column: column.unwrap_or(1),
                    ..CsvLayout::default()
                },
            };
            if column == Some(0) && rate.is_none() {
                return Err(
                    "--column 0 is the time column; give --rate HZ if the file has none".into(),
                );
            }
            Ok(Some(Some(Args {
                signal: p.clone(),
                method: method.unwrap_or(Method::Auto),
                modes,
                layout,
                band_hz,
            })))
        }
        other => Err(format!(
            "expected one SIGNAL_CSV, got {} paths\n\n{USAGE}",
            other.len()
        )),
    }
}

fn config(method: Method, modes: Option<usize>, band_hz: Option<(f64, f64)>) -> EstimateConfig {
    let base = match method {
        Method::Paper => EstimateConfig::paper(),
        m => EstimateConfig {
            method: m,
            ..EstimateConfig::default()
        },
    };
    EstimateConfig {
        modes: modes.or(base.modes),
        band_hz: band_hz.or(base.band_hz),
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

fn main() -> std::process::ExitCode {
    common::run("estimate_modal", run_main)
}

fn run_main() -> Result<(), Box<dyn std::error::Error>> {
    match parse_args()? {
        None => {
            println!("{USAGE}");
            Ok(())
        }
        Some(None) => demo(),
        Some(Some(args)) => {
            let signal = read_signal_csv_with(&args.signal, &args.layout)
                .map_err(|e| format!("{}: {e}", args.signal.display()))?;
            let e =
                estimate(&signal, &config(args.method, args.modes, args.band_hz)).map_err(|e| {
                    match (&e, args.band_hz) {
                        (
                            ModalError::BandAboveNyquist { .. }
                            | ModalError::InvalidBand { .. }
                            | ModalError::RecordTooShort { .. }
                            | ModalError::NoPeak { .. },
                            Some((lo, hi)),
                        ) => format!("{}: --band {lo}:{hi}: {e}", args.signal.display()),
                        _ => format!("{}: {e}", args.signal.display()),
                    }
                })?;
            println!(
                "{}",
                serde_json::to_string_pretty(&to_json(args.method, &e))?
            );
            if e.modes.is_empty() {
                // The JSON above says why (its warnings); the exit status says it failed.
                let why: Vec<String> = e.warnings.iter().map(ToString::to_string).collect();
                return Err(format!(
                    "{}: no mode could be measured ({})",
                    args.signal.display(),
                    why.join("; ")
                )
                .into());
            }
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
        let e = estimate(&signal, &config(method, None, None))?;
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
