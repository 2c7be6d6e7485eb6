//! How far a branch's numbers can be trusted: what the tracker and the lift saw inside its
//! test window, how well our fit explains the signal and how well it is determined, and
//! whether the paper's reading is a peak of a swing; each concern a note, the notes deciding
//! the trust flags.

use modal_estimate::{Estimate, HalfPower, Mode, Signal, Warning};
use nalgebra::{Point3, Vector3};
use serde::Serialize;

use crate::analysis::{BranchResult, JUMP_M};
use crate::stats::median;

/// The quality behind a branch's numbers: what the tracker, the lift and the fit saw inside
/// the branch's test window (the whole record without one), and whether each estimate can
/// be trusted (a note says why not).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct BranchQuality {
    /// Frames in the test window.
    pub window_frames: usize,
    /// Share of the window's frames where the tracker followed the branch's marker.
    pub window_tracked_fraction: f64,
    /// Share of the window's frames with a 3D position kept for the angles.
    pub window_lifted_fraction: f64,
    /// Lifted positions of the marker dropped as isolated jumps in the window.
    pub jumps_dropped: usize,
    /// Sustained steps of the marker's kept positions in the window: a frame more than twice
    /// [`JUMP_M`] from where the two before it put it (constant velocity), and the next more
    /// than [`JUMP_M`] from its own prediction, as when a lift stays on another surface or a
    /// track moves to another marker.
    pub position_steps: usize,
    /// How far the marker's median position relative to its parent's marker inside the
    /// window lies from that on the first frames (where the markers were drawn, so the
    /// identities are right), over the distance between the two markers there: a branch
    /// swings about its rest, so this stays small; a track that moved to another marker
    /// does not. `None` when either marker has no position there.
    pub parent_offset_drift: Option<f64>,
    /// Cycles of our mode in the stretch our fit used.
    pub fit_cycles: Option<f64>,
    /// RMS of our fit's residual over the RMS of the fitted signal (0: the fit explains it
    /// all; 1: nothing).
    pub fit_residual_ratio: Option<f64>,
    /// Our frequency and damping can be trusted (no note against them).
    pub ours_trusted: bool,
    /// The paper method's can be trusted (no note against them).
    pub paper_trusted: bool,
}

/// Share of a test window's frames below which the tracker or the lift is too sparse to
/// trust the branch's numbers.
pub const MIN_WINDOW_FRACTION: f64 = 0.9;
/// Fewest cycles of our mode in the fitted stretch for a trusted estimate (the estimator's
/// own short-decay warning starts lower).
pub const MIN_TRUSTED_CYCLES: f64 = 3.0;
/// Residual RMS over signal RMS above which our fit does not explain the record.
pub const MAX_RESIDUAL_RATIO: f64 = 0.5;
/// Largest relative 95 % half-width (two standard errors over the value) of our frequency
/// for a trusted estimate: the method's accuracy goal, 1 %.
pub const MAX_FREQUENCY_UNCERTAINTY: f64 = 0.01;
/// Largest relative 95 % half-width of our damping ratio for a trusted estimate: the
/// method's accuracy goal, 15 %.
pub const MAX_DAMPING_UNCERTAINTY: f64 = 0.15;
/// The paper's half-power band must span at least this many FFT bins for its damping to be
/// the branch's rather than the record length's (a narrower band is the window's main lobe).
pub const MIN_HALF_POWER_BINS: f64 = 2.0;
/// Largest [`BranchQuality::parent_offset_drift`] of a trusted track. A branch pulled and
/// released swings about its rest, so its median position relative to its parent's marker
/// stays within a few per cent of the distance between them (the twin: at most 3 % on
/// every branch of seeds 4, 7 and 11 that was tracked on its own marker); the tracks that
/// had moved to another marker or surface gave 36 %, 78 %, 81 % and 239 %. A 15° pull held
/// for the whole window would give 26 %.
pub const MAX_PARENT_OFFSET_DRIFT: f64 = 0.25;
/// Frames at the start of the record whose median relative position is the reference of
/// [`BranchQuality::parent_offset_drift`].
const REFERENCE_FRAMES: usize = 5;
/// The paper's FFT peak in one of its lowest bins is the record's trend, not a swing.
pub const PAPER_TREND_BINS: usize = 2;

