//! From marker trajectories to each branch's modes: the hierarchy of the tracked markers,
//! the lifted trajectories in the tree frame, the relative angles (branch-angles) and each
//! branch's own mode (modal-estimate, ours and the paper's).

use std::collections::BTreeMap;

use branch_angles::{AngleConfig, Hierarchy, MarkerNode, MarkerTrack, Trajectories, branch_angles};
use modal_estimate::{Estimate, EstimateConfig, Mode, Signal, Warning, estimate};
use nalgebra::{Isometry3, Point3, Vector3};
use serde::Serialize;

use crate::capture::{Capture, DroppedMarker, MarkerSpec};
use crate::error::{Result, StageExt};

/// A mode within this relative distance of an ancestor's frequency is the ancestor's.
const ANCESTOR_MODE_TOLERANCE: f64 = 0.04;

/// Fewest cycles a mode must complete in the fitted segment to be a branch's swing.
const MIN_MODE_CYCLES: f64 = 2.0;

/// The modes of one marked branch.
#[derive(Debug, Clone)]
pub struct BranchResult {
    /// The child marker (names the branch).
    pub id: String,
    /// The parent marker.
    pub parent: String,
    /// Level (1 for the children of the root).
    pub level: usize,
    /// Share of frames where the tracker followed the branch's marker (a centre, not lost).
    pub tracked_fraction: f64,
    /// Share of frames where the marker has a 3D position (lifted, and not dropped as a
    /// jump).
    pub lifted_fraction: f64,
    /// Our estimate (largest-amplitude mode of the signed angle's free decay).
    pub ours: Option<Mode>,
    /// The paper's method: FFT peak frequency and eq. (6) damping.
    pub paper: Option<(f64, Option<f64>)>,
    /// The paper method's bin width, hertz.
    pub paper_bin_hz: Option<f64>,
    /// Why a value is missing, when one is.
    pub notes: Vec<String>,
    /// The signed relative angle that moves most (times, radians), for figures.
    pub series: (Vec<f64>, Vec<Option<f64>>),
    /// The signal ours was fitted on (times, values): the child's displacement from its
    /// parent's marker along its main direction of motion, metres, or the signed angle,
    /// radians, when that displacement cannot be formed.
    pub fitted: FittedSignal,
    /// Fitted segment, seconds.
    pub segment_s: Option<(f64, f64)>,
    /// The branch's test window, seconds, when one was given.
    pub window_s: Option<(f64, f64)>,
    /// How far each number can be trusted.
    pub quality: BranchQuality,
}

/// The signal our estimate was fitted on.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FittedSignal {
    /// Frame times, seconds.
    pub times_s: Vec<f64>,
    /// Values (`None` where the marker or its parent has no position).
    pub values: Vec<Option<f64>>,
    /// `true` for a displacement in metres, `false` for the angle fallback in radians.
    pub displacement: bool,
}

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
/// The paper's FFT peak in one of its lowest bins is the record's trend, not a swing.
pub const PAPER_TREND_BINS: usize = 2;

/// The hierarchy of the markers that were tracked, dropping markers whose parent is gone
/// (with the reason).
///
/// # Errors
/// The hierarchy's own errors (no root, two roots, a cycle, an unknown parent).
pub fn hierarchy(
    markers: &[MarkerSpec],
    tracked: &[String],
    dropped: &mut Vec<DroppedMarker>,
) -> Result<Hierarchy> {
    let mut kept: Vec<&MarkerSpec> = markers.iter().filter(|m| tracked.contains(&m.id)).collect();
    loop {
        let ids: Vec<&str> = kept.iter().map(|m| m.id.as_str()).collect();
        let orphan = kept.iter().position(|m| {
            m.parent
                .as_deref()
                .is_some_and(|p| !ids.contains(&p) && markers.iter().any(|q| q.id == p))
        });
        match orphan {
            Some(i) => {
                let m = kept.remove(i);
                dropped.push(DroppedMarker {
                    id: m.id.clone(),
                    reason: format!(
                        "its parent {} is not tracked, so its branch has no angle",
                        m.parent.as_deref().unwrap_or("?")
                    ),
                });
            }
            None => break,
        }
    }
    Hierarchy::new(
        kept.iter()
            .map(|m| MarkerNode {
                id: m.id.clone(),
                parent: m.parent.clone(),
            })
            .collect(),
    )
    .stage("marker hierarchy")
}

/// A lifted position further than this from the median of its neighbours (two frames each
/// side) is a lift that landed on another surface: a branch marker moves at most about a
/// centimetre per frame at 30 fps (3 cm at 2.5 Hz peaks at 0.5 m/s). Metres.
pub const JUMP_M: f64 = 0.04;

