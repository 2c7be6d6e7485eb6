//! The multi-marker tracker: mean-shift per marker as the paper ran it, with what the paper
//! did by hand done automatically and a motion model that knows how unsure it is.
//!
//! Each frame:
//! 1. **Predict** every marker with a constant-velocity Kalman filter ([`MotionModel`]); its
//!    covariance is the gate: how far from the prediction a measurement may lie.
//! 2. **Quick pass**: mean-shift from the prediction over a region three windows wide; the
//!    measurement is the weighted centroid of the blob the window converged on (for a marker
//!    smeared by motion blur, the streak's centre), or the window's centroid when no
//!    marker-sized blob is there. A marker found in the last frame is `tracked` when the
//!    measurement lies in the gate, looks like the marker (its [`Observation::confidence`] is
//!    at least [`TrackerConfig::min_confidence`]), no other marker holds that place or is
//!    nearer to it, after a jump of more than half a window, its surroundings still look
//!    like the marker's ([`TrackerConfig::context_check`]), and it lies near the line the
//!    marker has been swinging along, when it has one (a same-look marker crossing its path
//!    is off that line where the two paths are apart).
//! 3. **Detection** for every other marker: the motion model takes the miss as a manoeuvre
//!    (a release), so the gate opens to [`TrackerConfig::search_radius_windows`] windows, and
//!    wider with every further frame without a measurement, up to the whole frame. In the gate,
//!    the marker's appearance is thresholded into connected blobs; blobs of a marker's width
//!    and colour are candidates. All undecided markers and all candidates are then **assigned
//!    jointly and exclusively** at least total cost (squared gate distance plus appearance,
//!    surroundings and the offset from the marker's swing line), so a candidate goes to the
//!    marker it fits best, and to none whose gate or appearance it does not fit. A marker so
//!    found is `recovered`.
//! 4. A marker without a measurement coasts on its prediction (`predicted`) for up to
//!    [`TrackerConfig::max_coast_frames`] frames, then is `lost` (no centre) while the search
//!    goes on.
//!
//! Centres are in pixel coordinates with pixel centres at integers.

use image::RgbImage;
use nalgebra::{Point2, Vector2};

use crate::assign::assign;
use crate::detect::{Blob, Labeler};
use crate::error::{Result, TrackError};
use crate::hsv::ChannelRange;
use crate::kalman::Kalman;
use crate::meanshift::{Axes, Moments, TermCriteria, moments_from_f64_sums};
use crate::model::{AppearanceModel, MarkerModel, marker_mask};
use crate::rect::PixelRect;
use crate::region::{Lookup, Mode, PixelFilter, Region, Streak};
use crate::swing::Swing;
use crate::template::Template;

/// Squared gate distance (2 degrees of freedom) inside which a measurement belongs to a
/// prediction: the chi-square quantile of 0.999.
const GATE_CHI2: f64 = 13.82;
/// Standard deviation of a measured centre (pixels).
const MEASUREMENT_PX: f64 = 1.0;
/// Least acceleration noise of the motion model (pixels per frame²): a marker at rest still
/// trembles.
const ACCELERATION_MIN_PX: f64 = 0.7;
/// Share of each frame's squared innovation blended into the acceleration noise: the model
/// expects as much change as it has recently seen.
const ACCELERATION_RATE: f64 = 0.3;
/// Markers closer than this fraction of their mean window size are on the same blob.
const EXCLUSION_FRACTION: f64 = 0.75;
/// The context template is this many times the window in each direction: the marker and
/// half a window of its surroundings on every side.
const CONTEXT_SCALE: i32 = 2;
/// Share of each accepted frame's patch blended into the context template.
const CONTEXT_RATE: f32 = 0.1;
/// Share of each confidently tracked frame's patch blended into a gray target's template.
const TEMPLATE_RATE: f32 = 0.05;
/// Least confidence (template correlation) of a frame that updates a gray target's template.
const TEMPLATE_UPDATE_CONFIDENCE: f64 = 0.8;
/// A quick-pass result after a jump whose context correlation is this far below the
/// marker's typical one goes to the joint assignment, where other candidates compete.
const CONTEXT_DROP: f64 = 0.08;
/// Typical context correlation below which the surroundings are too plain or too noisy to
/// tell markers apart, and the context is not used for the marker.
const CONTEXT_MIN_LEVEL: f64 = 0.6;
/// Most a candidate's context shortfall (from the best candidate's) may cost.
const CONTEXT_CAP: f64 = 12.0;
/// Least spread assumed for a marker's context correlation.
const CONTEXT_SIGMA_MIN: f64 = 0.02;
/// Most a candidate's confidence shortfall (from the best candidate's) may cost.
const APPEARANCE_CAP: f64 = 8.0;
/// Spreads below its usual confidence at which a measurement is not accepted without
/// competition.
const TYPICAL_SIGMAS: f64 = 3.0;
/// Least spread assumed for a marker's confidence.
const CONFIDENCE_SIGMA_MIN: f64 = 0.08;
/// Share of each found frame blended into a marker's running appearance statistics.
const APPEARANCE_RATE: f64 = 0.2;
/// Prior probability that a marker is not where the motion model expects it (a release, a
/// jump): the weight of the wide component of the motion likelihood.
const MANOEUVRE_PRIOR: f64 = 0.1;
/// Cost (negative log-likelihood, relative to a perfect candidate at the prediction) above
/// which a marker rather stays unmatched.
const UNMATCHED_COST: f64 = 12.0;
/// Distance (windows, plus one frame's motion) from the border within which a marker last
/// seen there counts as having left the frame when predicted outside it.
const BORDER_WINDOWS: f64 = 2.0;
/// Cost of taking, by a manoeuvre, a place that lies in another marker's normal gate.
const OWNED_COST: f64 = 6.0;
/// Distance (windows) within which candidates of different markers are one place: two
/// markers cannot both be closer than this, so one place cannot go to two of them.
const PLACE_SHARE: f64 = 0.5;
/// Least lead (cost units, nats) of a marker's best place over its next choice for the marker
/// to be decided on its own, before its neighbours: e^3, twenty times likelier.
const ANCHOR_MARGIN: f64 = 3.0;
/// Reach (windows) within which a decided marker's displacement guides an ambiguous one.
const NEIGHBOUR_RADIUS_WINDOWS: f64 = 6.0;
/// A marker found again after this many frames without a measurement, away from its coasted
/// prediction, starts at rest, its velocity unknown (of the order of a window per frame).
const STOP_AFTER_MISSES: usize = 2;

/// Distance, in windows, within which a same-look marker can take this one's place.
const CROWD_WINDOWS: f64 = 3.0;

/// A quick-pass measurement further than this many spreads from the marker's swing line
/// goes to detection (a same-look marker crossing its path took the window).
const LINE_ACCEPT_SPREADS: f64 = 3.0;

/// Largest cost of a candidate off the marker's swing line (nats; 4 is an offset of about
/// 2.8 spreads).
const LINE_COST_CAP: f64 = 4.0;

/// Largest cost of disagreeing with the neighbours' displacement.
const NEIGHBOUR_CAP: f64 = 6.0;
/// Reach (windows) within which a marker that is not found counts as merged with a found
/// marker of the same look.
const MERGED_WINDOWS: f64 = 0.75;
/// Largest distance (8-bit RGB) between two markers' mean colours for them to look alike.
const SAME_LOOK_RGB: f32 = 40.0;
/// Rate of the running means of how alike two markers move.
const COHERENCE_RATE: f64 = 0.2;
/// Least running mean of the two markers' squared displacements (px^2 per frame) for their
/// likeness to mean anything (static markers are alike by default).
const COHERENCE_MIN_MOTION_PX2: f64 = 1.0;
/// Largest share of the squared displacements that their squared difference may be for two
/// markers to count as moving alike (their displacements agree to about a third).
const COHERENCE_RATIO: f64 = 0.1;
/// Extra cost of a candidate on a look-alike the marker has turned down before, when it lies
/// outside the motion model's normal gate.
const DISTRACTOR_COST: f64 = 6.0;
/// A candidate within this fraction of the window of a known look-alike is on it.
const DISTRACTOR_RADIUS: f64 = 0.3;
/// Look-alikes remembered per marker (the oldest is forgotten first).
const MAX_DISTRACTORS: usize = 32;
/// Sightings counted per look-alike, at most.
const MAX_SEEN: u32 = 64;
/// A look-alike seen again within this distance (pixels) has not moved.
const STATIC_PX: f64 = 1.5;
/// Border of CamShift's size estimate around the window (OpenCV's `TOLERANCE`).
const ADAPTIVE_BORDER_PX: i32 = 10;
/// Blobs of fewer pixels are noise, not pieces of a marker.
const FRAGMENT_MIN_PIXELS: usize = 3;
/// A pixel whose colour moved this much (8-bit levels, in some channel) since the previous
/// frame has changed (colour noise and JPEG stay below it).
const CHANGED_LEVEL: u8 = 30;
/// A candidate farther than a window from where its marker was last seen (in the frame
/// before) changed on less than this share of its pixels: it was there already, so it is
/// not the marker arriving.
const STATIC_SHARE: f64 = 0.3;
/// Extra cost of such a static candidate.
const STATIC_JUMP_COST: f64 = 8.0;
/// A pixel no brighter than this in every channel is a hole (no data).
const HOLE_LEVEL: u8 = 2;
/// Share of holes around a marker above which its blob bridges 2-pixel gaps.
const HOLES_SPARSE: f64 = 0.06;
/// Share of holes above which it bridges 3-pixel gaps (a splatted projection image).
const HOLES_SPLATTED: f64 = 0.15;
/// Largest gap (pixels) tried between a marker's pixels on the first frame.
const MAX_GAP_PX: usize = 4;
/// The marker is one blob when the blob nearest the window's centre holds this share of the
/// window's blob weight.
const ONE_BLOB_SHARE: f64 = 0.8;
/// Blob pixels are those whose weight is at least this share of the marker's typical pixel
/// weight.
const BLOB_THRESHOLD: f32 = 0.35;
/// A blob needs at least this share of the marker's pixels (a partly covered marker).
const BLOB_MIN_PIXELS: f64 = 0.15;
/// A candidate blob's width (minor axis) lies within these multiples of the marker's.
const BLOB_WIDTH_RANGE: [f64; 2] = [0.4, 1.7];
/// Longest streak a blob may be, in marker widths (a marker swept across 5 of its widths
/// during the exposure).
const BLOB_MAX_LENGTH: f64 = 6.0;
/// Most candidates per marker and frame (the heaviest blobs).
const MAX_CANDIDATES: usize = 16;
/// Share of the velocity kept per frame without a measurement: a swing turns back.
const COAST_VELOCITY_DECAY: f64 = 0.8;

/// Whether the window keeps its size or adapts it as CamShift does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WindowMode {
    /// The initial window's size throughout (the paper's choice).
    #[default]
    Fixed,
    /// CamShift's size from the second moments, kept within half and twice the initial size.
    Adaptive,
}

