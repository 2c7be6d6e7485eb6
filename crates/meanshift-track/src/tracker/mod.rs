//! The multi-marker tracker: mean-shift per marker as the paper ran it, with what the paper
//! did by hand done automatically and a motion model that knows how unsure it is.
//!
//! Each frame:
//! 1. **Predict** every marker with a constant-velocity Kalman filter ([`MotionModel`]); its
//!    covariance is the gate: how far from the prediction a measurement may lie. A learnt
//!    swing bends the prediction; before one is learnt, a marker coasting after a miss (or
//!    hidden behind another of its look) goes on at the acceleration of its last positions.
//!    A shake of the camera (colour models: measured on edge points of the still scene,
//!    `tracker::camera`) moves every prediction with the scene, and the frame before is read
//!    where the shake moved it as the background of streaks. For the RGB kernel model, whose
//!    bins move with the light, the frame is read through lookup tables rescaled by the
//!    light's change per channel since the first frame (`tracker::light`).
//! 2. **Quick pass**: mean-shift from the prediction over a region three windows wide; the
//!    measurement is the weighted centroid of the blob the window converged on (for a marker
//!    smeared by motion blur, the streak's centre; for a marker whose blob runs on along a
//!    thin twig of its hue, the disc the blob's opening leaves), or the window's centroid
//!    when no marker-sized blob is there. A marker found in the last frame is `tracked` when the
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
//!    marker it fits best, and to none whose gate or appearance it does not fit. Some places
//!    cost more: one at another marker's home (its first-frame centre) beyond anywhere this
//!    marker has been tracked (branch markers swing about their homes: a look-alike there is
//!    the other marker, even when that marker's own track has lost it); one far beyond
//!    anywhere this marker has been tracked from its own home (the quick pass does not accept
//!    it there either: colour models); and, for a marker that the quick
//!    pass saw at its prediction only a little too dim to be tracked, any place outside its
//!    normal gate (it is most likely still there: coasting a frame beats jumping to a
//!    look-alike). A marker so found is `recovered`.
//! 4. A marker without a measurement coasts on its prediction (`predicted`) for up to
//!    [`TrackerConfig::max_coast_frames`] frames, then is `lost` (no centre) while the search
//!    goes on.
//! 5. **Parked on a look-alike**: a track that has stood still for [`PARKED_FRAMES`] frames
//!    away from its home, on a place where the marker once turned down a look-alike or
//!    where detection threw it by a jump, is on a look-alike (a branch marker at rest stands
//!    at its home; one held away from it got there by moving). The place becomes a known
//!    static look-alike, those frames are revised to `predicted`, and the marker is looked
//!    for about its home.
//! 6. **Swaps undone**: two markers of one look (colour models) whose last frames each run
//!    along the swing line the other is known by, and not their own, are exchanged, with
//!    their observations since they last met (`tracker::swaps`), or, for two of one look
//!    that did not meet in the last 30 frames, over the frames the swap was judged on; so
//!    are two where one track runs along the other's line, moving and far from its own,
//!    while the other's track is elsewhere (it took the other marker where they met). The frames between the swap
//!    and its repair are revised in [`Tracker::tracks`]: a caller that reads a frame's
//!    result at once may see up to 30 earlier frames change later.
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
use crate::model::{AppearanceModel, MarkerModel, is_hole, marker_mask};
use crate::rect::PixelRect;
use crate::region::{
    Lookup, Mode, PixelFilter, Region, STREAK_MIN_CONTRAST, STREAK_MIN_HUE_SHARE, STREAK_MIN_SHADE,
    STREAK_RESIDUAL, Sparse, Streak, Trail,
};
use crate::swing::Swing;
use crate::template::{Template, TemplateScratch};

mod blobs;
mod camera;
mod config;
mod frame;
mod init;
mod joint;
mod light;
mod passes;
mod previous;
mod state;
mod swaps;

pub use swaps::MAX_REVISED_FRAMES;
mod track;

use blobs::*;
pub use config::{MotionModel, TrackerConfig, WindowMode};
use joint::*;
use light::LightProbe;
use passes::{Again, Flag, Went};
use previous::PreviousFrame;
use state::*;
pub use track::{DepthView, MarkerInit, Observation, Track, TrackStatus, TrackSummary};

