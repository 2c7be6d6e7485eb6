//! How the tracker is set up: its window mode, motion model and every tunable.

use super::*;

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
    /// 24 and 16), so that a blurred, paler marker still counts; the recovering tracker
    /// raises a marker's saturation floor halfway to its core where the first frame shows
    /// much paler pixels of its look (a reddish-brown look-alike touching it or, elsewhere,
    /// pixels of its hue under 0.6 of its core saturation, or under 0.72 where they make a
    /// surface of ten markers' worth or more, such as bark). Default:
    /// saturation 60..=255, value 32..=255, any hue.
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
