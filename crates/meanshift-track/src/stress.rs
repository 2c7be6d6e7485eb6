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
//! the same image. The truth of a marker is its centre at the middle of the exposure (for a
//! streak, the streak's centre) and the fraction of its disc that is visible (inside the
//! frame and not covered). [`score_stress`] measures tracks against that truth the strict way:
//! only fully visible frames count towards accuracy, a loss is counted from the frame a marker
//! becomes fully visible, and any frame reported as found far from the truth is counted.
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
    #[allow(clippy::too_many_lines)] // longer than 100 lines; to be split by concept (issue 21)
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
    #[allow(clippy::too_many_lines)] // longer than 100 lines; to be split by concept (issue 21)
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

/// One marker of a scene and its motion.
#[derive(Debug, Clone, PartialEq)]
pub struct StressMarker {
    /// Name (`A`, `B`, ...).
    pub id: String,
    /// Rest position (pixels).
    pub rest: Point2<f64>,
    /// Unit direction of the pull.
    pub direction: Vector2<f64>,
    /// Pull amplitude (pixels).
    pub amplitude_px: f64,
    /// Share of the amplitude that swings across the pull (an elliptical path).
    pub across: f64,
    /// Natural frequency (hertz).
    pub frequency_hz: f64,
    /// Damping ratio.
    pub damping_ratio: f64,
    /// Diameter (pixels).
    pub diameter_px: f64,
    /// Colour.
    pub rgb: [u8; 3],
    /// Where its stem is rooted (pixels), if it has one.
    pub stem_root: Option<Point2<f64>>,
}

impl StressMarker {
    /// Centre at `t_s`, before any camera shake.
    pub fn position(&self, t_s: f64, pull_s: f64, release_s: f64) -> Point2<f64> {
        let (along, across) = if t_s <= pull_s {
            (0.0, 0.0)
        } else if t_s <= release_s {
            let u = (t_s - pull_s) / (release_s - pull_s);
            (u * u * (3.0 - 2.0 * u), 0.0)
        } else {
            let t = t_s - release_s;
            let w = 2.0 * std::f64::consts::PI * self.frequency_hz;
            let z = self.damping_ratio;
            let wd = w * (1.0 - z * z).sqrt();
            let decay = (-z * w * t).exp();
            (
                decay * ((wd * t).cos() + z * w / wd * (wd * t).sin()),
                decay * (wd * t).sin(),
            )
        };
        let normal = Vector2::new(-self.direction.y, self.direction.x);
        self.rest
            + self.direction * (self.amplitude_px * along)
            + normal * (self.amplitude_px * self.across * across)
    }
}

/// A branch in front of a marker for some frames.
#[derive(Debug, Clone, Copy, PartialEq)]
struct OcclusionEvent {
    marker: usize,
    /// First fully covered frame.
    start: usize,
    /// Fully covered frames.
    frames: usize,
    /// Direction of the branch.
    direction: Vector2<f64>,
    half_width_px: f64,
    half_length_px: f64,
}

/// A thick segment with round ends.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Capsule {
    a: Point2<f64>,
    b: Point2<f64>,
    half_width: f64,
}

