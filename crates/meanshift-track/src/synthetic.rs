//! Seeded synthetic tracking sequences with ground truth, like the paper's captures seen on a
//! 512x424 projection image: red markers of 7–13 px on branches that are pulled and released
//! (damped swings of 10–40 px at 1–3 Hz), with motion blur, holes where no point projected,
//! reddish distractors, sensor noise and twigs that briefly cover markers. For tests, benches
//! and checking a tracker configuration; `kinect-io`'s `synth` renders the full 3D version.

use image::{Rgb, RgbImage};
use nalgebra::{Point2, Vector2};

use crate::error::{Result, TrackError};
use crate::rect::PixelRect;
use crate::rng::Rng;
use crate::tracker::{MarkerInit, Track};

/// The paper's markers: saturated red (as `kinect-io`'s `synth::MARKER_RGB`).
pub const MARKER_RGB: [u8; 3] = [215, 25, 30];
/// Reddish distractors (brick-red leaves, red bark, a maroon object): hues within a bin or two
/// of the markers', less saturated or darker.
const DISTRACTOR_RGB: [[u8; 3]; 3] = [[170, 62, 48], [190, 90, 70], [150, 40, 60]];
/// Distractors lie this far from a marker's path (pixels): near enough for a search to see
/// them, not on the path itself.
const DISTRACTOR_OFFSET_PX: [f64; 2] = [16.0, 36.0];
/// Bark colour of the occluding twigs.
const TWIG_RGB: [u8; 3] = [96, 74, 52];
/// Sub-samples per frame for motion blur.
const BLUR_SAMPLES: usize = 6;

/// What to generate. [`SequenceConfig::paper_like`] matches the description of the
/// paper's captures.
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceConfig {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Number of frames.
    pub frames: usize,
    /// Frame rate in hertz (Kinect V2: 30).
    pub fps_hz: f64,
    /// Number of markers.
    pub markers: usize,
    /// Marker diameters are drawn from this range (pixels).
    pub marker_diameter_px: [f64; 2],
    /// Swing amplitudes are drawn from this range (pixels).
    pub amplitude_px: [f64; 2],
    /// Natural frequencies are drawn from this range (hertz).
    pub frequency_hz: [f64; 2],
    /// Damping ratios are drawn from this range.
    pub damping_ratio: [f64; 2],
    /// The pull starts at this frame and ends (the release) at `release_frame`.
    pub pull_start_frame: usize,
    /// Frame of the release.
    pub release_frame: usize,
    /// Exposure as a fraction of the frame period (motion blur; 0 = none).
    pub exposure_fraction: f64,
    /// Fraction of pixels that are holes (black, no point projected).
    pub hole_fraction: f64,
    /// Number of static reddish distractor blobs.
    pub distractors: usize,
    /// Number of twigs crossing marker paths (brief partial occlusions).
    pub occluders: usize,
    /// Standard deviation of the colour noise per channel (8-bit levels).
    pub noise_sigma: f64,
    /// Random seed.
    pub seed: u64,
}

impl SequenceConfig {
    /// 512x424 frames at 30 Hz, 5 s, 8 markers of 7–13 px, swings of 10–40 px at 1–3 Hz
    /// (damping ratio 0.02–0.08) released at 1 s after a 0.5 s pull, exposure half the frame
    /// period, 3 % holes, 4 distractors, 3 twigs, noise 3 levels.
    pub fn paper_like(seed: u64) -> Self {
        Self {
            width: 512,
            height: 424,
            frames: 150,
            fps_hz: 30.0,
            markers: 8,
            marker_diameter_px: [7.0, 13.0],
            amplitude_px: [10.0, 40.0],
            frequency_hz: [1.0, 3.0],
            damping_ratio: [0.02, 0.08],
            pull_start_frame: 15,
            release_frame: 30,
            exposure_fraction: 0.5,
            hole_fraction: 0.03,
            distractors: 4,
            occluders: 3,
            noise_sigma: 3.0,
            seed,
        }
    }

