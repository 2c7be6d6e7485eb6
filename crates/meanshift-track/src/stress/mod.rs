//! Stress sequences for the marker tracker, with ground truth and visibility: the conditions
//! under which real footage breaks trackers, one at a time and all at once.
//!
//! Each [`Condition`] is a preset of [`StressConfig`]: whole-frame and per-marker motion blur
//! (a blurred marker is a longer, paler streak: its saturation falls with its coverage),
//! jumps of 2–5 window widths per frame, markers that leave the frame and come back, branches
//! in front of a marker for 1–10 frames, two markers of one colour crossing, illumination
//! flicker, JPEG artefacts, 15/30/60/240 fps, a 240 fps release of one marker on a plant stem
//! against a grey wall (blur to 2.5 times its width, a third less saturation, 2.5 widths per
//! frame), Kinect-style 512x424 scenes of bark and sky, and same-colour look-alikes.
//!
//! A [`StressScene`] renders frame `k` on demand ([`StressScene::frame`]), so long sequences
//! (a 240 fps clip) need no memory for frames that are not in use; the same `k` always gives
//! the same image. The truth of a marker is the centre of what its exposure drew (the mean of
//! its centres over the exposure: for a marker moving evenly, its centre at mid-exposure; for
//! a streak whose motion changes within the exposure, as at a release, a swing's turn or the
//! start of a camera shake, the streak's centre) and the fraction of its disc that is
//! visible (inside the frame and not covered). [`score_stress`] measures tracks against that
//! truth the strict way: only fully visible frames count towards accuracy, a loss is counted
//! from the frame a marker becomes fully visible, and any frame reported as found far from
//! the truth is counted.
//!
//! Tests and benches tune on [`TUNING_SEEDS`] and are judged on [`EVALUATION_SEEDS`]; a
//! second generator written apart from this one (`eval/stress_opencv.py`) judges the tracker
//! and OpenCV's on the same frames.

use image::codecs::jpeg::JpegEncoder;
use image::{Rgb, RgbImage};
use nalgebra::{Point2, Vector2};

use crate::error::{Result, TrackError};
use crate::rect::PixelRect;
use crate::rng::Rng;
use crate::tracker::{MarkerInit, Track, TrackStatus};

mod paint;
mod scene;
mod score;

use paint::*;
use scene::*;
pub use scene::{StressMarker, StressScene};
pub use score::{StressScore, score_stress};

/// Seeds the tracker's settings were tuned on.
pub const TUNING_SEEDS: std::ops::Range<u64> = 0..8;
/// Seeds that only judge: no setting was chosen by looking at them.
pub const EVALUATION_SEEDS: std::ops::Range<u64> = 1000..1008;

/// The paper's red markers (as `kinect-io`'s `synth::MARKER_RGB`).
const MARKER_RGB: [u8; 3] = [215, 25, 30];
/// Reddish-brown distractors: brick-red leaves, red bark, a maroon object.
const DISTRACTOR_RGB: [[u8; 3]; 3] = [[170, 62, 48], [150, 60, 45], [150, 40, 60]];
/// Bark of stems, twigs and occluding branches.
const BARK_RGB: [u8; 3] = [92, 72, 52];
/// A green plant stem.
const STEM_RGB: [u8; 3] = [86, 104, 56];
/// Largest image side (pixels) and frame count a config may ask for.
const MAX_SIDE_PX: u32 = 4096;
/// Largest number of frames.
const MAX_FRAMES: usize = 100_000;
/// Largest number of markers.
const MAX_MARKERS: usize = 64;
/// Most exposure sub-samples per frame (motion blur).
const MAX_SUBSAMPLES: usize = 48;
/// Frequency of the camera shake at a release (hertz) and its decay time (seconds).
const SHAKE_HZ: f64 = 6.0;
const SHAKE_DECAY_S: f64 = 0.15;
/// A marker is fully visible when at least this fraction of its disc is (sampling error).
pub const FULLY_VISIBLE: f64 = 0.999;