/// Squared gate distance (2 degrees of freedom) inside which a measurement belongs to a
/// prediction: the chi-square quantile of 0.999.
const GATE_CHI2: f64 = 13.82;
/// The margin of a settled marker's narrow quick region about its window, in windows (a
/// quarter each way: 1.5x1.5 windows, a quarter of the full region's 3x3), and how far from
/// the prediction the narrow pass's best may lie and still stand.
const NARROW_REACH_WINDOWS: f64 = 0.25;
/// A marker is settled for a narrow quick pass (see [`Tracker::quick_pass`]) when its gate's
/// radius is at most this share of its window...
const NARROW_GATE_WINDOWS: f64 = 0.75;
/// ... and no look-alike it knows lies within this many windows of its prediction.
const NARROW_CLEAR_WINDOWS: f64 = 1.75;
/// ... and its full region was weighed, holding nothing but the marker, at most this many
/// frames before.
const NARROW_RECHECK_FRAMES: usize = 8;
/// Speed (windows per frame) up to which a marker found in the last frame counts as at rest
/// beside its static look-alikes (see `MarkerState::look_alikes_away`): a moving marker's
/// blob is a streak that a split would cut.
const RESTING_WINDOWS_PER_FRAME: f64 = 0.25;
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
/// [`EXCLUSION_FRACTION`] between two parts of one blob that the split gave to two markers
/// found in the last frame: a marker partly behind another of its look is 0.6–0.75 of a
/// window from it while they cross (crossing seeds, 4 December 2026), while the two halves
/// of one marker's disc are about 0.42 of its width apart, under this.
const SPLIT_EXCLUSION_FRACTION: f64 = 0.5;
/// Fastest motion (windows per frame) at which [`SPLIT_EXCLUSION_FRACTION`] holds: a blob
/// that two faster markers share may be one marker's streak, whose two halves are far apart.
const SPLIT_MAX_WINDOWS_PER_FRAME: f64 = 1.0;
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
/// Least `1 - rho^2` of a marker's usual context correlation in [`state::correlation_spread`]
/// (a correlation of 0.99): the learnt spread already covers noise above it.
const CORRELATION_SPREAD_FLOOR: f64 = 0.02;
/// Least way (windows) from the last measurement of a blob that counts as blurred along it
/// (`MarkerState::blurred_along`): half a window, the reach of plain mean-shift.
const BLURRED_MIN_WINDOWS: f64 = 0.5;
/// Least ratio of a blurred blob's spread along its way to its spread across (standard
/// deviations): a disc gives 1, a streak as long as two discs about 1.7.
const BLURRED_ELONGATION: f64 = 1.5;
/// Least confidence of a blurred blob, as a share of the marker's usual confidence: motion
/// blur at a release takes about a third of a marker's saturation (issue 19's real clip, as
/// [`BLUR_KEPT_SATURATION`]), and fainter drawn-out blobs are smears of twigs and edges (on
/// the combined condition's seed 12004 a marker's track took one at 0.38 against its usual
/// 0.85 and lost the marker for 35 frames).
const BLURRED_KEPT_CONFIDENCE: f64 = 0.6;
/// Cosine of the largest angle between a blurred blob's longer axis and its way from the last
/// measurement (45 degrees: a release's first streak, drawn along the curve of the swing,
/// lay 27 degrees off the chord on the blur condition's seed 14008).
const BLURRED_MAX_ANGLE_COS: f64 = std::f64::consts::FRAC_1_SQRT_2;
/// Most a candidate's confidence shortfall (from the best candidate's) may cost.
const APPEARANCE_CAP: f64 = 8.0;
/// Spreads below its usual confidence at which a measurement is not accepted without
/// competition.
const TYPICAL_SIGMAS: f64 = 3.0;
/// Least spread assumed for a marker's confidence.
const CONFIDENCE_SIGMA_MIN: f64 = 0.08;
/// Least spread assumed for a gray target's confidence (its template's correlation).
const TEMPLATE_SIGMA_MIN: f64 = 0.02;
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
/// Frames of its speed at leaving that a marker that left the frame may have come back in by
/// when it is first seen again (besides [`BORDER_WINDOWS`]): the frame it came in, partly
/// visible and not found, and the next.
const ENTRY_SPEED_FRAMES: f64 = 2.0;
/// Least speed (windows per frame) a marker that left the frame is taken to come back at: it
/// may have left slowly, pulled out, and come back released.
const ENTRY_RELEASE_WINDOWS: f64 = 2.0;
/// Cost of taking, by a manoeuvre, a place that lies in another marker's normal gate.
const OWNED_COST: f64 = 6.0;
/// Cost (nats) of taking a place at another marker's home (its first-frame centre,
/// within [`HOME_NEAR_WINDOWS`]) that lies beyond this marker's own reach: a branch marker swings about
/// its home, so a look-alike at another marker's home, far beyond anywhere this one has
/// been, is that marker (whose own track may have lost it), not this one.
const HOME_COST: f64 = 6.0;
/// Windows around a marker's home that count as its place: a child marker is carried that
/// far by its parent's pull (the twin: up to about a window and a half).
const HOME_NEAR_WINDOWS: f64 = 2.0;
/// Least distance (windows) from a marker's home of a known static look-alike that a track
/// standing on it is parked from, however near home: a look-alike touching the marker at
/// rest lies about one marker width (under a window) away.
const LOOK_ALIKE_FROM_HOME_WINDOWS: f64 = 0.75;
/// Offset (spreads) from a marker's signature swing line beyond which a still track near
/// its home is not the marker held in a pull (a pull is held on the line the release then
/// swings along): as far as a track that took another marker's path must be from its own.
const PARKED_OFF_LINE_SPREADS: f64 = swaps::STOLEN_OWN_OFFSET;
/// Windows beyond the farthest this marker has been found from its home within which a
/// place is still its own reach (a release throws a marker further than its pull).
const HOME_MARGIN_WINDOWS: f64 = 2.0;
/// Windows past a colour marker's reach from its home beyond which a place is not its own
/// (the quick pass does not accept it there, and detection prices it as another's home).
const FAR_BEYOND_REACH_WINDOWS: f64 = 5.0;
/// Share of [`TrackerConfig::min_confidence`] from which a quick-pass measurement at the
/// prediction, too dim to be tracked, still holds the marker there against a jump.
const DIM_SHARE: f64 = 0.5;
/// Distance (windows) within which candidates of different markers are one place: two
/// markers cannot both be closer than this, so one place cannot go to two of them.
const PLACE_SHARE: f64 = 0.5;
/// ... when they hold one blob (their boxes overlap by at least this share of their union),
/// or are closer than this many windows: two blobs of one look side by side are two places
/// (two markers of one look crossing, one partly in front of the other).
const PLACE_BLOB_OVERLAP: f64 = 0.5;
const PLACE_SAME_SHARE: f64 = 0.25;
/// Least lead (cost units, nats) of a marker's best place over its next choice for the marker
/// to be decided on its own, before its neighbours: e^3, twenty times likelier.
const ANCHOR_MARGIN: f64 = 3.0;
/// Reach (windows) within which a decided marker's displacement guides an ambiguous one.
const NEIGHBOUR_RADIUS_WINDOWS: f64 = 6.0;
/// A marker found again after this many frames without a measurement, away from its coasted
/// prediction, starts at rest, its velocity unknown (of the order of a window per frame).
const STOP_AFTER_MISSES: usize = 2;