    /// Check the sizes and ranges.
    ///
    /// # Errors
    /// [`TrackError::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<()> {
        if self.width < 64 || self.height < 64 {
            return Err(TrackError::param("size", "frames must be at least 64x64"));
        }
        if self.width > crate::hsv::MAX_IMAGE_SIDE_PX || self.height > crate::hsv::MAX_IMAGE_SIDE_PX
        {
            return Err(TrackError::param(
                "size",
                format!(
                    "{}x{} px; at most {} px a side",
                    self.width,
                    self.height,
                    crate::hsv::MAX_IMAGE_SIDE_PX
                ),
            ));
        }
        if self.frames == 0 || self.markers == 0 {
            return Err(TrackError::param("frames/markers", "must be at least 1"));
        }
        // Every frame is kept: the sequence must fit in memory, checked before rendering.
        let bytes = self.frames as f64 * f64::from(self.width) * f64::from(self.height) * 3.0;
        if bytes > MAX_SEQUENCE_BYTES {
            return Err(TrackError::param(
                "frames",
                format!(
                    "{} frames of {}x{} px take {bytes:e} bytes, more than the limit of {MAX_SEQUENCE_BYTES:e}",
                    self.frames, self.width, self.height
                ),
            ));
        }
        if self.markers > 1000 {
            return Err(TrackError::param(
                "markers",
                format!("{}; at most 1000", self.markers),
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
        if self.marker_diameter_px[0] < 2.0 || self.damping_ratio[1] >= 1.0 {
            return Err(TrackError::param(
                "marker_diameter_px/damping_ratio",
                "diameters of at least 2 px and damping ratios below 1",
            ));
        }
        if self.pull_start_frame > self.release_frame {
            return Err(TrackError::param("pull_start_frame", "after release_frame"));
        }
        for (name, v) in [
            ("fps_hz", self.fps_hz),
            ("exposure_fraction", self.exposure_fraction + 1.0),
            ("hole_fraction", self.hole_fraction + 1.0),
            ("noise_sigma", self.noise_sigma + 1.0),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(TrackError::param(name, "must be finite and >= 0 (fps > 0)"));
            }
        }
        if self.exposure_fraction > 1.0 || self.hole_fraction > 0.5 {
            return Err(TrackError::param(
                "exposure_fraction/hole_fraction",
                "at most 1 and 0.5",
            ));
        }
        Ok(())
    }
}

/// One marker's motion: a point that is pulled along `direction` and released.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticMarker {
    /// Name (`A`, `B`, ...).
    pub id: String,
    /// Rest position (pixels).
    pub rest: Point2<f64>,
    /// Unit direction of the swing.
    pub direction: Vector2<f64>,
    /// Pull amplitude (pixels).
    pub amplitude_px: f64,
    /// Natural frequency (hertz).
    pub frequency_hz: f64,
    /// Damping ratio.
    pub damping_ratio: f64,
    /// Diameter (pixels).
    pub diameter_px: f64,
}

/// A generated sequence.
#[derive(Debug, Clone)]
pub struct Sequence {
    /// The frames.
    pub frames: Vec<RgbImage>,
    /// The markers and their motion.
    pub markers: Vec<SyntheticMarker>,
    /// True centre of every marker (outer: frame; inner: marker, in `markers` order), taken
    /// at the middle of the exposure.
    pub truth: Vec<Vec<Point2<f64>>>,
    /// The windows a user would draw on frame 0 (square, a little larger than the marker).
    pub inits: Vec<MarkerInit>,
}

impl SyntheticMarker {
    /// Centre at time `t_s` (seconds from the start), for a pull from `pull_s` to `release_s`.
    pub fn position(&self, t_s: f64, pull_s: f64, release_s: f64) -> Point2<f64> {
        let s = if t_s <= pull_s {
            0.0
        } else if t_s <= release_s {
            let u = (t_s - pull_s) / (release_s - pull_s).max(1e-9);
            // Smooth pull (the branch is drawn aside by hand).
            self.amplitude_px * (u * u * (3.0 - 2.0 * u))
        } else {
            let t = t_s - release_s;
            let w = 2.0 * std::f64::consts::PI * self.frequency_hz;
            let z = self.damping_ratio;
            let wd = w * (1.0 - z * z).sqrt();
            // Free vibration from rest at the amplitude: x(0) = A, x'(0) = 0.
            self.amplitude_px * (-z * w * t).exp() * ((wd * t).cos() + z * w / wd * (wd * t).sin())
        };
        self.rest + self.direction * s
    }
}

