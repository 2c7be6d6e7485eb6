//! A marker's weights over a region of a frame, and mean-shift on them: the histogram models'
//! back-projection (OpenCV's arithmetic per window, sub-pixel centroid at the end) and the
//! kernel model's Bhattacharyya mean-shift (Comaniciu, Ramesh, Meer 2003).

use image::RgbImage;
use nalgebra::Point2;

use crate::histogram::Histogram;
use crate::hsv::{ChannelRange, hsv_converter, rgb_to_gray};
use crate::meanshift::{Moments, TermCriteria, moments_from_f64_sums};
use crate::model::{AppearanceModel, MarkerModel};
use crate::rect::PixelRect;
use crate::tracker::DepthView;

/// No bin (masked out, gated, claimed or outside the histogram's range).
pub(crate) const NO_BIN: u32 = u32::MAX;
/// Shift in pixels below which the kernel (Bhattacharyya) mean-shift has converged
/// (Comaniciu et al. 2003 stop below one pixel; sub-pixel centres need a finer stop, since
/// on a uniform blob each step covers only part of the remaining distance).
const KERNEL_EPSILON_PX: f64 = 0.05;
/// Iteration limit of the kernel mean-shift.
const KERNEL_MAX_ITERATIONS: usize = 30;
/// Border of CamShift's size estimate around the converged window (OpenCV's `TOLERANCE`).
const ADAPTIVE_BORDER_PX: i32 = 10;

/// Least distance (8-bit RGB levels) between the marker's colour and the background for a
/// streak to be told from it.
const STREAK_MIN_CONTRAST: f32 = 40.0;
/// Least coverage of a streak pixel: the share of the exposure the marker spent on it.
const STREAK_MIN_COVERAGE: f32 = 0.15;
/// Coverage at and above which a streak pixel weighs as much as the marker's own colour.
const STREAK_FULL_COVERAGE: f32 = 0.5;
/// Largest distance (8-bit levels) of a streak pixel from the line between background and
/// marker colour, and as a share of the coverage times the contrast (colour noise, JPEG).
const STREAK_RESIDUAL: [f32; 2] = [15.0, 0.3];

/// What a moving marker leaves: a streak whose pixels mix the marker's colour with the
/// background in proportion to the time it covered them (`p = a m + (1 - a) b`). The
/// background of a pixel is taken from the previous frame, which a marker fast enough to blur
/// has left; a static or slow marker gives no streak weight (its colour does the work).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Streak<'a> {
    /// The previous frame (same size as the frame).
    pub(crate) previous: &'a RgbImage,
    /// The marker's mean colour (RGB).
    pub(crate) colour: [f32; 3],
}

impl Streak<'_> {
    /// The streak weight (0..255) of colour `p` over background `b`: 255 times the coverage
    /// up to [`STREAK_FULL_COVERAGE`], 0 off the mixing line or below
    /// [`STREAK_MIN_COVERAGE`].
    #[inline]
    fn weight(&self, p: [u8; 3], b: [u8; 3]) -> f32 {
        let m = self.colour;
        let d = [
            m[0] - f32::from(b[0]),
            m[1] - f32::from(b[1]),
            m[2] - f32::from(b[2]),
        ];
        let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        if dd < STREAK_MIN_CONTRAST * STREAK_MIN_CONTRAST {
            return 0.0;
        }
        let e = [
            f32::from(p[0]) - f32::from(b[0]),
            f32::from(p[1]) - f32::from(b[1]),
            f32::from(p[2]) - f32::from(b[2]),
        ];
        // Compared before dividing: most pixels are background over background.
        let ed = e[0] * d[0] + e[1] * d[1] + e[2] * d[2];
        if ed < STREAK_MIN_COVERAGE * dd {
            return 0.0;
        }
        let a = ed / dd;
        let r = [e[0] - a * d[0], e[1] - a * d[1], e[2] - a * d[2]];
        let rr = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
        let limit = STREAK_RESIDUAL[0].max(STREAK_RESIDUAL[1] * a.min(1.0) * dd.sqrt());
        if rr > limit * limit {
            return 0.0;
        }
        255.0 * (a / STREAK_FULL_COVERAGE).min(1.0)
    }
}

