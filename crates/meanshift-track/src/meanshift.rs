//! OpenCV's `meanShift` and `CamShift` on an 8-bit probability image (a back-projection),
//! reproduced rule for rule: the termination criteria (`eps` squared and rounded, at least one
//! iteration), the rounding of every shift (half to even), the clamping of the window to the
//! image, CamShift's 10-pixel tolerance border and its window-size rules. The parity fixtures
//! check the windows for equality.

use image::GrayImage;
use nalgebra::Point2;

use crate::error::{Result, TrackError};
use crate::rect::PixelRect;
use crate::view::dim_i32;

/// Default iteration limit of OpenCV's `meanShift` when the criteria have no count.
const DEFAULT_MAX_ITERATIONS: u32 = 100;
/// CamShift's border around the converged window for the size estimate (`TOLERANCE` in
/// OpenCV's `camshift.cpp`).
const CAMSHIFT_TOLERANCE_PX: i32 = 10;

/// OpenCV's `TermCriteria` for mean-shift: stop after `max_iterations` iterations
/// (`COUNT`) or when the window moves by less than `epsilon_px` (`EPS`), whichever comes
/// first. `None` leaves that criterion out, as OpenCV's type flags do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TermCriteria {
    /// Iteration limit (`COUNT`); OpenCV uses at least 1, and 100 when absent.
    pub max_iterations: Option<u32>,
    /// Shift in pixels below which the search stops (`EPS`); OpenCV rounds its square to an
    /// integer and stops when `dx² + dy²` is below it, and uses 1 when absent.
    pub epsilon_px: Option<f64>,
}

impl TermCriteria {
    /// `(EPS | COUNT, 10, 1)`, the criteria of OpenCV's CamShift sample and of the paper's
    /// mean-shift tracking.
    pub const OPENCV_SAMPLE: TermCriteria = TermCriteria {
        max_iterations: Some(10),
        epsilon_px: Some(1.0),
    };

    fn resolve(&self) -> Result<(u32, i64)> {
        let n = self
            .max_iterations
            .map_or(DEFAULT_MAX_ITERATIONS, |n| n.max(1));
        let eps = match self.epsilon_px {
            None => 1.0,
            Some(e) if e.is_nan() || e.is_infinite() => {
                return Err(TrackError::param(
                    "epsilon_px",
                    format!("{e} is not a finite number"),
                ));
            }
            Some(e) => e.max(0.0),
        };
        // cvRound(eps * eps); saturate like OpenCV's int conversion would for huge values.
        let eps2 = (eps * eps).round_ties_even().min(i64::MAX as f64) as i64;
        Ok((n, eps2))
    }
}

impl Default for TermCriteria {
    fn default() -> Self {
        Self::OPENCV_SAMPLE
    }
}

/// Raw and central image moments of a window of an 8-bit image (OpenCV's `Moments`, the
/// orders mean-shift needs). Raw moments are relative to the window's top-left pixel.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Moments {
    /// Sum of values.
    pub m00: f64,
    /// Sum of `x * value`.
    pub m10: f64,
    /// Sum of `y * value`.
    pub m01: f64,
    /// Sum of `x² * value`.
    pub m20: f64,
    /// Sum of `x * y * value`.
    pub m11: f64,
    /// Sum of `y² * value`.
    pub m02: f64,
    /// Central second moment in x.
    pub mu20: f64,
    /// Central mixed second moment.
    pub mu11: f64,
    /// Central second moment in y.
    pub mu02: f64,
}

/// Moments of `rect` of `image`; `rect` must lie inside the image (checked by callers).
/// Integer sums are exact, then converted as OpenCV's `completeMomentState` does.
pub(crate) fn moments_in(image: &GrayImage, rect: PixelRect) -> Moments {
    let width = image.width() as usize;
    let data = image.as_raw();
    let (mut s0, mut sx, mut sy, mut sxx, mut sxy, mut syy) = (0u64, 0u64, 0u64, 0u64, 0u64, 0u64);
    for (j, y) in (rect.y as usize..rect.bottom() as usize).enumerate() {
        let row = &data[y * width + rect.x as usize..y * width + rect.right() as usize];
        let (mut r0, mut rx, mut rxx) = (0u64, 0u64, 0u64);
        for (i, &p) in row.iter().enumerate() {
            let p = u64::from(p);
            let i = i as u64;
            r0 += p;
            rx += i * p;
            rxx += i * i * p;
        }
        let j = j as u64;
        s0 += r0;
        sx += rx;
        sxx += rxx;
        sy += j * r0;
        sxy += j * rx;
        syy += j * j * r0;
    }
    moments_from_sums([s0, sx, sy, sxx, sxy, syy])
}