/// Most memory a generated sequence may take, bytes (2 GiB): its frames are all kept.
pub const MAX_SEQUENCE_BYTES: f64 = 2.0 * 1024.0 * 1024.0 * 1024.0;

/// Generate a sequence.
///
/// # Errors
/// As [`SequenceConfig::validate`].
pub fn generate(config: &SequenceConfig) -> Result<Sequence> {
    config.validate()?;
    let mut rng = Rng::new(config.seed ^ 0x6D61_726B_6572); // "marker"
    let markers = grid_markers(config, &mut rng);
    let (background, twigs) = static_scene(config, &mut rng, &markers);
    let inits = markers
        .iter()
        .map(|m| {
            let size = (m.diameter_px + 4.0).round() as i32;
            MarkerInit {
                id: m.id.clone(),
                window: PixelRect::centered_at(m.rest, size, size),
            }
        })
        .collect();
    let mut frames = Vec::with_capacity(config.frames);
    let mut truth = Vec::with_capacity(config.frames);
    for f in 0..config.frames {
        let (img, centres) = render_frame(config, &mut rng, &background, &markers, &twigs, f);
        frames.push(img);
        truth.push(centres);
    }
    Ok(Sequence {
        frames,
        markers,
        truth,
        inits,
    })
}

/// The markers on a loose grid, so that their paths rarely cross.
fn grid_markers(config: &SequenceConfig, rng: &mut Rng) -> Vec<SyntheticMarker> {
    let (w, h) = (f64::from(config.width), f64::from(config.height));
    let margin = config.amplitude_px[1] + config.marker_diameter_px[1] + 8.0;
    let cols = (config.markers as f64).sqrt().ceil() as usize;
    let rows = config.markers.div_ceil(cols);
    let mut markers = Vec::with_capacity(config.markers);
    for k in 0..config.markers {
        let (c, r) = (k % cols, k / cols);
        let cell_w = (w - 2.0 * margin) / cols as f64;
        let cell_h = (h - 2.0 * margin) / rows as f64;
        let rest = Point2::new(
            margin + cell_w * (c as f64 + 0.3 + 0.4 * rng.uniform()),
            margin + cell_h * (r as f64 + 0.3 + 0.4 * rng.uniform()),
        );
        let angle = (rng.uniform() - 0.5) * 0.8; // mostly horizontal swings
        markers.push(SyntheticMarker {
            id: marker_id(k),
            rest,
            direction: Vector2::new(angle.cos(), angle.sin()),
            amplitude_px: rng.range(config.amplitude_px),
            frequency_hz: rng.range(config.frequency_hz),
            damping_ratio: rng.range(config.damping_ratio),
            diameter_px: rng.range(config.marker_diameter_px),
        });
    }
    markers
}

/// A twig in front of the markers: column x, rows y0..y1 and half width, pixels.
type Twig = (f64, f64, f64, f64);