/// What a pixel must pass to count, besides the model and its mask (in the [`Lookup`]): a
/// depth gate, and rectangles other markers hold.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PixelFilter<'a> {
    /// `(gate, marker depth, depth map)`: pixels farther than the gate from the marker's
    /// depth do not count.
    pub(crate) depth: Option<(f64, f64, DepthView<'a>)>,
    pub(crate) masked: &'a [PixelRect],
    /// Streak weights for a moving marker (colour models), the greater of the two counts.
    pub(crate) streak: Option<Streak<'a>>,
}

impl PixelFilter<'_> {
    fn rejects(&self, x: i32, y: i32) -> bool {
        self.masked
            .iter()
            .any(|r| x >= r.x && y >= r.y && i64::from(x) < r.right() && i64::from(y) < r.bottom())
            || self
                .depth
                .is_some_and(|(g, dm, d)| d.at(x, y).is_some_and(|v| (v - dm).abs() > g))
    }
}

/// The model's weights over a region of the frame.
#[derive(Debug, Default)]
pub(crate) struct Region {
    pub(crate) rect: PixelRect,
    /// Per-pixel weight: the back-projection (histogram models) or the target histogram's
    /// value scaled to 0..255 (kernel model).
    pub(crate) weights: Vec<f32>,
    /// Histogram bins (kernel model), [`NO_BIN`] where the pixel does not count.
    pub(crate) bins: Vec<u32>,
    /// Candidate histogram scratch (kernel model).
    p: Vec<f64>,
    /// Pixel scratch of a kernel step.
    pixels: Vec<(i32, i32, u32, f64)>,
}

/// A model and a mask as table lookups: per feature channel and value, the histogram bin's
/// offset (0 for a channel the histogram does not read), or at least `total` when the value
/// is outside the histogram's range or the mask. The three offsets of a pixel are summed:
/// any sum of `total` or more reads the padding of `values` (weight 0, no bin), so a pixel is
/// weighed without a branch.
#[derive(Debug, Default, Clone)]
pub(crate) struct Lookup {
    tables: [Vec<u32>; 3],
    /// Weight per bin, padded with zeros to `3 total + 1` entries.
    values: Vec<f32>,
    /// Bin per entry of `values` ([`NO_BIN`] in the padding).
    bins: Vec<u32>,
}

impl Lookup {
    /// The lookup of a marker's model and mask (the mask applies to the HSV models only);
    /// both are fixed once the marker is learned, so it is built once per marker.
    pub(crate) fn new(
        appearance: &AppearanceModel,
        model: &MarkerModel,
        mask: &ChannelRange,
    ) -> Self {
        let hsv = matches!(
            appearance,
            AppearanceModel::Hue { .. } | AppearanceModel::HueSaturation { .. }
        );
        let mut lookup = Self::default();
        lookup.build(model, hsv.then_some(mask));
        lookup
    }

    fn build(&mut self, model: &MarkerModel, mask: Option<&ChannelRange>) {
        let (hist, weights): (&Histogram, &mut dyn Iterator<Item = f32>) = match model {
            MarkerModel::Projected { projector } => (
                projector.histogram(),
                &mut projector.bin_values().iter().map(|&v| f32::from(v)),
            ),
            MarkerModel::Kernel { hist, weight, .. } => (hist, &mut weight.iter().copied()),
        };
        // At most 2^24 bins (the histogram's limit): 3 total + 1 fits in u32.
        let total = hist.values().len();
        let outside = total as u32;
        for t in &mut self.tables {
            t.clear();
            t.resize(256, 0);
        }
        for (c, t) in hist.offset_tables(outside) {
            if let Some(table) = self.tables.get_mut(c) {
                for (d, s) in table.iter_mut().zip(t) {
                    *d = (*d + s).min(outside);
                }
            }
        }
        if let Some(mask) = mask {
            for (c, table) in self.tables.iter_mut().enumerate() {
                for (v, d) in table.iter_mut().enumerate() {
                    if !(usize::from(mask.lower[c])..=usize::from(mask.upper[c])).contains(&v) {
                        *d = outside;
                    }
                }
            }
        }
        self.values.clear();
        self.values.extend(weights);
        self.values.resize(3 * total + 1, 0.0);
        self.bins.clear();
        self.bins.extend(0..total as u32);
        self.bins.resize(3 * total + 1, NO_BIN);
    }
}

