//! A marker's surroundings as a gray template, compared by normalised cross-correlation.
//!
//! Markers of one colour (the paper's red markers, or the white targets of a structural
//! test) look the same to a colour histogram; what tells them apart is what is around them:
//! the branch they sit on, a fork, the background. When a fast swing carries a marker nearer
//! to where its neighbour was, the histogram alone cannot say which blob is which; the
//! surroundings can.

use image::RgbImage;
use nalgebra::Point2;

use crate::hsv::rgb_to_gray;

/// A gray patch centred on a marker, `NaN` where it fell outside the frame.
#[derive(Debug, Clone)]
pub(crate) struct ContextTemplate {
    width: usize,
    height: usize,
    values: Vec<f32>,
}

/// Pixel centre nearest to `center`, as integers.
fn anchor(center: Point2<f64>) -> (i64, i64) {
    (center.x.round() as i64, center.y.round() as i64)
}

/// The gray values of the `width` x `height` patch centred at `center`, `NaN` outside the
/// frame.
fn patch(frame: &RgbImage, center: Point2<f64>, width: usize, height: usize, out: &mut Vec<f32>) {
    out.clear();
    let (cx, cy) = anchor(center);
    let x0 = cx - (width / 2) as i64;
    let y0 = cy - (height / 2) as i64;
    let (fw, fh) = (i64::from(frame.width()), i64::from(frame.height()));
    let raw = frame.as_raw();
    for y in y0..y0 + height as i64 {
        for x in x0..x0 + width as i64 {
            if (0..fw).contains(&x) && (0..fh).contains(&y) {
                let k = ((y * fw + x) * 3) as usize;
                out.push(f32::from(rgb_to_gray([raw[k], raw[k + 1], raw[k + 2]])));
            } else {
                out.push(f32::NAN);
            }
        }
    }
}

impl ContextTemplate {
    /// The patch of `width` x `height` pixels centred at `center`.
    pub(crate) fn learn(
        frame: &RgbImage,
        center: Point2<f64>,
        width: usize,
        height: usize,
    ) -> Self {
        let mut values = Vec::with_capacity(width * height);
        patch(frame, center, width, height, &mut values);
        Self {
            width,
            height,
            values,
        }
    }

    /// Zero-mean normalised cross-correlation (-1..=1) between the template and the patch at
    /// `center`, over the pixels inside the frame in both. 0 when either has no contrast
    /// there or fewer than [`MIN_PIXELS`] pixels overlap.
    pub(crate) fn ncc(&self, frame: &RgbImage, center: Point2<f64>, scratch: &mut Vec<f32>) -> f64 {
        patch(frame, center, self.width, self.height, scratch);
        let pairs = || {
            self.values
                .iter()
                .zip(scratch.iter())
                .filter(|(a, b)| !a.is_nan() && !b.is_nan())
                .map(|(&a, &b)| (f64::from(a), f64::from(b)))
        };
        let (mut n, mut sa, mut sb) = (0usize, 0.0, 0.0);
        for (a, b) in pairs() {
            n += 1;
            sa += a;
            sb += b;
        }
        if n < MIN_PIXELS {
            return 0.0;
        }
        let (ma, mb) = (sa / n as f64, sb / n as f64);
        let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
        for (a, b) in pairs() {
            let (da, db) = (a - ma, b - mb);
            sab += da * db;
            saa += da * da;
            sbb += db * db;
        }
        if saa <= 0.0 || sbb <= 0.0 {
            return 0.0;
        }
        (sab / (saa * sbb).sqrt()).clamp(-1.0, 1.0)
    }

    /// Blend the patch at `center` into the template: `t <- (1 - rate) t + rate p`, so that
    /// slow changes (a branch turning, the light) are followed. Pixels known in only one of
    /// the two take the known value.
    pub(crate) fn update(
        &mut self,
        frame: &RgbImage,
        center: Point2<f64>,
        rate: f32,
        scratch: &mut Vec<f32>,
    ) {
        patch(frame, center, self.width, self.height, scratch);
        for (t, &p) in self.values.iter_mut().zip(scratch.iter()) {
            *t = match (t.is_nan(), p.is_nan()) {
                (false, false) => *t + rate * (p - *t),
                (true, _) => p,
                (false, true) => *t,
            };
        }
    }
}

/// Fewest overlapping pixels for a meaningful correlation.
const MIN_PIXELS: usize = 16;

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(offset: u32) -> RgbImage {
        // A bright square with a dark bar on its left at `offset`, and a plain bright square
        // 30 px to the right.
        RgbImage::from_fn(100, 40, |x, y| {
            let in_a = (offset..offset + 8).contains(&x) && (16..24).contains(&y);
            let bar = (offset.saturating_sub(6)..offset.saturating_sub(2)).contains(&x)
                && (10..30).contains(&y);
            let in_b = (offset + 30..offset + 38).contains(&x) && (16..24).contains(&y);
            let v = if in_a || in_b {
                230
            } else if bar {
                20
            } else {
                90
            };
            image::Rgb([v, v, v])
        })
    }

    #[test]
    fn correlation_tells_look_alike_markers_apart_by_their_surroundings() {
        let frame = scene(20);
        let t = ContextTemplate::learn(&frame, Point2::new(23.5, 19.5), 24, 24);
        let mut s = Vec::new();
        let own = t.ncc(&frame, Point2::new(23.5, 19.5), &mut s);
        let other = t.ncc(&frame, Point2::new(53.5, 19.5), &mut s);
        assert!((own - 1.0).abs() < 1e-9, "{own}");
        assert!(other < 0.9, "{other}");
        // The same scene shifted: the marker is found where it moved.
        let moved = scene(40);
        assert!((t.ncc(&moved, Point2::new(43.5, 19.5), &mut s) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn patches_past_the_border_and_flat_patches_are_handled() {
        let frame = scene(20);
        let mut t = ContextTemplate::learn(&frame, Point2::new(2.0, 2.0), 24, 24);
        let mut s = Vec::new();
        let v = t.ncc(&frame, Point2::new(2.0, 2.0), &mut s);
        assert!(v.is_finite());
        let flat = RgbImage::from_pixel(100, 40, image::Rgb([50, 50, 50]));
        assert_eq!(t.ncc(&flat, Point2::new(50.0, 20.0), &mut s), 0.0);
        // Far outside: no overlap.
        assert_eq!(t.ncc(&frame, Point2::new(-500.0, -500.0), &mut s), 0.0);
        // Updating from a patch inside fills the unknown pixels.
        t.update(&frame, Point2::new(50.0, 20.0), 0.5, &mut s);
        assert!(t.values.iter().all(|v| !v.is_nan()));
    }
}
