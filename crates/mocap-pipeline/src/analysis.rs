//! From marker trajectories to each branch's modes: the hierarchy of the tracked markers,
//! the lifted trajectories in the tree frame, the relative angles (branch-angles) and each
//! branch's own mode (modal-estimate, ours and the paper's).

use std::collections::BTreeMap;

use branch_angles::{
    AngleConfig, BranchAngles, DEFAULT_JUMP_M, Hierarchy, MarkerNode, MarkerTrack, Series,
    Trajectories, branch_angles, drop_jumps, relative_swing,
};
use modal_estimate::{EstimateConfig, MIN_SWING_CYCLES, Mode, Signal, estimate};
use nalgebra::{Isometry3, Vector3};

use crate::capture::{Capture, DroppedMarker, MarkerSpec};
use crate::error::{Result, StageExt};
use crate::quality::{BranchQuality, judge_fit, judge_identity, judge_paper, judge_track};

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

impl BranchResult {
    /// A branch with nothing measured yet, over `times_s`.
    fn empty(b: &BranchAngles, times_s: Vec<f64>) -> Self {
        Self {
            id: b.child.clone(),
            parent: b.parent.clone(),
            level: b.level,
            tracked_fraction: 0.0,
            lifted_fraction: 0.0,
            ours: None,
            paper: None,
            paper_bin_hz: None,
            notes: Vec::new(),
            series: (times_s, Vec::new()),
            fitted: FittedSignal::default(),
            segment_s: None,
            window_s: None,
            quality: BranchQuality::default(),
        }
    }

    /// The trust flags from the notes: an estimate is trusted when it exists and no note
    /// about it (or about the track it came from) speaks against it.
    pub(crate) fn settle_trust(&mut self) {
        let distrusts = |prefixes: &[&str]| {
            self.notes
                .iter()
                .any(|n| prefixes.iter().any(|p| n.starts_with(p)))
        };
        let ours = self.ours.is_some() && !distrusts(&["ours:", "track:"]);
        let paper = self.paper.is_some() && !distrusts(&["paper:", "track:"]);
        self.quality.ours_trusted = ours;
        self.quality.paper_trusted = paper;
    }
}

impl FittedSignal {
    /// The displacement when it could be formed, else the angle `fallback` (its measured
    /// samples only).
    fn new(times_s: &[f64], displacement: Option<Vec<Option<f64>>>, fallback: &Series) -> Self {
        match displacement {
            Some(values) => Self {
                times_s: times_s.to_vec(),
                values,
                displacement: true,
            },
            None => Self {
                times_s: times_s.to_vec(),
                values: fallback
                    .values
                    .iter()
                    .zip(&fallback.measured)
                    .map(|(v, m)| v.filter(|_| *m))
                    .collect(),
                displacement: false,
            },
        }
    }
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
    let nodes: Vec<MarkerNode> = markers
        .iter()
        .map(|m| MarkerNode {
            id: m.id.clone(),
            parent: m.parent.clone(),
        })
        .collect();
    let pruned = Hierarchy::of_present(&nodes, tracked).stage("marker hierarchy")?;
    dropped.extend(
        pruned
            .orphans
            .into_iter()
            .map(|(id, parent)| DroppedMarker {
                id,
                reason: format!("its parent {parent} is not tracked, so its branch has no angle"),
            }),
    );
    Ok(pruned.hierarchy)
}