/// The stress conditions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Condition {
    /// Projection-image-like frames at 30 fps with a pull and release: the reference.
    Baseline,
    /// Whole-frame motion blur at the release (camera shake) and long per-marker exposure:
    /// streaks that are paler than the marker.
    MotionBlur,
    /// Fast swings at 30 fps: jumps of 2–5 window widths per frame.
    Jumps,
    /// Markers near the border whose pull takes them out of the frame; they come back at the
    /// release.
    Reentry,
    /// Branches in front of markers for 1–10 frames.
    Occlusion,
    /// Pairs of markers of one colour whose paths cross.
    Crossing,
    /// Illumination flicker: gain and white balance change from frame to frame.
    Flicker,
    /// Heavy JPEG compression (quality 30–60, chroma subsampled).
    Jpeg,
    /// The baseline's motion filmed at 15 fps.
    Fps15,
    /// The baseline's motion filmed at 60 fps.
    Fps60,
    /// The baseline's motion filmed at 240 fps.
    Fps240,
    /// One 14 px red marker on a plant stem against a grey wall, released at 240 fps: a
    /// streak of 2.5 marker widths, a third less saturation, 2.5 widths per frame, ringing
    /// at 7–9 Hz.
    Release240,
    /// Kinect-style 512x424 bark-and-sky scene: markers of 12–20 px, a whole-frame blur at
    /// the release, jumps of 20–45 px, swings of up to 100 px, reddish-brown distractors,
    /// holes, brief partial occlusions.
    KinectStyle,
    /// Static discs of the markers' own colour and size near their paths.
    LookAlikes,
    /// Everything at once.
    Combined,
}

impl Condition {
    /// Every condition.
    pub const ALL: [Condition; 15] = [
        Condition::Baseline,
        Condition::MotionBlur,
        Condition::Jumps,
        Condition::Reentry,
        Condition::Occlusion,
        Condition::Crossing,
        Condition::Flicker,
        Condition::Jpeg,
        Condition::Fps15,
        Condition::Fps60,
        Condition::Fps240,
        Condition::Release240,
        Condition::KinectStyle,
        Condition::LookAlikes,
        Condition::Combined,
    ];

    /// Short name (`baseline`, `blur`, `jumps`, ...).
    pub fn name(&self) -> &'static str {
        match self {
            Self::Baseline => "baseline",
            Self::MotionBlur => "blur",
            Self::Jumps => "jumps",
            Self::Reentry => "reentry",
            Self::Occlusion => "occlusion",
            Self::Crossing => "crossing",
            Self::Flicker => "flicker",
            Self::Jpeg => "jpeg",
            Self::Fps15 => "fps15",
            Self::Fps60 => "fps60",
            Self::Fps240 => "fps240",
            Self::Release240 => "release240",
            Self::KinectStyle => "kinect",
            Self::LookAlikes => "lookalikes",
            Self::Combined => "combined",
        }
    }

    /// The condition of a [`Condition::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name() == name)
    }
}

/// What the scene behind the markers looks like.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Background {
    /// Smooth green-gray mottling (a projection image of foliage and ground).
    Mottled,
    /// A plain grey wall with faint texture.
    GreyWall,
    /// Sky above, a trunk and branches of bark.
    BarkSky,
}

/// Everything a stress scene is made of. [`StressConfig::condition`] gives the presets.
#[derive(Debug, Clone, PartialEq)]
pub struct StressConfig {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Frame rate in hertz.
    pub fps_hz: f64,
    /// Length in seconds.
    pub duration_s: f64,
    /// The scene.
    pub background: Background,
    /// Number of markers.
    pub markers: usize,
    /// Marker diameters are drawn from this range (pixels).
    pub marker_diameter_px: [f64; 2],
    /// Pull amplitudes (pixels).
    pub amplitude_px: [f64; 2],
    /// Natural frequencies (hertz).
    pub frequency_hz: [f64; 2],
    /// Damping ratios.
    pub damping_ratio: [f64; 2],
    /// Start of the pull (seconds).
    pub pull_start_s: f64,
    /// The release (seconds).
    pub release_s: f64,
    /// Exposure as a fraction of the frame period (motion blur).
    pub exposure_fraction: f64,
    /// Peak camera shake at the release (pixels; 0 for none): a whole-frame blur.
    pub shake_px: f64,
    /// Markers sit on stems that bend with them (a plant, a twig).
    pub stems: bool,
    /// Markers whose pull carries them out of the frame.
    pub reentries: usize,
    /// Pairs of markers whose paths cross (counted within `markers`).
    pub crossing_pairs: usize,
    /// Branches in front of a marker: number of events.
    pub occlusions: usize,
    /// Each occlusion covers the marker fully for this many frames (range).
    pub occlusion_frames: [usize; 2],
    /// Thin static twigs across marker paths (brief partial occlusions).
    pub twigs: usize,
    /// Static reddish-brown distractors.
    pub distractors: usize,
    /// Static discs of the marker colour and size near the paths.
    pub lookalikes: usize,
    /// Relative amplitude of the illumination flicker (0 for none).
    pub flicker: f64,
    /// JPEG quality range (`None`: no compression).
    pub jpeg_quality: Option<[u8; 2]>,
    /// Fraction of pixels that are holes (black).
    pub hole_fraction: f64,
    /// Colour noise per channel (8-bit levels).
    pub noise_sigma: f64,
    /// Random seed.
    pub seed: u64,
}