pub(crate) fn moments_from_sums(sums: [u64; 6]) -> Moments {
    moments_from_f64_sums(sums.map(|s| s as f64))
}

/// Moments from the sums of `v`, `v x`, `v y`, `v x²`, `v x y`, `v y²`, central moments as
/// OpenCV's `completeMomentState`.
pub(crate) fn moments_from_f64_sums([m00, m10, m01, m20, m11, m02]: [f64; 6]) -> Moments {
    let (mut cx, mut cy) = (0.0, 0.0);
    if m00.abs() > f64::EPSILON {
        let inv = 1.0 / m00;
        cx = m10 * inv;
        cy = m01 * inv;
    }
    Moments {
        m00,
        m10,
        m01,
        m20,
        m11,
        m02,
        mu20: m20 - m10 * cx,
        mu11: m11 - m10 * cy,
        mu02: m02 - m01 * cy,
    }
}

/// Outcome of [`mean_shift`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MeanShiftResult {
    /// The converged window (inside the image).
    pub window: PixelRect,
    /// Iterations done (OpenCV's return value).
    pub iterations: u32,
}

fn check_prob(prob: &GrayImage, window: &PixelRect) -> Result<()> {
    if prob.width() == 0 || prob.height() == 0 {
        return Err(TrackError::EmptyImage {
            what: "probability image".into(),
        });
    }
    if window.is_empty() {
        return Err(TrackError::EmptyWindow {
            what: "window".into(),
            width: window.width,
            height: window.height,
        });
    }
    Ok(())
}

fn outside(window: &PixelRect, prob: &GrayImage) -> TrackError {
    TrackError::WindowOutsideImage {
        what: "window".into(),
        x: window.x,
        y: window.y,
        width: window.width,
        height: window.height,
        image_width: prob.width(),
        image_height: prob.height(),
    }
}

/// OpenCV's `cv::meanShift(probImage, window, criteria)`.
///
/// # Errors
/// [`TrackError::EmptyImage`], [`TrackError::EmptyWindow`] (OpenCV: "Input window has
/// non-positive sizes"), [`TrackError::InvalidParameter`] for a non-finite epsilon, and
/// [`TrackError::WindowOutsideImage`] where OpenCV would fail an assertion (a window that only
/// touches the image's right or bottom edge).
pub fn mean_shift(
    prob: &GrayImage,
    window: PixelRect,
    criteria: TermCriteria,
) -> Result<MeanShiftResult> {
    check_prob(prob, &window)?;
    let (niters, eps2) = criteria.resolve()?;
    let size = PixelRect::image(prob.width(), prob.height());
    let (w, h) = (dim_i32(prob.width()), dim_i32(prob.height()));
    let clipped = window.intersect(&size);
    let mut cur = window;
    let mut i = 0;
    while i < niters {
        cur = cur.intersect(&size);
        if cur == PixelRect::default() {
            cur.x = w / 2;
            cur.y = h / 2;
        }
        cur.width = cur.width.max(1);
        cur.height = cur.height.max(1);
        if !cur.is_inside(&size) {
            return Err(outside(&window, prob));
        }
        let m = moments_in(prob, cur);
        if m.m00.abs() < f64::EPSILON {
            break;
        }
        let dx = round_i32(m.m10 / m.m00 - f64::from(clipped.width) * 0.5);
        let dy = round_i32(m.m01 / m.m00 - f64::from(clipped.height) * 0.5);
        let nx = (cur.x + dx).max(0).min(w - cur.width);
        let ny = (cur.y + dy).max(0).min(h - cur.height);
        let (dx, dy) = (i64::from(nx - cur.x), i64::from(ny - cur.y));
        cur.x = nx;
        cur.y = ny;
        i += 1;
        if dx * dx + dy * dy < eps2 {
            // OpenCV breaks before its loop increment: report the iteration count it returns.
            i -= 1;
            break;
        }
    }
    Ok(MeanShiftResult {
        window: cur,
        iterations: i,
    })
}