/// A lifted position further than this from the median of its neighbours is a lift that
/// landed on another surface (branch-angles' [`DEFAULT_JUMP_M`]), metres.
pub const JUMP_M: f64 = DEFAULT_JUMP_M;

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
                positions_m: drop_jumps(&capture.positions_m[k], JUMP_M)
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
        let share = |n: usize| n as f64 / times.len().max(1) as f64;
        let mut result = BranchResult::empty(b, times.clone());
        result.tracked_fraction = share(
            tracked
                .get(&b.child)
                .map_or(0, |t| t.iter().filter(|x| **x).count()),
        );
        result.lifted_fraction = share(track.map_or(0, |t| t.positions_m.iter().flatten().count()));
        let (w0, w1) = windows_s
            .get(&b.child)
            .copied()
            .unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
        let series = swinging_component(b, (w0, w1));
        result.series.1 = series.values.clone();
        // Ours is fitted on the child's displacement from its parent's marker along its
        // main direction of motion: the angle sees only the part of a swing across the
        // chord, and a twig swinging along it (toward or away from the parent's marker)
        // leaves the angle a small, distorted copy of its motion.
        let displacement = relative_swing(trajectories, &b.parent, &b.child, (w0, w1));
        let window = |signal: Signal| match windows_s.get(&b.child) {
            Some(&(start_s, end_s)) => signal.slice_time(start_s, end_s),
            None => signal,
        };
        result.window_s = windows_s.get(&b.child).copied();
        result.fitted = FittedSignal::new(&times, displacement, series);
        // A relative angle carries its ancestors' swings too (the paper's Fig. 12: higher
        // levels show more modes, the stem's among them): the branch's own mode is the
        // strongest one that is none of its ancestors'. (Inside the branch's own test window
        // its ancestors are still: no exclusion.)
        let mut ancestors = Vec::new();
        let mut at = (!windows_s.contains_key(&b.child)).then(|| b.parent.clone());
        while let Some(id) = at {
            if let Some(f) = own.get(&id) {
                ancestors.push(*f);
            }
            at = hierarchy.parent_of(&id).map(str::to_string);
        }
        let measured: Vec<bool> = result.fitted.values.iter().map(Option::is_some).collect();
        match Signal::from_measured(times.clone(), result.fitted.values.clone(), &measured) {
            Ok(signal) => fit_ours(&mut result, &window(signal), &ancestors),
            Err(e) => result.notes.push(format!("ours: {e}")),
        }
        if let Some(m) = result.ours {
            own.insert(b.child.clone(), m.frequency_hz);
        }
        fit_paper(&mut result, &times, &p.angle_rad, &window);
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
        judge_identity(
            &mut result,
            &times,
            (w0, w1),
            track.map(|t| t.positions_m.as_slice()),
            trajectories
                .marker(&b.parent)
                .map(|t| t.positions_m.as_slice()),
        );
        result.settle_trust();
        out.push(result);
    }
    Ok(out)
}

/// The signed angle component with the larger spread inside `window_s` (it carries the
/// swing), or the angle itself when there is no signed decomposition.
fn swinging_component(b: &BranchAngles, (w0, w1): (f64, f64)) -> &Series {
    let spread = |s: &Series| {
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
    match &b.signed {
        Some(s) if spread(&s.w_rad) > spread(&s.u_rad) => &s.w_rad,
        Some(s) => &s.u_rad,
        None => &b.angle_rad,
    }
}

/// Our estimate on `signal` (already cut to the test window): the branch's own mode, none
/// of `ancestors_hz`, with its fitted stretch and the notes on its quality.
fn fit_ours(result: &mut BranchResult, signal: &Signal, ancestors_hz: &[f64]) {
    let e = match estimate(signal, &EstimateConfig::default()) {
        Ok(e) => e,
        Err(e) => {
            result.notes.push(format!("ours: {e}"));
            return;
        }
    };
    result.ours = e.own_mode(ancestors_hz);
    result.segment_s = e.segment.map(|s| (s.start_s, s.end_s));
    match result.ours {
        Some(m) => judge_fit(result, &m, signal, &e),
        None => result.notes.push(if e.modes.is_empty() {
            "ours: no mode found".to_string()
        } else {
            format!(
                "ours: the fit's {} mode(s) are trends (under {MIN_SWING_CYCLES} cycles in the segment) or an ancestor's; none is the branch's own",
                e.modes.len()
            )
        }),
    }
}

/// The paper's method (FFT peak and half-power band) on eq. (1)'s angle, cut by `window`,
/// with the notes on its quality.
fn fit_paper(
    result: &mut BranchResult,
    times: &[f64],
    angle: &Series,
    window: &dyn Fn(Signal) -> Signal,
) {
    match Signal::new(times.to_vec(), angle.values.clone())
        .and_then(|signal| estimate(&window(signal), &EstimateConfig::paper()))
    {
        Ok(e) => {
            if let Some(h) = e.half_power {
                result.paper = Some((h.frequency_hz, h.damping_ratio));
                result.paper_bin_hz = Some(h.bin_width_hz);
                judge_paper(result, &h, &e.warnings);
            }
        }
        Err(e) => result.notes.push(format!("paper: {e}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