impl WindowMode {
    /// `fixed` or `adaptive`.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Fixed => "fixed",
            Self::Adaptive => "adaptive",
        }
    }

    /// The mode of a name (`fixed`, `adaptive`).
    ///
    /// # Errors
    /// [`TrackError::InvalidParameter`] for any other name.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "fixed" => Ok(Self::Fixed),
            "adaptive" => Ok(Self::Adaptive),
            other => Err(TrackError::param(
                "window mode",
                format!("{other:?}; expected fixed or adaptive"),
            )),
        }
    }
}

/// How the tracker predicts a marker's centre in the next frame. Velocities are in pixels per
/// frame: the tracker assumes the frames it is given are equally spaced in time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MotionModel {
    /// The last centre, with no velocity (plain mean-shift, the paper).
    Static,
    /// A constant-velocity Kalman filter whose acceleration noise follows the recent motion
    /// (at least `min_acceleration_px` pixels per frame²); its covariance sets the gate.
    ConstantVelocity {
        /// Least acceleration noise, pixels per frame².
        min_acceleration_px: f64,
    },
}

impl MotionModel {
    /// The default: a constant-velocity Kalman filter with at least 0.7 px/frame² of
    /// acceleration noise.
    pub const KALMAN: MotionModel = MotionModel::ConstantVelocity {
        min_acceleration_px: ACCELERATION_MIN_PX,
    };
}

/// Tracker settings. [`TrackerConfig::default`] is the recovering tracker with the paper's hue
/// model; [`TrackerConfig::paper`] is plain mean-shift as the paper ran it (no prediction, no
/// recovery), for side-by-side comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerConfig {
    /// Appearance model. Default: [`AppearanceModel::PAPER`] (16-bin hue).
    pub model: AppearanceModel,
    /// Pixels outside this HSV range do not count for the hue and hue–saturation models
    /// (gray pixels have hue 0, red, so a saturation floor is needed). Each marker lowers the
    /// saturation and value floors to half of what its own palest pixels show (never below
    /// 24 and 16), so that a blurred, paler marker still counts. Default: saturation
    /// 60..=255, value 32..=255, any hue.
    pub hsv_mask: ChannelRange,
    /// Fixed or adaptive window. Default: fixed.
    pub window: WindowMode,
    /// Mean-shift stopping rule per search. Default: OpenCV's `(EPS | COUNT, 10, 1)`.
    pub criteria: TermCriteria,
    /// Prediction. Default: [`MotionModel::KALMAN`].
    pub motion: MotionModel,
    /// Confidence (see [`Observation::confidence`]) below which a measurement is not
    /// accepted (0..1). Default 0.35.
    pub min_confidence: f64,
    /// Whether a marker that is not where mean-shift expects it is looked for by detection
    /// (false: plain mean-shift, never lost). Default true.
    pub recovery: bool,
    /// Radius of the gate on the first frame without a measurement, in window sizes (the
    /// larger of width and height); it grows with every further such frame. Default 5 (a
    /// release moves a marker 2–5 windows in a frame).
    pub search_radius_windows: f64,
    /// Frames a marker may coast on its prediction before it is reported lost. Default 5.
    pub max_coast_frames: usize,
    /// With a depth map: pixels whose depth differs from the marker's by more than this do
    /// not vote (metres). `None` (default) disables gating.
    pub depth_gate_m: Option<f64>,
    /// Never let two markers take the same blob. Default true.
    pub exclusive: bool,
    /// Down-weight colours common around the marker when learning a histogram model
    /// (Comaniciu et al. 2003, background-weighted histogram). Default true; the paper's
    /// plain histogram with false.
    pub background_weighting: bool,
    /// Tell look-alike markers apart by their surroundings: a gray patch twice the window,
    /// learned on the first frame and updated slowly, is compared with each candidate's by
    /// normalised cross-correlation; a candidate that correlates worse than the marker
    /// usually does costs more in the assignment. Default true; false for the paper's
    /// tracker.
    pub context_check: bool,
}

impl TrackerConfig {
    /// Defaults for `model`.
    pub fn for_model(model: AppearanceModel) -> Self {
        Self {
            model,
            hsv_mask: ChannelRange {
                lower: [0, 60, 32],
                upper: [180, 255, 255],
            },
            window: WindowMode::Fixed,
            criteria: TermCriteria::OPENCV_SAMPLE,
            motion: MotionModel::KALMAN,
            min_confidence: 0.35,
            recovery: true,
            search_radius_windows: 5.0,
            max_coast_frames: 5,
            depth_gate_m: None,
            exclusive: true,
            background_weighting: true,
            context_check: true,
        }
    }

    /// The paper's tracker: hue model, fixed window, no prediction, no recovery, no
    /// exclusivity; a marker is never declared lost (plain mean-shift stays where it is).
    pub fn paper() -> Self {
        Self {
            motion: MotionModel::Static,
            recovery: false,
            exclusive: false,
            background_weighting: false,
            context_check: false,
            max_coast_frames: usize::MAX,
            ..Self::for_model(AppearanceModel::PAPER)
        }
    }

    /// Check every field.
    ///
    /// # Errors
    /// [`TrackError::InvalidParameter`] naming the field: a model with zero bins, a confidence
    /// outside 0..=1, a search radius that is not positive and finite, an acceleration noise
    /// that is not positive and finite, a depth gate that is not positive and finite, or a
    /// non-finite epsilon.
    pub fn validate(&self) -> Result<()> {
        crate::histogram::Histogram::new(self.model.spec())?;
        if !(0.0..=1.0).contains(&self.min_confidence) {
            return Err(TrackError::param(
                "min_confidence",
                format!("{} is not in 0..=1", self.min_confidence),
            ));
        }
        if !(self.search_radius_windows.is_finite() && self.search_radius_windows > 0.0) {
            return Err(TrackError::param(
                "search_radius_windows",
                format!("{} must be positive and finite", self.search_radius_windows),
            ));
        }
        if let MotionModel::ConstantVelocity {
            min_acceleration_px: a,
        } = self.motion
            && !(a.is_finite() && a > 0.0)
        {
            return Err(TrackError::param(
                "motion",
                format!("min_acceleration_px {a} must be positive and finite"),
            ));
        }
        if let Some(g) = self.depth_gate_m
            && !(g.is_finite() && g > 0.0)
        {
            return Err(TrackError::param(
                "depth_gate_m",
                format!("{g} must be positive and finite"),
            ));
        }
        if let Some(e) = self.criteria.epsilon_px
            && !e.is_finite()
        {
            return Err(TrackError::param(
                "criteria.epsilon_px",
                format!("{e} is not finite"),
            ));
        }
        Ok(())
    }
}

impl Default for TrackerConfig {
    fn default() -> Self {
        Self::for_model(AppearanceModel::PAPER)
    }
}

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
    /// Not measured; the centre is the motion model's prediction (coasting).
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
    /// model, the Bhattacharyya coefficient instead of the weight share. 1 for user-set
    /// centres; 0 when nothing was measured (`predicted`, `lost`).
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
    width: u32,
    height: u32,
    depth_m: &'a [Option<f64>],
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

/// What a marker looked like on the first frame, as the measurements see it.
#[derive(Debug, Clone, Copy)]
struct Reference {
    /// Weight in the user's window (mean-shift confidence).
    mass: f64,
    /// Mean weight of the marker's blob pixels.
    pixel_weight: f64,
    /// Blob pixels weigh at least this.
    threshold: f32,
    /// Pixels of the marker's blob.
    pixels: f64,
    /// Minor axis of the marker's blob (pixels): its width, which motion blur keeps.
    width_px: f64,
    /// Largest gap between a marker's pixels (holes, splats) that still makes one blob: the
    /// least that made the marker one blob on the first frame (1 is 8-connectivity).
    gap: usize,
}

/// A place where a marker's look-alike was seen and turned down.
#[derive(Debug, Clone, Copy)]
struct Distractor {
    at: Point2<f64>,
    /// Its pixels (the blob's box, grown by a pixel).
    bounds: PixelRect,
    /// Times seen at this place (within [`STATIC_PX`]); static from 2 on.
    seen: u32,
}

#[derive(Debug, Clone)]
struct MarkerState {
    id: String,
    model: MarkerModel,
    /// The model and the mask as per-pixel table lookups (built once).
    lookup: Lookup,
    init_size: (i32, i32),
    size: (i32, i32),
    filter: Kalman,
    /// The swing learnt from the marker's recent track (turns the prediction).
    swing: Swing,
    /// Acceleration noise of the motion model now (pixels per frame²).
    acceleration_px: f64,
    last_center: Point2<f64>,
    reference: Reference,
    depth_m: Option<f64>,
    /// Frames since the last measurement.
    misses: usize,
    last_status: TrackStatus,
    /// The surroundings, with [`TrackerConfig::context_check`].
    context: Option<Template>,
    /// The marker's own window as a gray template (gray model): its measurement.
    template: Option<Template>,
    /// Typical context correlation of accepted frames.
    context_level: f64,
    /// Variance of the context correlation of accepted frames.
    context_var: f64,
    /// Typical confidence of accepted frames.
    confidence_mean: f64,
    /// Variance of the confidence of accepted frames.
    confidence_var: f64,
    /// Innovation variance of this frame's prediction (pixels²).
    gate_var: f64,
    /// Look-alikes this marker turned down.
    distractors: Vec<Distractor>,
    /// Mean colour (RGB) of the marker's pixels on the first frame.
    colour: [f32; 3],
}

/// A measurement: where, how well it looks like the marker, and the pixels it holds.
#[derive(Debug, Clone, Copy)]
struct Measured {
    center: Point2<f64>,
    /// The window at the measurement.
    window: PixelRect,
    /// Pixels this measurement occupies (the blob's box, or the window).
    holds: PixelRect,
    confidence: f64,
    /// Moments of the window and a border (histogram models), for the adaptive size.
    moments: Option<Moments>,
}

/// Share of the pixels of `holds` whose colour changed since `previous` by more than
/// [`CHANGED_LEVEL`] in some channel: a marker that just arrived changed its pixels; a
/// static look-alike did not.
fn changed_share(frame: &RgbImage, previous: &RgbImage, holds: PixelRect) -> f64 {
    let r = holds.intersect(&image_rect(frame.width(), frame.height()));
    if r.is_empty() || previous.dimensions() != frame.dimensions() {
        return 1.0;
    }
    let (mut changed, mut all) = (0usize, 0usize);
    for y in r.y..r.bottom() as i32 {
        for x in r.x..r.right() as i32 {
            let (a, b) = (
                frame.get_pixel(x as u32, y as u32).0,
                previous.get_pixel(x as u32, y as u32).0,
            );
            all += 1;
            if a.iter()
                .zip(&b)
                .any(|(&p, &q)| p.abs_diff(q) > CHANGED_LEVEL)
            {
                changed += 1;
            }
        }
    }
    changed as f64 / all.max(1) as f64
}