/// The result of a mean-shift from one start.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Mode {
    pub(crate) center: Point2<f64>,
    pub(crate) window: PixelRect,
    /// Back-projection mass in the window relative to the reference (histogram models), or
    /// the Bhattacharyya coefficient (kernel model), capped to 0..=1.
    pub(crate) confidence: f64,
    /// Moments of the converged window and a border (histogram models), for the adaptive size.
    pub(crate) moments: Option<Moments>,
}

impl Region {
    /// Compute the weights of `model` over `rect` (clipped to the frame).
    pub(crate) fn fill(
        &mut self,
        appearance: &AppearanceModel,
        model: &MarkerModel,
        lookup: &Lookup,
        frame: &RgbImage,
        rect: PixelRect,
        filter: &PixelFilter<'_>,
    ) {
        let rect = rect.intersect(&PixelRect::image(frame.width(), frame.height()));
        self.rect = rect;
        let area = rect.area() as usize;
        self.weights.clear();
        self.weights.reserve(area);
        let kernel = matches!(model, MarkerModel::Kernel { .. });
        self.bins.clear();
        if kernel {
            self.bins.reserve(area);
        }
        match appearance {
            AppearanceModel::Hue { .. } | AppearanceModel::HueSaturation { .. } => {
                self.fill_rows(lookup, frame, rect, filter, kernel, hsv_converter());
            }
            AppearanceModel::Rgb { .. } => {
                self.fill_rows(lookup, frame, rect, filter, kernel, |p| p);
            }
            AppearanceModel::Gray { .. } => {
                self.fill_rows(lookup, frame, rect, filter, kernel, |p| {
                    [rgb_to_gray(p), 0, 0]
                });
            }
        }
    }

    /// The pixel loop of [`Region::fill`], one copy per feature conversion.
    #[inline(always)]
    fn fill_rows(
        &mut self,
        lookup: &Lookup,
        frame: &RgbImage,
        rect: PixelRect,
        filter: &PixelFilter<'_>,
        kernel: bool,
        features: impl Fn([u8; 3]) -> [u8; 3],
    ) {
        let raw = frame.as_raw();
        let stride = frame.width() as usize * 3;
        let check = !filter.masked.is_empty() || filter.depth.is_some();
        let previous = filter
            .streak
            .filter(|s| s.previous.dimensions() == frame.dimensions())
            .map(|s| (s, s.previous.as_raw()));
        let Lookup {
            tables: [t0, t1, t2],
            values,
            bins,
        } = lookup;
        for y in rect.y..rect.bottom() as i32 {
            let start = y as usize * stride;
            let row = &raw[start + rect.x as usize * 3..start + rect.right() as usize * 3];
            for (i, p) in row.chunks_exact(3).enumerate() {
                let x = rect.x + i as i32;
                if check && filter.rejects(x, y) {
                    self.weights.push(0.0);
                    if kernel {
                        self.bins.push(NO_BIN);
                    }
                    continue;
                }
                let rgb = [p[0], p[1], p[2]];
                let f = features(rgb);
                let k = (t0[usize::from(f[0])] + t1[usize::from(f[1])] + t2[usize::from(f[2])])
                    as usize;
                let mut w = values[k];
                // A streak pixel weighs at most 255: only pixels below that can gain.
                if w < 255.0
                    && let Some((s, prev)) = previous
                {
                    let j = start + (rect.x as usize + i) * 3;
                    w = w.max(s.weight(rgb, [prev[j], prev[j + 1], prev[j + 2]]));
                }
                self.weights.push(w);
                if kernel {
                    self.bins.push(bins[k]);
                }
            }
        }
    }

    pub(crate) fn index(&self, x: i32, y: i32) -> usize {
        (y - self.rect.y) as usize * self.rect.width as usize + (x - self.rect.x) as usize
    }

