//! A stress scene: its markers' paths, occlusions and static objects, and the frames and
//! truth it renders on demand.

use super::*;

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
pub(super) struct OcclusionEvent {
    pub(super) marker: usize,
    /// First fully covered frame.
    pub(super) start: usize,
    /// Fully covered frames.
    pub(super) frames: usize,
    /// Direction of the branch.
    pub(super) direction: Vector2<f64>,
    pub(super) half_width_px: f64,
    pub(super) half_length_px: f64,
}

/// A thick segment with round ends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Capsule {
    pub(super) a: Point2<f64>,
    pub(super) b: Point2<f64>,
    pub(super) half_width: f64,
}

impl Capsule {
    pub(super) fn distance(&self, p: Point2<f64>) -> f64 {
        let ab = self.b - self.a;
        let len2 = ab.norm_squared();
        let u = if len2 > 0.0 {
            ((p - self.a).dot(&ab) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (p - (self.a + ab * u)).norm()
    }

    pub(super) fn covers(&self, p: Point2<f64>) -> bool {
        self.distance(p) <= self.half_width
    }

    pub(super) fn bounds(&self) -> [f64; 4] {
        let r = self.half_width;
        [
            self.a.x.min(self.b.x) - r,
            self.a.y.min(self.b.y) - r,
            self.a.x.max(self.b.x) + r,
            self.a.y.max(self.b.y) + r,
        ]
    }

    pub(super) fn shifted(&self, d: Vector2<f64>) -> Self {
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
    pub(super) config: StressConfig,
    pub(super) markers: Vec<StressMarker>,
    /// The static scene under the markers (with distractors and look-alikes).
    pub(super) back: Vec<f32>,
    /// Static twigs in front of the markers.
    pub(super) twigs: Vec<Capsule>,
    pub(super) occlusions: Vec<OcclusionEvent>,
    pub(super) inits: Vec<MarkerInit>,
    pub(super) frames: usize,
}

/// Points of a unit disc at which visibility is sampled (centre, and rings at 1/3, 2/3 and
/// 0.97 of the radius).
pub(super) fn disc_samples() -> Vec<Vector2<f64>> {
    let mut out = vec![Vector2::zeros()];
    for (r, n) in [(1.0 / 3.0, 8), (2.0 / 3.0, 16), (0.97, 24)] {
        for k in 0..n {
            let a = 2.0 * std::f64::consts::PI * f64::from(k) / f64::from(n);
            out.push(Vector2::new(r * a.cos(), r * a.sin()));
        }
    }
    out
}

pub(super) fn marker_id(k: usize) -> String {
    b"ABCDEFGHIJKLMNOPQRSTUVWXYZ"
        .get(k)
        .map_or_else(|| format!("M{k}"), |&c| char::from(c).to_string())
}

/// Distance between segments `p0 p1` and `q0 q1` (sampled; enough for placement).
pub(super) fn segment_distance(p: [Point2<f64>; 2], q: [Point2<f64>; 2]) -> f64 {
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

    pub(super) fn time_s(&self, frame: usize) -> f64 {
        frame as f64 / self.config.fps_hz
    }

    pub(super) fn exposure_s(&self) -> f64 {
        self.config.exposure_fraction / self.config.fps_hz
    }

    /// Whole-frame camera shake at `t_s` (pixels).
    pub(super) fn shake(&self, t_s: f64) -> Vector2<f64> {
        let t = t_s - self.config.release_s;
        if self.config.shake_px <= 0.0 || t <= 0.0 {
            return Vector2::zeros();
        }
        let a = self.config.shake_px * (-t / SHAKE_DECAY_S).exp();
        let p = 2.0 * std::f64::consts::PI * SHAKE_HZ * t;
        Vector2::new(a * p.sin(), 0.6 * a * (p * 1.3 + 0.5).sin())
    }

    pub(super) fn marker_at(&self, k: usize, t_s: f64) -> Point2<f64> {
        self.markers[k].position(t_s, self.config.pull_start_s, self.config.release_s)
            + self.shake(t_s)
    }

    /// True centre of every marker in `frame`, in marker order: the centre of what the
    /// exposure drew, the mean of its centres at the exposure's sub-samples (those
    /// [`StressScene::frame`] renders). For a marker moving evenly that is its centre at the
    /// middle of the exposure; where the motion changes within the exposure (a release, the
    /// first frame of a camera shake, the turn of a swing) it is the streak's centre, which
    /// the middle of the exposure is not: a shake that starts halfway through the exposure
    /// draws every marker's streak from its still place out along the shake, and the streak's
    /// centre lies several pixels from where the marker was at mid-exposure.
    pub fn truth(&self, frame: usize) -> Vec<Point2<f64>> {
        let times = self.exposure_times(frame);
        let n = times.len() as f64;
        (0..self.markers.len())
            .map(|k| {
                let sum = times.iter().fold(Vector2::zeros(), |acc, &ts| {
                    acc + self.marker_at(k, ts).coords
                });
                Point2::from(sum / n)
            })
            .collect()
    }

    /// Every marker's centre at the middle of `frame`'s exposure, in marker order (the
    /// stress sequences' truth until 5 December 2026; it differs from [`StressScene::truth`]
    /// only where the motion changes within the exposure).
    pub fn mid_exposure(&self, frame: usize) -> Vec<Point2<f64>> {
        let t = self.time_s(frame);
        (0..self.markers.len())
            .map(|k| self.marker_at(k, t))
            .collect()
    }

    /// The times (seconds) of `frame`'s exposure sub-samples, as [`StressScene::frame`]
    /// renders them.
    fn exposure_times(&self, frame: usize) -> Vec<f64> {
        let t = self.time_s(frame);
        let exposure = self.exposure_s();
        let subs = self.subsamples(frame);
        (0..subs)
            .map(|s| t + exposure * ((s as f64 + 0.5) / subs as f64 - 0.5))
            .collect()
    }

    /// The branch in front of marker `k`'s centre `c` in `frame`, if any: fully over it on
    /// the event's frames, half off it the frame before and after.
    pub(super) fn occluder(
        &self,
        event: &OcclusionEvent,
        frame: usize,
        c: Point2<f64>,
    ) -> Option<Capsule> {
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
        let times = self.exposure_times(frame);
        let full = PixelRect::image(cfg.width, cfg.height);
        let shaking = times.iter().any(|&ts| self.shake(ts).norm() > 0.05);
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
            for &ts in &times {
                let shake = self.shake(ts);
                let mut layer = Canvas::from_shifted(&back, dirty, shake);
                self.draw_moving(&mut layer, frame, ts, shake);
                for (a, v) in acc.iter_mut().zip(&layer.data) {
                    *a += v;
                }
            }
            canvas.set_rect(dirty, &acc, 1.0 / times.len() as f32);
        }
        finish(&canvas, cfg, frame, &mut rng)
    }

    /// Exposure sub-samples of `frame`: one per pixel of the fastest motion during the
    /// exposure (markers or shake), at least 1, at most [`MAX_SUBSAMPLES`].
    pub(super) fn subsamples(&self, frame: usize) -> usize {
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
    pub(super) fn moving_bounds(&self, frame: usize) -> PixelRect {
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

    pub(super) fn stem(&self, k: usize, tip: Point2<f64>) -> Option<Capsule> {
        let m = &self.markers[k];
        m.stem_root.map(|root| Capsule {
            a: root,
            b: tip,
            half_width: (m.diameter_px * 0.18).max(1.0),
        })
    }

    /// Stems, markers and branches in front at time `ts`, with the camera shaken by `shake`.
    pub(super) fn draw_moving(
        &self,
        layer: &mut Canvas,
        frame: usize,
        ts: f64,
        shake: Vector2<f64>,
    ) {
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

/// Place the markers: paths apart from each other, inside the frame (but for re-entries),
/// crossing pairs on purpose.
pub(super) fn place_markers(cfg: &StressConfig, rng: &mut Rng) -> Vec<StressMarker> {
    let mut out: Vec<StressMarker> = Vec::with_capacity(cfg.markers);
    for k in 0..cfg.markers {
        let mut m = draw_marker(cfg, rng, k);
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
            (m.rest, m.direction) = free_place(cfg, rng, &m, &out, reentry);
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

/// Marker `k`'s size, colour and motion, drawn from the config's ranges (not yet placed).
fn draw_marker(cfg: &StressConfig, rng: &mut Rng, k: usize) -> StressMarker {
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
}

/// The ends of a marker's swing.
fn swing_path(m: &StressMarker) -> [Point2<f64>; 2] {
    let reach = m.amplitude_px * (1.0 + m.across);
    [m.rest - m.direction * reach, m.rest + m.direction * reach]
}

/// A rest position and swing direction for `m` whose path stays inside the frame (a
/// re-entering marker: pulled towards a side border) and clear of the markers already
/// `placed`: the clearest of up to 300 draws, the first with 10 px to spare.
fn free_place(
    cfg: &StressConfig,
    rng: &mut Rng,
    m: &StressMarker,
    placed: &[StressMarker],
    reentry: bool,
) -> (Point2<f64>, Vector2<f64>) {
    let (w, h) = (f64::from(cfg.width), f64::from(cfg.height));
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
        let [p0, p1] = swing_path(&probe);
        let inside =
            |p: Point2<f64>| p.x > margin && p.y > margin && p.x < w - margin && p.y < h - margin;
        if !(reentry || inside(p0) && inside(p1)) {
            continue;
        }
        let clearance = placed
            .iter()
            .map(|o| {
                segment_distance(swing_path(&probe), swing_path(o))
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
    best.map_or(
        (Point2::new(w * 0.5, h * 0.5), m.direction),
        |(_, rest, dir)| (rest, dir),
    )
}