/// A candidate of one marker, with its surroundings' correlation and its cost.
#[derive(Debug, Clone, Copy)]
struct Scored {
    measured: Measured,
    context: Option<f64>,
    cost: f64,
}

/// One candidate of the joint assignment.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    marker: usize,
    measured: Measured,
    cost: f64,
    context: Option<f64>,
}

/// The tracker. Create it on the first frame with the users' windows, then call
/// [`Tracker::update`] once per frame.
#[derive(Debug)]
pub struct Tracker {
    config: TrackerConfig,
    width: u32,
    height: u32,
    markers: Vec<MarkerState>,
    tracks: Vec<Track>,
    region: Region,
    labeler: Labeler,
    /// Patch scratch for the context correlation.
    patch: Vec<f32>,
    /// The last frame given: the background of this frame's streaks.
    previous: Option<RgbImage>,
    /// Per pair of markers (row-major `n x n`), how alike they have moved.
    coherence: Vec<Coherence>,
}

/// How alike two markers have moved: running means of the squared difference of their
/// displacements and of the sum of their squared displacements, over frames both were found
/// in consecutively.
#[derive(Debug, Clone, Copy, Default)]
struct Coherence {
    difference_px2: f64,
    motion_px2: f64,
}

impl Coherence {
    fn learn(&mut self, a: Vector2<f64>, b: Vector2<f64>) {
        self.difference_px2 += COHERENCE_RATE * ((a - b).norm_squared() - self.difference_px2);
        self.motion_px2 += COHERENCE_RATE * (a.norm_squared() + b.norm_squared() - self.motion_px2);
    }

    /// Not seen to move differently: alike (one rig, one branch, one camera shake), or not
    /// seen moving enough to tell.
    fn coherent(&self) -> bool {
        self.motion_px2 < COHERENCE_MIN_MOTION_PX2
            || self.difference_px2 <= COHERENCE_RATIO * self.motion_px2
    }
}

fn image_rect(width: u32, height: u32) -> PixelRect {
    PixelRect::image(width, height)
}

fn clamp_into(p: Point2<f64>, width: u32, height: u32) -> Point2<f64> {
    let finite = |v: f64| if v.is_finite() { v } else { 0.0 };
    Point2::new(
        finite(p.x).clamp(0.0, f64::from(width) - 1.0),
        finite(p.y).clamp(0.0, f64::from(height) - 1.0),
    )
}

impl Tracker {
    /// Start tracking `markers` on the first frame: learn each marker's appearance from its
    /// window and refine its centre there.
    ///
    /// # Errors
    /// As [`TrackerConfig::validate`]; [`TrackError::EmptyImage`] for an empty frame;
    /// [`TrackError::InvalidParameter`] for no markers; [`TrackError::DuplicateId`];
    /// [`TrackError::EmptyWindow`] / [`TrackError::WindowOutsideImage`] for a window that is
    /// empty or not entirely inside the frame; [`TrackError::EmptyModel`] when a window holds
    /// no pixel the model can use; [`TrackError::SizeMismatch`] for a depth map of another
    /// size.
    pub fn new(
        config: TrackerConfig,
        first_frame: &RgbImage,
        depth: Option<DepthView<'_>>,
        markers: &[MarkerInit],
    ) -> Result<Self> {
        config.validate()?;
        let (width, height) = first_frame.dimensions();
        if width == 0 || height == 0 {
            return Err(TrackError::EmptyImage {
                what: "frame 0".into(),
            });
        }
        if markers.is_empty() {
            return Err(TrackError::param("markers", "no marker to track"));
        }
        let mut tracker = Self {
            config,
            width,
            height,
            markers: Vec::with_capacity(markers.len()),
            tracks: Vec::with_capacity(markers.len()),
            region: Region::default(),
            labeler: Labeler::default(),
            patch: Vec::new(),
            previous: None,
            coherence: vec![Coherence::default(); markers.len() * markers.len()],
        };
        tracker.check_depth(depth.as_ref())?;
        for (k, init) in markers.iter().enumerate() {
            if markers[..k].iter().any(|m| m.id == init.id) {
                return Err(TrackError::DuplicateId {
                    id: init.id.clone(),
                });
            }
        }
        for init in markers {
            tracker.add_marker(first_frame, depth.as_ref(), init)?;
        }
        if tracker.config.recovery {
            tracker.learn_distractors(first_frame, depth.as_ref());
            tracker.previous = Some(first_frame.clone());
        }
        Ok(tracker)
    }

    fn check_depth(&self, depth: Option<&DepthView<'_>>) -> Result<()> {
        if let Some(d) = depth
            && (d.width, d.height) != (self.width, self.height)
        {
            return Err(TrackError::SizeMismatch {
                what: "depth map".into(),
                expected_width: self.width,
                expected_height: self.height,
                found_width: d.width,
                found_height: d.height,
            });
        }
        Ok(())
    }

    #[allow(clippy::too_many_lines)] // longer than 100 lines; to be split by concept (issue 21)
    fn add_marker(
        &mut self,
        frame: &RgbImage,
        depth: Option<&DepthView<'_>>,
        init: &MarkerInit,
    ) -> Result<()> {
        let w = init.window;
        if w.is_empty() {
            return Err(TrackError::EmptyWindow {
                what: format!("of marker {:?}", init.id),
                width: w.width,
                height: w.height,
            });
        }
        if !w.is_inside(&image_rect(self.width, self.height)) {
            return Err(TrackError::WindowOutsideImage {
                what: format!("of marker {:?}", init.id),
                x: w.x,
                y: w.y,
                width: w.width,
                height: w.height,
                image_width: self.width,
                image_height: self.height,
            });
        }
        let config = &self.config;
        let model = MarkerModel::learn(
            &init.id,
            frame,
            w,
            &config.model,
            &config.hsv_mask,
            config.background_weighting,
        )?;
        let mask = marker_mask(frame, w, &config.model, &config.hsv_mask);
        let lookup = Lookup::new(&config.model, &model, &mask);
        let center = w.center();
        let side = f64::from(w.width.max(w.height));
        let mut state = MarkerState {
            id: init.id.clone(),
            model,
            lookup,
            init_size: (w.width, w.height),
            size: (w.width, w.height),
            filter: Kalman::new(center, MEASUREMENT_PX, 0.1 * side),
            swing: Swing::default(),
            acceleration_px: ACCELERATION_MIN_PX,
            last_center: center,
            reference: Reference {
                mass: 1.0,
                pixel_weight: 255.0,
                threshold: 255.0 * BLOB_THRESHOLD,
                pixels: w.area() as f64 * 0.5,
                width_px: side * 0.8,
                gap: 1,
            },
            depth_m: None,
            misses: 0,
            last_status: TrackStatus::Tracked,
            context: None,
            context_level: 1.0,
            context_var: 0.0,
            confidence_mean: 1.0,
            confidence_var: 0.0,
            gate_var: 1.0,
            distractors: Vec::new(),
            colour: [0.0; 3],
            template: None,
        };
        // The reference: the window's mass, and the blob of the marker in it.
        state.depth_m = depth.and_then(|d| window_depth(d, w));
        let region = w.grown(w.width, w.height);
        fill(
            &mut self.region,
            config,
            &state,
            frame,
            None,
            depth,
            region,
            &[],
        );
        state.reference.mass = self.region.mass(w).max(1.0);
        learn_blob(&mut state, &self.region, &mut self.labeler, w);
        state.reference.gap = state.reference.gap.max(hole_gap(frame, w));
        state.colour = mean_colour(frame, &self.region, w, state.reference.threshold);
        let mode = self.region.locate(
            &state.model,
            &config.criteria,
            state.reference.mass,
            center,
            state.size,
        );
        let gray = matches!(config.model, AppearanceModel::Gray { .. });
        let measured = if config.recovery && gray {
            // A black-and-white target is located by its own window from here on; centre the
            // template on the target as mean-shift sees it.
            state.template = Some(Template::learn(
                frame,
                mode.center,
                w.width as usize,
                w.height as usize,
            ));
            Measured {
                confidence: 1.0,
                ..plain(&self.region, mode)
            }
        } else if config.recovery {
            let near = |c: &Measured| (c.center - mode.center).norm();
            candidates_in(&mut self.region, &mut self.labeler, &state, None, &[])
                .into_iter()
                .filter(|c| c.holds.intersect(&w).area() > 0)
                .min_by(|a, b| near(a).total_cmp(&near(b)))
                .unwrap_or_else(|| plain(&self.region, mode))
        } else {
            plain(&self.region, mode)
        };
        let observation = Observation {
            center: Some(measured.center),
            window: measured.window,
            status: TrackStatus::Tracked,
            confidence: measured.confidence,
        };
        state.last_center = measured.center;
        state.filter.position = measured.center;
        if self.config.context_check {
            state.context = Some(Template::learn(
                frame,
                measured.center,
                (w.width * CONTEXT_SCALE) as usize,
                (w.height * CONTEXT_SCALE) as usize,
            ));
        }
        self.markers.push(state);
        self.tracks.push(Track {
            id: init.id.clone(),
            observations: vec![observation],
        });
        Ok(())
    }

    /// Every marker-like blob of each marker's appearance on the first frame that is not a
    /// marker: a look-alike from the start.
    fn learn_distractors(&mut self, frame: &RgbImage, depth: Option<&DepthView<'_>>) {
        let centres: Vec<(Point2<f64>, f64)> = self
            .markers
            .iter()
            .map(|m| (m.last_center, window_px(m)))
            .collect();
        let whole = image_rect(self.width, self.height);
        for m in &mut self.markers {
            if m.template.is_some() {
                continue;
            }
            fill(
                &mut self.region,
                &self.config,
                m,
                frame,
                None,
                depth,
                whole,
                &[],
            );
            for c in candidates_in(&mut self.region, &mut self.labeler, m, None, &[]) {
                if centres
                    .iter()
                    .all(|(p, side)| (p - c.center).norm() > 0.5 * side)
                {
                    let side = window_px(m);
                    remember_distractor(m, c.center, c.holds, side);
                    remember_distractor(m, c.center, c.holds, side);
                }
            }
        }
    }