/// `positions` with the isolated jumps taken out (as gaps, filled later like any other).
pub fn drop_jumps(positions: &[Option<Point3<f64>>]) -> Vec<Option<Point3<f64>>> {
    let n = positions.len();
    (0..n)
        .map(|i| {
            let p = positions[i]?;
            let around: Vec<Point3<f64>> = (i.saturating_sub(2)..(i + 3).min(n))
                .filter(|&j| j != i)
                .filter_map(|j| positions[j])
                .collect();
            if around.len() < 2 {
                return Some(p);
            }
            let median = |f: fn(&Point3<f64>) -> f64| {
                let mut v: Vec<f64> = around.iter().map(f).collect();
                v.sort_by(f64::total_cmp);
                0.5 * (v[(v.len() - 1) / 2] + v[v.len() / 2])
            };
            let m = Point3::new(median(|p| p.x), median(|p| p.y), median(|p| p.z));
            ((p - m).norm() <= JUMP_M).then_some(p)
        })
        .collect()
}

/// Trajectories of the hierarchy's markers in the tree frame (`cloud_to_tree` applied).
///
/// # Errors
/// When the trajectories cannot be built (a time base that is not increasing).
pub fn trajectories(
    capture: &Capture,
    hierarchy: &Hierarchy,
    cloud_to_tree: &Isometry3<f64>,
) -> Result<Trajectories> {
    let markers = hierarchy
        .markers()
        .iter()
        .filter_map(|node| {
            let k = capture.ids.iter().position(|id| *id == node.id)?;
            Some(MarkerTrack {
                id: node.id.clone(),
                positions_m: drop_jumps(&capture.positions_m[k])
                    .iter()
                    .map(|p| p.map(|p| cloud_to_tree * p))
                    .collect(),
            })
        })
        .collect();
    Trajectories::new(capture.times_s.clone(), markers).stage("trajectories")
}

/// Per marker and frame, whether the tracker gave a centre.
pub fn tracked_frames(capture: &Capture) -> BTreeMap<String, Vec<bool>> {
    capture
        .ids
        .iter()
        .zip(&capture.centers)
        .map(|(id, c)| (id.clone(), c.iter().map(Option::is_some).collect()))
        .collect()
}

/// Per marker, the share of frames where the tracker gave a centre.
pub fn tracked_fractions(capture: &Capture) -> BTreeMap<String, f64> {
    capture
        .ids
        .iter()
        .zip(&capture.centers)
        .map(|(id, c)| {
            let n = c.iter().filter(|c| c.is_some()).count();
            (id.clone(), n as f64 / capture.times_s.len().max(1) as f64)
        })
        .collect()
}