/// Confidence under which a measurement the tracker follows is reported
/// [`TrackStatus::Predicted`] rather than found: on the stress generator's tuning seeds
/// (`docs/validation.md`, "What a confidence value means"), found frames under 0.6 were
/// within 3 px of the truth 27-28 % of the time and more than 8 px off 43-46 %.
pub(crate) const TRUSTED_CONFIDENCE: f64 = 0.6;
/// Weak measurements in a row, each within [`WEAK_STILL_WINDOWS`] of the one before, after which
/// the track is taken to be held by a still look-alike rather than following its marker.
const WEAK_STILL_FRAMES: usize = 3;
/// Distance (windows) between two weak measurements in a row within which the track stood
/// still.
const WEAK_STILL_WINDOWS: f64 = 0.25;

/// Whether the tracker followed a measurement in this observation: found, or a measurement
/// under [`TRUSTED_CONFIDENCE`] reported as an estimate (`predicted` with a confidence;
/// coasting has confidence 0). The track's own rules (swaps, parking) read this, not the
/// reported status.
fn followed(o: &Observation) -> bool {
    o.status.found() || weakly_followed(o)
}

/// Whether an observation is a weak measurement: followed, but reported as an estimate
/// (`predicted` with its own confidence, not 0 as while coasting).
fn weakly_followed(o: &Observation) -> bool {
    o.status == TrackStatus::Predicted && o.confidence > 0.0
}

/// Distance, in windows, within which a same-look marker can take this one's place.
const CROWD_WINDOWS: f64 = 3.0;

/// A quick-pass measurement further than this many spreads from the marker's swing line
/// goes to detection (a same-look marker crossing its path took the window).
const LINE_ACCEPT_SPREADS: f64 = 3.0;

