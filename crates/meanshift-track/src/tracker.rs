//! The multi-marker tracker: mean-shift per marker on a window of fixed size (the paper's
//! choice) or CamShift's adaptive size, with what the paper did by hand done automatically:
//! prediction from recent motion, a low-confidence test, an enlarged search started from four
//! directions around the prediction, exclusive assignment so that two markers of one colour
//! never take the same blob, coasting through brief occlusions, and user re-seeding.
//!
//! Each frame, per marker:
//! 1. predict the centre (static, constant velocity, or an alpha–beta filter);
//! 2. mean-shift from the prediction over a region a little larger than the window, computing
//!    the model's weights only there (never over the whole frame);
//! 3. accept when the confidence is at least [`TrackerConfig::min_confidence`], no marker
//!    nearer to its own prediction already took the same place, and, after a jump of more
//!    than half a window, the surroundings still look like the marker's
//!    ([`TrackerConfig::context_check`]) (status `tracked`);
//! 4. otherwise search: mean-shift with a window twice the size, started at the prediction,
//!    the last centre and four points left, right, above and below it at half and full
//!    [`TrackerConfig::search_radius_windows`], each refined with the normal window; the
//!    places other markers took this frame do not vote. The best candidate by confidence,
//!    discounted by its distance from the prediction and by how much less familiar its
//!    surroundings are, is accepted if confident enough (status `recovered`);
//! 5. otherwise coast on the prediction for up to [`TrackerConfig::max_coast_frames`] frames
//!    (status `predicted`) with a decaying velocity, then report `lost` (no centre) while the
//!    search keeps widening.
//!
//! Centres are the weighted centroid of the converged window, in pixel coordinates with pixel
//! centres at integers.

use image::RgbImage;
use nalgebra::{Point2, Vector2};

use crate::context::ContextTemplate;
use crate::error::{Result, TrackError};
use crate::hsv::ChannelRange;
use crate::meanshift::{Axes, Moments, TermCriteria, moments_from_f64_sums};
use crate::model::{AppearanceModel, MarkerModel};
use crate::rect::PixelRect;

/// No bin (masked out, gated, claimed or outside the histogram's range).
const NO_BIN: u32 = u32::MAX;
/// Shift in pixels below which the kernel (Bhattacharyya) mean-shift has converged
/// (Comaniciu et al. 2003 stop below one pixel; sub-pixel centres need a finer stop, since
/// on a uniform blob each step covers only part of the remaining distance).
const KERNEL_EPSILON_PX: f64 = 0.05;
/// Iteration limit of the kernel mean-shift.
const KERNEL_MAX_ITERATIONS: usize = 30;
/// Border of CamShift's size estimate around the converged window (OpenCV's `TOLERANCE`).
const ADAPTIVE_BORDER_PX: i32 = 10;
/// The search window is this many times the marker window (the paper's "increased search
/// area").
const SEARCH_WINDOW_SCALE: i32 = 2;
/// Markers closer than this fraction of their mean window size are on the same blob.
const EXCLUSION_FRACTION: f64 = 0.75;
/// The context template is this many times the window in each direction: the marker and
/// half a window of its surroundings on every side.
const CONTEXT_SCALE: i32 = 2;
/// Share of each accepted frame's patch blended into the context template.
const CONTEXT_RATE: f32 = 0.1;
/// Share of each accepted frame's correlation blended into the marker's typical correlation.
const CONTEXT_LEVEL_RATE: f64 = 0.2;
/// A candidate of the quick pass whose context correlation is this far below the marker's
/// typical one is doubted and sent to the search.
const CONTEXT_DROP: f64 = 0.08;
/// Typical context correlation below which the surroundings are too plain or too noisy to
/// tell markers apart, and the context check is skipped for the marker.
const CONTEXT_MIN_LEVEL: f64 = 0.6;
/// The search discounts a candidate by a Gaussian of its distance from the prediction with
/// this fraction of the search radius as its sigma: a confident blob at the edge of the
/// search is worth an eighth of one at the prediction.
const SEARCH_SIGMA_FRACTION: f64 = 0.5;
/// Share of the velocity kept per coasting frame.
const COAST_VELOCITY_DECAY: f64 = 0.5;
/// Two centres closer than this fraction of the window size are the same place.
const SAME_PLACE_FRACTION: f64 = 0.25;
/// The search does not accept a candidate whose context correlation is this far below the
/// marker's typical one (more than [`CONTEXT_DROP`]: motion blur at a release lowers the
/// correlation of the true marker too).
const CONTEXT_REJECT: f64 = 0.12;
/// Scale of the context term in the search score, `exp((ncc - typical) / scale)`: a
/// candidate 0.1 below is worth about an eighth of one at the typical level.
const CONTEXT_SHARPNESS: f64 = 0.05;

