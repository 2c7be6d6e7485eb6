//! SVG figures of a branch: its angle series (with its test window and the stretch our fit
//! used) and the spectrum of that stretch (with the truth, ours and the paper's frequency).
//! Hand-written SVG: two line plots per branch do not justify a plotting dependency.

use std::fmt::Write as _;

use modal_estimate::{Signal, SpectrumConfig, spectrum};

use crate::analysis::BranchResult;

/// Figure size, pixels.
const W: f64 = 720.0;
const H: f64 = 300.0;
/// Plot area margins, pixels: left (tick labels and the y label), right, top (title and
/// legend), bottom (tick labels and the x label).
const LEFT: f64 = 64.0;
const RIGHT: f64 = 16.0;
const TOP: f64 = 40.0;
const BOTTOM: f64 = 44.0;
/// Upper end of the spectrum figure, hertz (above every branch frequency of a tree).
const SPECTRUM_MAX_HZ: f64 = 6.0;

/// Tick values for an axis from `lo` to `hi`: 1, 2 or 5 times a power of ten apart, about
/// five of them, all inside the range.
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    let span = hi - lo;
    if !(span.is_finite() && span > 0.0) {
        return vec![lo];
    }
    let raw = span / 5.0;
    let power = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * power)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * power);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

/// A tick label with as many decimals as the step needs.
fn tick_label(v: f64, step: f64) -> String {
    let decimals = if step >= 1.0 {
        0
    } else {
        (-step.log10().floor()) as usize
    };
    let v = if v.abs() < step * 1e-9 { 0.0 } else { v };
    format!("{v:.decimals$}")
}

/// Text safe inside SVG.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// One line plot: axes with ticks, grid and labels; series, shaded spans, vertical marks
/// and a legend.
struct Plot {
    x: (f64, f64),
    y: (f64, f64),
    spans: String,
    body: String,
    legend: Vec<(String, String, bool)>,
}

impl Plot {
    fn new(x: (f64, f64), y: (f64, f64)) -> Self {
        let pad = |(a, b): (f64, f64)| {
            if b > a { (a, b) } else { (a - 1.0, a + 1.0) }
        };
        Self {
            x: pad(x),
            y: pad(y),
            spans: String::new(),
            body: String::new(),
            legend: Vec::new(),
        }
    }

    fn px(&self, x: f64) -> f64 {
        LEFT + (x - self.x.0) / (self.x.1 - self.x.0) * (W - LEFT - RIGHT)
    }

    fn py(&self, y: f64) -> f64 {
        H - BOTTOM - (y - self.y.0) / (self.y.1 - self.y.0) * (H - TOP - BOTTOM)
    }

    /// A series (NaN breaks the line).
    fn line(&mut self, points: &[(f64, f64)], colour: &str, label: &str) {
        let mut d = String::new();
        let mut pen_up = true;
        for &(x, y) in points {
            if !(x.is_finite() && y.is_finite()) {
                pen_up = true;
                continue;
            }
            let _ = write!(
                d,
                "{}{:.1},{:.1} ",
                if pen_up { "M" } else { "L" },
                self.px(x),
                self.py(y)
            );
            pen_up = false;
        }
        let _ = writeln!(
            self.body,
            "<path d=\"{d}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.3\"/>"
        );
        self.legend.push((label.into(), colour.into(), false));
    }

    /// A shaded span of x, drawn under the grid and the series (later spans on top).
    fn span(&mut self, (a, b): (f64, f64), colour: &str, label: &str) {
        let (a, b) = (a.max(self.x.0), b.min(self.x.1));
        if b <= a {
            return;
        }
        let (x0, x1) = (self.px(a), self.px(b));
        let _ = writeln!(
            self.spans,
            "<rect x=\"{x0:.1}\" y=\"{TOP}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"{colour}\"/>",
            x1 - x0,
            H - TOP - BOTTOM
        );
        self.legend.push((label.into(), colour.into(), true));
    }

    /// A dashed vertical mark at `x`.
    fn mark(&mut self, x: f64, colour: &str, label: &str) {
        if !(self.x.0..=self.x.1).contains(&x) {
            return;
        }
        let px = self.px(x);
        let _ = writeln!(
            self.body,
            "<line x1=\"{px:.1}\" y1=\"{TOP}\" x2=\"{px:.1}\" y2=\"{:.1}\" stroke=\"{colour}\" stroke-width=\"1.2\" stroke-dasharray=\"5 3\"/>",
            H - BOTTOM
        );
        self.legend.push((label.into(), colour.into(), false));
    }

