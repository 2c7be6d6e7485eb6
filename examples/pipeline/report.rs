//! The pipeline's report: the Table-1-like table (terminal and Markdown), `report.json`, and
//! SVG figures (angle series and spectrum per branch).

use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;
use treemocap::modal_estimate::{Signal, SpectrumConfig, spectrum};

use crate::chain::BranchResult;

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
    /// Why something is missing.
    pub notes: Vec<String>,
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

fn pct(v: Option<f64>) -> String {
    v.map_or_else(|| "-".to_string(), |v| format!("{:+.1}%", 100.0 * v))
}

/// The table, as Markdown (also printed to the terminal).
pub fn table(rows: &[BranchRow]) -> String {
    let twin = rows.iter().any(|r| r.true_frequency_hz.is_some());
    let mut s = String::new();
    if twin {
        s.push_str("| branch | level | tracked | f true | f ours | err | f paper | err | xi true | xi ours | err | xi paper | err |\n");
        s.push_str(
            "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
        );
    } else {
        s.push_str(
            "| branch | level | tracked | f ours | ± | f paper | xi ours | ± | xi paper |\n",
        );
        s.push_str("| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
    }
    for r in rows {
        let name = format!("{} ({})", r.id, r.parent);
        let tracked = format!("{:.1}%", 100.0 * r.tracked_fraction);
        if twin {
            let _ = writeln!(
                s,
                "| {name} | {} | {tracked} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                r.level,
                cell(r.true_frequency_hz, 3),
                cell(r.frequency_hz, 3),
                pct(BranchRow::error(r.frequency_hz, r.true_frequency_hz)),
                cell(r.paper_frequency_hz, 3),
                pct(BranchRow::error(r.paper_frequency_hz, r.true_frequency_hz)),
                cell(r.true_damping_ratio, 3),
                cell(r.damping_ratio, 3),
                pct(BranchRow::error(r.damping_ratio, r.true_damping_ratio)),
                cell(r.paper_damping_ratio, 3),
                pct(BranchRow::error(
                    r.paper_damping_ratio,
                    r.true_damping_ratio
                )),
            );
        } else {
            let _ = writeln!(
                s,
                "| {name} | {} | {tracked} | {} | {} | {} | {} | {} | {} |",
                r.level,
                cell(r.frequency_hz, 3),
                cell(r.frequency_std_hz, 3),
                cell(r.paper_frequency_hz, 3),
                cell(r.damping_ratio, 3),
                cell(r.damping_std, 3),
                cell(r.paper_damping_ratio, 3),
            );
        }
    }
    s
}

/// Figure size, pixels.
const W: f64 = 640.0;
const H: f64 = 240.0;
const PAD: f64 = 44.0;

fn polyline(points: &[(f64, f64)], colour: &str) -> String {
    let mut d = String::new();
    let mut pen_up = true;
    for &(x, y) in points {
        if !(x.is_finite() && y.is_finite()) {
            pen_up = true;
            continue;
        }
        let _ = write!(d, "{}{x:.1},{y:.1} ", if pen_up { "M" } else { "L" });
        pen_up = false;
    }
    format!("<path d=\"{d}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.2\"/>")
}

fn frame(title: &str, x_label: &str, y_label: &str, x: (f64, f64), y: (f64, f64)) -> String {
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\" font-family=\"sans-serif\" font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    );
    let _ = writeln!(
        s,
        "<rect x=\"{PAD}\" y=\"{t}\" width=\"{w}\" height=\"{h}\" fill=\"none\" stroke=\"#888\"/>",
        t = PAD / 2.0,
        w = W - 1.5 * PAD,
        h = H - 1.5 * PAD
    );
    let _ = writeln!(s, "<text x=\"{PAD}\" y=\"14\">{title}</text>");
    let _ = writeln!(
        s,
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{x_label}</text>",
        W / 2.0,
        H - 4.0
    );
    let _ = writeln!(
        s,
        "<text x=\"12\" y=\"{}\" transform=\"rotate(-90 12 {})\" text-anchor=\"middle\">{y_label}</text>",
        H / 2.0,
        H / 2.0
    );
    for (v, anchor, px, py) in [
        (x.0, "start", PAD, H - PAD + 14.0),
        (x.1, "end", W - PAD / 2.0, H - PAD + 14.0),
        (y.1, "end", PAD - 3.0, PAD / 2.0 + 10.0),
        (y.0, "end", PAD - 3.0, H - PAD),
    ] {
        let _ = writeln!(
            s,
            "<text x=\"{px}\" y=\"{py}\" text-anchor=\"{anchor}\">{v:.3}</text>"
        );
    }
    s
}

fn map(v: f64, lo: f64, hi: f64, a: f64, b: f64) -> f64 {
    a + (v - lo) / (hi - lo).max(1e-300) * (b - a)
}

/// The angle series of a branch (degrees against seconds), the fitted segment shaded.
pub fn series_svg(r: &BranchResult) -> String {
    let (t, v) = &r.series;
    let deg: Vec<f64> = v
        .iter()
        .map(|x| x.map_or(f64::NAN, f64::to_degrees))
        .collect();
    let (lo, hi) = deg
        .iter()
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let (lo, hi) = if lo < hi { (lo, hi) } else { (-1.0, 1.0) };
    let (t0, t1) = (
        t.first().copied().unwrap_or(0.0),
        t.last().copied().unwrap_or(1.0),
    );
    let (x0, x1, y0, y1) = (PAD, W - PAD / 2.0, H - PAD, PAD / 2.0);
    let mut s = frame(
        &format!(
            "branch {} ({} → {}), level {}: signed angle",
            r.id, r.parent, r.id, r.level
        ),
        "time (s)",
        "angle (deg)",
        (t0, t1),
        (lo, hi),
    );
    if let Some((a, b)) = r.segment_s {
        let _ = writeln!(
            s,
            "<rect x=\"{:.1}\" y=\"{y1}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"#e8f0ff\"/>",
            map(a, t0, t1, x0, x1),
            map(b, t0, t1, x0, x1) - map(a, t0, t1, x0, x1),
            y0 - y1
        );
    }
    let pts: Vec<(f64, f64)> = t
        .iter()
        .zip(&deg)
        .map(|(&t, &d)| (map(t, t0, t1, x0, x1), map(d, lo, hi, y0, y1)))
        .collect();
    s.push_str(&polyline(&pts, "#c0392b"));
    s.push_str("\n</svg>\n");
    s
}

/// The amplitude spectrum of the fitted segment with the truth, ours and the paper's
/// frequencies marked.
pub fn spectrum_svg(r: &BranchResult, truth_hz: Option<f64>) -> String {
    let (t, v) = &r.series;
    let (a, b) = r.segment_s.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
    let sliced: (Vec<f64>, Vec<Option<f64>>) = t
        .iter()
        .zip(v)
        .filter(|(t, _)| (a..=b).contains(*t))
        .map(|(&t, &v)| (t, v))
        .unzip();
    let spec = Signal::new(sliced.0, sliced.1)
        .ok()
        .and_then(|s| spectrum(&s, &SpectrumConfig::default()).ok());
    let f_max = 6.0;
    let mut s;
    match spec {
        Some(spec) => {
            let pts: Vec<(f64, f64)> = spec
                .frequencies_hz
                .iter()
                .zip(&spec.values)
                .filter(|(f, _)| **f <= f_max)
                .map(|(&f, &a)| (f, a.to_degrees()))
                .collect();
            let top = pts.iter().map(|p| p.1).fold(1e-12, f64::max);
            let (x0, x1, y0, y1) = (PAD, W - PAD / 2.0, H - PAD, PAD / 2.0);
            s = frame(
                &format!("branch {}: spectrum of the fitted decay (Hann)", r.id),
                "frequency (Hz)",
                "amplitude (deg)",
                (0.0, f_max),
                (0.0, top),
            );
            let mapped: Vec<(f64, f64)> = pts
                .iter()
                .map(|&(f, a)| (map(f, 0.0, f_max, x0, x1), map(a, 0.0, top, y0, y1)))
                .collect();
            s.push_str(&polyline(&mapped, "#2c3e50"));
            let marks = [
                (truth_hz, "#27ae60", "truth"),
                (r.ours.map(|m| m.frequency_hz), "#c0392b", "ours"),
                (r.paper.map(|p| p.0), "#8e44ad", "paper"),
            ];
            for (k, (f, colour, label)) in marks.into_iter().enumerate() {
                if let Some(f) = f.filter(|f| *f <= f_max) {
                    let x = map(f, 0.0, f_max, x0, x1);
                    let _ = writeln!(
                        s,
                        "<line x1=\"{x:.1}\" y1=\"{y1}\" x2=\"{x:.1}\" y2=\"{y0}\" stroke=\"{colour}\" stroke-dasharray=\"4 3\"/>\n<text x=\"{:.1}\" y=\"{:.1}\" fill=\"{colour}\">{label} {f:.3} Hz</text>",
                        x + 4.0,
                        y1 + 14.0 + 13.0 * k as f64
                    );
                }
            }
        }
        None => {
            s = frame(
                &format!("branch {}: no spectrum (no fitted segment)", r.id),
                "frequency (Hz)",
                "amplitude (deg)",
                (0.0, f_max),
                (0.0, 1.0),
            );
        }
    }
    s.push_str("\n</svg>\n");
    s
}

/// Write `text` to `path` through a temporary file and a rename, so that a failure never
/// leaves half a file.
///
/// # Errors
/// A message naming the path.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), String> {
    let tmp = path.with_extension(format!(
        "{}.part",
        path.extension().and_then(|e| e.to_str()).unwrap_or("")
    ));
    std::fs::write(&tmp, bytes).map_err(|e| format!("{}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, path).map_err(|e| format!("{}: {e}", path.display()))
}