/// Notes against our estimate: the estimator's own warnings that mean a number should not
/// be trusted, too few cycles, a residual that the fit does not explain.
pub(crate) fn judge_fit(result: &mut BranchResult, mode: &Mode, signal: &Signal, e: &Estimate) {
    let (start, end) = result
        .segment_s
        .unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
    let cycles = e.segment.map(|s| mode.frequency_hz * (s.end_s - s.start_s));
    result.quality.fit_cycles = cycles;
    let inside: Vec<f64> = signal
        .times_s()
        .iter()
        .zip(signal.values())
        .filter(|(t, _)| (start..=end).contains(*t))
        .filter_map(|(_, v)| *v)
        .collect();
    let n = inside.len().max(1) as f64;
    let mean = inside.iter().sum::<f64>() / n;
    let rms = (inside.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    result.quality.fit_residual_ratio = e.residual_rms.filter(|_| rms > 0.0).map(|r| r / rms);
    for w in &e.warnings {
        if distrusting(w) {
            result.notes.push(format!("ours: {w}"));
        }
    }
    let uncertainties = [
        (
            "frequency",
            mode.frequency_hz,
            mode.frequency_std_hz,
            MAX_FREQUENCY_UNCERTAINTY,
        ),
        (
            "damping ratio",
            mode.damping_ratio,
            mode.damping_std,
            MAX_DAMPING_UNCERTAINTY,
        ),
    ];
    for (what, value, sd, limit) in uncertainties {
        if let Some(sd) = sd.filter(|sd| 2.0 * sd > limit * value) {
            result.notes.push(format!(
                "ours: the {what} is known to ±{:.2} % (two standard errors), more than {:.0} %",
                200.0 * sd / value,
                100.0 * limit
            ));
        }
    }
    if let Some(c) = cycles.filter(|c| *c < MIN_TRUSTED_CYCLES) {
        result.notes.push(format!(
            "ours: only {c:.1} cycles of {:.3} Hz in the fitted stretch (at least {MIN_TRUSTED_CYCLES} to trust)",
            mode.frequency_hz
        ));
    }
    if let Some(r) = result
        .quality
        .fit_residual_ratio
        .filter(|r| *r > MAX_RESIDUAL_RATIO)
    {
        result.notes.push(format!(
            "ours: the fit leaves {:.0} % of the signal's RMS unexplained (more than {:.0} %)",
            100.0 * r,
            100.0 * MAX_RESIDUAL_RATIO
        ));
    }
}

/// Whether an estimator warning means its numbers should not be trusted (the others, such
/// as interpolated gaps or the paper method's bin-width uncertainty, are information).
fn distrusting(w: &Warning) -> bool {
    matches!(
        w,
        Warning::ShortDecay { .. }
            | Warning::DampingUncertain { .. }
            | Warning::NotConverged { .. }
            | Warning::HalfPowerOpen
            | Warning::NoRelease
            | Warning::FarFromPeak { .. }
            | Warning::OutsideBand { .. }
    )
}

/// Notes against the paper method's result: a peak in its lowest bins (the record's trend,
/// not a swing), a frequency that disagrees with ours by more than its bin width, and its
/// own warnings.
pub(crate) fn judge_paper(result: &mut BranchResult, h: &HalfPower, warnings: &[Warning]) {
    if h.bin <= PAPER_TREND_BINS {
        result.notes.push(format!(
            "paper: its FFT peak is bin {} ({:.3} Hz), the record's slow trend rather than a swing",
            h.bin, h.frequency_hz
        ));
    }
    if let Some(m) = &result.ours
        && (h.frequency_hz - m.frequency_hz).abs() > h.bin_width_hz
    {
        result.notes.push(format!(
            "paper: {:.3} Hz disagrees with ours ({:.3} Hz) by more than its bin width ({:.3} Hz)",
            h.frequency_hz, m.frequency_hz, h.bin_width_hz
        ));
    }
    if let (Some(lo), Some(hi)) = (h.lower_hz, h.upper_hz)
        && hi - lo < MIN_HALF_POWER_BINS * h.bin_width_hz
    {
        result.notes.push(format!(
            "paper: its half-power band ({:.3} Hz) spans fewer than {MIN_HALF_POWER_BINS} FFT bins of {:.3} Hz: the damping ratio is the record length's, not the branch's",
            hi - lo,
            h.bin_width_hz
        ));
    }
    for w in warnings {
        if distrusting(w) {
            result.notes.push(format!("paper: {w}"));
        }
    }
}

/// The tracker's and the lift's record inside the test window, and a note when it is too
/// sparse or the kept positions step like a marker that changed surface or identity.
pub(crate) fn judge_track(
    result: &mut BranchResult,
    times: &[f64],
    (w0, w1): (f64, f64),
    tracked: Option<&[bool]>,
    kept: Option<&[Option<Point3<f64>>]>,
    lifted: Option<&[Option<Point3<f64>>]>,
) {
    let inside: Vec<usize> = (0..times.len())
        .filter(|&i| (w0..=w1).contains(&times[i]))
        .collect();
    let n = inside.len();
    let q = &mut result.quality;
    q.window_frames = n;
    let share = |f: &dyn Fn(usize) -> bool| {
        inside.iter().filter(|&&i| f(i)).count() as f64 / n.max(1) as f64
    };
    q.window_tracked_fraction = share(&|i| tracked.is_some_and(|t| t.get(i) == Some(&true)));
    q.window_lifted_fraction =
        share(&|i| kept.is_some_and(|k| k.get(i).is_some_and(Option::is_some)));
    q.jumps_dropped = inside
        .iter()
        .filter(|&&i| {
            lifted.is_some_and(|l| l.get(i).is_some_and(Option::is_some))
                && kept.is_some_and(|k| k.get(i).is_some_and(Option::is_none))
        })
        .count();
    // A position fails when the two before it (constant velocity) do not predict it within
    // JUMP_M: a swing's own acceleration moves it about 2 cm from that prediction at most (a
    // 2.5 Hz twig swinging 10 cm at 30 fps). A track or lift that moves to another surface
    // and stays fails on two frames running (the jump, then the prediction that carries its
    // velocity).
    let positions: Vec<Option<Point3<f64>>> = inside
        .iter()
        .map(|&i| kept.and_then(|k| k.get(i).copied().flatten()))
        .collect();
    let misses: Vec<f64> = (0..positions.len())
        .map(|k| match (k.checked_sub(2), positions[k]) {
            (Some(k2), Some(p)) => match (positions[k2], positions[k - 1]) {
                (Some(p2), Some(p1)) => (p - (p1 + (p1 - p2))).norm(),
                _ => 0.0,
            },
            _ => 0.0,
        })
        .collect();
    // A single position off by less than JUMP_M misses the next frame's prediction by less
    // than twice that; a step of twice JUMP_M or more that stays is a step.
    let steps = misses
        .windows(2)
        .filter(|w| w[0] > 2.0 * JUMP_M && w[1] > JUMP_M)
        .count();
    q.position_steps = steps;
    let (tracked_share, lifted_share) = (q.window_tracked_fraction, q.window_lifted_fraction);
    if tracked_share < MIN_WINDOW_FRACTION {
        result.notes.push(format!(
            "track: the marker was tracked on only {:.1} % of its test window's {n} frames",
            100.0 * tracked_share
        ));
    }
    if lifted_share < MIN_WINDOW_FRACTION {
        result.notes.push(format!(
            "track: the marker has a 3D position on only {:.1} % of its test window's {n} frames",
            100.0 * lifted_share
        ));
    }
    if steps > 0 {
        result.notes.push(format!(
            "track: the marker's 3D position jumps more than {:.0} cm off its motion and stays {steps} time(s) in its test window (a lift on another surface, or a track on another marker)",
            2.0 * JUMP_M * 100.0
        ));
    }
}

/// The marker's drift from its place relative to its parent's marker (see
/// [`BranchQuality::parent_offset_drift`]), with a note when it is larger than
/// [`MAX_PARENT_OFFSET_DRIFT`]. `child` and `parent` are the kept positions.
pub(crate) fn judge_identity(
    result: &mut BranchResult,
    times: &[f64],
    (w0, w1): (f64, f64),
    child: Option<&[Option<Point3<f64>>]>,
    parent: Option<&[Option<Point3<f64>>]>,
) {
    let (Some(child), Some(parent)) = (child, parent) else {
        return;
    };
    let relative: Vec<(f64, Vector3<f64>)> = times
        .iter()
        .zip(child.iter().zip(parent))
        .filter_map(|(t, (c, p))| Some((*t, c.as_ref()? - p.as_ref()?)))
        .collect();
    // Per-coordinate median (positions are finite: a NaN would give `None` and no verdict).
    let centre = |v: &[Vector3<f64>]| -> Option<Vector3<f64>> {
        let axis = |k: usize| median(&mut v.iter().map(|r| r[k]).collect::<Vec<f64>>());
        Some(Vector3::new(axis(0)?, axis(1)?, axis(2)?))
    };
    let first: Vec<Vector3<f64>> = relative
        .iter()
        .take(REFERENCE_FRAMES)
        .map(|r| r.1)
        .collect();
    let inside: Vec<Vector3<f64>> = relative
        .iter()
        .filter(|(t, _)| (w0..=w1).contains(t))
        .map(|r| r.1)
        .collect();
    let (Some(reference), Some(inside)) = (centre(&first), centre(&inside)) else {
        return;
    };
    let chord_m = reference.norm();
    if chord_m.is_nan() || chord_m <= 0.0 {
        return;
    }
    let moved_m = (inside - reference).norm();
    let drift = moved_m / chord_m;
    result.quality.parent_offset_drift = Some(drift);
    if drift > MAX_PARENT_OFFSET_DRIFT {
        result.notes.push(format!(
            "track: in its test window the marker sits {:.0} cm from its place relative to its parent's marker on the first frames ({:.0} % of the {:.0} cm between them; a branch swings about its rest): the track or the lift may be on another marker or surface",
            100.0 * moved_m,
            100.0 * drift,
            100.0 * chord_m
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::FittedSignal;

    fn blank(id: &str) -> BranchResult {
        BranchResult {
            id: id.into(),
            parent: "A".into(),
            level: 1,
            tracked_fraction: 1.0,
            lifted_fraction: 1.0,
            ours: None,
            paper: None,
            paper_bin_hz: None,
            notes: Vec::new(),
            series: (Vec::new(), Vec::new()),
            fitted: FittedSignal::default(),
            segment_s: None,
            window_s: None,
            quality: BranchQuality::default(),
        }
    }

    /// A marker swinging at 2.5 Hz with 10 cm amplitude at 30 fps, as `(times, positions)`.
    fn swing() -> (Vec<f64>, Vec<Option<Point3<f64>>>) {
        let times: Vec<f64> = (0..150).map(|i| f64::from(i) / 30.0).collect();
        let positions = times
            .iter()
            .map(|t| {
                let x = 0.1 * (2.0 * std::f64::consts::PI * 2.5 * t).cos();
                Some(Point3::new(x, 1.5, 1.0))
            })
            .collect();
        (times, positions)
    }

    fn steps_of(times: &[f64], kept: &[Option<Point3<f64>>]) -> (usize, BranchResult) {
        let mut r = blank("B");
        let tracked = vec![true; times.len()];
        judge_track(
            &mut r,
            times,
            (f64::NEG_INFINITY, f64::INFINITY),
            Some(&tracked),
            Some(kept),
            Some(kept),
        );
        (r.quality.position_steps, r)
    }

    #[test]
    fn a_fast_swing_and_a_small_outlier_are_not_steps_a_surface_change_is() {
        let (times, smooth) = swing();
        let (steps, r) = steps_of(&times, &smooth);
        assert_eq!(steps, 0, "{:?}", r.notes);
        assert!(r.notes.is_empty(), "{:?}", r.notes);
        // One position 3.5 cm off (the jump filter leaves it): not a step.
        let mut outlier = smooth.clone();
        outlier[60] = outlier[60].map(|p| p + Vector3::new(0.0, -0.035, 0.0));
        assert_eq!(steps_of(&times, &outlier).0, 0);
        // From frame 80 on, the lift sits on a surface 10 cm nearer: one step, a note.
        let mut moved = smooth;
        for p in moved.iter_mut().skip(80) {
            *p = p.map(|p| p + Vector3::new(0.0, -0.10, 0.0));
        }
        let (steps, r) = steps_of(&times, &moved);
        assert_eq!(steps, 1);
        assert!(
            r.notes.iter().any(|n| n.starts_with("track:")),
            "{:?}",
            r.notes
        );
    }

    #[test]
    fn a_track_on_another_marker_is_noted_a_swing_is_not() {
        let times: Vec<f64> = (0..150).map(|i| f64::from(i) / 30.0).collect();
        let parent: Vec<Option<Point3<f64>>> = times
            .iter()
            .map(|_| Some(Point3::new(0.0, 0.0, 2.0)))
            .collect();
        // A branch 40 cm from its parent's marker, at rest, held 6 cm off for a second, then
        // swinging about its rest: no note.
        let swing: Vec<Option<Point3<f64>>> = times
            .iter()
            .map(|&t| {
                let dx = if t < 1.0 {
                    0.0
                } else if t < 2.0 {
                    0.06
                } else {
                    0.06 * (-(t - 2.0)).exp() * (std::f64::consts::TAU * 2.0 * (t - 2.0)).cos()
                };
                Some(Point3::new(0.4 + dx, 0.1, 2.0))
            })
            .collect();
        let mut r = blank("B");
        judge_identity(&mut r, &times, (1.0, 5.0), Some(&swing), Some(&parent));
        assert!(
            r.quality.parent_offset_drift.unwrap() < 0.1,
            "{:?}",
            r.quality
        );
        assert!(r.notes.is_empty(), "{:?}", r.notes);
        // The same track moved at 0.5 s, crossing, to a marker 1.2 m from the parent's.
        let moved: Vec<Option<Point3<f64>>> = swing
            .iter()
            .zip(&times)
            .map(|(p, &t)| {
                p.map(|p| {
                    if t < 0.5 {
                        p
                    } else {
                        Point3::new(1.2, 0.1, 2.1)
                    }
                })
            })
            .collect();
        let mut r = blank("B");
        r.ours = Some(Mode {
            frequency_hz: 2.0,
            frequency_std_hz: Some(0.001),
            damping_ratio: 0.1,
            damping_std: Some(0.001),
            damped_frequency_hz: 2.0,
            decay_rate_per_s: 1.3,
            amplitude: 0.06,
            amplitude_std: None,
            phase_rad: 0.0,
            reference_time_s: 2.0,
        });
        judge_identity(&mut r, &times, (1.0, 5.0), Some(&moved), Some(&parent));
        assert!(
            r.quality.parent_offset_drift.unwrap() > 1.5,
            "{:?}",
            r.quality
        );
        assert_eq!(r.notes.len(), 1, "{:?}", r.notes);
        assert!(r.notes[0].starts_with("track: "), "{:?}", r.notes);
        r.settle_trust();
        assert!(!r.quality.ours_trusted);
        // Without the parent's positions nothing can be said.
        let mut r = blank("B");
        judge_identity(&mut r, &times, (1.0, 5.0), Some(&moved), None);
        assert_eq!(r.quality.parent_offset_drift, None);
    }

    #[test]
    fn sparse_tracking_inside_the_window_is_noted() {
        let (times, mut kept) = swing();
        let mut tracked = vec![true; times.len()];
        for k in 40..60 {
            tracked[k] = false;
            kept[k] = None;
        }
        let mut r = blank("B");
        // The loss lies inside the window 1..2 s (frames 30..60): 20 of 31 frames lost.
        judge_track(
            &mut r,
            &times,
            (1.0, 2.0),
            Some(&tracked),
            Some(&kept),
            Some(&kept),
        );
        assert_eq!(r.quality.window_frames, 31);
        assert!(r.quality.window_tracked_fraction < 0.4);
        assert_eq!(r.notes.len(), 2, "{:?}", r.notes);
        // Outside it, nothing is said.
        let mut r = blank("B");
        judge_track(
            &mut r,
            &times,
            (3.0, 4.0),
            Some(&tracked),
            Some(&kept),
            Some(&kept),
        );
        assert!(r.notes.is_empty(), "{:?}", r.notes);
    }

    #[test]
    fn the_papers_trend_peaks_disagreements_and_narrow_bands_are_noted() {
        let h = |bin: usize, f: f64, band: f64| HalfPower {
            frequency_hz: f,
            bin,
            bin_width_hz: 0.25,
            peak_value: 1.0,
            lower_hz: Some(f - band / 2.0),
            upper_hz: Some(f + band / 2.0),
            damping_ratio: Some(band / (2.0 * f)),
        };
        let mode = |f: f64| Mode {
            frequency_hz: f,
            frequency_std_hz: Some(0.001),
            damping_ratio: 0.1,
            damping_std: Some(0.001),
            damped_frequency_hz: f,
            decay_rate_per_s: 0.1,
            amplitude: 1.0,
            amplitude_std: None,
            phase_rad: 0.0,
            reference_time_s: 0.0,
        };
        let mut agree = blank("C");
        agree.ours = Some(mode(2.0));
        judge_paper(&mut agree, &h(8, 2.0, 0.6), &[]);
        assert!(agree.notes.is_empty(), "{:?}", agree.notes);
        let mut far = blank("C");
        far.ours = Some(mode(2.0));
        judge_paper(&mut far, &h(18, 4.5, 0.6), &[]);
        assert_eq!(far.notes.len(), 1, "{:?}", far.notes);
        let mut trend = blank("C");
        judge_paper(&mut trend, &h(2, 0.5, 0.6), &[]);
        assert!(trend.notes[0].contains("trend"), "{:?}", trend.notes);
        let mut narrow = blank("C");
        judge_paper(&mut narrow, &h(8, 2.0, 0.3), &[]);
        assert!(
            narrow.notes[0].contains("record length"),
            "{:?}",
            narrow.notes
        );
    }
}