/// Spreads from a marker's swing line beyond which a place is far off it: a place detection
/// took the marker to (or a weak measurement) there is not recorded in its swing (see
/// `MarkerState::found`).
const FAR_OFF_LINE_SPREADS: f64 = 4.0;

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
/// Least number of found markers, seen moving in proportion with a jumping gray target
/// ([`Coherence::gain`]), that can overrule where it was found.
const COHERENT_WITNESSES: usize = 2;
/// Distance (windows) by which a lone witness (the only marker seen moving in proportion
/// with a jumping gray target) must disagree with the target's displacement to overrule it.
const LONE_WITNESS_WINDOWS: f64 = 2.0;
/// How much surer (confidence) a lone witness must have been found than the target it
/// overrules: two look-alike targets that disagree cannot both be right, and the one found
/// on the weaker likeness gives way.
const LONE_WITNESS_MARGIN: f64 = 0.05;
/// Share of the displacement a witness gives by which it may be off without disagreeing: a
/// gain learnt over the first frames of a release is rough (on the real rig, the top row
/// moved 1.9 times the second row's first step and 1.2 times its next).
const GAIN_TOLERANCE: f64 = 0.5;
/// How much less surely (confidence) than a jumping gray target a witness may have been
/// found and still testify: a witness on a weaker likeness may be the one that jumped wrong
/// (the template spread's floor).
const WITNESS_SLACK: f64 = TEMPLATE_SIGMA_MIN;
/// Distance (windows) a gray target must have moved against the way its rig-mates jumped
/// for [`Tracker::against_the_rig`] (parts of one rig do not move against each other; a
/// quarter window is well above mean-shift's noise).
const AGAINST_WINDOWS: f64 = 0.25;
/// Rounds of flagging and looking again per frame: the second asks again with the first's
/// answers (a target that jumped with those flagged first, which were its witnesses).
const INCOHERENCE_ROUNDS: usize = 2;
/// Least squared correlation of two markers' displacements for one to tell the other's.
const PROPORTIONAL_R2: f64 = 0.8;
/// Largest ratio of two markers' displacements for one to tell the other's.
const PROPORTIONAL_GAIN: f64 = 4.0;
/// Most witnesses asked, the nearest first.
const COHERENT_NEAREST: usize = 4;
/// Distance (windows) between a jumping target's displacement and the one a witness gives it
/// beyond which the two disagree.
const INCOHERENT_WINDOWS: f64 = 1.0;
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
/// Least share of a remembered look-alike's box that a blob inside it must cover to be taken
/// for a part of it.
const LOOK_ALIKE_PART_SHARE: f64 = 0.5;
/// Look-alikes remembered per marker (the oldest is forgotten first).
const MAX_DISTRACTORS: usize = 32;
/// Sightings counted per look-alike, at most.
const MAX_SEEN: u32 = 64;
/// A look-alike seen again within this distance (pixels) has not moved.
const STATIC_PX: f64 = 1.5;
/// Frames a track must have stood still away from its home, on a once-seen look-alike or
/// where detection threw it, to count as parked there (a quarter of a second at 30 fps: a swinging marker passes a place
/// in a frame or two, and turns at the end of a swing in three or four).
const PARKED_FRAMES: usize = 8;
/// Of those frames, the least found (a parked track on a dim look-alike misses some).
const PARKED_MIN_FOUND: usize = 6;
/// A track taken by detection to a place more than this many windows from where it was
/// (and parked there) was not followed there.
const PARKED_JUMP_WINDOWS: f64 = 2.0;
/// Distance (windows) from where the two frames after it lead back to, past which a
/// detection on a look-alike that the track jumped away from was a one-frame excursion.
const EXCURSION_WINDOWS: f64 = 3.0;
/// Distance (windows) from a look-alike the marker once turned down within which a
/// one-frame excursion is on it (a half-covered look-alike is measured a few pixels off).
const EXCURSION_LOOK_ALIKE_WINDOWS: f64 = 0.5;
/// Distance (windows) between the first window's mean-shift centre and the nearest blob's
/// centre past which that blob is the marker merged with something touching it.
const INIT_MERGED_WINDOWS: f64 = 0.25;
/// Frames looked back, at most, for where a parked track came to its place.
const PARKED_LOOKBACK_FRAMES: usize = 4 * PARKED_FRAMES;
/// Distance (windows) from a parked track's place within which its earlier centres count as
/// the same stay (a look-alike's measured centre jitters by a few pixels).
const PARKED_STAY_WINDOWS: f64 = 0.5;
/// Frames off the place, at most, inside one stay there (a detection on a piece of
/// something else for a frame, then the look-alike again).
const PARKED_EXCURSION_FRAMES: usize = 1;
/// Largest distance (pixels) of each of those centres from their mean for the track to
/// stand still (a parked window jitters by a pixel with noise and JPEG artefacts).
const PARKED_PX: f64 = 2.0;
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
/// Least speed (marker widths per frame) at which a marker's blob may be a streak along its
/// motion rather than a static candidate (see `passes::streak_along_motion`).
const STREAK_MIN_SPEED_WIDTHS: f64 = 0.25;
/// Least length (marker widths) along the motion of a blob's box for it to be a streak: a
/// marker-sized disc's box reaches at most 1.41 widths along any direction (a diagonal); a
/// marker that moves a width during the exposure draws a streak two widths long.
const STREAK_MIN_LENGTH_WIDTHS: f64 = 2.0;
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
/// Half-side of the square whose median saturation is a marker's core saturation, as a
/// share of the window's side: the middle of a marker, clear of its rim.
const CORE_WINDOWS: f64 = 0.2;
/// Levels under a marker's core saturation from which a pixel of its first blob is paler
/// than the marker (noise and JPEG move a marker's pixels by a few levels; a reddish-brown
/// look-alike beside a red marker is 40–60 paler).
const PALER_LEVELS: f64 = 36.0;
/// Levels under a marker's core saturation from which a pixel of its first blob is paler
/// than the marker, for a look-alike touching it there ([`paler_part`]), and from which a
/// static look-alike of the first frame is kept out of the marker's weights by a saturation
/// floor in its box (`MarkerState::paler_boxes`). Lower than [`PALER_LEVELS`], which raises
/// the floor over the whole frame: here the paler part must also lie off the marker's
/// centre, or the floor holds only in a look-alike's box, so a blurred marker, paler by a
/// third, loses only what lies over the look-alike. The stress scenes' reddish-brown
/// look-alikes are 30–45 levels paler than their red markers (178–187 against 200–230);
/// a marker's own pixels away from its rim stay within about 15 of its core (crossing seed
/// 6028's first frame: 199–225 about a core of 215).
const TOUCHING_PALER_LEVELS: f64 = 25.0;
/// Paler pixels of a marker's first blob, as a share of its own, that make a touching
/// look-alike rather than a rim (a marker's rim on the stress sequences is 1–20 % of its
/// pixels).
const PALER_SHARE: f64 = 0.4;
/// Least distance (windows) of the paler pixels' centroid from the marker's own for them to
/// be a look-alike beside it, not its rim all round.
const PALER_OFFSET_WINDOWS: f64 = 0.25;
/// Paler pixels of a colour marker's look elsewhere on the first frame, in markers' worth of
/// pixels, that raise its saturation floor (see `Tracker::background_floor`): a marker-sized
/// patch of bark of its hue is enough for its blob to run on into.
const BACKGROUND_PALER_MARKERS: f64 = 1.0;
/// Share of a marker's core saturation under which pixels of its look do not weigh as the
/// marker where nothing paler of its look raised its floor on the first frame (see
/// `Tracker::own_floor`). Chosen between what it keeps out and what it must keep: a
/// compressed frame's chroma blocks bled from a red marker into bark lie at 0.44-0.62 of
/// its core (combined condition, seed 14000), and at 0.6 a heavily blurred release under a
/// camera shake (blur condition, tuning seed 300), which the hue weights had carried, was
/// lost for 9 frames; at 0.5 neither.
const OWN_FLOOR_SATURATION: f64 = 0.5;
/// Share of a marker's core saturation under which pixels of its look are paler than a
/// blurred streak of it (motion blur at a release takes about a third of a marker's
/// saturation: issue 19's real pull-and-release clip), and may be kept out by a raised
/// saturation floor. A blurred streak under that floor still counts by its blend with the
/// background (streak weights).
const BLUR_KEPT_SATURATION: f64 = 0.6;
/// Share of a marker's core saturation under which an extended surface of paler pixels of
/// its look (at least [`SURFACE_PALER_MARKERS`] markers' worth: bark of its hue, not a few
/// look-alikes or colour fringes) raises its saturation floor, though a blurred streak of
/// the marker is as pale: a marker's blob runs on into such a surface, which the look-alike
/// masks (made for marker-sized blobs) cannot keep out, and the streak still counts by its
/// blend with the background. Bark of a marker's hue lies at 0.56-0.73 of the core over the
/// third generator's tuning seeds (`eval/independent_kinect.py`, seeds 1-39: 0.72 left two
/// of them at 0.727 and 0.728 unfloored); look-alikes and JPEG fringes of our own generator
/// lie at 0.70-0.85 but are not surfaces (2-4 markers' worth).
const SURFACE_KEPT_SATURATION: f64 = 0.8;
/// Paler pixels, in markers' worth, that make an extended surface (see
/// [`SURFACE_KEPT_SATURATION`]).
const SURFACE_PALER_MARKERS: f64 = 10.0;
/// Share of a cut quick-pass blob's box that a detection blob must hold to be that blob
/// seen whole (see `holds_whole`).
const WHOLE_HOLDS_SHARE: f64 = 0.8;
/// Least confidence of the whole blob against the cut one's.
const WHOLE_CONFIDENCE_SHARE: f64 = 0.9;
/// A blob needs at least this share of the marker's pixels (a partly covered marker).
const BLOB_MIN_PIXELS: f64 = 0.15;
/// A blob that two markers' predictions fall on and that holds at most this many times the
/// pixels of one of them may be that marker alone (see [`blobs::candidates_in`]).
const ONE_MARKER_PIXELS: f64 = 1.15;
/// A candidate blob's width (minor axis) lies within these multiples of the marker's.
const BLOB_WIDTH_RANGE: [f64; 2] = [0.4, 1.7];
/// Longest streak a blob may be, in marker widths (a marker swept across 5 of its widths
/// during the exposure).
const BLOB_MAX_LENGTH: f64 = 6.0;
/// Most candidates per marker and frame (the heaviest blobs).
const MAX_CANDIDATES: usize = 16;
/// Share of the velocity kept per frame without a measurement: a swing turns back.
const COAST_VELOCITY_DECAY: f64 = 0.8;
/// A merged marker moving at most this many windows a frame coasts at its own speed, not
/// slowed by [`COAST_VELOCITY_DECAY`]: two markers crossing pass each other at their own
/// speeds, and one slowed down while hidden in the other's blob fell behind onto the other
/// as they parted (crossing tuning seed 2). A faster one is slowed as a missed one is (a
/// velocity taken from a jump ran away by 150 px in 5 frames on the third generator's
/// tuning seed 5 without it).
const MERGED_STEADY_WINDOWS: f64 = 0.5;
/// Windows beyond the farthest a colour marker was tracked from its home within which it
/// is taken to stay (see [`MarkerState::held_in_frame`]).
const HOLD_REACH_WINDOWS: f64 = 1.0;

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
    /// The frame it was first seen at this place.
    first_frame: usize,
    /// The frame it was seen at this place the second time (static since), if it was.
    static_frame: Option<usize>,
    /// Its core saturation (8-bit levels), where it was measured (look-alikes of the first
    /// frame).
    saturation: Option<f64>,
    /// Another marker's look-alike of the first frame, not this marker's own (see
    /// `Tracker::share_look_alikes`): a measurement centred on it is refused, but its pixels
    /// are not masked (this marker's own weights did not make it a blob).
    shared: bool,
}

