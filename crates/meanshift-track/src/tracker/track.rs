//! What the tracker gives back: per marker its observations, their status, and a summary;
//! and the depth map it may gate with.

use super::*;

/// A marker to track and the window a user drew around it on the first frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MarkerInit {
    /// Unique name.
    pub id: String,
    /// Window on the first frame (top-left corner and size, pixels), inside the image.
    pub window: PixelRect,
}

/// How a marker's centre in a frame was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackStatus {
    /// Measured where the motion model expected it, looking like the marker.
    Tracked,
    /// Measured after the motion model was surprised (a release, a jump) or after frames
    /// without a measurement, by detection and joint assignment.
    Recovered,
    /// Not measured, or measured too unlike the marker to be trusted (confidence under 0.6,
    /// which the tracker still follows): the centre is the tracker's estimate, not a place
    /// to stand behind. The confidence tells the two apart: 0 for the motion model's
    /// prediction (coasting), the weak measurement's own confidence otherwise.
    Predicted,
    /// Not measured for too long; no centre.
    Lost,
    /// Set by the user ([`Tracker::set_center`]).
    Set,
}

impl TrackStatus {
    /// `tracked`, `recovered`, `predicted`, `lost` or `set`.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Tracked => "tracked",
            Self::Recovered => "recovered",
            Self::Predicted => "predicted",
            Self::Lost => "lost",
            Self::Set => "set",
        }
    }

    /// True for a measured or user-set centre (`tracked`, `recovered`, `set`).
    pub fn found(&self) -> bool {
        matches!(self, Self::Tracked | Self::Recovered | Self::Set)
    }
}

/// One marker in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Sub-pixel centre; `None` only when lost.
    pub center: Option<Point2<f64>>,
    /// The converged window.
    pub window: PixelRect,
    /// How the centre was obtained.
    pub status: TrackStatus,
    /// How much the measurement looks like the marker, 0..=1: the share of the marker's
    /// colour evidence at the measured place (the mean weight of its blob's pixels relative
    /// to the marker's own on the first frame, capped at 1), times how well the blob's width
    /// matches the marker's and how much of the marker's area it holds. For the kernel (RGB)
    /// model, the greater of the Bhattacharyya coefficient and the weight share (a blurred
    /// marker's streak is weighed as the marker but its blended colours fill other bins of
    /// its histogram). 1 for user-set
    /// centres; 0 when nothing was measured (coasting `predicted`, `lost`); a `predicted`
    /// frame with a confidence was measured under 0.6 (see [`TrackStatus::Predicted`]).
    ///
    /// What it is worth, measured on the stress sequences (`docs/validation.md`, "What a
    /// confidence value means"): a `tracked` frame at 0.8 or more was within 3 px of the
    /// truth in 98–99.7 % of frames; below 0.6, measurements were more often wrong than
    /// right, which is why they are reported `predicted`; `recovered` frames were more than 8 px off in 6–15 % of frames even at high
    /// confidence (detection after a loss can take a look-alike). Take `recovered` frames
    /// as provisional until the track is `tracked` again.
    pub confidence: f64,
}

/// A marker's track: one observation per frame, frame 0 first.
#[derive(Debug, Clone, PartialEq)]
pub struct Track {
    /// Marker name.
    pub id: String,
    /// Per frame.
    pub observations: Vec<Observation>,
}

/// How a track's frames were obtained: frames per status and the longest run without a
/// measurement.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TrackSummary {
    /// Frames [`TrackStatus::Tracked`].
    pub tracked: usize,
    /// Frames [`TrackStatus::Recovered`].
    pub recovered: usize,
    /// Frames [`TrackStatus::Predicted`].
    pub predicted: usize,
    /// Frames [`TrackStatus::Lost`].
    pub lost: usize,
    /// Frames [`TrackStatus::Set`].
    pub set: usize,
    /// Longest run of consecutive frames without a measurement (predicted or lost).
    pub longest_loss_frames: usize,
}

impl Track {
    /// Frames per status and the longest loss.
    ///
    /// ```
    /// use meanshift_track::{Observation, Track, TrackStatus, PixelRect};
    /// let at = |status| Observation {
    ///     center: None,
    ///     window: PixelRect::new(0, 0, 1, 1),
    ///     status,
    ///     confidence: 0.0,
    /// };
    /// let track = Track {
    ///     id: "A".into(),
    ///     observations: vec![
    ///         at(TrackStatus::Tracked),
    ///         at(TrackStatus::Predicted),
    ///         at(TrackStatus::Lost),
    ///         at(TrackStatus::Recovered),
    ///         at(TrackStatus::Predicted),
    ///     ],
    /// };
    /// let s = track.summary();
    /// assert_eq!((s.tracked, s.recovered, s.predicted, s.lost), (1, 1, 2, 1));
    /// assert_eq!(s.longest_loss_frames, 2);
    /// ```
    pub fn summary(&self) -> TrackSummary {
        let mut s = TrackSummary::default();
        let mut run = 0;
        for o in &self.observations {
            match o.status {
                TrackStatus::Tracked => s.tracked += 1,
                TrackStatus::Recovered => s.recovered += 1,
                TrackStatus::Predicted => s.predicted += 1,
                TrackStatus::Lost => s.lost += 1,
                TrackStatus::Set => s.set += 1,
            }
            run = if o.status.found() { 0 } else { run + 1 };
            s.longest_loss_frames = s.longest_loss_frames.max(run);
        }
        s
    }
}

/// A per-pixel depth map (metres) of the same size as the frames, for depth gating; `None`
/// where there is no depth (such pixels are not gated).
#[derive(Debug, Clone, Copy)]
pub struct DepthView<'a> {
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) depth_m: &'a [Option<f64>],
}

impl<'a> DepthView<'a> {
    /// A view of `depth_m`, row-major.
    ///
    /// # Errors
    /// [`TrackError::SizeMismatch`] when the slice does not hold `width * height` values.
    pub fn new(width: u32, height: u32, depth_m: &'a [Option<f64>]) -> Result<Self> {
        if depth_m.len() as u64 != u64::from(width) * u64::from(height) {
            return Err(TrackError::SizeMismatch {
                what: "depth map values".into(),
                expected_width: width,
                expected_height: height,
                found_width: u32::try_from(depth_m.len()).unwrap_or(u32::MAX),
                found_height: 1,
            });
        }
        Ok(Self {
            width,
            height,
            depth_m,
        })
    }

    /// Depth at a pixel inside the map, `None` where there is none or it is not finite.
    pub(crate) fn at(&self, x: i32, y: i32) -> Option<f64> {
        self.depth_m[y as usize * self.width as usize + x as usize].filter(|d| d.is_finite())
    }
}