impl Capsule {
    fn distance(&self, p: Point2<f64>) -> f64 {
        let ab = self.b - self.a;
        let len2 = ab.norm_squared();
        let u = if len2 > 0.0 {
            ((p - self.a).dot(&ab) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (p - (self.a + ab * u)).norm()
    }

    fn covers(&self, p: Point2<f64>) -> bool {
        self.distance(p) <= self.half_width
    }

    fn bounds(&self) -> [f64; 4] {
        let r = self.half_width;
        [
            self.a.x.min(self.b.x) - r,
            self.a.y.min(self.b.y) - r,
            self.a.x.max(self.b.x) + r,
            self.a.y.max(self.b.y) + r,
        ]
    }

    fn shifted(&self, d: Vector2<f64>) -> Self {
        Self {
            a: self.a + d,
            b: self.b + d,
            ..*self
        }
    }
}

/// A generated scene: frames on demand, truth and visibility per frame.
#[derive(Debug, Clone)]
pub struct StressScene {
    config: StressConfig,
    markers: Vec<StressMarker>,
    /// The static scene under the markers (with distractors and look-alikes).
    back: Vec<f32>,
    /// Static twigs in front of the markers.
    twigs: Vec<Capsule>,
    occlusions: Vec<OcclusionEvent>,
    inits: Vec<MarkerInit>,
    frames: usize,
}

/// Points of a unit disc at which visibility is sampled (centre, and rings at 1/3, 2/3 and
/// 0.97 of the radius).
fn disc_samples() -> Vec<Vector2<f64>> {
    let mut out = vec![Vector2::zeros()];
    for (r, n) in [(1.0 / 3.0, 8), (2.0 / 3.0, 16), (0.97, 24)] {
        for k in 0..n {
            let a = 2.0 * std::f64::consts::PI * f64::from(k) / f64::from(n);
            out.push(Vector2::new(r * a.cos(), r * a.sin()));
        }
    }
    out
}

fn marker_id(k: usize) -> String {
    b"ABCDEFGHIJKLMNOPQRSTUVWXYZ"
        .get(k)
        .map_or_else(|| format!("M{k}"), |&c| char::from(c).to_string())
}

/// Distance between segments `p0 p1` and `q0 q1` (sampled; enough for placement).
fn segment_distance(p: [Point2<f64>; 2], q: [Point2<f64>; 2]) -> f64 {
    let c = Capsule {
        a: q[0],
        b: q[1],
        half_width: 0.0,
    };
    (0..=16)
        .map(|k| c.distance(p[0] + (p[1] - p[0]) * (f64::from(k) / 16.0)))
        .fold(f64::INFINITY, f64::min)
}

impl StressScene {
    /// Build the scene of `config`: place the markers and the static objects, paint the
    /// background.
    ///
    /// # Errors
    /// As [`StressConfig::validate`].
    pub fn new(config: &StressConfig) -> Result<Self> {
        config.validate()?;
        let mut rng = Rng::new(config.seed ^ 0x7374_7265_7373); // "stress"
        let (w, h) = (f64::from(config.width), f64::from(config.height));
        let markers = place_markers(config, &mut rng);
        let frames = config.frames();
        let mut scene = Self {
            config: config.clone(),
            back: Vec::new(),
            twigs: Vec::new(),
            occlusions: Vec::new(),
            inits: Vec::new(),
            frames,
            markers,
        };
        scene.back = paint_background(config, &mut rng);
        // Distractors and look-alikes near the markers' paths, static.
        let mut statics: Vec<(Point2<f64>, f64, [u8; 3])> = Vec::new();
        for k in 0..config.distractors + config.lookalikes {
            let m = &scene.markers[k % scene.markers.len()];
            let along = m.direction * (m.amplitude_px * rng.range([-0.8, 1.3]));
            let normal = Vector2::new(-m.direction.y, m.direction.x);
            let lookalike = k >= config.distractors;
            let (radius, rgb, offset) = if lookalike {
                (
                    m.diameter_px * 0.5 * rng.range([0.85, 1.2]),
                    m.rgb,
                    m.diameter_px * rng.range([1.6, 3.0]),
                )
            } else {
                (
                    rng.range([3.0, 9.0]),
                    DISTRACTOR_RGB[k % DISTRACTOR_RGB.len()],
                    m.diameter_px * 0.5 + rng.range([8.0, 30.0]),
                )
            };
            let c = m.rest + along + normal * (rng.sign() * offset);
            if c.x > 0.0 && c.y > 0.0 && c.x < w && c.y < h {
                statics.push((c, radius, rgb));
            }
        }
        let mut canvas = Canvas::full(config.width, config.height, std::mem::take(&mut scene.back));
        for &(c, r, rgb) in &statics {
            canvas.disc(c, r, rgb);
        }
        scene.back = canvas.data;
        // Twigs across the widest swings, away from the rest positions.
        let mut by_amplitude: Vec<usize> = (0..scene.markers.len()).collect();
        by_amplitude.sort_by(|&a, &b| {
            scene.markers[b]
                .amplitude_px
                .total_cmp(&scene.markers[a].amplitude_px)
        });
        for &k in by_amplitude.iter().take(config.twigs) {
            let m = &scene.markers[k];
            let at = m.rest + m.direction * (m.amplitude_px * rng.range([0.5, 0.85]));
            let normal = Vector2::new(-m.direction.y, m.direction.x);
            let tilt = normal + m.direction * rng.range([-0.4, 0.4]);
            let tilt = tilt / tilt.norm();
            scene.twigs.push(Capsule {
                a: at - tilt * 28.0,
                b: at + tilt * 28.0,
                half_width: rng.range([1.2, 2.5]),
            });
        }
        // Occlusions after the release, where motion is fastest.
        let release_frame = (config.release_s * config.fps_hz).ceil() as usize;
        for k in 0..config.occlusions {
            let marker = k % scene.markers.len();
            let frames_covered = rng.int(config.occlusion_frames[0], config.occlusion_frames[1]);
            let last_start = frames
                .saturating_sub(frames_covered + 2)
                .max(release_frame + 1);
            let start = rng.int(release_frame + 1, last_start);
            let a = rng.range([0.0, std::f64::consts::PI]);
            let d = scene.markers[marker].diameter_px;
            scene.occlusions.push(OcclusionEvent {
                marker,
                start,
                frames: frames_covered,
                direction: Vector2::new(a.cos(), a.sin()),
                half_width_px: d * rng.range([0.8, 1.2]),
                half_length_px: d * 3.0,
            });
        }
        // The windows a user draws on frame 0: a little larger than the marker, a little off.
        let truth0 = scene.truth(0);
        scene.inits = scene
            .markers
            .iter()
            .zip(&truth0)
            .map(|(m, c)| {
                let size = (m.diameter_px * 1.2 + 2.0).round() as i32;
                let jitter = Vector2::new(rng.range([-1.5, 1.5]), rng.range([-1.5, 1.5]));
                MarkerInit {
                    id: m.id.clone(),
                    window: PixelRect::centered_at(c + jitter, size, size),
                }
            })
            .collect();
        Ok(scene)
    }

    /// The config.
    pub fn config(&self) -> &StressConfig {
        &self.config
    }

    /// Number of frames.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// The markers.
    pub fn markers(&self) -> &[StressMarker] {
        &self.markers
    }

    /// The windows a user would draw on frame 0.
    pub fn inits(&self) -> &[MarkerInit] {
        &self.inits
    }

    fn time_s(&self, frame: usize) -> f64 {
        frame as f64 / self.config.fps_hz
    }

    fn exposure_s(&self) -> f64 {
        self.config.exposure_fraction / self.config.fps_hz
    }

    /// Whole-frame camera shake at `t_s` (pixels).
    fn shake(&self, t_s: f64) -> Vector2<f64> {
        let t = t_s - self.config.release_s;
        if self.config.shake_px <= 0.0 || t <= 0.0 {
            return Vector2::zeros();
        }
        let a = self.config.shake_px * (-t / SHAKE_DECAY_S).exp();
        let p = 2.0 * std::f64::consts::PI * SHAKE_HZ * t;
        Vector2::new(a * p.sin(), 0.6 * a * (p * 1.3 + 0.5).sin())
    }

    fn marker_at(&self, k: usize, t_s: f64) -> Point2<f64> {
        self.markers[k].position(t_s, self.config.pull_start_s, self.config.release_s)
            + self.shake(t_s)
    }

    /// True centre of every marker in `frame` (middle of the exposure), in marker order.
    pub fn truth(&self, frame: usize) -> Vec<Point2<f64>> {
        let t = self.time_s(frame);
        (0..self.markers.len())
            .map(|k| self.marker_at(k, t))
            .collect()
    }

    /// The branch in front of marker `k`'s centre `c` in `frame`, if any: fully over it on
    /// the event's frames, half off it the frame before and after.
    fn occluder(&self, event: &OcclusionEvent, frame: usize, c: Point2<f64>) -> Option<Capsule> {
        let end = event.start + event.frames;
        let normal = Vector2::new(-event.direction.y, event.direction.x);
        let offset = if (event.start..end).contains(&frame) {
            0.0
        } else if frame + 1 == event.start || frame == end {
            event.half_width_px + 0.3 * self.markers[event.marker].diameter_px
        } else {
            return None;
        };
        let centre = c + normal * offset;
        Some(Capsule {
            a: centre - event.direction * event.half_length_px,
            b: centre + event.direction * event.half_length_px,
            half_width: event.half_width_px,
        })
    }

    /// Fraction of each marker's disc that is visible in `frame` (inside the image and not
    /// covered by twigs, branches in front, or markers drawn over it), in marker order.
    pub fn visibility(&self, frame: usize) -> Vec<f64> {
        let t = self.time_s(frame);
        let truth = self.truth(frame);
        let shake = self.shake(t);
        let (w, h) = (f64::from(self.config.width), f64::from(self.config.height));
        let samples = disc_samples();
        let occluders: Vec<Capsule> = self
            .twigs
            .iter()
            .map(|c| c.shifted(shake))
            .chain(
                self.occlusions
                    .iter()
                    .filter_map(|e| self.occluder(e, frame, truth[e.marker])),
            )
            .collect();
        (0..self.markers.len())
            .map(|k| {
                let r = self.markers[k].diameter_px * 0.5;
                let visible = samples
                    .iter()
                    .filter(|s| {
                        let p = truth[k] + *s * r;
                        let inside = p.x >= -0.5 && p.y >= -0.5 && p.x <= w - 0.5 && p.y <= h - 0.5;
                        let over_marker = (k + 1..self.markers.len())
                            .any(|j| (p - truth[j]).norm() <= self.markers[j].diameter_px * 0.5);
                        inside && !over_marker && !occluders.iter().any(|c| c.covers(p))
                    })
                    .count();
                visible as f64 / samples.len() as f64
            })
            .collect()
    }

    /// Render `frame` (0-based). The same frame always renders the same image.
    ///
    /// # Errors
    /// [`TrackError::InvalidParameter`] for a frame past the end or a JPEG round trip that
    /// fails.
    pub fn frame(&self, frame: usize) -> Result<RgbImage> {
        if frame >= self.frames {
            return Err(TrackError::param(
                "frame",
                format!("{frame} is past the last frame {}", self.frames - 1),
            ));
        }
        let cfg = &self.config;
        let mut rng = Rng::new(
            cfg.seed
                .wrapping_mul(0x9E37_79B9)
                .wrapping_add(frame as u64)
                .rotate_left(17),
        );
        let t = self.time_s(frame);
        let exposure = self.exposure_s();
        let subs = self.subsamples(frame);
        let full = PixelRect::image(cfg.width, cfg.height);
        let shaking = (0..subs).any(|s| {
            self.shake(t + exposure * ((s as f64 + 0.5) / subs as f64 - 0.5))
                .norm()
                > 0.05
        });
        let dirty = if shaking {
            full
        } else {
            self.moving_bounds(frame).intersect(&full)
        };
        // The static part: the background with the twigs over it.
        let back = Canvas::full(cfg.width, cfg.height, self.back.clone());
        let mut canvas = back.clone();
        for twig in &self.twigs {
            canvas.capsule(twig, BARK_RGB);
        }
        if !dirty.is_empty() {
            let mut acc = vec![0.0f32; dirty.area() as usize * 3];
            for s in 0..subs {
                let ts = t + exposure * ((s as f64 + 0.5) / subs as f64 - 0.5);
                let shake = self.shake(ts);
                let mut layer = Canvas::from_shifted(&back, dirty, shake);
                self.draw_moving(&mut layer, frame, ts, shake);
                for (a, v) in acc.iter_mut().zip(&layer.data) {
                    *a += v;
                }
            }
            canvas.set_rect(dirty, &acc, 1.0 / subs as f32);
        }
        finish(&canvas, cfg, frame, &mut rng)
    }

    /// Exposure sub-samples of `frame`: one per pixel of the fastest motion during the
    /// exposure (markers or shake), at least 1, at most [`MAX_SUBSAMPLES`].
    fn subsamples(&self, frame: usize) -> usize {
        let t = self.time_s(frame);
        let e = self.exposure_s();
        if e <= 0.0 {
            return 1;
        }
        let (a, b) = (t - 0.5 * e, t + 0.5 * e);
        let mut path = (self.shake(b) - self.shake(a)).norm();
        for k in 0..self.markers.len() {
            path = path.max((self.marker_at(k, b) - self.marker_at(k, a)).norm());
        }
        ((path * 1.5).ceil() as usize).clamp(1, MAX_SUBSAMPLES)
    }

    /// Bounding box of everything that moves during `frame`'s exposure.
    fn moving_bounds(&self, frame: usize) -> PixelRect {
        let t = self.time_s(frame);
        let e = self.exposure_s();
        let mut b = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        let mut grow = |r: [f64; 4]| {
            b[0] = b[0].min(r[0]);
            b[1] = b[1].min(r[1]);
            b[2] = b[2].max(r[2]);
            b[3] = b[3].max(r[3]);
        };
        for ts in [t - 0.5 * e, t, t + 0.5 * e] {
            for (k, m) in self.markers.iter().enumerate() {
                let c = self.marker_at(k, ts);
                let r = m.diameter_px * 0.5 + 1.0;
                grow([c.x - r, c.y - r, c.x + r, c.y + r]);
                if let Some(stem) = self.stem(k, c) {
                    grow(stem.bounds());
                }
            }
            for e in &self.occlusions {
                if let Some(c) = self.occluder(e, frame, self.marker_at(e.marker, ts)) {
                    grow(c.bounds());
                }
            }
        }
        if !b[0].is_finite() {
            return PixelRect::default();
        }
        let x0 = b[0].floor() as i32 - 2;
        let y0 = b[1].floor() as i32 - 2;
        PixelRect::new(
            x0,
            y0,
            (b[2].ceil() as i32 + 3 - x0).max(0),
            (b[3].ceil() as i32 + 3 - y0).max(0),
        )
    }

    fn stem(&self, k: usize, tip: Point2<f64>) -> Option<Capsule> {
        let m = &self.markers[k];
        m.stem_root.map(|root| Capsule {
            a: root,
            b: tip,
            half_width: (m.diameter_px * 0.18).max(1.0),
        })
    }

    /// Stems, markers and branches in front at time `ts`, with the camera shaken by `shake`.
    fn draw_moving(&self, layer: &mut Canvas, frame: usize, ts: f64, shake: Vector2<f64>) {
        let centres: Vec<Point2<f64>> = (0..self.markers.len())
            .map(|k| self.marker_at(k, ts))
            .collect();
        let stem_rgb = if self.config.background == Background::BarkSky {
            BARK_RGB
        } else {
            STEM_RGB
        };
        for (k, c) in centres.iter().enumerate() {
            if let Some(stem) = self.stem(k, *c) {
                // The root is fixed to the scene, so it moves with the camera.
                let stem = Capsule {
                    a: stem.a + shake,
                    ..stem
                };
                layer.capsule(&stem, stem_rgb);
            }
        }
        for (m, c) in self.markers.iter().zip(&centres) {
            layer.disc(*c, m.diameter_px * 0.5, m.rgb);
        }
        for twig in &self.twigs {
            layer.capsule(&twig.shifted(shake), BARK_RGB);
        }
        for e in &self.occlusions {
            if let Some(c) = self.occluder(e, frame, centres[e.marker]) {
                layer.capsule(&c, BARK_RGB);
            }
        }
    }
}

/// Flicker, noise, holes and JPEG, per frame.
fn finish(canvas: &Canvas, cfg: &StressConfig, frame: usize, rng: &mut Rng) -> Result<RgbImage> {
    let t = frame as f64 / cfg.fps_hz;
    let (gain, cast) = if cfg.flicker > 0.0 {
        let g = 1.0
            + cfg.flicker
                * (0.6 * (2.0 * std::f64::consts::PI * 3.7 * t).sin()
                    + 0.4 * rng.range([-1.0, 1.0]));
        let cast = [
            1.0 + 0.08 * rng.range([-1.0, 1.0]),
            1.0,
            1.0 + 0.08 * rng.range([-1.0, 1.0]),
        ];
        (g, cast)
    } else {
        (1.0, [1.0; 3])
    };
    let mut img = RgbImage::new(cfg.width, cfg.height);
    for (p, src) in img.pixels_mut().zip(canvas.data.chunks_exact(3)) {
        if cfg.hole_fraction > 0.0 && rng.uniform() < cfg.hole_fraction {
            *p = Rgb([0, 0, 0]);
            continue;
        }
        for c in 0..3 {
            let mut v = f64::from(src[c]) * gain * cast[c];
            if cfg.noise_sigma > 0.0 {
                v += cfg.noise_sigma * rng.normal();
            }
            p.0[c] = v.round().clamp(0.0, 255.0) as u8;
        }
    }
    if let Some([q0, q1]) = cfg.jpeg_quality {
        let q = rng.int(usize::from(q0), usize::from(q1)) as u8;
        let mut bytes = Vec::new();
        JpegEncoder::new_with_quality(&mut bytes, q)
            .encode_image(&img)
            .map_err(|e| TrackError::param("jpeg_quality", format!("encoding failed: {e}")))?;
        img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Jpeg)
            .map_err(|e| TrackError::param("jpeg_quality", format!("decoding failed: {e}")))?
            .to_rgb8();
    }
    Ok(img)
}

/// Place the markers: paths apart from each other, inside the frame (but for re-entries),
/// crossing pairs on purpose.
#[allow(clippy::too_many_lines)] // longer than 100 lines; to be split by concept (issue 21)
fn place_markers(cfg: &StressConfig, rng: &mut Rng) -> Vec<StressMarker> {
    let (w, h) = (f64::from(cfg.width), f64::from(cfg.height));
    let mut out: Vec<StressMarker> = Vec::with_capacity(cfg.markers);
    let draw = |rng: &mut Rng, k: usize| {
        let d = rng.range(cfg.marker_diameter_px);
        let a = rng.range([-0.6, 0.6])
            + if rng.uniform() < 0.5 {
                0.0
            } else {
                std::f64::consts::PI
            };
        let jitter = |rng: &mut Rng, c: u8, spread: f64| {
            (f64::from(c) + rng.range([-spread, spread])).clamp(0.0, 255.0) as u8
        };
        let rgb = [
            jitter(rng, MARKER_RGB[0], 15.0),
            jitter(rng, MARKER_RGB[1], 10.0),
            jitter(rng, MARKER_RGB[2], 10.0),
        ];
        StressMarker {
            id: marker_id(k),
            rest: Point2::origin(),
            direction: Vector2::new(a.cos(), a.sin()),
            amplitude_px: rng.range(cfg.amplitude_px),
            across: rng.range([0.0, 0.25]),
            frequency_hz: rng.range(cfg.frequency_hz),
            damping_ratio: rng.range(cfg.damping_ratio),
            diameter_px: d,
            rgb,
            stem_root: None,
        }
    };
    let path = |m: &StressMarker| {
        let reach = m.amplitude_px * (1.0 + m.across);
        [m.rest - m.direction * reach, m.rest + m.direction * reach]
    };
    for k in 0..cfg.markers {
        let mut m = draw(rng, k);
        let pair_second = k % 2 == 1 && k < 2 * cfg.crossing_pairs;
        let reentry = k >= 2 * cfg.crossing_pairs && k < 2 * cfg.crossing_pairs + cfg.reentries;
        if pair_second {
            // On the first of the pair's path, swinging across it with a smaller amplitude.
            let first = &out[k - 1];
            m.rest = first.rest
                + first.direction * (first.amplitude_px * rng.range([0.35, 0.65]))
                + Vector2::new(-first.direction.y, first.direction.x)
                    * (first.diameter_px * rng.range([-0.2, 0.2]));
            m.direction = Vector2::new(-first.direction.y, first.direction.x);
            m.amplitude_px = first.amplitude_px * rng.range([0.3, 0.5]);
            m.diameter_px = first.diameter_px * rng.range([0.9, 1.1]);
            m.rgb = first.rgb;
            m.frequency_hz = first.frequency_hz * rng.range([0.6, 0.8]);
        } else {
            let margin = m.diameter_px + 6.0;
            let mut best: Option<(f64, Point2<f64>, Vector2<f64>)> = None;
            for _ in 0..300 {
                let mut dir = m.direction;
                let rest = if reentry {
                    // Pulled towards the nearest side border, 0.55 amplitudes from it.
                    let right = rng.uniform() < 0.5;
                    dir = Vector2::new(if right { 1.0 } else { -1.0 }, rng.range([-0.2, 0.2]));
                    dir /= dir.norm();
                    let x = if right {
                        w - 0.55 * m.amplitude_px
                    } else {
                        0.55 * m.amplitude_px
                    };
                    Point2::new(x, rng.range([margin + 30.0, h - margin - 30.0]))
                } else {
                    Point2::new(
                        rng.range([margin, w - margin]),
                        rng.range([margin, h - margin]),
                    )
                };
                let probe = StressMarker {
                    rest,
                    direction: dir,
                    ..m.clone()
                };
                let [p0, p1] = path(&probe);
                let inside = |p: Point2<f64>| {
                    p.x > margin && p.y > margin && p.x < w - margin && p.y < h - margin
                };
                if !(reentry || inside(p0) && inside(p1)) {
                    continue;
                }
                let clearance = out
                    .iter()
                    .map(|o| {
                        segment_distance(path(&probe), path(o))
                            - 1.5 * (o.diameter_px + probe.diameter_px)
                    })
                    .fold(f64::INFINITY, f64::min);
                if best.as_ref().is_none_or(|b| clearance > b.0) {
                    best = Some((clearance, rest, dir));
                }
                if clearance > 10.0 {
                    break;
                }
            }
            if let Some((_, rest, dir)) = best {
                m.rest = rest;
                m.direction = dir;
            } else {
                m.rest = Point2::new(w * 0.5, h * 0.5);
            }
        }
        if cfg.stems {
            // Rooted below the marker, off the swing line.
            let len = rng.range([60.0, 140.0]);
            let lean = rng.range([-0.5, 0.5]);
            m.stem_root = Some(m.rest + Vector2::new(lean, 1.0) * len);
        }
        out.push(m);
    }
    out
}

/// The static background of `cfg`, as RGB floats.
fn paint_background(cfg: &StressConfig, rng: &mut Rng) -> Vec<f32> {
    let (w, h) = (cfg.width as usize, cfg.height as usize);
    let mut data = vec![0.0f32; w * h * 3];
    let (fx, fy) = (rng.range([0.015, 0.05]), rng.range([0.015, 0.05]));
    let phase = rng.range([0.0, 6.0]);
    for y in 0..h {
        for x in 0..w {
            let (xf, yf) = (x as f64, y as f64);
            let rgb = match cfg.background {
                Background::Mottled => {
                    let v = ((xf * fx + phase).sin() + (yf * fy).cos()) * 0.5;
                    [110.0 + 25.0 * v, 118.0 + 20.0 * v, 96.0 + 10.0 * v]
                }
                Background::GreyWall => {
                    let v = 6.0 * ((xf * 0.01 + phase).sin() * (yf * 0.013).cos());
                    let speckle = 3.0 * (((x * 7 + y * 13) % 11) as f64 / 10.0 - 0.5);
                    let g = 128.0 + v + speckle;
                    [g, g, g + 2.0]
                }
                Background::BarkSky => {
                    let u = yf / h as f64;
                    let cloud = 12.0 * ((xf * fx + phase).sin() * (yf * fy * 2.0).cos()).max(0.0);
                    [
                        120.0 + 60.0 * u + cloud,
                        165.0 + 40.0 * u + cloud,
                        225.0 + 8.0 * u + cloud * 0.5,
                    ]
                }
            };
            let k = (y * w + x) * 3;
            for c in 0..3 {
                data[k + c] = rgb[c].clamp(0.0, 255.0) as f32;
            }
        }
    }
    if cfg.background == Background::BarkSky {
        let mut canvas = Canvas::full(cfg.width, cfg.height, data);
        let (wf, hf) = (f64::from(cfg.width), f64::from(cfg.height));
        // A trunk with bark streaks, and a few branches off it.
        let x = rng.range([0.2, 0.8]) * wf;
        let trunk = Capsule {
            a: Point2::new(x + rng.range([-30.0, 30.0]), hf + 10.0),
            b: Point2::new(x + rng.range([-40.0, 40.0]), -10.0),
            half_width: rng.range([18.0, 30.0]),
        };
        canvas.capsule(&trunk, BARK_RGB);
        for _ in 0..4 {
            let from = trunk.a + (trunk.b - trunk.a) * rng.range([0.2, 0.9]);
            let a = rng.range([-2.6, -0.5]);
            let to = from + Vector2::new(a.cos() * rng.sign(), a.sin()) * rng.range([80.0, 220.0]);
            canvas.capsule(
                &Capsule {
                    a: from,
                    b: to,
                    half_width: rng.range([3.0, 7.0]),
                },
                [104, 80, 58],
            );
        }
        // Bark texture: darker vertical streaks inside the trunk.
        let mut data = canvas.data;
        for yy in 0..h {
            for xx in 0..w {
                let p = Point2::new(xx as f64, yy as f64);
                if trunk.covers(p) {
                    let streak = 14.0 * ((xx as f64 * 0.9).sin() * (yy as f64 * 0.05).cos());
                    let k = (yy * w + xx) * 3;
                    for c in 0..3 {
                        data[k + c] = (f64::from(data[k + c]) + streak).clamp(0.0, 255.0) as f32;
                    }
                }
            }
        }
        return data;
    }
    data
}

/// An RGB float image of the pixels of `rect` (image coordinates), with anti-aliased drawing
/// (4x4 sub-pixel coverage).
#[derive(Debug, Clone)]
struct Canvas {
    rect: PixelRect,
    data: Vec<f32>,
}

impl Canvas {
    /// The whole `width` x `height` image, from row-major RGB floats.
    fn full(width: u32, height: u32, data: Vec<f32>) -> Self {
        Self {
            rect: PixelRect::image(width, height),
            data,
        }
    }