    /// Track every marker into the next frame.
    ///
    /// # Errors
    /// [`TrackError::EmptyImage`] for an empty frame; [`TrackError::SizeMismatch`] when the
    /// frame (or depth map) differs in size from the first frame. The tracker is unchanged
    /// by a failed call.
    #[allow(clippy::too_many_lines)] // longer than 100 lines; to be split by concept (issue 21)
    pub fn update(&mut self, frame: &RgbImage, depth: Option<DepthView<'_>>) -> Result<()> {
        let index = self.frames();
        if frame.width() == 0 || frame.height() == 0 {
            return Err(TrackError::EmptyImage {
                what: format!("frame {index}"),
            });
        }
        if frame.dimensions() != (self.width, self.height) {
            return Err(TrackError::SizeMismatch {
                what: format!("frame {index}"),
                expected_width: self.width,
                expected_height: self.height,
                found_width: frame.width(),
                found_height: frame.height(),
            });
        }
        self.check_depth(depth.as_ref())?;
        let depth = depth.as_ref();
        let n = self.markers.len();
        let (width, height) = (self.width, self.height);
        for m in &mut self.markers {
            m.predict(&self.config);
            m.gate_var = m.filter.innovation_var(MEASUREMENT_PX);
        }
        let predictions: Vec<Point2<f64>> = self
            .markers
            .iter()
            .map(|m| clamp_into(m.filter.position, width, height))
            .collect();

        // Quick pass: near the prediction, the candidate that fits best.
        let mut quick: Vec<Option<Scored>> = Vec::with_capacity(n);
        let mut rejected: Vec<Vec<(Point2<f64>, PixelRect)>> = Vec::with_capacity(n);
        for i in 0..n {
            let (best, others) = self.quick_pass(frame, depth, i, &predictions);
            quick.push(best);
            rejected.push(others);
        }

        // Accept confident results in the normal gate, nearest to their prediction first.
        let d2: Vec<f64> = (0..n)
            .map(|i| {
                let m = &self.markers[i];
                quick[i].as_ref().map_or(f64::INFINITY, |q| {
                    (q.measured.center - m.filter.position).norm_squared() / m.gate_var
                })
            })
            .collect();
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| d2[a].total_cmp(&d2[b]));
        let mut results: Vec<Option<(Measured, TrackStatus, Option<f64>)>> = vec![None; n];
        let mut claimed: Vec<(usize, PixelRect, Point2<f64>)> = Vec::new();
        let mut undecided = Vec::new();
        for &i in &order {
            let m = &self.markers[i];
            let Some(q) = quick[i] else {
                undecided.push(i);
                continue;
            };
            if !self.config.recovery {
                results[i] = Some((q.measured, TrackStatus::Tracked, q.context));
                continue;
            }
            let c = q.measured.center;
            // Identity is in doubt only after a jump of more than half a window, the reach of
            // plain mean-shift: a slower marker cannot have swapped with a look-alike.
            let jumped = (c - m.last_center).norm() > 0.5 * window_px(m);
            let familiar =
                !jumped || !m.context_informative() || q.context.is_none_or(|v| m.familiar(v));
            let accept = m.misses == 0
                && q.measured.confidence >= self.config.min_confidence
                && m.typical(q.measured.confidence)
                && d2[i] <= GATE_CHI2
                && !m.on_distractor(c)
                && familiar
                && (!crowded(&self.markers, i)
                    || m.swing
                        .line()
                        .is_none_or(|l| l.offset(c).abs() <= LINE_ACCEPT_SPREADS))
                && !(self.config.exclusive
                    && (taken(&self.markers, i, c, &claimed)
                        || nearer_to_other(&self.markers, i, c, &predictions)));
            if accept {
                claimed.push((i, q.measured.holds, c));
                results[i] = Some((q.measured, TrackStatus::Tracked, q.context));
            } else {
                undecided.push(i);
            }
        }

        // Detection in the opened gates, then one joint assignment.
        if !undecided.is_empty() {
            let assigned = self.detect_and_assign(frame, depth, &undecided, &claimed, &quick);
            for (&i, found) in undecided.iter().zip(assigned) {
                results[i] = found.map(|(q, c)| (q, TrackStatus::Recovered, c));
            }
        }

        // What a found marker saw near it and was not is a look-alike to remember, unless it
        // is some marker's place.
        let places_now: Vec<Point2<f64>> = predictions
            .iter()
            .copied()
            .chain(results.iter().flatten().map(|r| r.0.center))
            .collect();
        for (i, result) in results.iter().enumerate() {
            let Some((q, _, _)) = result else { continue };
            let side = window_px(&self.markers[i]);
            for &(p, bounds) in &rejected[i] {
                if (p - q.center).norm() > side && places_now.iter().all(|c| (c - p).norm() > side)
                {
                    remember_distractor(&mut self.markers[i], p, bounds, side);
                }
            }
        }

        // How alike the markers found in this frame and the last have moved.
        let moved: Vec<Option<Vector2<f64>>> = results
            .iter()
            .zip(&self.markers)
            .map(|(r, m)| {
                r.as_ref()
                    .filter(|_| m.last_status.found())
                    .map(|(q, _, _)| q.center - m.last_center)
            })
            .collect();
        for (a, da) in moved.iter().enumerate() {
            for (b, db) in moved.iter().enumerate().skip(a + 1) {
                if let (Some(da), Some(db)) = (da, db) {
                    self.coherence[a * n + b].learn(*da, *db);
                    self.coherence[b * n + a] = self.coherence[a * n + b];
                }
            }
        }

        // A marker not found where a found marker of its look now is has merged with it (two
        // markers of one colour crossing): it moves with that marker until they part, rather
        // than coasting away and being lost.
        let merged: Vec<bool> = (0..n)
            .map(|i| {
                let m = &self.markers[i];
                let reach = MERGED_WINDOWS * window_px(m);
                results[i].is_none()
                    && (0..n).any(|j| {
                        j != i
                            && same_look(m, &self.markers[j])
                            && results[j]
                                .as_ref()
                                .is_some_and(|(q, _, _)| (q.center - predictions[i]).norm() < reach)
                    })
            })
            .collect();