#[derive(Debug, Clone)]
struct MarkerState {
    id: String,
    model: MarkerModel,
    /// The model and the mask as per-pixel table lookups (built once; the kernel model's
    /// rescaled to each frame's light, see [`LightProbe`]).
    lookup: Lookup,
    /// The kernel model's lookup tables as learnt, when they follow the light.
    learnt_tables: Option<Box<[[u32; 256]; 3]>>,
    init_size: (i32, i32),
    size: (i32, i32),
    filter: Kalman,
    /// The swing learnt from the marker's recent track (turns the prediction).
    swing: Swing,
    /// Acceleration noise of the motion model now (pixels per frame²).
    acceleration_px: f64,
    last_center: Point2<f64>,
    /// The centre on the first frame: a branch marker swings about it.
    home: Point2<f64>,
    /// The farthest the marker has been tracked from its home (pixels): places the quick
    /// pass followed it to, not places detection took it to (those may be look-alikes).
    reach_px: f64,
    /// Detection weighs the marker's gate whole until this frame: its gate was last found
    /// cluttered with its look (see `blobs::fill`).
    dense_until: usize,
    /// The swing line the marker is known by: its first, replaced only by lines along the
    /// same direction (a swap of two markers of one look is seen against it).
    signature: Option<crate::swing::SwingLine>,
    /// The frame of the last exchange of this marker's state with another's (see
    /// `swaps.rs`): its swing history before it may be another track's.
    exchanged_at: Option<usize>,
    reference: Reference,
    depth_m: Option<f64>,
    /// Frames since the last measurement.
    misses: usize,
    /// Speed (pixels per frame) at the first frame of the current run of misses: how deep
    /// into the frame a marker that left it can be when it is first seen again.
    exit_speed_px: f64,
    /// Whether the last measurement found the marker again far from where coasting put it
    /// (its motion restarted, see [`MarkerState::found`]): a marker found again at the
    /// border after it was out of the frame came in across it, and has not left.
    restarted: bool,
    /// The frame whose full quick region last held no candidate but the marker, while no
    /// later one held another (see [`Tracker::quick_pass`]).
    clear_at: Option<usize>,
    /// Frames in a row followed on a measurement too weak to report as found (under
    /// [`TRUSTED_CONFIDENCE`], or cut): the search widens over them as over misses.
    weak_run: usize,
    /// The last of the current run of weak measurements, and how many of the run's last
    /// ones in a row lay each within [`WEAK_STILL_WINDOWS`] of the one before (see
    /// [`MarkerState::held_by_still_weak`]).
    weak_place: Option<(Point2<f64>, usize)>,
    last_status: TrackStatus,
    /// Where the marker was in the last frame and what surrounds it there, for the streak's
    /// trailing end in the next ([`Trail`]; set at the end of each frame).
    trail: Option<Trail>,
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
    /// The marker's core saturation on the first frame (colour markers; see
    /// `core_saturation`).
    core_saturation: Option<f64>,
    /// Mean colour (RGB) of the marker's pixels on the first frame.
    colour: [f32; 3],
    /// The least brightness a streak pixel of the marker may imply, as a share of `colour`
    /// (see `Streak::shade`): [`STREAK_MIN_SHADE`], or the marker's own darkest shade on
    /// the first frame where that is darker (see `darkest_shade`).
    shade: f32,
    /// How far a streak pixel of the marker may lie off the mixing line across the marker's
    /// colour, as a share of coverage times contrast (see `Streak::hue_share`): learnt from
    /// the marker's rim on the first frame (see `rim_hue_share`).
    hue_share: f32,
    /// Mean colour (RGB) of the central half of the marker's window on the first frame (see
    /// `core_colour`): its hue, without its rim's blends.
    core_colour: [f32; 3],
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
    /// Whether the blob reaches the edge of the quick pass's region where the image goes on
    /// (see [`cut_by`]): its centre may be pulled back from the marker's.
    cut: bool,
    /// Whether this is a part of a blob shared with another marker's prediction (see
    /// [`candidates_in`]).
    split: bool,
    /// What a split part is priced for its blob being one other marker's worth of pixels
    /// and wider than this marker (see [`candidates_in`]); 0 elsewhere.
    misfit: f64,
    /// The blob's weighted second central moments `[xx, xy, yy]` (pixels²), for a
    /// measurement at a blob (see [`MarkerState::blurred_along`]).
    spread: Option<[f64; 3]>,
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

/// A marker's measurement in a frame, its status and its surroundings' correlation.
type Found = (Measured, TrackStatus, Option<f64>);
/// A quick pass's best candidate and the places of the others.
type QuickFound = (Option<Scored>, Vec<(Point2<f64>, PixelRect)>);
/// A place claimed in a frame: the marker, the pixels it holds, its centre.
type Claim = (usize, PixelRect, Point2<f64>);

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
    patch: TemplateScratch,
    /// The last frame given, where this frame reads it: the background of its streaks.
    previous: Option<PreviousFrame>,
    /// Per pair of markers (row-major `n x n`), how alike they have moved.
    coherence: Vec<Coherence>,
    /// The light's change since the first frame (the kernel model's markers only).
    light: Option<LightProbe>,
}