/// Relative angles and modes of every branch: ours on the child marker's displacement from
/// its parent's marker along its main direction of motion (free decay, matrix pencil +
/// least squares; the signed angle component that moves most where that displacement
/// cannot be formed), the paper's on eq. (1) (FFT peak and half-power band). The series
/// kept for the figures is the signed angle. A branch with an entry in `windows_s` is measured inside that time
/// window only (its own pull-and-release test); the others on the whole record.
///
/// # Errors
/// When the angles cannot be computed at all (a hierarchy marker without a trajectory).
pub fn analyse(
    hierarchy: &Hierarchy,
    trajectories: &Trajectories,
    root_direction: Vector3<f64>,
    windows_s: &BTreeMap<String, (f64, f64)>,
    capture: &Capture,
) -> Result<Vec<BranchResult>> {
    let tracked = tracked_frames(capture);
    let ours_angles = branch_angles(
        hierarchy,
        trajectories,
        &AngleConfig {
            root_direction,
            ..AngleConfig::default()
        },
    )
    .stage("branch angles")?;
    let paper_angles = branch_angles(
        hierarchy,
        trajectories,
        &AngleConfig {
            root_direction,
            ..AngleConfig::paper()
        },
    )
    .stage("branch angles (paper)")?;
    let times = trajectories.times_s().to_vec();
    let mut out = Vec::new();
    let mut own: BTreeMap<String, f64> = BTreeMap::new();
    for (b, p) in ours_angles.branches.iter().zip(&paper_angles.branches) {
        let track = trajectories.marker(&b.child);
        let lifted = track.map_or(0, |t| t.positions_m.iter().filter(|p| p.is_some()).count());
        let mut result = BranchResult {
            id: b.child.clone(),
            parent: b.parent.clone(),
            level: b.level,
            tracked_fraction: tracked.get(&b.child).map_or(0.0, |t| {
                t.iter().filter(|x| **x).count() as f64 / times.len().max(1) as f64
            }),
            lifted_fraction: lifted as f64 / times.len().max(1) as f64,
            ours: None,
            paper: None,
            paper_bin_hz: None,
            notes: Vec::new(),
            series: (times.clone(), Vec::new()),
            fitted: FittedSignal::default(),
            segment_s: None,
            window_s: None,
            quality: BranchQuality::default(),
        };
        // The signed component with the larger spread (inside the branch's window) carries
        // the swing.
        let (w0, w1) = windows_s
            .get(&b.child)
            .copied()
            .unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
        let spread = |s: &branch_angles::Series| {
            let v: Vec<f64> = s
                .values
                .iter()
                .zip(&s.times_s)
                .filter(|(_, t)| (w0..=w1).contains(*t))
                .filter_map(|(v, _)| *v)
                .collect();
            let n = v.len().max(1) as f64;
            let mean = v.iter().sum::<f64>() / n;
            v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n
        };
        let series = match &b.signed {
            Some(s) if spread(&s.w_rad) > spread(&s.u_rad) => &s.w_rad,
            Some(s) => &s.u_rad,
            None => &b.angle_rad,
        };
        result.series.1 = series.values.clone();
        // Ours is fitted on the child's displacement from its parent's marker along its
        // main direction of motion: the angle sees only the part of a swing across the
        // chord, and a twig swinging along it (toward or away from the parent's marker)
        // leaves the angle a small, distorted copy of its motion.
        let displacement = relative_swing(trajectories, &b.parent, &b.child, &times, (w0, w1));
        let window = |signal: Signal| match windows_s.get(&b.child) {
            Some(&(start_s, end_s)) => signal.slice_time(start_s, end_s),
            None => signal,
        };
        result.window_s = windows_s.get(&b.child).copied();
        let (values, measured) = match &displacement {
            Some(d) => (
                d.clone(),
                d.iter().map(Option::is_some).collect::<Vec<bool>>(),
            ),
            None => (series.values.clone(), series.measured.clone()),
        };
        result.fitted = FittedSignal {
            times_s: times.clone(),
            values: values
                .iter()
                .zip(&measured)
                .map(|(v, m)| v.filter(|_| *m))
                .collect(),
            displacement: displacement.is_some(),
        };
        match Signal::from_measured(times.clone(), values, &measured).and_then(|signal| {
            let signal = window(signal);
            estimate(&signal, &EstimateConfig::default()).map(|e| (signal, e))
        }) {
            Ok((signal, e)) => {
                // A relative angle carries its ancestors' swings too (the paper's Fig. 12:
                // higher levels show more modes, the stem's among them): the branch's own
                // mode is the strongest one that is none of its ancestors'.
                // (Inside the branch's own test window its ancestors are still: no exclusion.)
                let mut ancestors = Vec::new();
                let mut at = (!windows_s.contains_key(&b.child)).then(|| b.parent.clone());
                while let Some(id) = at {
                    if let Some(f) = own.get(&id) {
                        ancestors.push(*f);
                    }
                    at = hierarchy.parent_of(&id).map(str::to_string);
                }
                let is_ancestors = |m: &Mode| {
                    ancestors
                        .iter()
                        .any(|f| (m.frequency_hz - f).abs() <= ANCESTOR_MODE_TOLERANCE * f)
                };
                // A "mode" with fewer than two cycles in the fitted segment is the fit's
                // stand-in for a slow trend, not a swing.
                let span_s = e.segment.map_or(f64::INFINITY, |s| s.end_s - s.start_s);
                let swings = |m: &Mode| m.frequency_hz * span_s >= MIN_MODE_CYCLES;
                result.ours = e
                    .modes
                    .iter()
                    .find(|m| swings(m) && !is_ancestors(m))
                    .copied();
                if result.ours.is_none() {
                    result.notes.push(if e.modes.is_empty() {
                        "ours: no mode found".to_string()
                    } else {
                        format!(
                            "ours: the fit's {} mode(s) are trends (under {MIN_MODE_CYCLES} cycles in the segment) or an ancestor's; none is the branch's own",
                            e.modes.len()
                        )
                    });
                }
                if let Some(m) = result.ours {
                    own.insert(b.child.clone(), m.frequency_hz);
                }
                result.segment_s = e.segment.map(|s| (s.start_s, s.end_s));
                if let Some(m) = result.ours {
                    judge_fit(&mut result, &m, &signal, &e);
                }
            }
            Err(e) => result.notes.push(format!("ours: {e}")),
        }
        match Signal::new(times.clone(), p.angle_rad.values.clone())
            .and_then(|signal| estimate(&window(signal), &EstimateConfig::paper()))
        {
            Ok(e) => {
                if let Some(h) = e.half_power {
                    result.paper = Some((h.frequency_hz, h.damping_ratio));
                    result.paper_bin_hz = Some(h.bin_width_hz);
                    judge_paper(&mut result, &h, &e.warnings);
                }
            }
            Err(e) => result.notes.push(format!("paper: {e}")),
        }
        judge_track(
            &mut result,
            &times,
            (w0, w1),
            tracked.get(&b.child).map(Vec::as_slice),
            track.map(|t| t.positions_m.as_slice()),
            capture
                .ids
                .iter()
                .position(|id| *id == b.child)
                .map(|k| capture.positions_m[k].as_slice()),
        );
        let distrusts = |prefixes: &[&str]| {
            result
                .notes
                .iter()
                .any(|n| prefixes.iter().any(|p| n.starts_with(p)))
        };
        result.quality.ours_trusted = result.ours.is_some() && !distrusts(&["ours:", "track:"]);
        result.quality.paper_trusted = result.paper.is_some() && !distrusts(&["paper:", "track:"]);
        out.push(result);
    }
    Ok(out)
}