/// The static scene: a mottled background with distractors painted in, and the twigs.
fn static_scene(
    config: &SequenceConfig,
    rng: &mut Rng,
    markers: &[SyntheticMarker],
) -> (RgbImage, Vec<Twig>) {
    let mut background = RgbImage::new(config.width, config.height);
    let (fx, fy) = (rng.range([0.02, 0.05]), rng.range([0.02, 0.05]));
    for (x, y, p) in background.enumerate_pixels_mut() {
        let v = ((f64::from(x) * fx).sin() + (f64::from(y) * fy).cos()) * 0.5;
        let base = [110.0 + 25.0 * v, 118.0 + 20.0 * v, 96.0 + 10.0 * v];
        *p = Rgb(base.map(|c| c.clamp(0.0, 255.0) as u8));
    }
    let mut distractors = Vec::new();
    for k in 0..config.distractors {
        // Near a marker's path, so the search sees it.
        let m = &markers[k % markers.len()];
        let along = m.direction * (m.amplitude_px * rng.range([-1.4, 1.4]));
        let side = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
        let across =
            Vector2::new(-m.direction.y, m.direction.x) * (side * rng.range(DISTRACTOR_OFFSET_PX));
        distractors.push((
            m.rest + along + across,
            rng.range([3.0, 7.0]),
            DISTRACTOR_RGB[k % DISTRACTOR_RGB.len()],
        ));
    }
    for &(c, r, rgb) in &distractors {
        paint_disc(&mut background, c, r, rgb, 1.0);
    }
    // Twigs cross the paths of the widest swings, well away from the rest positions, so they
    // cover a marker only briefly (twice per swing at most).
    let mut by_amplitude: Vec<usize> = (0..markers.len()).collect();
    by_amplitude.sort_by(|&a, &b| markers[b].amplitude_px.total_cmp(&markers[a].amplitude_px));
    let mut twigs = Vec::new();
    for &k in by_amplitude.iter().take(config.occluders) {
        let m = &markers[k];
        let x = m.rest.x + m.direction.x * m.amplitude_px * rng.range([0.55, 0.8]);
        let half = rng.range([1.5, 3.0]);
        if (x - m.rest.x).abs() > m.diameter_px + half {
            twigs.push((x, m.rest.y - 25.0, m.rest.y + 25.0, half));
        }
    }
    (background, twigs)
}

/// Frame `f`: the markers (motion-blurred over the exposure), the twigs in front of them,
/// sensor noise and holes; and the markers' true centres.
fn render_frame(
    config: &SequenceConfig,
    rng: &mut Rng,
    background: &RgbImage,
    markers: &[SyntheticMarker],
    twigs: &[Twig],
    f: usize,
) -> (RgbImage, Vec<Point2<f64>>) {
    let pull_s = config.pull_start_frame as f64 / config.fps_hz;
    let release_s = config.release_frame as f64 / config.fps_hz;
    let exposure_s = config.exposure_fraction / config.fps_hz;
    let t = f as f64 / config.fps_hz;
    let mut img = background.clone();
    let mut centres = Vec::with_capacity(markers.len());
    for m in markers {
        centres.push(m.position(t, pull_s, release_s));
        let samples = if exposure_s > 0.0 { BLUR_SAMPLES } else { 1 };
        for s in 0..samples {
            let ts = t + exposure_s * ((s as f64 + 0.5) / samples as f64 - 0.5);
            let c = m.position(ts, pull_s, release_s);
            paint_disc(
                &mut img,
                c,
                m.diameter_px * 0.5,
                MARKER_RGB,
                1.0 / samples as f64,
            );
        }
    }
    // Twigs in front of the markers.
    for &(x, y0, y1, half) in twigs {
        let r = PixelRect::new(
            (x - half).round() as i32,
            y0.round() as i32,
            (2.0 * half).round() as i32,
            (y1 - y0).round() as i32,
        )
        .intersect(&PixelRect::image(config.width, config.height));
        for yy in r.y..r.bottom() as i32 {
            for xx in r.x..r.right() as i32 {
                img.put_pixel(xx as u32, yy as u32, Rgb(TWIG_RGB));
            }
        }
    }
    // Noise and holes.
    for p in img.pixels_mut() {
        if rng.uniform() < config.hole_fraction {
            *p = Rgb([0, 0, 0]);
            continue;
        }
        if config.noise_sigma > 0.0 {
            for c in &mut p.0 {
                *c = (f64::from(*c) + config.noise_sigma * rng.normal())
                    .round()
                    .clamp(0.0, 255.0) as u8;
            }
        }
    }
    (img, centres)
}