        let frame_index = self.tracks.first().map_or(0, |t| t.observations.len()) as u64;
        for (i, result) in results.into_iter().enumerate() {
            let m = &mut self.markers[i];
            let observation = match result {
                Some((q, status, context)) => {
                    let status = if status == TrackStatus::Tracked && !m.last_status.found() {
                        TrackStatus::Recovered
                    } else {
                        status
                    };
                    let o = m.found(q, status, &self.config, depth, frame_index);

                    m.learn_appearance(q.confidence, context);
                    if let (Some(_), Some(t)) = (context, m.context.as_mut()) {
                        t.update(frame, q.center, CONTEXT_RATE, &mut self.patch);
                    }
                    if let Some(t) = m.template.as_mut()
                        && status == TrackStatus::Tracked
                        && q.confidence >= TEMPLATE_UPDATE_CONFIDENCE
                    {
                        t.update(frame, q.center, TEMPLATE_RATE, &mut self.patch);
                    }
                    o
                }
                None if merged[i] => m.merged((width, height)),
                None => m.missed(&self.config, (width, height)),
            };
            self.tracks[i].observations.push(observation);
        }
        if let Some(p) = self.previous.as_mut() {
            p.copy_from_slice(frame);
        }
        Ok(())
    }

    /// Marker `i`'s quick pass: its candidates near the prediction (the gray template's
    /// matches, or the blobs of its weights), scored together; the best, and the places of
    /// the others. Plain mean-shift's mode without recovery, or as the fallback of a
    /// colour model when no blob fits (at half its confidence).
    fn quick_pass(
        &mut self,
        frame: &RgbImage,
        depth: Option<&DepthView<'_>>,
        i: usize,
        predictions: &[Point2<f64>],
    ) -> (Option<Scored>, Vec<(Point2<f64>, PixelRect)>) {
        let frame_side = f64::from(self.width.max(self.height));
        let m = &self.markers[i];
        let pred = predictions[i];
        let (w, h) = m.size;
        let side = window_px(m);
        let wide = m.gate_var + manoeuvre_var(&self.config, side, m.misses, frame_side);
        let found: Vec<Measured>;
        let mut fallback = None;
        if let (Some(t), true) = (&m.template, self.config.recovery) {
            let radius = (GATE_CHI2 * m.gate_var)
                .sqrt()
                .clamp(0.25 * side, 1.5 * side);
            found = template_candidates(t, m, frame, pred, radius, 4, &mut self.patch);
        } else {
            let region = PixelRect::centered_at(pred, w, h).grown(w, h);
            let masks = m.static_masks(region, pred);
            fill(
                &mut self.region,
                &self.config,
                m,
                frame,
                self.previous.as_ref(),
                depth,
                region,
                &masks,
            );
            let mode = self.region.locate(
                &m.model,
                &self.config.criteria,
                m.reference.mass,
                pred,
                m.size,
            );
            let plain_mode = plain(&self.region, mode);
            if !self.config.recovery {
                let scored = Scored {
                    measured: plain_mode,
                    context: None,
                    cost: 0.0,
                };
                return (Some(scored), Vec::new());
            }
            let others = sharing_predictions(&self.markers, i, predictions);
            found = candidates_in(&mut self.region, &mut self.labeler, m, Some(pred), &others);
            fallback = Some(Measured {
                confidence: plain_mode.confidence * 0.5,
                ..plain_mode
            });
        }
        // Surroundings tell candidates apart only when there is a choice; the chosen one's
        // are measured below in any case.
        let ambiguous = found.len() > 1 && m.context_informative();
        let with_context: Vec<(Measured, Option<f64>)> = found
            .into_iter()
            .map(|c| {
                let context = ambiguous
                    .then(|| {
                        m.context
                            .as_ref()
                            .map(|t| t.ncc_near(frame, c.center, &mut self.patch))
                    })
                    .flatten();
                (c, context)
            })
            .collect();
        let mut scored = m.score(&with_context, wide, crowded(&self.markers, i));
        scored.sort_by(|a, b| a.cost.total_cmp(&b.cost));
        let others = scored
            .iter()
            .skip(1)
            .map(|c| (c.measured.center, c.measured.holds))
            .collect();
        let mut best = scored.into_iter().next().or_else(|| {
            fallback.map(|f| Scored {
                measured: f,
                context: None,
                cost: f64::INFINITY,
            })
        });
        if let Some(b) = best.as_mut()
            && b.context.is_none()
        {
            b.context = m
                .context
                .as_ref()
                .map(|t| t.ncc_near(frame, b.measured.center, &mut self.patch));
        }
        (best, others)
    }

    /// Open the gates of `undecided` markers, find candidates in them (other markers'
    /// places masked), and assign candidates (with each marker's quick-pass measurement) to
    /// markers jointly. Per undecided marker: its measurement and context correlation, or
    /// `None`.
    #[allow(clippy::too_many_lines)] // longer than 100 lines; to be split by concept (issue 21)
    fn detect_and_assign(
        &mut self,
        frame: &RgbImage,
        depth: Option<&DepthView<'_>>,
        undecided: &[usize],
        claimed: &[(usize, PixelRect, Point2<f64>)],
        quick: &[Option<Scored>],
    ) -> Vec<Option<(Measured, Option<f64>)>> {
        let config = &self.config;
        let (width, height) = (self.width, self.height);
        let frame_side = f64::from(width.max(height));
        let masks: Vec<PixelRect> = if config.exclusive {
            claimed.iter().map(|c| c.1).collect()
        } else {
            Vec::new()
        };
        let all: Vec<Point2<f64>> = self.markers.iter().map(|m| m.filter.position).collect();
        let mut candidates: Vec<Candidate> = Vec::new();
        let mut seen: Vec<Vec<(Point2<f64>, PixelRect)>> = vec![Vec::new(); undecided.len()];
        for (row, &i) in undecided.iter().enumerate() {
            let m = &self.markers[i];
            let side = window_px(m);
            // The miss may be a manoeuvre (a release): the search opens to the search radius,
            // and wider while the marker stays unseen, up to the whole frame. The filter takes
            // the manoeuvre only if a candidate is taken.
            let wide = m.gate_var + manoeuvre_var(config, side, m.misses, frame_side);
            let pred = clamp_into(m.filter.position, width, height);
            // A marker that has left the frame comes back across the border near where it
            // left: its gate is the normal one around the border point, widened by a window
            // per missed frame, not the whole frame (where it would take whatever looks like
            // it on the far side).
            // (Only a marker last seen near the border has left: one predicted out of the
            // frame from the middle of it has a wrong velocity, and is searched everywhere.)
            let border_gap = {
                let c = m.last_center;
                c.x.min(c.y)
                    .min(f64::from(width) - c.x)
                    .min(f64::from(height) - c.y)
            };
            let outside = (m.filter.position - pred).norm() > 0.5 * side
                && border_gap < BORDER_WINDOWS * side + m.filter.velocity.norm();
            let border_px = (GATE_CHI2 * m.gate_var).sqrt() + (m.misses as f64 + 1.0) * side;
            let gate_px = if outside {
                (GATE_CHI2 * wide).sqrt().min(border_px)
            } else {
                (GATE_CHI2 * wide).sqrt().min(2.0 * frame_side)
            };
            // The quick pass's own measurement competes too (a marker half behind a twig).
            let mut found: Vec<Measured> = quick[i].iter().map(|q| q.measured).collect();
            if let Some(t) = &m.template {
                found.extend(template_candidates(
                    t,
                    m,
                    frame,
                    pred,
                    gate_px,
                    MAX_CANDIDATES,
                    &mut self.patch,
                ));
            } else {
                let (w, h) = m.size;
                let reach = gate_px.ceil() as i32 + w.max(h);
                let region = PixelRect::centered_at(pred, w, h).grown(reach, reach);
                let mut masks = masks.clone();
                masks.extend(m.static_masks(region, pred));
                fill(
                    &mut self.region,
                    config,
                    m,
                    frame,
                    self.previous.as_ref(),
                    depth,
                    region,
                    &masks,
                );
                let others = sharing_predictions(&self.markers, i, &all);
                found.extend(
                    candidates_in(&mut self.region, &mut self.labeler, m, Some(pred), &others)
                        .into_iter()
                        .take(MAX_CANDIDATES),
                );
            }
            if outside {
                found.retain(|c| (c.center - pred).norm() <= gate_px);
            }
            let mut with_context = Vec::with_capacity(found.len());
            for c in found {
                seen[row].push((c.center, c.holds));
                if c.confidence < config.min_confidence
                    || (config.exclusive && taken(&self.markers, i, c.center, claimed))
                {
                    continue;
                }
                let context = m
                    .context
                    .as_ref()
                    .filter(|_| m.context_informative())
                    .map(|t| t.ncc_near(frame, c.center, &mut self.patch));
                with_context.push((c, context));
            }
            let previous = self.previous.as_ref();
            for mut s in m.score(&with_context, wide, crowded(&self.markers, i)) {
                if let Some(prev) = previous
                    && m.misses == 0
                    && m.template.is_none()
                    && (s.measured.center - m.last_center).norm() > window_px(m)
                    && changed_share(frame, prev, s.measured.holds) < STATIC_SHARE
                {
                    s.cost += STATIC_JUMP_COST;
                }
                candidates.push(Candidate {
                    marker: i,
                    measured: s.measured,
                    cost: s.cost,
                    context: s.context,
                });
            }
        }
        // Columns: places, so that markers of one colour compete for the same blob.
        let mut places: Vec<(Point2<f64>, f64)> = Vec::new();
        let mut column = Vec::with_capacity(candidates.len());
        for c in &candidates {
            let side = window_px(&self.markers[c.marker]);
            let same = places
                .iter()
                .position(|(p, s)| (p - c.measured.center).norm() < PLACE_SHARE * side.min(*s));
            column.push(same.unwrap_or_else(|| {
                places.push((c.measured.center, side));
                places.len() - 1
            }));
        }
        let rows = undecided.len();
        let cols = places.len();
        let mut cost = vec![f64::INFINITY; rows * cols];
        // A place inside another undecided marker's normal gate is that marker's by motion:
        // a colour marker that could reach it only by a manoeuvre pays for taking it. (Gray
        // targets in rows are guided by their neighbours instead, which this would fight.)
        let in_gate = |i: usize, p: Point2<f64>| {
            let m = &self.markers[i];
            (p - m.filter.position).norm_squared() <= GATE_CHI2 * m.gate_var
        };
        for (c, &j) in candidates.iter().zip(&column) {
            if let Some(r) = undecided.iter().position(|&i| i == c.marker) {
                let p = places[j].0;
                let owned = self.markers[c.marker].template.is_none()
                    && !in_gate(c.marker, p)
                    && undecided.iter().any(|&o| {
                        o != c.marker
                            && same_look(&self.markers[o], &self.markers[c.marker])
                            && in_gate(o, p)
                    });
                let extra = if owned { OWNED_COST } else { 0.0 };
                let slot = &mut cost[r * cols + j];
                *slot = slot.min(c.cost + extra);
            }
        }
        let anchors: Vec<Anchor> = claimed
            .iter()
            .map(|&(j, _, c)| {
                let last = self.markers[j].last_center;
                Anchor {
                    marker: j,
                    last,
                    moved: c - last,
                }
            })
            .collect();
        let lasts: Vec<(usize, Point2<f64>, f64)> = undecided
            .iter()
            .map(|&i| (i, self.markers[i].last_center, window_px(&self.markers[i])))
            .collect();
        let places_at: Vec<Point2<f64>> = places.iter().map(|p| p.0).collect();
        let n = self.markers.len();
        let coherent = |a: usize, b: usize| self.coherence[a * n + b].coherent();
        let assignment = assign_anchored(&cost, cols, &lasts, &places_at, anchors, &coherent);
        let chosen: Vec<Option<(Measured, Option<f64>)>> = undecided
            .iter()
            .zip(&assignment)
            .map(|(&i, j)| {
                let j = (*j)?;
                let best = candidates
                    .iter()
                    .zip(&column)
                    .filter(|(c, col)| c.marker == i && **col == j)
                    .min_by(|a, b| a.0.cost.total_cmp(&b.0.cost))?;
                Some((best.0.measured, best.0.context))
            })
            .collect();
        // A marker found far outside its normal gate has manoeuvred: the filter takes the
        // manoeuvre, so the measurement sets the new velocity.
        for (&i, pick) in undecided.iter().zip(&chosen) {
            let m = &mut self.markers[i];
            if let Some((q, _)) = pick
                && (q.center - m.filter.position).norm_squared() > GATE_CHI2 * m.gate_var
            {
                let side = window_px(m);
                let sigma = manoeuvre_var(config, side, m.misses, frame_side).sqrt();
                m.filter.manoeuvre(sigma);
            }
        }
        // What a found marker saw in its gate and was not is a look-alike to remember,
        // unless it is some marker's place.
        let places_now: Vec<Point2<f64>> = self
            .markers
            .iter()
            .map(|m| m.filter.position)
            .chain(claimed.iter().map(|c| c.2))
            .chain(chosen.iter().flatten().map(|c| c.0.center))
            .collect();
        for ((&i, pick), blobs) in undecided.iter().zip(&chosen).zip(seen) {
            let Some((picked, _)) = pick else { continue };
            let side = window_px(&self.markers[i]);
            let near_marker = |p: &Point2<f64>| places_now.iter().any(|q| (q - p).norm() < side);
            let m = &mut self.markers[i];
            for (p, bounds) in blobs {
                if (p - picked.center).norm() > side && !near_marker(&p) {
                    remember_distractor(m, p, bounds, side);
                }
            }
        }
        chosen
    }

    /// Set a marker's centre in the latest frame by hand (the paper's first remedy); its
    /// observation becomes [`TrackStatus::Set`] with confidence 1 and tracking continues from
    /// there, with the motion history cleared.
    ///
    /// # Errors
    /// [`TrackError::UnknownMarker`]; [`TrackError::InvalidParameter`] for a centre that is
    /// not finite or lies outside the image.
    pub fn set_center(&mut self, id: &str, center: Point2<f64>) -> Result<()> {
        let Some(i) = self.markers.iter().position(|m| m.id == id) else {
            return Err(TrackError::UnknownMarker { id: id.to_string() });
        };
        let inside = center.x.is_finite()
            && center.y.is_finite()
            && (-0.5..f64::from(self.width) - 0.5).contains(&center.x)
            && (-0.5..f64::from(self.height) - 0.5).contains(&center.y);
        if !inside {
            return Err(TrackError::param(
                "center",
                format!(
                    "({}, {}) is not inside the {}x{} image",
                    center.x, center.y, self.width, self.height
                ),
            ));
        }
        let m = &mut self.markers[i];
        let side = window_px(m);
        m.filter = Kalman::new(center, MEASUREMENT_PX, 0.1 * side);
        m.swing.clear();
        m.acceleration_px = ACCELERATION_MIN_PX;
        m.last_center = center;
        m.misses = 0;
        m.last_status = TrackStatus::Set;
        let observation = Observation {
            center: Some(center),
            window: PixelRect::centered_at(center, m.size.0, m.size.1),
            status: TrackStatus::Set,
            confidence: 1.0,
        };
        if let Some(last) = self.tracks[i].observations.last_mut() {
            *last = observation;
        }
        Ok(())
    }

    /// Frames processed so far (the first frame included).
    pub fn frames(&self) -> usize {
        self.tracks.first().map_or(0, |t| t.observations.len())
    }

    /// The tracks, in the order the markers were given.
    pub fn tracks(&self) -> &[Track] {
        &self.tracks
    }

    /// The tracks, consuming the tracker.
    pub fn into_tracks(self) -> Vec<Track> {
        self.tracks
    }

    /// The configuration.
    pub fn config(&self) -> &TrackerConfig {
        &self.config
    }

    /// Frame size in pixels.
    pub fn frame_size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
}

impl MarkerState {
    /// Whether the surroundings tell this marker apart: they correlate well with
    /// themselves from frame to frame (a textured background, a fork, a target board), not
    /// only with noise.
    fn context_informative(&self) -> bool {
        self.context.is_some() && self.context_level >= CONTEXT_MIN_LEVEL
    }

