//! The report's branch rows and the Table-1-like table (terminal and Markdown).

use std::fmt::Write as _;

use serde::Serialize;

use crate::analysis::BranchResult;
use crate::quality::BranchQuality;

/// One row of the report's `branches`.
#[derive(Debug, Clone, Serialize)]
pub struct BranchRow {
    /// Child marker (names the branch).
    pub id: String,
    /// Parent marker.
    pub parent: String,
    /// Level, 1 for the children of the root.
    pub level: usize,
    /// Share of frames where the tracker followed the branch's marker.
    pub tracked_fraction: f64,
    /// Share of frames with a 3D position for the branch's marker.
    pub lifted_fraction: f64,
    /// True natural frequency (twin only), hertz.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub true_frequency_hz: Option<f64>,
    /// Ours, hertz.
    pub frequency_hz: Option<f64>,
    /// Standard error of ours, hertz.
    pub frequency_std_hz: Option<f64>,
    /// The paper's method (FFT peak bin), hertz.
    pub paper_frequency_hz: Option<f64>,
    /// True damping ratio (twin only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub true_damping_ratio: Option<f64>,
    /// Ours.
    pub damping_ratio: Option<f64>,
    /// Standard error of ours.
    pub damping_std: Option<f64>,
    /// The paper's method (half-power band, eq. 6).
    pub paper_damping_ratio: Option<f64>,
    /// The paper method's bin width, hertz.
    pub paper_bin_width_hz: Option<f64>,
    /// The branch's test window, seconds (when given).
    pub window_s: Option<(f64, f64)>,
    /// The stretch our fit used, seconds.
    pub fit_s: Option<(f64, f64)>,
    /// Why something is missing or should not be trusted: each note starts with what it is
    /// about (`ours:`, `paper:`, `track:`).
    pub notes: Vec<String>,
    /// The quality behind the numbers (test-window coverage, jumps, fit cycles and
    /// residual, whether ours and the paper's can be trusted).
    pub quality: BranchQuality,
}

impl BranchRow {
    /// A row from a branch result and, for the twin, the truth `(f, xi)`.
    pub fn new(r: &BranchResult, truth: Option<(f64, f64)>) -> Self {
        Self {
            id: r.id.clone(),
            parent: r.parent.clone(),
            level: r.level,
            tracked_fraction: r.tracked_fraction,
            lifted_fraction: r.lifted_fraction,
            true_frequency_hz: truth.map(|t| t.0),
            frequency_hz: r.ours.map(|m| m.frequency_hz),
            frequency_std_hz: r.ours.and_then(|m| m.frequency_std_hz),
            paper_frequency_hz: r.paper.map(|p| p.0),
            true_damping_ratio: truth.map(|t| t.1),
            damping_ratio: r.ours.map(|m| m.damping_ratio),
            damping_std: r.ours.and_then(|m| m.damping_std),
            paper_damping_ratio: r.paper.and_then(|p| p.1),
            paper_bin_width_hz: r.paper_bin_hz,
            window_s: r.window_s,
            fit_s: r.segment_s,
            notes: r.notes.clone(),
            quality: r.quality.clone(),
        }
    }

    /// Relative error of `value` against the truth, when both are known.
    pub fn error(value: Option<f64>, truth: Option<f64>) -> Option<f64> {
        match (value, truth) {
            (Some(v), Some(t)) if t != 0.0 => Some((v - t) / t),
            _ => None,
        }
    }
}

fn cell(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "-".to_string(), |v| format!("{v:.digits$}"))
}

/// A value with its ± (standard error, or the paper's half bin), `-` when unknown.
fn pm(v: Option<f64>, sd: Option<f64>, digits: usize) -> String {
    match (v, sd) {
        (Some(v), Some(sd)) => format!("{v:.digits$} ± {sd:.digits$}"),
        (Some(v), None) => format!("{v:.digits$} ± ?"),
        _ => "-".to_string(),
    }
}

fn pct(v: Option<f64>) -> String {
    v.map_or_else(|| "-".to_string(), |v| format!("{:+.1}", 100.0 * v))
}

/// Which estimates of a row can be trusted.
fn trust(r: &BranchRow) -> &'static str {
    match (r.quality.ours_trusted, r.quality.paper_trusted) {
        (true, true) => "ours, paper",
        (true, false) => "ours",
        (false, true) => "paper",
        (false, false) => "none",
    }
}

/// The table, as Markdown (also printed to the terminal). Every numeric column names its
/// unit; ours carries its standard error, the paper's frequency half its bin width (its
/// quantisation), the paper's damping `± ?` (it has no uncertainty model); `trusted` says
/// which estimates no note speaks against.
pub fn table(rows: &[BranchRow]) -> String {
    let twin = rows.iter().any(|r| r.true_frequency_hz.is_some());
    let mut s = String::new();
    if twin {
        s.push_str("| branch | level | tracked (%) | f true (Hz) | f ours (Hz) | err (%) | f paper (Hz) | err (%) | ξ true (1) | ξ ours (1) | err (%) | ξ paper (1) | err (%) | trusted |\n");
        s.push_str(
            "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
        );
    } else {
        s.push_str(
            "| branch | level | tracked (%) | f ours (Hz) | f paper (Hz) | ξ ours (1) | ξ paper (1) | trusted |\n",
        );
        s.push_str("| --- | --- | --- | --- | --- | --- | --- | --- |\n");
    }
    for r in rows {
        let name = format!("{} ({})", r.id, r.parent);
        let tracked = format!("{:.1}", 100.0 * r.tracked_fraction);
        let f_ours = pm(r.frequency_hz, r.frequency_std_hz, 3);
        let f_paper = pm(
            r.paper_frequency_hz,
            r.paper_bin_width_hz.map(|b| b / 2.0),
            3,
        );
        let xi_ours = pm(r.damping_ratio, r.damping_std, 3);
        // The paper's half-power damping has no uncertainty model: its ± is unknown.
        let xi_paper = pm(r.paper_damping_ratio, None, 3);
        if twin {
            let _ = writeln!(
                s,
                "| {name} | {} | {tracked} | {} | {f_ours} | {} | {f_paper} | {} | {} | {xi_ours} | {} | {xi_paper} | {} | {} |",
                r.level,
                cell(r.true_frequency_hz, 3),
                pct(BranchRow::error(r.frequency_hz, r.true_frequency_hz)),
                pct(BranchRow::error(r.paper_frequency_hz, r.true_frequency_hz)),
                cell(r.true_damping_ratio, 3),
                pct(BranchRow::error(r.damping_ratio, r.true_damping_ratio)),
                pct(BranchRow::error(
                    r.paper_damping_ratio,
                    r.true_damping_ratio
                )),
                trust(r),
            );
        } else {
            let _ = writeln!(
                s,
                "| {name} | {} | {tracked} | {f_ours} | {f_paper} | {xi_ours} | {xi_paper} | {} |",
                r.level,
                trust(r),
            );
        }
    }
    s
}