/// Blend a disc of colour `rgb` with opacity `alpha` (anti-aliased edge, 4x4 sub-pixels).
fn paint_disc(img: &mut RgbImage, c: Point2<f64>, radius: f64, rgb: [u8; 3], alpha: f64) {
    let r = PixelRect::new(
        (c.x - radius - 1.0).floor() as i32,
        (c.y - radius - 1.0).floor() as i32,
        (2.0 * radius + 3.0).ceil() as i32,
        (2.0 * radius + 3.0).ceil() as i32,
    )
    .intersect(&PixelRect::image(img.width(), img.height()));
    for y in r.y..r.bottom() as i32 {
        for x in r.x..r.right() as i32 {
            let mut inside = 0;
            for sy in 0..4 {
                for sx in 0..4 {
                    let px = f64::from(x) - 0.375 + 0.25 * f64::from(sx);
                    let py = f64::from(y) - 0.375 + 0.25 * f64::from(sy);
                    if (px - c.x).powi(2) + (py - c.y).powi(2) <= radius * radius {
                        inside += 1;
                    }
                }
            }
            if inside == 0 {
                continue;
            }
            let a = alpha * f64::from(inside) / 16.0;
            let p = img.get_pixel_mut(x as u32, y as u32);
            for (ch, &t) in p.0.iter_mut().zip(&rgb) {
                *ch = (f64::from(*ch) * (1.0 - a) + f64::from(t) * a).round() as u8;
            }
        }
    }
}

fn marker_id(k: usize) -> String {
    let letters = b"ABCDEFGHIJKLMNOPQRSTUVWXYZ";
    letters
        .get(k)
        .map_or_else(|| format!("M{k}"), |&c| char::from(c).to_string())
}

/// How well tracks follow the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Score {
    /// Marker-frames scored (markers × frames).
    pub marker_frames: usize,
    /// Marker-frames whose centre is within the tolerance of the truth.
    pub within_tolerance: usize,
    /// Marker-frames whose centre is within the tolerance of another marker's truth (an
    /// identity swap).
    pub identity_swaps: usize,
    /// Marker-frames reported lost.
    pub lost: usize,
    /// Mean error of the centres within tolerance (pixels).
    pub mean_error_px: f64,
    /// Largest error of any reported centre (pixels).
    pub max_error_px: f64,
}

impl Score {
    /// Fraction of marker-frames within the tolerance.
    pub fn fraction_within(&self) -> f64 {
        if self.marker_frames == 0 {
            0.0
        } else {
            self.within_tolerance as f64 / self.marker_frames as f64
        }
    }
}

/// Score `tracks` against `truth` (outer: frame, inner: marker, in the tracks' order).
///
/// # Errors
/// [`TrackError::InvalidParameter`] when the numbers of markers or frames differ or the
/// tolerance is not positive.
pub fn score(tracks: &[Track], truth: &[Vec<Point2<f64>>], tolerance_px: f64) -> Result<Score> {
    if !(tolerance_px.is_finite() && tolerance_px > 0.0) {
        return Err(TrackError::param("tolerance_px", "must be positive"));
    }
    let mut s = Score {
        marker_frames: 0,
        within_tolerance: 0,
        identity_swaps: 0,
        lost: 0,
        mean_error_px: 0.0,
        max_error_px: 0.0,
    };
    let mut sum = 0.0;
    for (i, track) in tracks.iter().enumerate() {
        if track.observations.len() != truth.len() {
            return Err(TrackError::param(
                "tracks",
                format!(
                    "marker {} has {} frames, the truth {}",
                    track.id,
                    track.observations.len(),
                    truth.len()
                ),
            ));
        }
        for (obs, frame_truth) in track.observations.iter().zip(truth) {
            let Some(own) = frame_truth.get(i) else {
                return Err(TrackError::param("truth", "fewer markers than tracks"));
            };
            s.marker_frames += 1;
            let Some(c) = obs.center else {
                s.lost += 1;
                continue;
            };
            let e = (c - own).norm();
            s.max_error_px = s.max_error_px.max(e);
            if e <= tolerance_px {
                s.within_tolerance += 1;
                sum += e;
            } else if frame_truth
                .iter()
                .enumerate()
                .any(|(j, t)| j != i && (c - t).norm() <= tolerance_px)
            {
                s.identity_swaps += 1;
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