    /// The costs of this marker's candidates (each with its context correlation), scored
    /// together; candidates outside the wide gate are dropped. A cost is a negative
    /// log-likelihood relative to a perfect candidate at the prediction:
    /// - motion: the mixture of the normal gate and, with prior [`MANOEUVRE_PRIOR`], a
    ///   manoeuvre of variance `wide`;
    /// - appearance: `-ln(confidence)`, plus the shortfall from the best candidate's
    ///   confidence in units of how much this marker's own confidence varies from frame to
    ///   frame (capped), and the same for the surroundings' correlation when they are
    ///   informative; relative to the best candidate, so that a marker whose look changes as a
    ///   whole (blur, light) is not locked out;
    /// - a static look-alike's penalty;
    /// - the offset from the marker's swing line: with `use_line` (a same-look marker is
    ///   near) as it is, otherwise beyond the least offset among the candidates.
    fn score(
        &self,
        candidates: &[(Measured, Option<f64>)],
        wide: f64,
        use_line: bool,
    ) -> Vec<Scored> {
        let best_conf = candidates
            .iter()
            .map(|c| c.0.confidence)
            .fold(0.0, f64::max);
        let best_context = candidates
            .iter()
            .filter_map(|c| c.1)
            .fold(f64::NEG_INFINITY, f64::max);
        let conf_sigma = self.confidence_var.sqrt().max(CONFIDENCE_SIGMA_MIN);
        let context_sigma = self.context_var.sqrt().max(CONTEXT_SIGMA_MIN);
        let informative = self.context_informative();
        // With a same-look marker near, the offset counts as it is; alone, only as far as
        // it exceeds the nearest candidate's (it tells candidates apart, but does not hold a
        // marker whose release swings beside the line of its pull away from its only one).
        let line = self.swing.line();
        let least_offset = match (line, use_line) {
            (Some(l), false) => candidates
                .iter()
                .map(|c| l.offset(c.0.center).abs())
                .fold(f64::INFINITY, f64::min),
            _ => 0.0,
        };
        candidates
            .iter()
            .filter_map(|&(measured, context)| {
                let r2 = (measured.center - self.filter.position).norm_squared();
                if r2 > GATE_CHI2 * wide.max(self.gate_var) {
                    return None;
                }
                let conf = measured.confidence;
                let appearance = -conf.max(1e-3).ln()
                    + (0.5 * ((best_conf - conf) / conf_sigma).powi(2)).min(APPEARANCE_CAP);
                let surroundings = match context {
                    Some(c) if informative => {
                        (0.5 * ((best_context - c) / context_sigma).powi(2)).min(CONTEXT_CAP)
                    }
                    _ => 0.0,
                };
                let penalty = if self.on_distractor(measured.center) {
                    DISTRACTOR_COST
                } else {
                    0.0
                };
                // A marker that swings along a line stays near it: a same-look marker
                // crossing its path is off the line where the paths are apart.
                let off_line = line.map_or(0.0, |l| {
                    let o = l.offset(measured.center).abs();
                    (0.5 * (o * o - least_offset * least_offset)).min(LINE_COST_CAP)
                });
                Some(Scored {
                    measured,
                    context,
                    cost: motion_cost(r2, self.gate_var, wide)
                        + appearance
                        + surroundings
                        + penalty
                        + off_line,
                })
            })
            .collect()
    }

    /// Whether a confidence is within what this marker usually shows (a blurred or paler
    /// marker may be less alike, so the check is loose: [`TYPICAL_SIGMAS`] spreads). A
    /// measurement that is not goes to detection, where it competes with other candidates.
    fn typical(&self, confidence: f64) -> bool {
        let sigma = self.confidence_var.sqrt().max(CONFIDENCE_SIGMA_MIN);
        confidence >= self.confidence_mean - TYPICAL_SIGMAS * sigma
    }

    /// Whether a context correlation `c` is within what this marker usually shows.
    fn familiar(&self, c: f64) -> bool {
        let sigma = self.context_var.sqrt().max(CONTEXT_SIGMA_MIN);
        c >= self.context_level - CONTEXT_DROP.max(3.0 * sigma)
    }

    /// Learn how this marker's confidence and context correlation vary (running means and
    /// variances of the frames it was found in).
    fn learn_appearance(&mut self, confidence: f64, context: Option<f64>) {
        let d = confidence - self.confidence_mean;
        self.confidence_mean += APPEARANCE_RATE * d;
        self.confidence_var += APPEARANCE_RATE * (d * d - self.confidence_var);
        if let Some(c) = context {
            let d = c - self.context_level;
            self.context_level += APPEARANCE_RATE * d;
            self.context_var += APPEARANCE_RATE * (d * d - self.context_var);
        }
    }

    /// True when `at` is on a static look-alike of this marker.
    fn on_distractor(&self, at: Point2<f64>) -> bool {
        let side = window_px(self);
        self.distractors
            .iter()
            .any(|d| d.seen >= 2 && (d.at - at).norm() < (DISTRACTOR_RADIUS * side).max(2.0))
    }

    /// The boxes of this marker's static look-alikes in `region` that it is not predicted to
    /// be on: their pixels do not count, so that a marker passing one is not pulled onto it.
    fn static_masks(&self, region: PixelRect, pred: Point2<f64>) -> Vec<PixelRect> {
        let (hw, hh) = (self.size.0 / 4, self.size.1 / 4);
        self.distractors
            .iter()
            .filter(|d| d.seen >= 2 && d.bounds.intersect(&region).area() > 0)
            .filter(|d| {
                let b = d.bounds.grown(hw, hh);
                !(pred.x >= f64::from(b.x)
                    && pred.y >= f64::from(b.y)
                    && pred.x < b.right() as f64
                    && pred.y < b.bottom() as f64)
            })
            .map(|d| d.bounds)
            .collect()
    }

    /// One frame ahead.
    fn predict(&mut self, config: &TrackerConfig) {
        match config.motion {
            MotionModel::Static => {
                self.filter.stop(0.0);
                self.filter.predict(self.acceleration_px);
            }
            MotionModel::ConstantVelocity { .. } => {
                let (p, v) = (self.filter.position, self.filter.velocity);
                self.filter.predict(self.acceleration_px);
                // A swing turns: the learnt acceleration bends the prediction.
                if let Some(a) = self.swing.acceleration(p, v) {
                    self.filter.position += a;
                    self.filter.velocity += a;
                }
            }
        }
    }

    /// Record a measurement.
    fn found(
        &mut self,
        q: Measured,
        status: TrackStatus,
        config: &TrackerConfig,
        depth: Option<&DepthView<'_>>,
        frame: u64,
    ) -> Observation {
        let innovation = (q.center - self.filter.position).norm_squared();
        self.filter.update(q.center, MEASUREMENT_PX);
        let side = window_px(self);
        if self.misses >= STOP_AFTER_MISSES && innovation > side * side {
            // Found again after frames of coasting, a window or more from where the coasting
            // put it: that jump is not a velocity (it made a marker found again at the end of
            // a swing fly off the frame), and where the swing is now in its cycle is unknown.
            self.filter.stop(side);
        }
        if let MotionModel::ConstantVelocity {
            min_acceleration_px,
        } = config.motion
        {
            // The model expects as much change as it has recently seen; a recovery after a
            // miss says little about the acceleration, and is left out.
            if self.misses == 0 {
                let a2 = self.acceleration_px * self.acceleration_px;
                let next = a2 + ACCELERATION_RATE * (0.5 * innovation - a2);
                self.acceleration_px = next.sqrt().max(min_acceleration_px);
            }
        } else {
            self.filter.stop(0.0);
        }
        if config.window == WindowMode::Adaptive
            && let Some(m) = q.moments
            && m.m00 > 0.0
        {
            let (w, h) = Axes::of(&m).window_size();
            let (w0, h0) = self.init_size;
            self.size = (
                w.clamp((w0 / 2).max(1), w0 * 2),
                h.clamp((h0 / 2).max(1), h0 * 2),
            );
        }
        if let Some(d) = depth
            && let Some(dm) = window_depth(d, q.window)
        {
            self.depth_m = Some(dm);
        }
        self.last_center = q.center;
        self.misses = 0;
        self.last_status = status;
        self.swing.record(frame, q.center);
        Observation {
            center: Some(q.center),
            window: q.window,
            status,
            confidence: q.confidence,
        }
    }

    /// No measurement this frame: coast, then lose.
    /// Not found, and merged with a marker of the same look: it coasts on its own motion
    /// (the two cross) and the frame does not count as a miss, so that it is neither given
    /// up while hidden in the other's blob nor looked for far away, and is taken up again
    /// as soon as it shows.
    fn merged(&mut self, (width, height): (u32, u32)) -> Observation {
        self.filter.velocity *= COAST_VELOCITY_DECAY;
        let pred = clamp_into(self.filter.position, width, height);
        self.last_status = TrackStatus::Predicted;
        Observation {
            center: Some(pred),
            window: PixelRect::centered_at(pred, self.size.0, self.size.1),
            status: TrackStatus::Predicted,
            confidence: 0.0,
        }
    }

    fn missed(&mut self, config: &TrackerConfig, (width, height): (u32, u32)) -> Observation {
        self.misses += 1;
        self.filter.velocity *= COAST_VELOCITY_DECAY;
        let pred = clamp_into(self.filter.position, width, height);
        let lost = self.misses > config.max_coast_frames;
        self.last_status = if lost {
            TrackStatus::Lost
        } else {
            TrackStatus::Predicted
        };
        Observation {
            center: (!lost).then_some(pred),
            window: PixelRect::centered_at(pred, self.size.0, self.size.1),
            status: self.last_status,
            confidence: 0.0,
        }
    }
}

/// Whether two markers look alike: one appearance model and colours within
/// [`SAME_LOOK_RGB`] (gray targets: any two).
fn same_look(a: &MarkerState, b: &MarkerState) -> bool {
    let d2: f32 = a
        .colour
        .iter()
        .zip(&b.colour)
        .map(|(x, y)| (x - y) * (x - y))
        .sum();
    d2 <= SAME_LOOK_RGB * SAME_LOOK_RGB
}

/// Whether a marker of the same look is predicted within [`CROWD_WINDOWS`] windows of marker
/// `i`: only then can the two be confused, and only then does the swing line count (alone,
/// a marker whose release swings beside the line of its pull must not be held to it).
fn crowded(markers: &[MarkerState], i: usize) -> bool {
    let m = &markers[i];
    let reach = CROWD_WINDOWS * window_px(m);
    markers.iter().enumerate().any(|(j, o)| {
        j != i
            && same_look(m, o)
            && (o.filter.position - m.filter.position).norm()
                < reach.max(CROWD_WINDOWS * window_px(o))
    })
}

/// Window size (the larger side) of a marker, pixels.
fn window_px(m: &MarkerState) -> f64 {
    f64::from(m.size.0.max(m.size.1))
}