impl StressConfig {
    /// The preset of `condition`.
    // One table: an arm per condition over the baseline; split, it would no longer read
    // as one.
    #[allow(clippy::too_many_lines)]
    pub fn condition(condition: Condition, seed: u64) -> Self {
        let base = Self {
            width: 512,
            height: 424,
            fps_hz: 30.0,
            duration_s: 4.0,
            background: Background::Mottled,
            markers: 8,
            marker_diameter_px: [8.0, 14.0],
            amplitude_px: [20.0, 55.0],
            frequency_hz: [1.0, 3.0],
            damping_ratio: [0.02, 0.08],
            pull_start_s: 0.4,
            release_s: 1.0,
            exposure_fraction: 0.5,
            shake_px: 0.0,
            stems: true,
            reentries: 0,
            crossing_pairs: 0,
            occlusions: 0,
            occlusion_frames: [1, 10],
            twigs: 2,
            distractors: 3,
            lookalikes: 0,
            flicker: 0.0,
            jpeg_quality: None,
            hole_fraction: 0.02,
            noise_sigma: 3.0,
            seed,
        };
        match condition {
            Condition::Baseline => base,
            Condition::MotionBlur => Self {
                exposure_fraction: 1.0,
                shake_px: 14.0,
                amplitude_px: [35.0, 70.0],
                ..base
            },
            Condition::Jumps => Self {
                width: 640,
                height: 480,
                markers: 5,
                marker_diameter_px: [10.0, 15.0],
                amplitude_px: [80.0, 120.0],
                frequency_hz: [2.0, 3.2],
                background: Background::BarkSky,
                ..base
            },
            Condition::Reentry => Self {
                markers: 6,
                reentries: 2,
                amplitude_px: [40.0, 70.0],
                ..base
            },
            Condition::Occlusion => Self {
                occlusions: 8,
                duration_s: 5.0,
                ..base
            },
            Condition::Crossing => Self {
                markers: 6,
                crossing_pairs: 2,
                amplitude_px: [35.0, 60.0],
                ..base
            },
            Condition::Flicker => Self {
                flicker: 0.35,
                ..base
            },
            Condition::Jpeg => Self {
                jpeg_quality: Some([30, 60]),
                ..base
            },
            Condition::Fps15 => Self {
                fps_hz: 15.0,
                duration_s: 6.0,
                ..base
            },
            Condition::Fps60 => Self {
                fps_hz: 60.0,
                ..base
            },
            Condition::Fps240 => Self {
                fps_hz: 240.0,
                duration_s: 2.5,
                ..base
            },
            Condition::Release240 => Self {
                width: 640,
                height: 480,
                fps_hz: 240.0,
                duration_s: 3.0,
                background: Background::GreyWall,
                markers: 1,
                marker_diameter_px: [13.0, 15.0],
                // 2.5 widths (35 px) per frame at the fastest: A = v / (2 pi f).
                amplitude_px: [140.0, 170.0],
                frequency_hz: [7.0, 9.0],
                damping_ratio: [0.03, 0.05],
                pull_start_s: 0.04,
                release_s: 41.0 / 240.0,
                // A 20 px path during the exposure: a 34 px streak, no pixel fully covered.
                exposure_fraction: 0.6,
                twigs: 0,
                distractors: 0,
                hole_fraction: 0.0,
                noise_sigma: 2.0,
                ..base
            },
            Condition::KinectStyle => Self {
                background: Background::BarkSky,
                markers: 8,
                marker_diameter_px: [12.0, 20.0],
                amplitude_px: [60.0, 100.0],
                frequency_hz: [1.2, 2.2],
                shake_px: 10.0,
                twigs: 3,
                distractors: 5,
                hole_fraction: 0.03,
                occlusions: 3,
                occlusion_frames: [1, 3],
                duration_s: 5.0,
                ..base
            },
            Condition::LookAlikes => Self {
                lookalikes: 4,
                distractors: 4,
                ..base
            },
            Condition::Combined => Self {
                background: Background::BarkSky,
                markers: 8,
                marker_diameter_px: [10.0, 18.0],
                amplitude_px: [40.0, 90.0],
                frequency_hz: [1.2, 2.5],
                exposure_fraction: 0.8,
                shake_px: 12.0,
                reentries: 1,
                crossing_pairs: 1,
                occlusions: 4,
                twigs: 3,
                distractors: 4,
                lookalikes: 2,
                flicker: 0.25,
                jpeg_quality: Some([40, 70]),
                hole_fraction: 0.03,
                duration_s: 5.0,
                ..base
            },
        }
    }