/// Whether the window keeps its size or adapts it as CamShift does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WindowMode {
    /// The initial window's size throughout (the paper's choice).
    #[default]
    Fixed,
    /// CamShift's size from the second moments, kept within half and twice the initial size.
    Adaptive,
}

/// How the tracker predicts a marker's centre in the next frame. Velocities are in pixels per
/// frame: the tracker assumes the frames it is given are equally spaced in time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MotionModel {
    /// The last centre (plain mean-shift, the paper).
    Static,
    /// The last centre plus the last frame-to-frame displacement.
    ConstantVelocity,
    /// An alpha–beta filter on position and velocity (Kalata 1984); `alpha` and `beta` in
    /// `0..=1` (position and velocity gains).
    AlphaBeta {
        /// Position gain.
        alpha: f64,
        /// Velocity gain.
        beta: f64,
    },
}

/// Tracker settings. [`TrackerConfig::default`] is the recovering tracker with the paper's hue
/// model; [`TrackerConfig::paper`] is plain mean-shift as the paper ran it (no prediction, no
/// recovery), for side-by-side comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerConfig {
    /// Appearance model. Default: [`AppearanceModel::PAPER`] (16-bin hue).
    pub model: AppearanceModel,
    /// Pixels outside this HSV range do not count for the hue and hue–saturation models
    /// (gray pixels have hue 0, red, so a saturation floor is needed). Default: saturation
    /// 60..=255, value 32..=255, any hue.
    pub hsv_mask: ChannelRange,
    /// Fixed or adaptive window. Default: fixed.
    pub window: WindowMode,
    /// Mean-shift stopping rule per search. Default: OpenCV's `(EPS | COUNT, 10, 1)`.
    pub criteria: TermCriteria,
    /// Prediction. Default: alpha–beta with alpha 0.85, beta 0.5 (follows a swinging branch
    /// and settles quickly after a release).
    pub motion: MotionModel,
    /// Confidence below which the tracker searches (0..1). For the histogram models the
    /// confidence is the back-projection mass in the window relative to the first frame's,
    /// capped at 1; for the RGB model it is the Bhattacharyya coefficient. Default 0.4 (0.7
    /// with [`TrackerConfig::for_model`] and the RGB model).
    pub min_confidence: f64,
    /// Whether low confidence triggers the enlarged search (false: plain mean-shift).
    /// Default true.
    pub recovery: bool,
    /// Radius of the recovery search around the prediction, in window sizes (the larger of
    /// width and height). Default 4.
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
    /// normalised cross-correlation; a candidate that correlates clearly worse than the
    /// marker usually does is searched past, and the search prefers the best-correlating
    /// candidate. Default true; false for the paper's tracker.
    pub context_check: bool,
}