    /// Sums of weight, weight·x, weight·y and second orders over `window ∩ region`
    /// (absolute pixel coordinates).
    pub(crate) fn sums(&self, window: PixelRect) -> [f64; 6] {
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

    /// Sum of the weights in `window`.
    pub(crate) fn mass(&self, window: PixelRect) -> f64 {
        self.sums(window)[0]
    }

    /// Mean-shift from `start` with a window of `size`, then the weighted centroid and the
    /// confidence of the converged window (`reference_mass`: the mass of the marker's own
    /// window on the first frame).
    pub(crate) fn locate(
        &mut self,
        model: &MarkerModel,
        criteria: &TermCriteria,
        reference_mass: f64,
        start: Point2<f64>,
        size: (i32, i32),
    ) -> Mode {
        match model {
            MarkerModel::Projected { .. } => {
                let max_iter = criteria.max_iterations.unwrap_or(100).max(1);
                let eps = criteria.epsilon_px.unwrap_or(1.0).max(0.0);
                let mut window = PixelRect::centered_at(start, size.0, size.1);
                let mut center = start;
                for _ in 0..max_iter {
                    let s = self.sums(window);
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
                let s = self.sums(window);
                if s[0] > 0.0 {
                    center = Point2::new(s[1] / s[0], s[2] / s[0]);
                }
                let grown = window.grown(ADAPTIVE_BORDER_PX, ADAPTIVE_BORDER_PX);
                let g = self.sums(grown);
                // Central moments do not depend on the origin of the coordinates.
                let moments = (g[0] > 0.0).then(|| moments_from_f64_sums(g));
                Mode {
                    center,
                    window,
                    confidence: (s[0] / reference_mass.max(1.0)).min(1.0),
                    moments,
                }
            }
            MarkerModel::Kernel { q, .. } => self.kernel_locate(q, start, size),
        }
    }

    /// Comaniciu–Ramesh–Meer mean-shift with the Epanechnikov kernel over the window's
    /// inscribed ellipse; the confidence is the Bhattacharyya coefficient at the end.
    fn kernel_locate(&mut self, q: &[f64], start: Point2<f64>, size: (i32, i32)) -> Mode {
        let (w, h) = (size.0.max(1) as usize, size.1.max(1) as usize);
        let mut y0 = start;
        let mut rho = 0.0;
        for _ in 0..KERNEL_MAX_ITERATIONS {
            let (next, r) = self.kernel_step(q, y0, w, h);
            rho = r;
            let Some(next) = next else { break };
            let moved = (next - y0).norm();
            y0 = next;
            if moved < KERNEL_EPSILON_PX {
                rho = self.kernel_step(q, y0, w, h).1;
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

    /// The Bhattacharyya coefficient of the kernel histogram at `center` with `q`.
    pub(crate) fn bhattacharyya(
        &mut self,
        q: &[f64],
        center: Point2<f64>,
        size: (i32, i32),
    ) -> f64 {
        let (w, h) = (size.0.max(1) as usize, size.1.max(1) as usize);
        self.kernel_step(q, center, w, h).1
    }

    /// One kernel mean-shift step at `y0`: the new position (None when the kernel holds no
    /// counted pixel) and the Bhattacharyya coefficient at `y0`.
    fn kernel_step(
        &mut self,
        q: &[f64],
        y0: Point2<f64>,
        w: usize,
        h: usize,
    ) -> (Option<Point2<f64>>, f64) {
        let window = PixelRect::centered_at(y0, w as i32, h as i32).intersect(&self.rect);
        if window.is_empty() || self.bins.len() != self.rect.area() as usize {
            return (None, 0.0);
        }
        let hx = (w as f64 * 0.5).max(0.5);
        let hy = (h as f64 * 0.5).max(0.5);
        self.p.clear();
        self.p.resize(q.len(), 0.0);
        self.pixels.clear();
        let mut total = 0.0;
        for y in window.y..window.bottom() as i32 {
            for x in window.x..window.right() as i32 {
                let bin = self.bins[self.index(x, y)];
                if bin == NO_BIN {
                    continue;
                }
                let dx = (f64::from(x) - y0.x) / hx;
                let dy = (f64::from(y) - y0.y) / hy;
                let r2 = dx * dx + dy * dy;
                if r2 >= 1.0 {
                    continue;
                }
                self.p[bin as usize] += 1.0 - r2;
                total += 1.0 - r2;
                self.pixels.push((x, y, bin, 1.0 - r2));
            }
        }
        if total <= 0.0 {
            return (None, 0.0);
        }
        let mut rho = 0.0;
        for (&p, &qv) in self.p.iter().zip(q) {
            if p > 0.0 && qv > 0.0 {
                rho += (p / total * qv).sqrt();
            }
        }
        let (mut sw, mut sx, mut sy) = (0.0, 0.0, 0.0);
        for &(x, y, bin, k) in &self.pixels {
            let p = self.p[bin as usize] / total;
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
}
