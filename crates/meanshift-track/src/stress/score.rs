//! Tracks scored against a scene's truth, the strict way.

use super::*;

/// How tracks fare against a scene's truth (see the module docs for the rules).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StressScore {
    /// Marker-frames where the marker is fully visible (frame 0 excluded).
    pub visible_frames: usize,
    /// Of those, frames with a centre within the tolerance.
    pub within_tolerance: usize,
    /// Frames (any visibility) whose centre is within the tolerance of another marker's
    /// truth and not of its own.
    pub identity_swaps: usize,
    /// Frames reported `tracked`, `recovered` or `set` with the centre farther than the
    /// false-report distance from the truth.
    pub false_found: usize,
    /// Frames reported found while the marker was entirely hidden.
    pub found_while_hidden: usize,
    /// Longest run of fully visible frames without a centre within the tolerance, counted
    /// since the marker was last held (hidden frames neither count nor end a run).
    pub longest_loss_frames: usize,
    /// Frames by status: tracked, recovered, predicted, lost, set.
    pub status_frames: [usize; 5],
    /// Mean error of the centres within tolerance (pixels).
    pub mean_error_px: f64,
}

impl StressScore {
    /// Fraction of fully visible marker-frames within the tolerance.
    pub fn fraction_within(&self) -> f64 {
        if self.visible_frames == 0 {
            1.0
        } else {
            self.within_tolerance as f64 / self.visible_frames as f64
        }
    }

    /// Add another score (another sequence) to this one.
    pub fn merge(&mut self, other: &StressScore) {
        let n = self.within_tolerance + other.within_tolerance;
        if n > 0 {
            self.mean_error_px = (self.mean_error_px * self.within_tolerance as f64
                + other.mean_error_px * other.within_tolerance as f64)
                / n as f64;
        }
        self.visible_frames += other.visible_frames;
        self.within_tolerance = n;
        self.identity_swaps += other.identity_swaps;
        self.false_found += other.false_found;
        self.found_while_hidden += other.found_while_hidden;
        self.longest_loss_frames = self.longest_loss_frames.max(other.longest_loss_frames);
        for (a, b) in self.status_frames.iter_mut().zip(other.status_frames) {
            *a += b;
        }
    }
}

pub(super) fn status_index(s: TrackStatus) -> usize {
    match s {
        TrackStatus::Tracked => 0,
        TrackStatus::Recovered => 1,
        TrackStatus::Predicted => 2,
        TrackStatus::Lost => 3,
        TrackStatus::Set => 4,
    }
}

/// Score `tracks` (in the scene's marker order) against the scene: accuracy within
/// `tolerance_px` on fully visible frames, and reports of `found` farther than `false_px`.
///
/// # Errors
/// [`TrackError::InvalidParameter`] when the tracks do not match the scene's markers and
/// frames, or a distance is not positive.
pub fn score_stress(
    tracks: &[Track],
    scene: &StressScene,
    tolerance_px: f64,
    false_px: f64,
) -> Result<StressScore> {
    if !(tolerance_px.is_finite() && tolerance_px > 0.0 && false_px.is_finite() && false_px > 0.0) {
        return Err(TrackError::param(
            "tolerance_px/false_px",
            "must be positive",
        ));
    }
    if tracks.len() != scene.markers.len() {
        return Err(TrackError::param(
            "tracks",
            format!(
                "{} tracks for {} markers",
                tracks.len(),
                scene.markers.len()
            ),
        ));
    }
    if let Some(t) = tracks.iter().find(|t| t.observations.len() != scene.frames) {
        return Err(TrackError::param(
            "tracks",
            format!(
                "marker {} has {} frames, the scene {}",
                t.id,
                t.observations.len(),
                scene.frames
            ),
        ));
    }
    let mut s = StressScore::default();
    let mut sum = 0.0;
    let mut runs = vec![0usize; tracks.len()];
    for f in 0..scene.frames {
        let truth = scene.truth(f);
        let vis = scene.visibility(f);
        for (i, track) in tracks.iter().enumerate() {
            let o = &track.observations[f];
            s.status_frames[status_index(o.status)] += 1;
            let err = o.center.map(|c| (c - truth[i]).norm());
            let found = matches!(
                o.status,
                TrackStatus::Tracked | TrackStatus::Recovered | TrackStatus::Set
            );
            if found && err.is_none_or(|e| e > false_px) {
                s.false_found += 1;
            }
            if found && vis[i] <= 0.0 {
                s.found_while_hidden += 1;
            }
            let held = err.is_some_and(|e| e <= tolerance_px);
            if let (Some(c), false) = (o.center, held)
                && truth
                    .iter()
                    .enumerate()
                    .any(|(j, t)| j != i && (c - t).norm() <= tolerance_px)
            {
                s.identity_swaps += 1;
            }
            if f == 0 {
                continue;
            }
            if held {
                runs[i] = 0;
            } else if vis[i] >= FULLY_VISIBLE {
                runs[i] += 1;
                s.longest_loss_frames = s.longest_loss_frames.max(runs[i]);
            }
            if vis[i] >= FULLY_VISIBLE {
                s.visible_frames += 1;
                if let (true, Some(e)) = (held, err) {
                    s.within_tolerance += 1;
                    sum += e;
                }
            }
        }
    }
    s.mean_error_px = if s.within_tolerance > 0 {
        sum / s.within_tolerance as f64
    } else {
        0.0
    };
    Ok(s)
}
