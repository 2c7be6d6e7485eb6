//! Painting a frame: the background of bark, sky, wall or distractors, the canvas the
//! scene draws on, and the sensor's part (noise, flicker, JPEG).

use super::*;

/// Flicker, noise, holes and JPEG, per frame.
pub(super) fn finish(
    canvas: &Canvas,
    cfg: &StressConfig,
    frame: usize,
    rng: &mut Rng,
) -> Result<RgbImage> {
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

/// The static background of `cfg`, as RGB floats.
pub(super) fn paint_background(cfg: &StressConfig, rng: &mut Rng) -> Vec<f32> {
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
pub(super) struct Canvas {
    pub(super) rect: PixelRect,
    pub(super) data: Vec<f32>,
}

impl Canvas {
    /// The whole `width` x `height` image, from row-major RGB floats.
    pub(super) fn full(width: u32, height: u32, data: Vec<f32>) -> Self {
        Self {
            rect: PixelRect::image(width, height),
            data,
        }
    }

    /// The pixels of `rect` of the `image_width`-wide image `src`, moved by `d` (rounded to
    /// whole pixels; the image's edges repeat).
    pub(super) fn from_shifted(src: &Canvas, rect: PixelRect, d: Vector2<f64>) -> Self {
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

    pub(super) fn index(&self, x: i32, y: i32) -> usize {
        ((y - self.rect.y) as usize * self.rect.width as usize + (x - self.rect.x) as usize) * 3
    }

    /// Blend `rgb` over the pixels where `inside` holds, by coverage.
    pub(super) fn shape(
        &mut self,
        bounds: [f64; 4],
        rgb: [u8; 3],
        inside: impl Fn(Point2<f64>) -> bool,
    ) {
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

    pub(super) fn disc(&mut self, c: Point2<f64>, r: f64, rgb: [u8; 3]) {
        self.shape([c.x - r, c.y - r, c.x + r, c.y + r], rgb, |p| {
            (p - c).norm_squared() <= r * r
        });
    }

    pub(super) fn capsule(&mut self, c: &Capsule, rgb: [u8; 3]) {
        self.shape(c.bounds(), rgb, |p| c.covers(p));
    }

    /// Write `values * scale` (the pixels of `rect`, which lies in this canvas) into it.
    pub(super) fn set_rect(&mut self, rect: PixelRect, values: &[f32], scale: f32) {
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