impl TrackerConfig {
    /// Defaults for `model`: the minimum confidence suits the model's confidence measure.
    pub fn for_model(model: AppearanceModel) -> Self {
        Self {
            model,
            hsv_mask: ChannelRange {
                lower: [0, 60, 32],
                upper: [180, 255, 255],
            },
            window: WindowMode::Fixed,
            criteria: TermCriteria::OPENCV_SAMPLE,
            motion: MotionModel::AlphaBeta {
                alpha: 0.85,
                beta: 0.5,
            },
            min_confidence: match model {
                AppearanceModel::Rgb { .. } => 0.7,
                _ => 0.4,
            },
            recovery: true,
            search_radius_windows: 4.0,
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
    /// outside 0..=1, a search radius that is not positive and finite, filter gains outside
    /// 0..=1, a depth gate that is not positive and finite, or a non-finite epsilon.
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
        if let MotionModel::AlphaBeta { alpha, beta } = self.motion
            && !((0.0..=1.0).contains(&alpha) && (0.0..=1.0).contains(&beta))
        {
            return Err(TrackError::param(
                "motion",
                format!("alpha {alpha} and beta {beta} must be in 0..=1"),
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
    /// Mean-shift from the prediction found the marker.
    Tracked,
    /// Found by the enlarged search, or found again after coasting or being lost.
    Recovered,
    /// Not found; the centre is the motion prediction (coasting).
    Predicted,
    /// Not found for too long; no centre.
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

    fn found(&self) -> bool {
        matches!(self, Self::Tracked | Self::Recovered | Self::Set)
    }
}

/// One marker in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Sub-pixel centre (weighted centroid of the converged window); `None` only when lost.
    pub center: Option<Point2<f64>>,
    /// The converged window.
    pub window: PixelRect,
    /// How the centre was obtained.
    pub status: TrackStatus,
    /// Confidence in 0..=1 (see [`TrackerConfig::min_confidence`]); 1 for user-set centres.
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

    fn at(&self, x: i32, y: i32) -> Option<f64> {
        self.depth_m[y as usize * self.width as usize + x as usize].filter(|d| d.is_finite())
    }
}

#[derive(Debug, Clone, Copy)]
struct Motion {
    position: Point2<f64>,
    velocity: Vector2<f64>,
}

#[derive(Debug, Clone)]
struct MarkerState {
    id: String,
    model: MarkerModel,
    init_size: (i32, i32),
    size: (i32, i32),
    motion: Motion,
    last_center: Point2<f64>,
    /// Back-projection mass of the first frame's window (histogram models).
    reference_mass: f64,
    depth_m: Option<f64>,
    coasting: usize,
    last_status: TrackStatus,
    /// The surroundings, with [`TrackerConfig::context_check`].
    context: Option<ContextTemplate>,
    /// Typical context correlation of accepted frames.
    context_level: f64,
}

/// The result of a mean-shift from one start.
#[derive(Debug, Clone, Copy)]
struct Mode {
    center: Point2<f64>,
    window: PixelRect,
    confidence: f64,
    /// Moments of the converged window (histogram models), for the adaptive size.
    moments: Option<Moments>,
}

/// The model's weights over a region of the frame.
#[derive(Debug, Default)]
struct Region {
    rect: PixelRect,
    /// Back-projection values (histogram models).
    weights: Vec<f32>,
    /// Histogram bins (kernel model), [`NO_BIN`] where the pixel does not count.
    bins: Vec<u32>,
    /// Candidate histogram scratch (kernel model).
    p: Vec<f64>,
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
    /// Patch scratch for the context correlation.
    patch: Vec<f32>,
}

fn image_rect(width: u32, height: u32) -> PixelRect {
    PixelRect::image(width, height)
}

fn clamp_into(p: Point2<f64>, width: u32, height: u32) -> Point2<f64> {
    Point2::new(
        p.x.clamp(0.0, f64::from(width) - 1.0),
        p.y.clamp(0.0, f64::from(height) - 1.0),
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
            patch: Vec::new(),
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
        let model = MarkerModel::learn(
            &init.id,
            frame,
            w,
            &self.config.model,
            &self.config.hsv_mask,
            self.config.background_weighting,
        )?;
        let center = w.center();
        let mut state = MarkerState {
            id: init.id.clone(),
            model,
            init_size: (w.width, w.height),
            size: (w.width, w.height),
            motion: Motion {
                position: center,
                velocity: Vector2::zeros(),
            },
            last_center: center,
            reference_mass: 1.0,
            depth_m: None,
            coasting: 0,
            last_status: TrackStatus::Tracked,
            context: None,
            context_level: 1.0,
        };
        // Reference mass: the mass of the user's window; then refine there.
        let region = w.grown(w.width, w.height);
        fill_region(
            &mut self.region,
            &self.config,
            &state,
            frame,
            depth,
            region,
            &[],
        );
        if let MarkerModel::Projected { .. } = state.model {
            state.reference_mass = self.region.mass(w).max(1.0);
        }
        let mode = locate(&mut self.region, &self.config, &state, center, state.size);
        let observation = Observation {
            center: Some(mode.center),
            window: mode.window,
            status: TrackStatus::Tracked,
            confidence: mode.confidence,
        };
        state.last_center = mode.center;
        state.motion.position = mode.center;
        state.depth_m = depth.and_then(|d| window_depth(d, mode.window));
        if self.config.context_check {
            state.context = Some(ContextTemplate::learn(
                frame,
                mode.center,
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

    /// Track every marker into the next frame.
    ///
    /// # Errors
    /// [`TrackError::EmptyImage`] for an empty frame; [`TrackError::SizeMismatch`] when the
    /// frame (or depth map) differs in size from the first frame. The tracker is unchanged
    /// by a failed call.
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
        let predictions: Vec<Point2<f64>> = self
            .markers
            .iter()
            .map(|m| clamp_into(m.motion.predict(), self.width, self.height))
            .collect();

        // Quick pass: mean-shift from the prediction.
        let mut quick = Vec::with_capacity(n);
        for (m, &pred) in self.markers.iter().zip(&predictions) {
            let (w, h) = m.size;
            let region = PixelRect::centered_at(pred, w, h).grown(w, h);
            fill_region(&mut self.region, &self.config, m, frame, depth, region, &[]);
            quick.push(locate(&mut self.region, &self.config, m, pred, m.size));
        }
        let quick_context: Vec<Option<f64>> = self
            .markers
            .iter()
            .zip(&quick)
            .map(|(m, mode)| {
                m.context
                    .as_ref()
                    .map(|t| t.ncc(frame, mode.center, &mut self.patch))
            })
            .collect();

        // Accept confident results, nearest to their prediction first; a result on a place
        // already taken goes to the search.
        let threshold = self.config.min_confidence;
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| {
            let da = (quick[a].center - predictions[a]).norm();
            let db = (quick[b].center - predictions[b]).norm();
            da.total_cmp(&db)
        });
        let mut results: Vec<Option<(Mode, TrackStatus, Option<f64>)>> = vec![None; n];
        let mut claimed: Vec<(usize, PixelRect, Point2<f64>)> = Vec::new();
        let mut to_search = Vec::new();
        for &i in &order {
            let mode = quick[i];
            // Identity is in doubt only after a jump of more than half a window, the reach of
            // plain mean-shift: a slower marker cannot have swapped with a look-alike.
            let m = &self.markers[i];
            let jumped = (mode.center - m.last_center).norm() > 0.5 * window_px(m);
            let familiar = !jumped
                || !m.context_informative()
                || quick_context[i].is_none_or(|c| c >= m.context_level - CONTEXT_DROP);
            let accept = mode.confidence >= threshold
                && familiar
                && !(self.config.exclusive
                    && (taken(&self.markers, i, mode.center, &claimed)
                        || nearer_to_other(&self.markers, i, mode.center, &predictions)));
            if accept || !self.config.recovery {
                if accept {
                    claimed.push((i, mode.window, mode.center));
                }
                results[i] = Some((mode, TrackStatus::Tracked, quick_context[i]));
            } else {
                to_search.push(i);
            }
        }

        // Search for the rest, with the taken places masked out.
        for &i in &to_search {
            let m = &self.markers[i];
            let pred = predictions[i];
            let (w, h) = m.size;
            let size = f64::from(w.max(h));
            let widen = (m.coasting + 1).min(8) as f64;
            let radius = (self.config.search_radius_windows * size * widen)
                .min(f64::from(self.width.max(self.height)));
            let reach = radius.ceil() as i32 + w.max(h) * SEARCH_WINDOW_SCALE;
            let region = PixelRect::centered_at(pred, w, h).grown(reach, reach);
            let masks: Vec<PixelRect> = if self.config.exclusive {
                claimed.iter().map(|c| c.1).collect()
            } else {
                Vec::new()
            };
            fill_region(
                &mut self.region,
                &self.config,
                m,
                frame,
                depth,
                region,
                &masks,
            );
            let exclusive = self.config.exclusive;
            let markers = &self.markers;
            let scratch = &mut self.patch;
            let judge = |c: Point2<f64>| {
                let free = !exclusive
                    || !(taken(markers, i, c, &claimed)
                        || nearer_to_other(markers, i, c, &predictions));
                free.then(|| {
                    m.context
                        .as_ref()
                        .filter(|_| m.context_informative())
                        .map(|t| t.ncc(frame, c, scratch))
                })
            };
            let level = m.context_level;
            let quick_place = (quick[i].confidence >= threshold).then_some(quick[i].center);
            let best = search(
                &mut self.region,
                &self.config,
                m,
                (
                    pred,
                    radius,
                    SEARCH_SIGMA_FRACTION * self.config.search_radius_windows * size,
                ),
                quick[i],
                judge,
            );
            match best {
                // A candidate that looks less familiar than usual is still taken when it is
                // where the quick pass went: the search found nothing better, so the
                // surroundings changed rather than the marker.
                Some((mode, context))
                    if mode.confidence >= threshold
                        && (context.is_none_or(|c| c >= level - CONTEXT_REJECT)
                            || quick_place.is_some_and(|q| {
                                (q - mode.center).norm() < SAME_PLACE_FRACTION * size
                            })) =>
                {
                    claimed.push((i, mode.window, mode.center));
                    results[i] = Some((mode, TrackStatus::Recovered, context));
                }
                other => {
                    let confidence = other.map_or(quick[i].confidence, |(m, _)| m.confidence);
                    results[i] = Some((
                        Mode {
                            center: pred,
                            window: PixelRect::centered_at(pred, w, h),
                            confidence,
                            moments: None,
                        },
                        TrackStatus::Predicted,
                        None,
                    ));
                }
            }
        }

        for (i, result) in results.into_iter().enumerate() {
            let Some((mode, status, context)) = result else {
                continue;
            };
            let size = (self.width, self.height);
            let m = &mut self.markers[i];
            let observation = m.advance(mode, status, &self.config, depth, size);
            if let (Some(c), Some(t)) = (context, m.context.as_mut())
                && observation.status != TrackStatus::Predicted
            {
                t.update(frame, mode.center, CONTEXT_RATE, &mut self.patch);
                m.context_level += CONTEXT_LEVEL_RATE * (c - m.context_level);
            }
            self.tracks[i].observations.push(observation);
        }
        Ok(())
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
        m.motion = Motion {
            position: center,
            velocity: Vector2::zeros(),
        };
        m.last_center = center;
        m.coasting = 0;
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

impl Motion {
    fn predict(&self) -> Point2<f64> {
        self.position + self.velocity
    }
}

impl MarkerState {
    /// Whether the surroundings tell this marker apart: they correlate well with
    /// themselves from frame to frame (a textured background, a fork, a target board), not
    /// only with noise.
    fn context_informative(&self) -> bool {
        self.context.is_some() && self.context_level >= CONTEXT_MIN_LEVEL
    }

    /// Record this frame's outcome and update the motion state.
    fn advance(
        &mut self,
        mode: Mode,
        status: TrackStatus,
        config: &TrackerConfig,
        depth: Option<&DepthView<'_>>,
        (width, height): (u32, u32),
    ) -> Observation {
        let was_found = self.last_status.found();
        if status == TrackStatus::Predicted {
            self.coasting += 1;
            let pred = clamp_into(self.motion.predict(), width, height);
            self.motion.position = pred;
            // A swinging branch turns back: extrapolating a release's speed for frames on end
            // would run the prediction away from it.
            self.motion.velocity *= COAST_VELOCITY_DECAY;
            let lost = self.coasting > config.max_coast_frames;
            self.last_status = if lost {
                TrackStatus::Lost
            } else {
                TrackStatus::Predicted
            };
            return Observation {
                center: (!lost).then_some(pred),
                window: mode.window,
                status: self.last_status,
                confidence: mode.confidence,
            };
        }
        let z = mode.center;
        let status = if was_found {
            status
        } else {
            TrackStatus::Recovered
        };
        match config.motion {
            MotionModel::Static => {
                self.motion.velocity = Vector2::zeros();
                self.motion.position = z;
            }
            MotionModel::ConstantVelocity => {
                self.motion.velocity = if was_found {
                    z - self.last_center
                } else {
                    Vector2::zeros()
                };
                self.motion.position = z;
            }
            MotionModel::AlphaBeta { alpha, beta } => {
                if was_found {
                    let pred = self.motion.predict();
                    let r = z - pred;
                    self.motion.position = pred + r * alpha;
                    self.motion.velocity += r * beta;
                } else {
                    self.motion.position = z;
                    self.motion.velocity = Vector2::zeros();
                }
            }
        }
        if config.window == WindowMode::Adaptive
            && let Some(m) = mode.moments
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
            && let Some(dm) = window_depth(d, mode.window)
        {
            self.depth_m = Some(dm);
        }
        self.last_center = z;
        self.coasting = 0;
        self.last_status = status;
        Observation {
            center: Some(z),
            window: mode.window,
            status,
            confidence: mode.confidence,
        }
    }
}

/// Window size (the larger side) of a marker, pixels.
fn window_px(m: &MarkerState) -> f64 {
    f64::from(m.size.0.max(m.size.1))
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
        (c - at).norm() < EXCLUSION_FRACTION * 0.5 * (mine + window_px(&markers[j]))
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

/// Compute the marker model's weights over `rect` (clipped to the frame), with depth gating
/// and the `masked` rectangles zeroed.
fn fill_region(
    region: &mut Region,
    config: &TrackerConfig,
    marker: &MarkerState,
    frame: &RgbImage,
    depth: Option<&DepthView<'_>>,
    rect: PixelRect,
    masked: &[PixelRect],
) {
    let rect = rect.intersect(&image_rect(frame.width(), frame.height()));
    region.rect = rect;
    let area = rect.area() as usize;
    let gate = match (config.depth_gate_m, marker.depth_m, depth) {
        (Some(g), Some(dm), Some(d)) => Some((g, dm, d)),
        _ => None,
    };
    let raw = frame.as_raw();
    let stride = frame.width() as usize * 3;
    let is_masked = |x: i32, y: i32| {
        masked
            .iter()
            .any(|r| x >= r.x && y >= r.y && i64::from(x) < r.right() && i64::from(y) < r.bottom())
    };
    let gated = |x: i32, y: i32| {
        gate.is_some_and(|(g, dm, d)| d.at(x, y).is_some_and(|v| (v - dm).abs() > g))
    };
    match &marker.model {
        MarkerModel::Projected { projector } => {
            region.weights.clear();
            region.weights.reserve(area);
            for y in rect.y..rect.bottom() as i32 {
                let row = &raw[y as usize * stride..];
                for x in rect.x..rect.right() as i32 {
                    let k = x as usize * 3;
                    let rgb = [row[k], row[k + 1], row[k + 2]];
                    let v = match config.model.features(rgb, &config.hsv_mask) {
                        Some(f) if !gated(x, y) && !is_masked(x, y) => {
                            f32::from(projector.value_of(&f))
                        }
                        _ => 0.0,
                    };
                    region.weights.push(v);
                }
            }
        }
        MarkerModel::Kernel { hist, q } => {
            region.bins.clear();
            region.bins.reserve(area);
            region.p.clear();
            region.p.resize(q.len(), 0.0);
            for y in rect.y..rect.bottom() as i32 {
                let row = &raw[y as usize * stride..];
                for x in rect.x..rect.right() as i32 {
                    let k = x as usize * 3;
                    let rgb = [row[k], row[k + 1], row[k + 2]];
                    let bin = match hist.bin_of(&rgb) {
                        Some(b) if !gated(x, y) && !is_masked(x, y) => b as u32,
                        _ => NO_BIN,
                    };
                    region.bins.push(bin);
                }
            }
        }
    }
}

impl Region {
    fn index(&self, x: i32, y: i32) -> usize {
        (y - self.rect.y) as usize * self.rect.width as usize + (x - self.rect.x) as usize
    }

    /// Sums of weight, weight·x, weight·y and second orders over `window ∩ region`
    /// (absolute pixel coordinates).
    fn sums(&self, window: PixelRect) -> [f64; 6] {
        let w = window.intersect(&self.rect);
        let mut s = [0.0; 6];
        if w.is_empty() {
            return s;
        }
        for y in w.y..w.bottom() as i32 {
            let start = self.index(w.x, y);
            let row = &self.weights[start..start + w.width as usize];
            let (mut r0, mut rx, mut rxx) = (0.0f64, 0.0f64, 0.0f64);
            for (i, &v) in row.iter().enumerate() {
                let v = f64::from(v);
                let x = f64::from(w.x) + i as f64;
                r0 += v;
                rx += v * x;
                rxx += v * x * x;
            }
            let yf = f64::from(y);
            s[0] += r0;
            s[1] += rx;
            s[2] += r0 * yf;
            s[3] += rxx;
            s[4] += rx * yf;
            s[5] += r0 * yf * yf;
        }
        s
    }

    fn mass(&self, window: PixelRect) -> f64 {
        self.sums(window)[0]
    }
}

/// Mean-shift from `start` with a window of `size`, then the weighted centroid and the
/// confidence of the converged window.
fn locate(
    region: &mut Region,
    config: &TrackerConfig,
    marker: &MarkerState,
    start: Point2<f64>,
    size: (i32, i32),
) -> Mode {
    match &marker.model {
        MarkerModel::Projected { .. } => {
            let max_iter = config.criteria.max_iterations.unwrap_or(100).max(1);
            let eps = config.criteria.epsilon_px.unwrap_or(1.0).max(0.0);
            let mut window = PixelRect::centered_at(start, size.0, size.1);
            let mut center = start;
            for _ in 0..max_iter {
                let s = region.sums(window);
                if s[0] <= 0.0 {
                    break;
                }
                let c = Point2::new(s[1] / s[0], s[2] / s[0]);
                let next = PixelRect::centered_at(c, size.0, size.1);
                let moved = (c - center).norm();
                center = c;
                if next == window {
                    break;
                }
                window = next;
                if moved < eps {
                    break;
                }
            }
            let s = region.sums(window);
            if s[0] > 0.0 {
                center = Point2::new(s[1] / s[0], s[2] / s[0]);
            }
            let grown = window.grown(ADAPTIVE_BORDER_PX, ADAPTIVE_BORDER_PX);
            let g = region.sums(grown);
            // Central moments do not depend on the origin of the coordinates.
            let moments = (g[0] > 0.0).then(|| moments_from_f64_sums(g));
            Mode {
                center,
                window,
                confidence: (s[0] / marker.reference_mass).min(1.0),
                moments,
            }
        }
        MarkerModel::Kernel { q, .. } => kernel_locate(region, q, start, size),
    }
}

/// Comaniciu–Ramesh–Meer mean-shift with the Epanechnikov kernel over the window's
/// inscribed ellipse; the confidence is the Bhattacharyya coefficient at the end.
fn kernel_locate(region: &mut Region, q: &[f64], start: Point2<f64>, size: (i32, i32)) -> Mode {
    let (w, h) = (size.0.max(1) as usize, size.1.max(1) as usize);
    let mut y0 = start;
    let mut rho = 0.0;
    for _ in 0..KERNEL_MAX_ITERATIONS {
        let (next, r) = kernel_step(region, q, y0, w, h);
        rho = r;
        let Some(next) = next else { break };
        let moved = (next - y0).norm();
        y0 = next;
        if moved < KERNEL_EPSILON_PX {
            rho = kernel_step(region, q, y0, w, h).1;
            break;
        }
    }
    Mode {
        center: y0,
        window: PixelRect::centered_at(y0, size.0, size.1),
        confidence: rho.clamp(0.0, 1.0),
        moments: None,
    }
}

/// One kernel mean-shift step at `y0`: the new position (None when the kernel holds no
/// counted pixel) and the Bhattacharyya coefficient at `y0`.
fn kernel_step(
    region: &mut Region,
    q: &[f64],
    y0: Point2<f64>,
    w: usize,
    h: usize,
) -> (Option<Point2<f64>>, f64) {
    let window = PixelRect::centered_at(y0, w as i32, h as i32).intersect(&region.rect);
    if window.is_empty() {
        return (None, 0.0);
    }
    let hx = (w as f64 * 0.5).max(0.5);
    let hy = (h as f64 * 0.5).max(0.5);
    region.p.iter_mut().for_each(|v| *v = 0.0);
    let mut total = 0.0;
    let mut pixels = Vec::with_capacity(window.area() as usize);
    for y in window.y..window.bottom() as i32 {
        for x in window.x..window.right() as i32 {
            let bin = region.bins[region.index(x, y)];
            if bin == NO_BIN {
                continue;
            }
            let dx = (f64::from(x) - y0.x) / hx;
            let dy = (f64::from(y) - y0.y) / hy;
            let r2 = dx * dx + dy * dy;
            if r2 >= 1.0 {
                continue;
            }
            region.p[bin as usize] += 1.0 - r2;
            total += 1.0 - r2;
            pixels.push((x, y, bin, 1.0 - r2));
        }
    }
    if total <= 0.0 {
        return (None, 0.0);
    }
    let mut rho = 0.0;
    for (&p, &qv) in region.p.iter().zip(q) {
        if p > 0.0 && qv > 0.0 {
            rho += (p / total * qv).sqrt();
        }
    }
    let (mut sw, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for (x, y, bin, k) in pixels {
        let p = region.p[bin as usize] / total;
        // sqrt(q/p) times the kernel profile: the spatially weighted mean converges to the
        // Bhattacharyya maximum on uniform blobs, where the flat mean stalls short of it.
        let weight = (q[bin as usize] / p).sqrt() * k;
        sw += weight;
        sx += weight * f64::from(x);
        sy += weight * f64::from(y);
    }
    if sw <= 0.0 {
        return (None, rho);
    }
    (Some(Point2::new(sx / sw, sy / sw)), rho)
}

/// The recovery search around `pred`: the quick pass's result, and starts at the prediction,
/// the last centre, and four directions at half and full `radius`, each with a window twice
/// the size, refined with the normal one. Candidates `judge` rejects (`None`: other markers'
/// places) are skipped; for the others it gives the context correlation when the marker's
/// surroundings are informative. The best by confidence, times a Gaussian of the distance
/// from the prediction (`sigma`: half the search radius before any widening), times the
/// context term, wins; it is returned with its correlation.
fn search(
    region: &mut Region,
    config: &TrackerConfig,
    marker: &MarkerState,
    (pred, radius, sigma): (Point2<f64>, f64, f64),
    quick: Mode,
    mut judge: impl FnMut(Point2<f64>) -> Option<Option<f64>>,
) -> Option<(Mode, Option<f64>)> {
    let (w, h) = marker.size;
    let big = (w * SEARCH_WINDOW_SCALE, h * SEARCH_WINDOW_SCALE);
    let mut starts = vec![pred, marker.last_center];
    for fraction in [0.5, 1.0] {
        let d = radius * fraction;
        for (dx, dy) in [(-d, 0.0), (d, 0.0), (0.0, -d), (0.0, d)] {
            starts.push(Point2::new(pred.x + dx, pred.y + dy));
        }
    }
    let mut best: Option<(f64, Mode, Option<f64>)> = None;
    let candidates = starts.into_iter().map(|start| {
        let coarse = locate(region, config, marker, start, big);
        locate(region, config, marker, coarse.center, (w, h))
    });
    for fine in std::iter::once(quick).chain(candidates) {
        let Some(context) = judge(fine.center) else {
            continue;
        };
        let d = (fine.center - pred).norm() / sigma;
        let familiarity = context.map_or(1.0, |c| {
            ((c - marker.context_level).min(0.0) / CONTEXT_SHARPNESS).exp()
        });
        let score = fine.confidence * (-0.5 * d * d).exp() * familiarity;
        if best.as_ref().is_none_or(|(s, _, _)| score > *s) {
            best = Some((score, fine, context));
        }
    }
    best.map(|(_, m, c)| (m, c))
}
