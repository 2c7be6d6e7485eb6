//! SVG figures of a branch: its angle series and the spectrum of its fitted decay.

use std::fmt::Write as _;

use modal_estimate::{Signal, SpectrumConfig, spectrum};

use crate::analysis::BranchResult;

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