/// The weights of marker `m`'s model over `rect`, with its mask, depth gate and the `masked`
/// rectangles, and its streak weights against the `previous` frame (recovering tracker, colour
/// models).
#[allow(clippy::too_many_arguments)]
fn fill(
    region: &mut Region,
    config: &TrackerConfig,
    m: &MarkerState,
    frame: &RgbImage,
    previous: Option<&RgbImage>,
    depth: Option<&DepthView<'_>>,
    rect: PixelRect,
    masked: &[PixelRect],
) {
    let gate = match (config.depth_gate_m, m.depth_m, depth) {
        (Some(g), Some(dm), Some(d)) => Some((g, dm, *d)),
        _ => None,
    };
    let colour_model = !matches!(config.model, AppearanceModel::Gray { .. });
    let streak = previous
        .filter(|_| config.recovery && colour_model)
        .map(|previous| Streak {
            previous,
            colour: m.colour,
        });
    let filter = PixelFilter {
        depth: gate,
        masked,
        streak,
    };
    region.fill(&config.model, &m.model, &m.lookup, frame, rect, &filter);
}

/// Learn the marker's blob in its first window: threshold, pixel count, width.
fn learn_blob(m: &mut MarkerState, region: &Region, labeler: &mut Labeler, window: PixelRect) {
    // The marker's pixels: the heaviest tenth of the window sets the scale.
    let mut inside: Vec<f32> = Vec::new();
    let w = window.intersect(&region.rect);
    for y in w.y..w.bottom() as i32 {
        for x in w.x..w.right() as i32 {
            let v = region.weights[region.index(x, y)];
            if v > 0.0 {
                inside.push(v);
            }
        }
    }
    if inside.is_empty() {
        return;
    }
    let k = inside.len() / 10;
    let top = *inside.select_nth_unstable_by(k, |a, b| b.total_cmp(a)).1;
    let threshold = (top * BLOB_THRESHOLD).max(1.0);
    let c = window.center();
    // The least gap that makes the marker's pixels in its window one blob.
    let mut best = None;
    for gap in 1..=MAX_GAP_PX {
        let blobs = labeler.blobs(&region.weights, region.rect, region.rect, threshold, 1, gap);
        let inside: Vec<(f64, &Blob)> = blobs
            .iter()
            .map(|b| {
                let part =
                    b.bounds.intersect(&window).area() as f64 / b.bounds.area().max(1) as f64;
                (b.mass * part, b)
            })
            .filter(|(w, _)| *w > 0.0)
            .collect();
        let total: f64 = inside.iter().map(|(w, _)| w).sum();
        let main = inside
            .iter()
            .min_by(|a, b| {
                (a.1.centroid - c)
                    .norm()
                    .total_cmp(&(b.1.centroid - c).norm())
            })
            .map(|(w, b)| (*w, **b));
        if let Some((w, b)) = main {
            best = Some((gap, b));
            if w >= ONE_BLOB_SHARE * total {
                break;
            }
        }
    }
    if let Some((gap, _)) = best {
        m.reference.gap = gap;
    }

    let best = best.map(|(_, b)| b);
    m.reference.threshold = threshold;
    if let Some(b) = best {
        m.reference.pixels = b.pixels as f64;
        m.reference.pixel_weight = b.mass / b.pixels as f64;
        m.reference.width_px = b.width_px().max(2.0);
    } else {
        m.reference.pixel_weight = f64::from(top);
    }
}

/// The gap a marker's blob must bridge where the image has holes (pixels with no data,
/// black, as a projection image where no point projected): around `window` (a window on
/// every side), more than [`HOLES_SPARSE`] holes need 2 pixels, more than [`HOLES_SPLATTED`]
/// need 3 (splats with holes between them).
fn hole_gap(frame: &RgbImage, window: PixelRect) -> usize {
    let around = window
        .grown(window.width, window.height)
        .intersect(&image_rect(frame.width(), frame.height()));
    let (mut holes, mut all) = (0usize, 0usize);
    for y in around.y..around.bottom() as i32 {
        for x in around.x..around.right() as i32 {
            let p = frame.get_pixel(x as u32, y as u32).0;
            all += 1;
            if p.iter().all(|&c| c <= HOLE_LEVEL) {
                holes += 1;
            }
        }
    }
    let share = holes as f64 / all.max(1) as f64;
    if share > HOLES_SPLATTED {
        3
    } else if share > HOLES_SPARSE {
        2
    } else {
        1
    }
}

/// Mean RGB of the pixels of `window` whose weight is at least `threshold` (the marker's
/// own), or of the whole window if none is.
fn mean_colour(frame: &RgbImage, region: &Region, window: PixelRect, threshold: f32) -> [f32; 3] {
    let w = window.intersect(&region.rect);
    let (mut sum, mut all, mut n, mut n_all) = ([0.0f64; 3], [0.0f64; 3], 0.0f64, 0.0f64);
    for y in w.y..w.bottom() as i32 {
        for x in w.x..w.right() as i32 {
            let p = frame.get_pixel(x as u32, y as u32).0;
            let own = region.weights[region.index(x, y)] >= threshold;
            for c in 0..3 {
                all[c] += f64::from(p[c]);
                if own {
                    sum[c] += f64::from(p[c]);
                }
            }
            n_all += 1.0;
            if own {
                n += 1.0;
            }
        }
    }
    let (s, k) = if n > 0.0 {
        (sum, n)
    } else {
        (all, n_all.max(1.0))
    };
    [(s[0] / k) as f32, (s[1] / k) as f32, (s[2] / k) as f32]
}

/// True when a blob could be the marker: wide as the marker (blur makes a streak longer, not
/// wider), not longer than a streak can be, with enough of its pixels.
fn plausible(blob: &Blob, r: &Reference) -> bool {
    let width = blob.width_px() / r.width_px;
    let length = blob.length_px() / r.width_px;
    (BLOB_WIDTH_RANGE[0]..=BLOB_WIDTH_RANGE[1]).contains(&width)
        && length <= BLOB_MAX_LENGTH
        && blob.pixels as f64 >= BLOB_MIN_PIXELS * r.pixels
}

/// How much a blob looks like the marker, 0..=1 (see [`Observation::confidence`]): its
/// colour (mean weight against the marker's), its width (a wider blob is another object; a
/// narrower one may be the marker partly covered) and the share of the marker's pixels it
/// holds.
fn blob_confidence(blob: &Blob, r: &Reference) -> f64 {
    let colour = (blob.mass / blob.pixels as f64 / r.pixel_weight).min(1.0);
    let wider = (blob.width_px() / r.width_px).ln().max(0.0);
    let shape = (-0.5 * (wider / 0.35).powi(2)).exp();
    let held = (blob.pixels as f64 / (0.6 * r.pixels)).min(1.0);
    colour * shape * held
}

/// The marker-like blobs of the region's weights as measurements (heaviest first), with the
/// pairs of nearby fragments that make one marker together (a marker cut by a twig). A blob
/// on which another marker (`others`: predictions of markers found in the last frame) is
/// predicted as well as this one (`own`) is shared: this marker's candidate is the part
/// nearer to it.
fn candidates_in(
    region: &mut Region,
    labeler: &mut Labeler,
    m: &MarkerState,
    own: Option<Point2<f64>>,
    others: &[Point2<f64>],
) -> Vec<Measured> {
    let blobs = labeler.blobs(
        &region.weights,
        region.rect,
        region.rect,
        m.reference.threshold,
        FRAGMENT_MIN_PIXELS,
        m.reference.gap,
    );

    let (w, h) = m.size;
    let on = |p: &Point2<f64>, r: PixelRect| {
        p.x >= f64::from(r.x)
            && p.y >= f64::from(r.y)
            && p.x < r.right() as f64
            && p.y < r.bottom() as f64
    };
    let mut out = Vec::new();
    for (k, b) in blobs.iter().enumerate() {
        if out.len() >= MAX_CANDIDATES {
            break;
        }
        let sharing: Vec<Point2<f64>> = others
            .iter()
            .filter(|p| on(p, b.bounds.grown(w / 2, h / 2)))
            .copied()
            .collect();
        if let Some(own) = own.filter(|p| !sharing.is_empty() && on(p, b.bounds.grown(w, h))) {
            let mut centres = vec![own];
            centres.extend(sharing);
            let parts = labeler.split(&region.weights, region.rect, b, &centres);
            if let Some(part) = parts
                .first()
                .filter(|p| p.pixels > 0 && plausible(p, &m.reference))
            {
                out.push(measured_at(region, m, part));
            }
            continue;
        }
        if plausible(b, &m.reference) {
            let mut steady = *b;
            let window = PixelRect::centered_at(b.centroid, m.size.0, m.size.1);
            let pieces = (m.reference.pixels * BLOB_MIN_PIXELS).ceil() as usize;
            steady.centroid =
                labeler.edge_centroid(&region.weights, region.rect, b, window, pieces);
            out.push(measured_at(region, m, &steady));
        }
        // Fragments closer than the marker's width whose union is a whole marker.
        for c in &blobs[k + 1..] {
            if (b.centroid - c.centroid).norm() < m.reference.width_px {
                let u = b.merged(c);
                if plausible(&u, &m.reference) {
                    out.push(measured_at(region, m, &u));
                }
            }
        }
    }
    out
}

/// A measurement at a blob: its centroid, the window there and its confidence.
fn measured_at(region: &mut Region, m: &MarkerState, blob: &Blob) -> Measured {
    let window = PixelRect::centered_at(blob.centroid, m.size.0, m.size.1);
    let confidence = match &m.model {
        // The kernel model's colour evidence is the Bhattacharyya coefficient.
        MarkerModel::Kernel { q, .. } => {
            let colour =
                (blob.mass / blob.pixels as f64 / m.reference.pixel_weight).clamp(1e-9, 1.0);
            region.bhattacharyya(q, blob.centroid, m.size) * blob_confidence(blob, &m.reference)
                / colour
        }
        MarkerModel::Projected { .. } => blob_confidence(blob, &m.reference),
    };
    Measured {
        center: blob.centroid,
        window,
        holds: blob.bounds.grown(1, 1),
        confidence: confidence.clamp(0.0, 1.0),
        moments: moments_of(region, window),
    }
}

/// The gray target's template matches within `radius` of `center` as measurements; the
/// confidence is the correlation (negative counts as 0).
fn template_candidates(
    t: &Template,
    m: &MarkerState,
    frame: &RgbImage,
    center: Point2<f64>,
    radius: f64,
    max: usize,
    scratch: &mut Vec<f32>,
) -> Vec<Measured> {
    let (w, h) = m.size;
    t.search(frame, center, radius, max, scratch)
        .into_iter()
        .map(|found| {
            let window = PixelRect::centered_at(found.center, w, h);
            Measured {
                center: found.center,
                window,
                holds: window,
                confidence: found.ncc.max(0.0),
                moments: None,
            }
        })
        .collect()
}

/// Moments of `window` and a 10-pixel border (CamShift's size estimate).
fn moments_of(region: &Region, window: PixelRect) -> Option<Moments> {
    let g = region.sums(window.grown(ADAPTIVE_BORDER_PX, ADAPTIVE_BORDER_PX));
    (g[0] > 0.0).then(|| moments_from_f64_sums(g))
}