    /// The pixels of `rect` of the `image_width`-wide image `src`, moved by `d` (rounded to
    /// whole pixels; the image's edges repeat).
    fn from_shifted(src: &Canvas, rect: PixelRect, d: Vector2<f64>) -> Self {
        let (w, h) = (i64::from(src.rect.width), i64::from(src.rect.height));
        let (dx, dy) = (d.x.round() as i64, d.y.round() as i64);
        let mut data = Vec::with_capacity(rect.area() as usize * 3);
        for y in i64::from(rect.y)..rect.bottom() {
            let sy = (y - dy).clamp(0, h - 1);
            for x in i64::from(rect.x)..rect.right() {
                let sx = (x - dx).clamp(0, w - 1);
                let s = ((sy * w + sx) * 3) as usize;
                data.extend_from_slice(&src.data[s..s + 3]);
            }
        }
        Self { rect, data }
    }

    fn index(&self, x: i32, y: i32) -> usize {
        ((y - self.rect.y) as usize * self.rect.width as usize + (x - self.rect.x) as usize) * 3
    }

    /// Blend `rgb` over the pixels where `inside` holds, by coverage.
    fn shape(&mut self, bounds: [f64; 4], rgb: [u8; 3], inside: impl Fn(Point2<f64>) -> bool) {
        if !bounds.iter().all(|v| v.is_finite()) {
            return;
        }
        let b = PixelRect::new(
            bounds[0].floor() as i32 - 1,
            bounds[1].floor() as i32 - 1,
            (bounds[2] - bounds[0]).ceil() as i32 + 3,
            (bounds[3] - bounds[1]).ceil() as i32 + 3,
        )
        .intersect(&self.rect);
        for y in b.y..b.bottom() as i32 {
            for x in b.x..b.right() as i32 {
                let mut n = 0;
                for sy in 0..4 {
                    for sx in 0..4 {
                        let p = Point2::new(
                            f64::from(x) - 0.375 + 0.25 * f64::from(sx),
                            f64::from(y) - 0.375 + 0.25 * f64::from(sy),
                        );
                        if inside(p) {
                            n += 1;
                        }
                    }
                }
                if n == 0 {
                    continue;
                }
                let a = n as f32 / 16.0;
                let k = self.index(x, y);
                for (d, &v) in self.data[k..k + 3].iter_mut().zip(&rgb) {
                    *d += a * (f32::from(v) - *d);
                }
            }
        }
    }