/// Notes against our estimate: the estimator's own warnings that mean a number should not
/// be trusted, too few cycles, a residual that the fit does not explain.
fn judge_fit(result: &mut BranchResult, mode: &Mode, signal: &Signal, e: &Estimate) {
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
    if let Some(sd) = mode.frequency_std_hz
        && 2.0 * sd > MAX_FREQUENCY_UNCERTAINTY * mode.frequency_hz
    {
        result.notes.push(format!(
            "ours: the frequency is known to ±{:.2} % (two standard errors), more than {:.0} %",
            200.0 * sd / mode.frequency_hz,
            100.0 * MAX_FREQUENCY_UNCERTAINTY
        ));
    }
    if let Some(sd) = mode.damping_std
        && 2.0 * sd > MAX_DAMPING_UNCERTAINTY * mode.damping_ratio
    {
        result.notes.push(format!(
            "ours: the damping ratio is known to ±{:.0} % (two standard errors), more than {:.0} %",
            200.0 * sd / mode.damping_ratio,
            100.0 * MAX_DAMPING_UNCERTAINTY
        ));
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
fn judge_paper(result: &mut BranchResult, h: &modal_estimate::HalfPower, warnings: &[Warning]) {
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
fn judge_track(
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

/// The child's position relative to its parent's marker, projected on the direction it
/// moves most in `window` (the first principal axis of the relative positions there),
/// metres: one coordinate of the swing whichever way it goes, across or along the chord.
fn relative_swing(
    trajectories: &Trajectories,
    parent: &str,
    child: &str,
    times: &[f64],
    window: (f64, f64),
) -> Option<Vec<Option<f64>>> {
    let (p, c) = (trajectories.marker(parent)?, trajectories.marker(child)?);
    let rel: Vec<Option<Vector3<f64>>> = p
        .positions_m
        .iter()
        .zip(&c.positions_m)
        .map(|(a, b)| Some(b.as_ref()? - a.as_ref()?))
        .collect();
    let inside: Vec<Vector3<f64>> = rel
        .iter()
        .zip(times)
        .filter(|(_, t)| (window.0..=window.1).contains(*t))
        .filter_map(|(r, _)| *r)
        .collect();
    if inside.len() < 3 {
        return None;
    }
    let mean = inside.iter().sum::<Vector3<f64>>() / inside.len() as f64;
    let cov = inside
        .iter()
        .map(|r| (r - mean) * (r - mean).transpose())
        .sum::<nalgebra::Matrix3<f64>>();
    let eig = nalgebra::SymmetricEigen::try_new(cov, f64::EPSILON, 1000)?;
    let k = eig.eigenvalues.imax();
    let axis: Vector3<f64> = eig.eigenvectors.column(k).into();
    Some(
        rel.iter()
            .map(|r| r.map(|r| (r - mean).dot(&axis)))
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let h = |bin: usize, f: f64, band: f64| modal_estimate::HalfPower {
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

    #[test]
    fn a_window_off_the_first_frame_drops_that_marker_and_its_children_only() {
        let spec = |id: &str, parent: Option<&str>, x: f64| MarkerSpec {
            id: id.into(),
            parent: parent.map(str::to_string),
            center: nalgebra::Point2::new(x, 10.0),
            size_px: 7,
        };
        let markers = vec![
            spec("A", None, 10.0),
            spec("B", Some("A"), 20.0),
            spec("C", Some("B"), 30.0),
            spec("D", Some("A"), 40.0),
        ];
        // B was not tracked (its window lay off the image): C loses its parent.
        let tracked = vec!["A".to_string(), "C".to_string(), "D".to_string()];
        let mut dropped = Vec::new();
        let h = hierarchy(&markers, &tracked, &mut dropped).expect("hierarchy");
        let ids: Vec<&str> = h.markers().iter().map(|m| m.id.as_str()).collect();
        assert_eq!(ids, ["A", "D"]);
        assert_eq!(dropped.len(), 1);
        assert_eq!(dropped[0].id, "C");
        assert!(
            dropped[0].reason.contains("parent B"),
            "{}",
            dropped[0].reason
        );
    }
}