/// The mode as the measurement (plain mean-shift).
fn plain(region: &Region, mode: Mode) -> Measured {
    Measured {
        center: mode.center,
        window: mode.window,
        holds: mode.window,
        confidence: mode.confidence,
        moments: mode.moments.or_else(|| moments_of(region, mode.window)),
    }
}

/// The predictions of the markers other than `i` that were found in the last frame: where
/// a blob must be shared.
fn sharing_predictions(
    markers: &[MarkerState],
    i: usize,
    predictions: &[Point2<f64>],
) -> Vec<Point2<f64>> {
    markers
        .iter()
        .zip(predictions)
        .enumerate()
        .filter(|(j, (m, _))| *j != i && m.misses == 0)
        .map(|(_, (_, p))| *p)
        .collect()
}

/// True when `at` is on another marker's predicted place: nearer to that marker's prediction
/// than to marker `i`'s, and within that marker's window size of it. Only markers found in
/// the last frame claim their prediction: a coasting marker's is a guess.
fn nearer_to_other(
    markers: &[MarkerState],
    i: usize,
    at: Point2<f64>,
    predictions: &[Point2<f64>],
) -> bool {
    let own = (at - predictions[i]).norm();
    predictions.iter().enumerate().any(|(j, p)| {
        let d = (at - p).norm();
        j != i && markers[j].last_status.found() && d < own && d < window_px(&markers[j])
    })
}

/// True when `at` is on a place another marker took this frame.
fn taken(
    markers: &[MarkerState],
    i: usize,
    at: Point2<f64>,
    claimed: &[(usize, PixelRect, Point2<f64>)],
) -> bool {
    let mine = window_px(&markers[i]);
    claimed.iter().any(|&(j, _, c)| {
        j != i && (c - at).norm() < EXCLUSION_FRACTION * 0.5 * (mine + window_px(&markers[j]))
    })
}

/// Median depth of the pixels of `window` with depth (the marker's depth for gating).
fn window_depth(depth: &DepthView<'_>, window: PixelRect) -> Option<f64> {
    let w = window.intersect(&PixelRect::image(depth.width, depth.height));
    let mut values: Vec<f64> = Vec::with_capacity(w.area() as usize);
    for y in w.y..w.bottom() as i32 {
        for x in w.x..w.right() as i32 {
            if let Some(d) = depth.at(x, y) {
                values.push(d);
            }
        }
    }
    if values.is_empty() {
        return None;
    }
    let mid = values.len() / 2;
    values.select_nth_unstable_by(mid, f64::total_cmp);
    Some(values[mid])
}

/// Negative log-likelihood of an innovation of squared length `r2` under the motion model's
/// mixture (no manoeuvre: variance `normal`; a manoeuvre, with prior [`MANOEUVRE_PRIOR`]:
/// variance `wide`), relative to a zero innovation: 0 at the prediction, growing slowly over
/// the normal gate and then with the wide one.
fn motion_cost(r2: f64, normal: f64, wide: f64) -> f64 {
    let (normal, wide) = (normal.max(1e-9), wide.max(normal).max(1e-9));
    let a0 = (1.0 - MANOEUVRE_PRIOR).ln() - normal.ln();
    let b0 = MANOEUVRE_PRIOR.ln() - wide.ln();
    log_sum_exp(a0, b0) - log_sum_exp(a0 - 0.5 * r2 / normal, b0 - 0.5 * r2 / wide)
}

fn log_sum_exp(a: f64, b: f64) -> f64 {
    let m = a.max(b);
    m + ((a - m).exp() + (b - m).exp()).ln()
}

/// Variance the gate opens by (pixels²) for a marker with window `side` after `misses`
/// frames without a measurement: [`TrackerConfig::search_radius_windows`] windows at the
/// gate's edge on the first, growing linearly while coasting and quadratically once lost,
/// never past twice the frame.
fn manoeuvre_var(config: &TrackerConfig, side: f64, misses: usize, frame_side: f64) -> f64 {
    let sigma = config.search_radius_windows * side / GATE_CHI2.sqrt();
    let k = misses as f64 + 1.0;
    let growth = if misses > config.max_coast_frames {
        k * k
    } else {
        k
    };
    (sigma * sigma * growth).min((2.0 * frame_side).powi(2))
}

/// Assign places (columns) to markers (rows) when several markers may be fooled at once (a
/// row of look-alike targets that all jump): the marker whose best place beats its
/// alternatives (another place, or none) by [`ANCHOR_MARGIN`] or more is decided first; it
/// becomes an anchor whose displacement this frame tells the still ambiguous markers near it
/// where to look (nearby markers move alike: one branch, one rig), and the next clearest
/// marker is decided, until none is clear; the rest are assigned jointly
/// ([`assign`]). `cost` is row-major `rows x columns` (infinite: not a candidate); `lasts`
/// each row's marker, its last centre and window side; `anchors` the markers decided before;
/// `coherent(a, b)` whether markers `a` and `b` have moved alike.
fn assign_anchored(
    cost: &[f64],
    columns: usize,
    lasts: &[(usize, Point2<f64>, f64)],
    places: &[Point2<f64>],
    mut anchors: Vec<Anchor>,
    coherent: &dyn Fn(usize, usize) -> bool,
) -> Vec<Option<usize>> {
    let rows = lasts.len();
    let mut result: Vec<Option<usize>> = vec![None; rows];
    let mut fixed = vec![false; rows];
    let mut taken = vec![false; columns];
    let mut adjusted = cost.to_vec();
    // Each round decides one row: at most `rows` rounds.
    for _ in 0..rows {
        let mut clearest: Option<(usize, usize, f64)> = None;
        for r in (0..rows).filter(|&r| !fixed[r]) {
            let row = &cost[r * columns..(r + 1) * columns];
            let (best, margin) = best_and_margin(row, &taken);
            let (marker, last, side) = lasts[r];
            // Markers clear on their own need no neighbours; ambiguous ones take the
            // displacement of the neighbours they have moved alike with as a prior.
            let neighbour = (margin < ANCHOR_MARGIN)
                .then(|| {
                    neighbour_displacement(
                        anchors.iter().filter(|a| coherent(marker, a.marker)),
                        last,
                        side,
                    )
                })
                .flatten();
            let out = &mut adjusted[r * columns..(r + 1) * columns];
            out.copy_from_slice(row);
            if let Some((d, sigma)) = neighbour {
                let expected = last + d;
                for (o, p) in out.iter_mut().zip(places) {
                    if o.is_finite() {
                        let z2: f64 = (p - expected).norm_squared() / (sigma * sigma);
                        *o += (0.5 * z2).min(NEIGHBOUR_CAP);
                    }
                }
            }
            let (best, margin) = if neighbour.is_some() {
                best_and_margin(out, &taken)
            } else {
                (best, margin)
            };
            if let Some(j) = best
                && margin >= ANCHOR_MARGIN
                && clearest.is_none_or(|c| margin > c.2)
            {
                clearest = Some((r, j, margin));
            }
        }
        let Some((r, j, _)) = clearest else { break };
        fixed[r] = true;
        taken[j] = true;
        result[r] = Some(j);
        anchors.push(Anchor {
            marker: lasts[r].0,
            last: lasts[r].1,
            moved: places[j] - lasts[r].1,
        });
    }
    // The rest, jointly, on the costs with their neighbour priors.
    let free: Vec<usize> = (0..rows).filter(|&r| !fixed[r]).collect();
    if !free.is_empty() {
        let mut sub = Vec::with_capacity(free.len() * columns);
        for &r in &free {
            sub.extend(
                adjusted[r * columns..(r + 1) * columns]
                    .iter()
                    .zip(&taken)
                    .map(|(&c, &t)| if t { f64::INFINITY } else { c }),
            );
        }
        let joint = assign(&sub, columns, &vec![UNMATCHED_COST; free.len()]);
        for (&r, j) in free.iter().zip(joint) {
            result[r] = j;
        }
    }
    result
}

/// A marker decided in this frame: its last centre and how far it moved.
struct Anchor {
    marker: usize,
    last: Point2<f64>,
    moved: Vector2<f64>,
}

/// A row's cheapest free column (if cheaper than staying unassigned) and by how much it beats
/// the next choice (another free column, or [`UNMATCHED_COST`]).
fn best_and_margin(row: &[f64], taken: &[bool]) -> (Option<usize>, f64) {
    let mut best: Option<(usize, f64)> = None;
    let mut second = UNMATCHED_COST;
    for (j, (&c, &t)) in row.iter().zip(taken).enumerate() {
        if t || !c.is_finite() {
            continue;
        }
        match best {
            Some((_, b)) if c >= b => second = second.min(c),
            _ => {
                if let Some((_, b)) = best {
                    second = second.min(b);
                }
                best = Some((j, c));
            }
        }
    }
    match best {
        Some((j, b)) if b < UNMATCHED_COST => (Some(j), second - b),
        _ => (None, 0.0),
    }
}

/// The displacement this frame of the anchors near `last` (within
/// [`NEIGHBOUR_RADIUS_WINDOWS`] windows), weighted by inverse squared distance, and how far
/// to trust it (pixels): half a window, or more when the anchors disagree.
fn neighbour_displacement<'a>(
    anchors: impl Iterator<Item = &'a Anchor>,
    last: Point2<f64>,
    side: f64,
) -> Option<(Vector2<f64>, f64)> {
    let reach = NEIGHBOUR_RADIUS_WINDOWS * side;
    let mut sum = Vector2::zeros();
    let mut weight = 0.0;
    let mut near = Vec::new();
    for a in anchors {
        let r = (a.last - last).norm();
        if r < reach {
            let w = 1.0 / (r * r).max(side * side);
            sum += w * a.moved;
            weight += w;
            near.push((w, a.moved));
        }
    }
    if weight <= 0.0 {
        return None;
    }
    let mean = sum / weight;
    let spread = near
        .iter()
        .map(|(w, d)| w * (d - mean).norm_squared())
        .sum::<f64>()
        / weight;
    Some((mean, (0.5 * side).max(spread.sqrt())))
}

/// Remember a look-alike at `p`: seen again where it was (within [`STATIC_PX`]), it counts
/// once more; seen elsewhere nearby (partly covered, or moving), its count halves, and below
/// 2 it starts over there. The oldest is forgotten past the limit.
fn remember_distractor(m: &mut MarkerState, p: Point2<f64>, bounds: PixelRect, side: f64) {
    if let Some(d) = m
        .distractors
        .iter_mut()
        .find(|d| (d.at - p).norm() < (DISTRACTOR_RADIUS * side).max(2.0))
    {
        if (d.at - p).norm() <= STATIC_PX {
            d.seen = d.seen.saturating_add(1).min(MAX_SEEN);
        } else {
            d.seen /= 2;
            if d.seen < 2 {
                d.at = p;
                d.bounds = bounds;
                d.seen = 1;
            }
        }
        return;
    }
    if m.distractors.len() >= MAX_DISTRACTORS {
        m.distractors.remove(0);
    }
    m.distractors.push(Distractor {
        at: p,
        bounds,
        seen: 1,
    });
}
