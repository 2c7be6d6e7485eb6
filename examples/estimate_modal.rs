//! Natural frequency and damping ratio of a signal (a branch's angle series, a strain record).
//!
//! ```text
//! cargo run --release --example estimate_modal -- <SIGNAL_CSV> [--method auto|paper|pencil|ambient]
//!     [--modes K] [--column N|NAME] [--rate HZ] [--band LO:HI]
//! ```
//!
//! `SIGNAL_CSV`: `t,value` rows (seconds, any unit) after an optional header line; an empty
//! value is a missing sample. `--column N` takes the values from column N (0-based, default
//! 1), `--column NAME` from the column of that header name (a branch of `branch_angles`'
//! output); `--rate HZ` says the file has no time column and its rows are samples at HZ (the
//! value column then defaults to 0). `--band LO:HI` limits the frequencies searched, hertz. Prints one JSON object:
//! `{"method": "...", "modes": [{"frequency_hz", "damping_ratio", "frequency_std_hz",
//! "damping_std", "amplitude"}, ...], "warnings": [...]}`, modes by amplitude, largest first
//! (a standard error the method cannot give is `null`). Also in the object: `"estimator"`
//! (what ran) and `"segment"` (release, start and end of the part used, seconds).
//!
//! With no arguments it runs on a synthetic decay with known f and xi and prints both
//! methods' errors side by side.

use std::path::PathBuf;

use clap::Parser;
use serde_json::{Value, json};
use treemocap::modal_estimate::csv::{CsvLayout, header_column, read_signal_csv_with};
use treemocap::modal_estimate::synthetic::DecaySpec;
use treemocap::modal_estimate::{Estimate, EstimateConfig, Method, ModalError, estimate};

mod common;

/// Natural frequency and damping ratio of each mode of a record, as one JSON object.
///
/// The record is a CSV of `t,value` rows (seconds, any unit) after an optional header line;
/// an empty value is a missing sample. auto (default) finds a pull-and-release's decay, or
/// treats a long wind record as ambient; pencil fits the free decay (matrix pencil +
/// Levenberg-Marquardt); ambient is random decrement on a wind record; paper is the paper's
/// FFT peak and half-power band. With no arguments: a synthetic decay with known f and xi,
/// and both methods' errors.
#[derive(Parser, Debug)]
#[command(name = "estimate_modal", version, about, allow_negative_numbers = true)]
struct Cli {
    /// The record (CSV)
    #[arg(value_name = "SIGNAL_CSV")]
    signal: Option<PathBuf>,
    /// The estimator [default: auto]
    #[arg(long, value_enum, requires = "signal")]
    method: Option<MethodArg>,
    /// Fix the number of modes (1 to 8)
    #[arg(long, value_name = "K", requires = "signal")]
    modes: Option<usize>,
    /// The values' column: a 0-based number, or a header name such as a branch of
    /// branch_angles' output [default: 1, or 0 with --rate]
    #[arg(long, value_name = "N|NAME", requires = "signal")]
    column: Option<String>,
    /// The file has no time column: its rows are samples HZ apart
    #[arg(long, value_name = "HZ", value_parser = positive, requires = "signal")]
    rate: Option<f64>,
    /// Search LO..HI hertz only [default: 1.5 cycles per record to Nyquist]
    #[arg(long, value_name = "LO:HI", value_parser = parse_band, requires = "signal")]
    band: Option<(f64, f64)>,
}

/// The estimators, as named on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum MethodArg {
    /// Decay fit, or ambient for a long wind record
    Auto,
    /// The paper's FFT peak and half-power band
    Paper,
    /// Matrix pencil + Levenberg-Marquardt on the free decay
    Pencil,
    /// Random decrement on a wind record
    Ambient,
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Self {
        match m {
            MethodArg::Auto => Method::Auto,
            MethodArg::Paper => Method::Paper,
            MethodArg::Pencil => Method::Pencil,
            MethodArg::Ambient => Method::Ambient,
        }
    }
}

struct Args {
    signal: PathBuf,
    method: Method,
    modes: Option<usize>,
    layout: CsvLayout,
    band_hz: Option<(f64, f64)>,
}

/// A positive finite number from an option's value.
fn positive(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("{text:?} is not a positive number")),
    }
}

/// `LO:HI` in hertz.
fn parse_band(text: &str) -> Result<(f64, f64), String> {
    let (lo, hi) = text
        .split_once(':')
        .ok_or_else(|| format!("{text:?} is not LO:HI (hertz, e.g. 0.1:2)"))?;
    let lo: f64 = lo
        .trim()
        .parse()
        .map_err(|_| format!("{lo:?} is not a number"))?;
    let hi = positive(hi.trim())?;
    if !(lo.is_finite() && lo >= 0.0 && lo < hi) {
        return Err(format!("{text:?} is not a band: need 0 <= LO < HI"));
    }
    Ok((lo, hi))
}

/// The arguments checked, `None` for the demo (no file).
fn args(cli: Cli) -> Result<Option<Args>, String> {
    let Some(signal) = cli.signal else {
        return Ok(None);
    };
    let column = match cli.column.as_deref() {
        None => None,
        Some(c) => Some(match c.parse::<usize>() {
            Ok(n) => n,
            Err(_) => {
                let text =
                    std::fs::read_to_string(&signal).map_err(|e| common::naming(&signal, e))?;
                header_column(&text, c).ok_or_else(|| {
                    format!(
                        "{}: --column {c:?}: no column of that name in the header",
                        signal.display()
                    )
                })?
            }
        }),
    };
    let layout = match cli.rate {
        Some(r) => CsvLayout::sampled(r, column.unwrap_or(0)),
        None => CsvLayout {
            value_column: column.unwrap_or(1),
            ..CsvLayout::default()
        },
    };
    if column == Some(0) && cli.rate.is_none() {
        return Err("--column 0 is the time column; give --rate HZ if the file has none".into());
    }
    Ok(Some(Args {
        signal,
        method: cli.method.unwrap_or(MethodArg::Auto).into(),
        modes: cli.modes,
        layout,
        band_hz: cli.band,
    }))
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
    let cli = Cli::parse();
    common::run("estimate_modal", || run_main(cli))
}

fn run_main(cli: Cli) -> Result<(), Box<dyn std::error::Error>> {
    match args(cli)? {
        None => demo(),
        Some(args) => {
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