    /// Number of frames.
    pub fn frames(&self) -> usize {
        (self.duration_s * self.fps_hz).round().max(1.0) as usize
    }

    /// Check sizes and ranges (sizes are bounded so that no config allocates without limit).
    ///
    /// # Errors
    /// [`TrackError::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<()> {
        if !(64..=MAX_SIDE_PX).contains(&self.width) || !(64..=MAX_SIDE_PX).contains(&self.height) {
            return Err(TrackError::param(
                "width/height",
                format!(
                    "{}x{} px; each side must be 64..={MAX_SIDE_PX}",
                    self.width, self.height
                ),
            ));
        }
        self.validate_motion()?;
        self.validate_sensor()
    }

    /// Frame rate, duration, marker sizes and the motion's ranges.
    fn validate_motion(&self) -> Result<()> {
        let positive = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(TrackError::param(name, format!("{v} must be positive")))
            }
        };
        positive("fps_hz", self.fps_hz)?;
        positive("duration_s", self.duration_s)?;
        if self.duration_s * self.fps_hz > MAX_FRAMES as f64 {
            return Err(TrackError::param(
                "duration_s",
                format!("more than {MAX_FRAMES} frames"),
            ));
        }
        if !(1..=MAX_MARKERS).contains(&self.markers) {
            return Err(TrackError::param(
                "markers",
                format!("{} is not in 1..={MAX_MARKERS}", self.markers),
            ));
        }
        for (name, [lo, hi]) in [
            ("marker_diameter_px", self.marker_diameter_px),
            ("amplitude_px", self.amplitude_px),
            ("frequency_hz", self.frequency_hz),
            ("damping_ratio", self.damping_ratio),
        ] {
            if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo <= hi) {
                return Err(TrackError::param(
                    name,
                    format!("[{lo}, {hi}] is not a range"),
                ));
            }
        }
        if self.marker_diameter_px[0] < 3.0 || self.marker_diameter_px[1] > 200.0 {
            return Err(TrackError::param(
                "marker_diameter_px",
                "diameters must be 3..=200 px",
            ));
        }
        if self.damping_ratio[1] >= 1.0 || self.frequency_hz[0] <= 0.0 {
            return Err(TrackError::param(
                "damping_ratio/frequency_hz",
                "damping ratios below 1 and positive frequencies",
            ));
        }
        if !(self.pull_start_s.is_finite()
            && self.release_s.is_finite()
            && 0.0 <= self.pull_start_s
            && self.pull_start_s < self.release_s)
        {
            return Err(TrackError::param(
                "pull_start_s/release_s",
                "0 <= pull start < release",
            ));
        }
        Ok(())
    }

    /// Exposure, shake, flicker, holes, noise, special markers, occluders and JPEG.
    fn validate_sensor(&self) -> Result<()> {
        for (name, v, hi) in [
            ("exposure_fraction", self.exposure_fraction, 1.0),
            ("shake_px", self.shake_px, 200.0),
            ("flicker", self.flicker, 0.9),
            ("hole_fraction", self.hole_fraction, 0.5),
            ("noise_sigma", self.noise_sigma, 100.0),
        ] {
            if !(v.is_finite() && (0.0..=hi).contains(&v)) {
                return Err(TrackError::param(name, format!("{v} is not in 0..={hi}")));
            }
        }
        if 2 * self.crossing_pairs + self.reentries > self.markers {
            return Err(TrackError::param(
                "crossing_pairs/reentries",
                "more special markers than markers",
            ));
        }
        let [o0, o1] = self.occlusion_frames;
        if o0 == 0 || o0 > o1 || o1 > 1000 {
            return Err(TrackError::param(
                "occlusion_frames",
                format!("[{o0}, {o1}] must be a range in 1..=1000"),
            ));
        }
        if self.occlusions + self.twigs + self.distractors + self.lookalikes > 1000 {
            return Err(TrackError::param("occluders", "more than 1000 objects"));
        }
        if let Some([q0, q1]) = self.jpeg_quality
            && !(1 <= q0 && q0 <= q1 && q1 <= 100)
        {
            return Err(TrackError::param(
                "jpeg_quality",
                format!("[{q0}, {q1}] must be a range in 1..=100"),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