/// OpenCV's `cvRound` of a double (round half to even) as `i32`, saturating.
pub(crate) fn round_i32(v: f64) -> i32 {
    let r = v.round_ties_even();
    if r.is_nan() {
        0
    } else {
        r.clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
    }
}

/// The oriented box of CamShift (OpenCV's `RotatedRect`), values as OpenCV computes them in
/// `float`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RotatedBox {
    /// Centre of the new window (`x + width / 2`, OpenCV's corner-based convention).
    pub center: Point2<f64>,
    /// Minor axis length, 4 standard deviations, pixels.
    pub width: f64,
    /// Major axis length, 4 standard deviations, pixels.
    pub height: f64,
    /// Orientation in degrees, `0 <= angle < 180` (OpenCV's convention).
    pub angle_deg: f64,
}

/// CamShift's ellipse of a window's second moments (lengths are 4 standard deviations).
pub(crate) struct Axes {
    pub(crate) length: f64,
    pub(crate) width: f64,
    cs: f64,
    sn: f64,
    theta: f64,
}

impl Axes {
    /// OpenCV's arithmetic, step for step; `m.m00` must be positive.
    pub(crate) fn of(m: &Moments) -> Axes {
        let inv_m00 = 1.0 / m.m00;
        let a = m.mu20 * inv_m00;
        let b = m.mu11 * inv_m00;
        let c = m.mu02 * inv_m00;
        let square = (4.0 * b * b + (a - c) * (a - c)).sqrt();
        let mut theta = (2.0 * b).atan2(a - c + square);
        let (mut cs, mut sn) = (theta.cos(), theta.sin());
        let rotate_a = (cs * cs * m.mu20 + 2.0 * cs * sn * m.mu11 + sn * sn * m.mu02).max(0.0);
        let rotate_c = (sn * sn * m.mu20 - 2.0 * cs * sn * m.mu11 + cs * cs * m.mu02).max(0.0);
        let mut length = (rotate_a * inv_m00).sqrt() * 4.0;
        let mut width = (rotate_c * inv_m00).sqrt() * 4.0;
        if length < width {
            std::mem::swap(&mut length, &mut width);
            std::mem::swap(&mut cs, &mut sn);
            theta = std::f64::consts::FRAC_PI_2 - theta;
        }
        Axes {
            length,
            width,
            cs,
            sn,
            theta,
        }
    }

    /// CamShift's next window size (before clipping to the image): the ellipse's extent plus
    /// 2 pixels in each direction.
    pub(crate) fn window_size(&self) -> (i32, i32) {
        let t0 = round_i32((self.length * self.cs).abs());
        let t1 = round_i32((self.width * self.sn).abs());
        let w = t0.max(t1).saturating_add(2);
        let t0 = round_i32((self.length * self.sn).abs());
        let t1 = round_i32((self.width * self.cs).abs());
        (w, t0.max(t1).saturating_add(2))
    }
}

/// Outcome of [`cam_shift`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CamShiftResult {
    /// The next search window.
    pub window: PixelRect,
    /// The oriented box; all zero when the window holds no probability.
    pub rotated: RotatedBox,
    /// Mean-shift iterations.
    pub iterations: u32,
}