    /// The whole SVG.
    fn finish(&self, title: &str, x_label: &str, y_label: &str) -> String {
        let mut s = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\" viewBox=\"0 0 {W} {H}\" font-family=\"sans-serif\" font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<text x=\"{LEFT}\" y=\"14\" font-size=\"12\" font-weight=\"bold\">{}</text>\n",
            escape(title)
        );
        s.push_str(&self.spans);
        let (x_ticks, y_ticks) = (ticks(self.x.0, self.x.1), ticks(self.y.0, self.y.1));
        let step = |t: &[f64]| if t.len() > 1 { t[1] - t[0] } else { 1.0 };
        for &t in &x_ticks {
            let px = self.px(t);
            let _ = writeln!(
                s,
                "<line x1=\"{px:.1}\" y1=\"{TOP}\" x2=\"{px:.1}\" y2=\"{:.1}\" stroke=\"#e4e4e4\"/>\n<text x=\"{px:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>",
                H - BOTTOM + 4.0,
                H - BOTTOM + 16.0,
                tick_label(t, step(&x_ticks))
            );
        }
        for &t in &y_ticks {
            let py = self.py(t);
            let _ = writeln!(
                s,
                "<line x1=\"{:.1}\" y1=\"{py:.1}\" x2=\"{:.1}\" y2=\"{py:.1}\" stroke=\"#e4e4e4\"/>\n<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>",
                LEFT - 4.0,
                W - RIGHT,
                LEFT - 6.0,
                py + 4.0,
                tick_label(t, step(&y_ticks))
            );
        }
        s.push_str(&self.body);
        let _ = writeln!(
            s,
            "<rect x=\"{LEFT}\" y=\"{TOP}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"none\" stroke=\"#666\"/>",
            W - LEFT - RIGHT,
            H - TOP - BOTTOM
        );
        let _ = writeln!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>\n<text x=\"14\" y=\"{:.1}\" transform=\"rotate(-90 14 {:.1})\" text-anchor=\"middle\">{}</text>",
            LEFT + (W - LEFT - RIGHT) / 2.0,
            H - 8.0,
            escape(x_label),
            TOP + (H - TOP - BOTTOM) / 2.0,
            TOP + (H - TOP - BOTTOM) / 2.0,
            escape(y_label)
        );
        let mut x = LEFT;
        for (label, colour, filled) in &self.legend {
            let swatch = if *filled {
                format!(
                    "<rect x=\"{x:.1}\" y=\"22\" width=\"14\" height=\"10\" fill=\"{colour}\" stroke=\"#999\"/>"
                )
            } else {
                format!(
                    "<line x1=\"{x:.1}\" y1=\"27\" x2=\"{:.1}\" y2=\"27\" stroke=\"{colour}\" stroke-width=\"2\"/>",
                    x + 14.0
                )
            };
            let _ = writeln!(
                s,
                "{swatch}<text x=\"{:.1}\" y=\"31\">{}</text>",
                x + 18.0,
                escape(label)
            );
            x += 26.0 + 6.2 * label.chars().count() as f64;
        }
        s.push_str("</svg>\n");
        s
    }
}

fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        })
}

/// A branch's series against time with its test window and the stretch our fit used.
fn time_series_svg(
    r: &BranchResult,
    t: &[f64],
    v: &[f64],
    (what, short): (&str, &str),
    unit: &str,
) -> String {
    let (lo, hi) = range(v.iter().copied());
    let margin = 0.05 * (hi - lo).max(1e-9);
    let x = (
        t.first().copied().unwrap_or(0.0),
        t.last().copied().unwrap_or(1.0),
    );
    let mut plot = Plot::new(x, (lo - margin, hi + margin));
    if let Some(w) = r.window_s {
        plot.span(w, "#ececec", "test window");
    }
    if let Some(f) = r.segment_s {
        plot.span(f, "#d2e2ff", "stretch our fit used");
    }
    let points: Vec<(f64, f64)> = t.iter().copied().zip(v.iter().copied()).collect();
    plot.line(&points, "#c0392b", what);
    plot.finish(
        &format!(
            "branch {} (parent {}), level {}: {what}",
            r.id, r.parent, r.level
        ),
        "time (s)",
        &format!("{short} ({unit})"),
    )
}

/// The signed relative angle of a branch (the paper's signal), degrees against seconds.
pub fn series_svg(r: &BranchResult) -> String {
    let deg: Vec<f64> = r
        .series
        .1
        .iter()
        .map(|x| x.map_or(f64::NAN, f64::to_degrees))
        .collect();
    time_series_svg(r, &r.series.0, &deg, ("relative angle", "angle"), "°")
}