    fn disc(&mut self, c: Point2<f64>, r: f64, rgb: [u8; 3]) {
        self.shape([c.x - r, c.y - r, c.x + r, c.y + r], rgb, |p| {
            (p - c).norm_squared() <= r * r
        });
    }

    fn capsule(&mut self, c: &Capsule, rgb: [u8; 3]) {
        self.shape(c.bounds(), rgb, |p| c.covers(p));
    }

    /// Write `values * scale` (the pixels of `rect`, which lies in this canvas) into it.
    fn set_rect(&mut self, rect: PixelRect, values: &[f32], scale: f32) {
        let rw = rect.width as usize * 3;
        for (j, y) in (rect.y..rect.bottom() as i32).enumerate() {
            let start = self.index(rect.x, y);
            for (d, a) in self.data[start..start + rw]
                .iter_mut()
                .zip(&values[j * rw..(j + 1) * rw])
            {
                *d = a * scale;
            }
        }
    }
}

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

fn status_index(s: TrackStatus) -> usize {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hsv::rgb_to_hsv;

    #[test]
    fn frames_are_reproducible_and_truth_matches_the_motion() {
        let cfg = StressConfig::condition(Condition::Baseline, 3);
        let scene = StressScene::new(&cfg).expect("valid");
        assert_eq!(scene.frames(), 120);
        let a = scene.frame(40).expect("in range");
        let b = scene.frame(40).expect("in range");
        assert_eq!(a, b);
        assert!(scene.frame(120).is_err());
        // At rest before the pull, every marker is where its window is.
        for (c, init) in scene.truth(0).iter().zip(scene.inits()) {
            assert!((c - init.window.center()).norm() < 2.5);
        }
        assert!(scene.visibility(0).iter().all(|&v| v >= FULLY_VISIBLE));
    }

    /// The release condition matches the clip it stands for: a streak of about 2.5 marker
    /// widths, about a third less saturation, about 2.5 widths per frame at the fastest.
    #[test]
    fn release_at_240_fps_blurs_and_pales_as_the_real_clip() {
        let cfg = StressConfig::condition(Condition::Release240, 1);
        let scene = StressScene::new(&cfg).expect("valid");
        let d = scene.markers()[0].diameter_px;
        let (mut fastest, mut at) = (0.0, 0);
        for f in 1..scene.frames() {
            let step = (scene.truth(f)[0] - scene.truth(f - 1)[0]).norm();
            if step > fastest {
                (fastest, at) = (step, f);
            }
        }
        assert!(
            (2.2..=2.8).contains(&(fastest / d)),
            "{fastest} px / {d} px"
        );
        let max_sat = |img: &RgbImage, c: Point2<f64>| {
            let mut best = 0u8;
            for y in (c.y - 20.0) as u32..(c.y + 20.0) as u32 {
                for x in (c.x - 40.0) as u32..(c.x + 40.0) as u32 {
                    if let Some(p) = img.get_pixel_checked(x, y) {
                        let hsv = rgb_to_hsv(p.0);
                        if hsv[0] < 10 || hsv[0] > 170 {
                            best = best.max(hsv[1]);
                        }
                    }
                }
            }
            best
        };
        let still = max_sat(&scene.frame(0).expect("frame"), scene.truth(0)[0]);
        let moving = max_sat(&scene.frame(at).expect("frame"), scene.truth(at)[0]);
        let loss = 1.0 - f64::from(moving) / f64::from(still);
        assert!(
            (0.2..=0.45).contains(&loss),
            "saturation {still} -> {moving}"
        );
    }

    #[test]
    fn jumps_are_two_to_five_windows_and_reentries_leave_the_frame() {
        let scene = StressScene::new(&StressConfig::condition(Condition::Jumps, 2)).expect("valid");
        let mut widest = 0.0f64;
        for k in 0..scene.markers().len() {
            let w = f64::from(scene.inits()[k].window.width);
            for f in 1..scene.frames() {
                let step = (scene.truth(f)[k] - scene.truth(f - 1)[k]).norm();
                widest = widest.max(step / w);
            }
        }
        assert!((2.0..=5.5).contains(&widest), "{widest}");
        let scene =
            StressScene::new(&StressConfig::condition(Condition::Reentry, 2)).expect("valid");
        let hidden = (0..scene.frames())
            .filter(|&f| scene.visibility(f).contains(&0.0))
            .count();
        assert!(hidden > 5, "{hidden}");
    }

    #[test]
    fn occlusions_hide_markers_for_their_frames() {
        let scene =
            StressScene::new(&StressConfig::condition(Condition::Occlusion, 4)).expect("valid");
        for e in &scene.occlusions {
            for f in e.start..e.start + e.frames {
                assert_eq!(scene.visibility(f)[e.marker], 0.0, "{e:?} frame {f}");
            }
            let before = scene.visibility(e.start - 1)[e.marker];
            assert!(before > 0.0 && before < 1.0, "{before}");
        }
    }

    #[test]
    fn bad_configs_are_errors() {
        let good = StressConfig::condition(Condition::Baseline, 0);
        for bad in [
            StressConfig {
                width: 10,
                ..good.clone()
            },
            StressConfig {
                width: 100_000,
                ..good.clone()
            },
            StressConfig {
                fps_hz: 0.0,
                ..good.clone()
            },
            StressConfig {
                duration_s: 1e12,
                ..good.clone()
            },
            StressConfig {
                markers: 0,
                ..good.clone()
            },
            StressConfig {
                markers: 1000,
                ..good.clone()
            },
            StressConfig {
                amplitude_px: [5.0, 1.0],
                ..good.clone()
            },
            StressConfig {
                damping_ratio: [0.0, 1.5],
                ..good.clone()
            },
            StressConfig {
                release_s: 0.1,
                ..good.clone()
            },
            StressConfig {
                flicker: f64::NAN,
                ..good.clone()
            },
            StressConfig {
                jpeg_quality: Some([0, 50]),
                ..good.clone()
            },
            StressConfig {
                crossing_pairs: 5,
                ..good.clone()
            },
            StressConfig {
                occlusion_frames: [0, 3],
                ..good.clone()
            },
        ] {
            assert!(StressScene::new(&bad).is_err(), "{bad:?}");
        }
        for c in Condition::ALL {
            assert_eq!(Condition::from_name(c.name()), Some(c));
            StressConfig::condition(c, 0)
                .validate()
                .expect("presets are valid");
        }
    }
}