/// How alike marker `a` has moved with marker `b` (entry `a n + b`): running means of the
/// squared difference of their displacements and of the sum of their squared
/// displacements, and of the products `da·db`, `da·da`, `db·db`, over frames both were found
/// in consecutively.
#[derive(Debug, Clone, Copy, Default)]
struct Coherence {
    difference_px2: f64,
    motion_px2: f64,
    ab_px2: f64,
    aa_px2: f64,
    bb_px2: f64,
}

impl Coherence {
    fn learn(&mut self, a: Vector2<f64>, b: Vector2<f64>) {
        let mean = |v: &mut f64, x: f64| *v += COHERENCE_RATE * (x - *v);
        mean(&mut self.difference_px2, (a - b).norm_squared());
        mean(&mut self.motion_px2, a.norm_squared() + b.norm_squared());
        mean(&mut self.ab_px2, a.dot(&b));
        mean(&mut self.aa_px2, a.norm_squared());
        mean(&mut self.bb_px2, b.norm_squared());
    }

    /// Not seen to move differently: alike (one rig, one branch, one camera shake), or not
    /// seen moving enough to tell.
    fn coherent(&self) -> bool {
        self.motion_px2 < COHERENCE_MIN_MOTION_PX2
            || self.difference_px2 <= COHERENCE_RATIO * self.motion_px2
    }

    /// Seen moving the same way (correlation at least [`PROPORTIONAL_R2`], each at least a
    /// pixel a frame in root mean square), by whatever amounts.
    fn same_way(&self) -> bool {
        self.aa_px2 >= 1.0
            && self.bb_px2 >= 1.0
            && self.ab_px2 > 0.0
            && self.ab_px2 * self.ab_px2 >= PROPORTIONAL_R2 * self.aa_px2 * self.bb_px2
    }