/// The signal ours was fitted on: the child's displacement from its parent's marker along
/// its main direction of motion (millimetres), or the angle (degrees) when that could not
/// be formed.
pub fn swing_svg(r: &BranchResult) -> String {
    let f = &r.fitted;
    let (scale, what, unit) = if f.displacement {
        (
            1e3,
            ("swing (displacement from the parent's marker)", "swing"),
            "mm",
        )
    } else {
        (
            180.0 / std::f64::consts::PI,
            ("relative angle (fallback)", "angle"),
            "°",
        )
    };
    let v: Vec<f64> = f
        .values
        .iter()
        .map(|x| x.map_or(f64::NAN, |x| x * scale))
        .collect();
    time_series_svg(r, &f.times_s, &v, what, unit)
}

/// The amplitude spectrum of the signal ours was fitted on, over the stretch the fit used
/// (Hann window), with the truth, ours and the paper's frequencies marked.
pub fn spectrum_svg(r: &BranchResult, truth_hz: Option<f64>) -> String {
    let f = &r.fitted;
    let (scale, unit) = if f.displacement {
        (1e3, "mm")
    } else {
        (180.0 / std::f64::consts::PI, "°")
    };
    let (a, b) = r.segment_s.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
    let sliced: (Vec<f64>, Vec<Option<f64>>) = f
        .times_s
        .iter()
        .zip(&f.values)
        .filter(|(t, _)| (a..=b).contains(*t))
        .map(|(&t, &v)| (t, v))
        .unzip();
    let spec = Signal::new(sliced.0, sliced.1)
        .ok()
        .and_then(|s| spectrum(&s, &SpectrumConfig::default()).ok());
    let y_label = format!("amplitude ({unit})");
    let Some(spec) = spec else {
        let plot = Plot::new((0.0, SPECTRUM_MAX_HZ), (0.0, 1.0));
        return plot.finish(
            &format!("branch {}: no spectrum (no fitted stretch)", r.id),
            "frequency (Hz)",
            &y_label,
        );
    };
    let points: Vec<(f64, f64)> = spec
        .frequencies_hz
        .iter()
        .zip(&spec.values)
        .filter(|(f, _)| **f <= SPECTRUM_MAX_HZ)
        .map(|(&f, &a)| (f, a * scale))
        .collect();
    let top = range(points.iter().map(|p| p.1)).1.max(1e-12);
    let mut plot = Plot::new((0.0, SPECTRUM_MAX_HZ), (0.0, 1.05 * top));
    plot.line(&points, "#2c3e50", "amplitude");
    let marks = [
        (truth_hz, "#27ae60", "truth"),
        (r.ours.map(|m| m.frequency_hz), "#c0392b", "ours"),
        (r.paper.map(|p| p.0), "#8e44ad", "paper (on the angle)"),
    ];
    for (f, colour, label) in marks {
        if let Some(f) = f {
            plot.mark(f, colour, &format!("{label} {f:.3} Hz"));
        }
    }
    plot.finish(
        &format!(
            "branch {}: spectrum of the {} over the stretch our fit used (Hann window)",
            r.id,
            if f.displacement { "swing" } else { "angle" }
        ),
        "frequency (Hz)",
        &y_label,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_inside() {
        assert_eq!(ticks(0.0, 6.0), vec![0.0, 2.0, 4.0, 6.0]);
        let t = ticks(-31.7, 9.6);
        assert_eq!(t, vec![-30.0, -20.0, -10.0, 0.0]);
        assert!(
            ticks(0.013, 0.071)
                .iter()
                .all(|v| (0.013..=0.071).contains(v))
        );
        assert_eq!(tick_label(0.25, 0.05), "0.25");
        assert_eq!(tick_label(-20.0, 10.0), "-20");
        assert_eq!(ticks(1.0, 1.0), vec![1.0]);
    }

    #[test]
    fn a_figure_has_its_axes_legend_and_spans() {
        let mut plot = Plot::new((0.0, 10.0), (-5.0, 5.0));
        plot.span((2.0, 8.0), "#eee", "test window");
        plot.line(
            &[(0.0, -5.0), (f64::NAN, 0.0), (10.0, 5.0)],
            "#f00",
            "angle",
        );
        plot.mark(3.0, "#0f0", "truth 3.000 Hz");
        let svg = plot.finish("t <1>", "time (s)", "angle (°)");
        for needle in [
            "time (s)",
            "angle (°)",
            "test window",
            "truth 3.000 Hz",
            "t &lt;1&gt;",
            ">-4<",
            ">4<",
        ] {
            assert!(svg.contains(needle), "{needle} missing");
        }
        assert!(svg.ends_with("</svg>\n"));
    }
}