/// OpenCV's `cv::CamShift(probImage, window, criteria)`: mean-shift, then the window size from
/// the second moments in a border of 10 pixels around the converged window.
///
/// # Errors
/// As [`mean_shift`].
pub fn cam_shift(
    prob: &GrayImage,
    window: PixelRect,
    criteria: TermCriteria,
) -> Result<CamShiftResult> {
    let ms = mean_shift(prob, window, criteria)?;
    let (w, h) = (dim_i32(prob.width()), dim_i32(prob.height()));
    let mut win = ms.window;
    win.x = (win.x - CAMSHIFT_TOLERANCE_PX).max(0);
    win.y = (win.y - CAMSHIFT_TOLERANCE_PX).max(0);
    win.width += 2 * CAMSHIFT_TOLERANCE_PX;
    if win.x + win.width > w {
        win.width = w - win.x;
    }
    win.height += 2 * CAMSHIFT_TOLERANCE_PX;
    if win.y + win.height > h {
        win.height = h - win.y;
    }
    let m = moments_in(prob, win);
    if m.m00.abs() < f64::EPSILON {
        return Ok(CamShiftResult {
            window: win,
            rotated: RotatedBox::default(),
            iterations: ms.iterations,
        });
    }
    let inv_m00 = 1.0 / m.m00;
    let xc = round_i32(m.m10 * inv_m00 + f64::from(win.x));
    let yc = round_i32(m.m01 * inv_m00 + f64::from(win.y));
    let axes = Axes::of(&m);
    let (size_w, size_h) = axes.window_size();
    win.width = size_w.min((w - xc) * 2);
    win.height = size_h.min((h - yc) * 2);
    win.x = (xc - win.width / 2).max(0);
    win.y = (yc - win.height / 2).max(0);
    win.width = (w - win.x).min(win.width);
    win.height = (h - win.y).min(win.height);

    let mut angle =
        ((std::f64::consts::FRAC_PI_2 + axes.theta) * 180.0 / std::f64::consts::PI) as f32;
    while angle < 0.0 {
        angle += 360.0;
    }
    while angle >= 360.0 {
        angle -= 360.0;
    }
    if angle >= 180.0 {
        angle -= 180.0;
    }
    let center_x = win.x as f32 + win.width as f32 * 0.5;
    let center_y = win.y as f32 + win.height as f32 * 0.5;
    Ok(CamShiftResult {
        window: win,
        rotated: RotatedBox {
            center: Point2::new(f64::from(center_x), f64::from(center_y)),
            width: f64::from(axes.width as f32),
            height: f64::from(axes.length as f32),
            angle_deg: f64::from(angle),
        },
        iterations: ms.iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Luma;

    fn blob(cx: f64, cy: f64) -> GrayImage {
        GrayImage::from_fn(60, 40, |x, y| {
            let d2 = (f64::from(x) - cx).powi(2) + (f64::from(y) - cy).powi(2);
            Luma([(250.0 * (-d2 / 18.0).exp()) as u8])
        })
    }

    #[test]
    fn converges_onto_a_blob_in_reach() {
        let prob = blob(30.0, 20.0);
        let r = mean_shift(
            &prob,
            PixelRect::new(22, 12, 12, 12),
            TermCriteria::default(),
        )
        .expect("valid");
        let c = r.window.center();
        assert!(
            (c.x - 30.0).abs() <= 1.0 && (c.y - 20.0).abs() <= 1.0,
            "{r:?}"
        );
        assert!(r.iterations >= 1);
    }

    #[test]
    fn bad_windows_are_errors() {
        let prob = blob(30.0, 20.0);
        for w in [PixelRect::new(0, 0, 0, 5), PixelRect::new(0, 0, 5, -1)] {
            assert!(matches!(
                mean_shift(&prob, w, TermCriteria::default()),
                Err(TrackError::EmptyWindow { .. })
            ));
        }
        // Touching the right edge: OpenCV asserts, we return an error.
        assert!(matches!(
            mean_shift(&prob, PixelRect::new(60, 5, 4, 4), TermCriteria::default()),
            Err(TrackError::WindowOutsideImage { .. })
        ));
        // Far away: OpenCV restarts from the image centre.
        assert!(
            mean_shift(
                &prob,
                PixelRect::new(500, 500, 4, 4),
                TermCriteria::default()
            )
            .is_ok()
        );
        assert!(matches!(
            mean_shift(
                &GrayImage::new(0, 0),
                PixelRect::new(0, 0, 1, 1),
                TermCriteria::default()
            ),
            Err(TrackError::EmptyImage { .. })
        ));
        let nan = TermCriteria {
            max_iterations: None,
            epsilon_px: Some(f64::NAN),
        };
        assert!(mean_shift(&prob, PixelRect::new(0, 0, 3, 3), nan).is_err());
    }

    #[test]
    fn moments_of_a_single_pixel() {
        let mut img = GrayImage::new(5, 5);
        img.put_pixel(3, 1, Luma([10]));
        let m = moments_in(&img, PixelRect::new(1, 0, 4, 4));
        assert_eq!((m.m00, m.m10, m.m01), (10.0, 20.0, 10.0));
        assert_eq!((m.mu20, m.mu11, m.mu02), (0.0, 0.0, 0.0));
    }
}