    /// The factor that takes `b`'s displacement to `a`'s, when both have been seen moving
    /// (a root mean square of at least 0.15 of a window `side` a frame), along one
    /// direction (correlation at least [`PROPORTIONAL_R2`]) and by amounts within
    /// [`PROPORTIONAL_GAIN`] of each other: parts of one rig that turns move alike up to
    /// their distances from the pivot.
    fn gain(&self, side: f64) -> Option<f64> {
        let least = (0.15 * side).powi(2);
        let gain = self.ab_px2 / self.bb_px2.max(f64::MIN_POSITIVE);
        (self.aa_px2 >= least
            && self.bb_px2 >= least
            && self.ab_px2 > 0.0
            && self.ab_px2 * self.ab_px2 >= PROPORTIONAL_R2 * self.aa_px2 * self.bb_px2
            && (1.0 / PROPORTIONAL_GAIN..=PROPORTIONAL_GAIN).contains(&gain))
        .then_some(gain)
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
        let moments_wanted = config.window == WindowMode::Adaptive;
        let mut tracker = Self {
            config,
            width,
            height,
            markers: Vec::with_capacity(markers.len()),
            tracks: Vec::with_capacity(markers.len()),
            region: Region::new(moments_wanted),
            labeler: Labeler::default(),
            patch: TemplateScratch::default(),
            previous: None,
            coherence: vec![Coherence::default(); markers.len() * markers.len()],
            light: None,
        };
        tracker.check_depth(depth.as_ref())?;
        for (k, init) in markers.iter().enumerate() {
            if markers[..k].iter().any(|m| m.id == init.id) {
                return Err(TrackError::DuplicateId {
                    id: init.id.clone(),
                });
            }
        }
        let mut found = Vec::with_capacity(markers.len());
        for init in markers {
            found.push(tracker.add_marker(first_frame, depth.as_ref(), init, markers)?);
        }
        if tracker.config.recovery {
            tracker.learn_distractors(first_frame, depth.as_ref(), found);
            // The previous frame gives colour markers their streaks and tells a still
            // look-alike from a moving marker; gray targets (templates) need neither, so they
            // are spared a copy of every frame.
            let gray = matches!(tracker.config.model, AppearanceModel::Gray { .. });
            if !gray {
                let away: Vec<PixelRect> = markers
                    .iter()
                    .map(|m| m.window.grown(m.window.width, m.window.height))
                    .collect();
                tracker.previous = Some(PreviousFrame::first(first_frame, &away));
            }
            if matches!(tracker.config.model, AppearanceModel::Rgb { .. }) {
                tracker.light = Some(LightProbe::of(first_frame));
                for m in &mut tracker.markers {
                    m.learnt_tables = Some(Box::new(m.lookup.tables()));
                }
            }
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

    /// Track every marker into the next frame.
    ///
    /// # Errors
    /// [`TrackError::EmptyImage`] for an empty frame; [`TrackError::SizeMismatch`] when the
    /// frame (or depth map) differs in size from the first frame. The tracker is unchanged
    /// by a failed call.
    pub fn update(&mut self, frame: &RgbImage, depth: Option<DepthView<'_>>) -> Result<()> {
        self.track_into(frame, depth)?;
        if self.previous.is_some() {
            let regions = self.next_regions();
            if let Some(p) = self.previous.as_mut() {
                p.keep(frame, &regions);
            }
        }
        Ok(())
    }

    /// [`Tracker::update`] with a frame the tracker may keep: a colour model's tracker needs
    /// the last frame's pixels (the background of a blurred marker's streak), which
    /// [`Tracker::update`] copies where the next frame will read them; given the frame, it
    /// keeps it whole instead, and hands back the frame it no longer needs (the one before,
    /// or this one for a gray model, which keeps none), for the caller to reuse or drop. For
    /// a caller that decodes every frame anyway: a 512x424 frame's copy costs about as much
    /// as tracking one marker in it.
    ///
    /// # Errors
    /// As [`Tracker::update`].
    ///
    /// # Examples
    /// ```
    /// use meanshift_track::{MarkerInit, PixelRect, Tracker, TrackerConfig};
    /// let frame = |x: u32| {
    ///     image::RgbImage::from_fn(80, 60, move |px, py| {
    ///         let on = px.abs_diff(x) < 5 && py.abs_diff(30) < 5;
    ///         image::Rgb(if on { [220, 30, 30] } else { [40, 90, 40] })
    ///     })
    /// };
    /// let marker = MarkerInit { id: "A".into(), window: PixelRect::new(15, 25, 11, 11) };
    /// let mut tracker = Tracker::new(TrackerConfig::default(), &frame(20), None, &[marker])?;
    /// for x in [23, 26, 29] {
    ///     let spare = tracker.update_owned(frame(x), None)?;
    ///     assert_eq!(spare.dimensions(), (80, 60));
    /// }
    /// let last = tracker.tracks()[0].observations.last().expect("3 frames");
    /// let center = last.center.expect("found");
    /// assert!((center.x - 29.0).abs() < 1.0, "{center}");
    /// # Ok::<(), meanshift_track::TrackError>(())
    /// ```
    pub fn update_owned(
        &mut self,
        frame: RgbImage,
        depth: Option<DepthView<'_>>,
    ) -> Result<RgbImage> {
        self.track_into(&frame, depth)?;
        Ok(match self.previous.as_mut() {
            Some(p) => p.replace(frame),
            None => frame,
        })
    }

    /// Everything [`Tracker::update`] does but keeping the frame.
    fn track_into(&mut self, frame: &RgbImage, depth: Option<DepthView<'_>>) -> Result<()> {
        self.check_frame(frame)?;
        self.check_depth(depth.as_ref())?;
        let depth = depth.as_ref();
        let n = self.markers.len();
        let (width, height) = (self.width, self.height);
        let frame_index = self.frames() as u64;
        if let Some(light) = &self.light {
            let gains = light.gains(frame);
            for m in &mut self.markers {
                if let Some(learnt) = &m.learnt_tables {
                    m.lookup.rescale(learnt, gains);
                }
            }
        }
        // The camera's own shift moves every marker with the scene.
        let shift = match self.previous.as_mut() {
            Some(p) => {
                p.measure_shift(frame);
                p.shift()
            }
            None => Vector2::zeros(),
        };
        for m in &mut self.markers {
            m.predict(&self.config, (width, height), frame_index);
            m.filter.position += shift;
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
        let (mut results, mut claimed, mut undecided) = self.accept_quick(&quick, &predictions);

        // Detection in the opened gates, then one joint assignment.
        let mut detection = self.detect_and_assign(frame, depth, &undecided, &claimed, &quick, &[]);
        detection.record_in(&undecided, &mut results);
        // A jump the markers it moves with did not make is looked for again, from where
        // they say it went, together with the markers that may have lacked the place it took.
        // A second round asks again with the first round's answers (a target that jumped
        // with the ones flagged first, and whose witnesses were those).
        let mut looked_again: Vec<usize> = Vec::new();
        for _ in 0..INCOHERENCE_ROUNDS {
            let mut flagged = self.flags(&results);
            flagged.retain(|f| !looked_again.contains(&f.marker));
            if flagged.is_empty() {
                break;
            }
            looked_again.extend(flagged.iter().map(|f| f.marker));
            let again = Again {
                flagged: &flagged,
                undecided,
                first: detection,
                quick: &quick,
            };
            (undecided, detection) = self.redetect(frame, depth, again, &mut results, &mut claimed);
        }
        self.learn_detection(&undecided, &claimed, detection);
        self.learn_look_alikes(&results, &rejected, &predictions);
        self.learn_coherence(&results);
        let merged = self.merged_markers(&results, &predictions);
        self.record(frame, depth, results, &merged);
        self.learn_parked();
        self.revise_excursions();
        self.repair_swaps();
        self.leave_trails(frame);
        Ok(())
    }

    /// Each colour marker's trail in `frame` for the next frame's streaks (see [`Trail`]):
    /// where it was found, alone ([`Tracker::alone`]), over a plain surrounding.
    fn leave_trails(&mut self, frame: &RgbImage) {
        let streaks =
            self.config.recovery && !matches!(self.config.model, AppearanceModel::Gray { .. });
        for i in 0..self.markers.len() {
            let trail = (streaks && self.alone(i))
                .then(|| blobs::trail(&self.markers[i], frame))
                .flatten();
            self.markers[i].trail = trail;
        }
    }

    /// A frame the tracker can take: not empty, the first frame's size.
    fn check_frame(&self, frame: &RgbImage) -> Result<()> {
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
        let side = window_px(m);
        m.filter = Kalman::new(center, MEASUREMENT_PX, 0.1 * side);
        m.swing.clear();
        m.acceleration_px = ACCELERATION_MIN_PX;
        m.last_center = center;
        m.reach_px = m.reach_px.max((center - m.home).norm());
        m.misses = 0;
        m.last_status = TrackStatus::Set;
        m.trail = None;
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

/// A measurement for unit tests: an 11x11 window and blob at `center`, confidence 0.9.
#[cfg(test)]
fn measured_at_point(center: Point2<f64>) -> Measured {
    Measured {
        center,
        window: PixelRect::centered_at(center, 11, 11),
        holds: PixelRect::centered_at(center, 11, 11),
        confidence: 0.9,
        moments: None,
        cut: false,
        split: false,
        misfit: 0.0,
        spread: None,
    }
}

/// A gray 192x64 frame with red 9x9 squares centred at `(x, 30)` for each `x` of `xs`
/// ([`two_red_markers`]' markers at 20 and 150).
#[cfg(test)]
fn red_squares(xs: [u32; 2]) -> RgbImage {
    RgbImage::from_fn(192, 64, |x, y| {
        if y.abs_diff(30) <= 4 && xs.iter().any(|&cx| x.abs_diff(cx) <= 4) {
            image::Rgb([215, 25, 30])
        } else {
            image::Rgb([100, 110, 95])
        }
    })
}

/// A tracker for unit tests: markers A and B of one red colour, 130 px apart on a gray
/// 192x64 frame.
#[cfg(test)]
fn two_red_markers() -> Result<Tracker> {
    let frame = red_squares([20, 150]);
    let inits = [
        MarkerInit {
            id: "A".into(),
            window: PixelRect::new(15, 25, 11, 11),
        },
        MarkerInit {
            id: "B".into(),
            window: PixelRect::new(145, 25, 11, 11),
        },
    ];
    Tracker::new(TrackerConfig::default(), &frame, None, &inits)
}

#[cfg(test)]
mod coherence_tests {
    use super::*;

    fn learnt(pairs: &[(Vector2<f64>, Vector2<f64>)]) -> Coherence {
        let mut c = Coherence::default();
        for _ in 0..10 {
            for &(a, b) in pairs {
                c.learn(a, b);
            }
        }
        c
    }

    #[test]
    fn a_gain_is_told_only_by_markers_seen_moving_in_proportion() {
        let side = 20.0;
        let b = Vector2::new(6.0, -3.0);
        // Twice as far, the same way (and back): gain 2.
        let g = learnt(&[(2.0 * b, b), (-2.0 * b, -b)]).gain(side);
        assert!(g.is_some_and(|g| (g - 2.0).abs() < 1e-9), "{g:?}");
        // Across each other, against each other, or too unlike in size: no gain.
        let across = Vector2::new(3.0, 6.0);
        assert_eq!(learnt(&[(across, b), (-across, -b)]).gain(side), None);
        assert_eq!(learnt(&[(-b, b), (b, -b)]).gain(side), None);
        assert_eq!(learnt(&[(6.0 * b, b), (-6.0 * b, -b)]).gain(side), None);
        // Not seen moving enough (under 0.15 windows a frame): no gain.
        let still = Vector2::new(1.0, 0.5);
        assert_eq!(learnt(&[(still, still), (-still, -still)]).gain(side), None);
    }
}
