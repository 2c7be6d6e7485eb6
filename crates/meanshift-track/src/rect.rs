//! Pixel rectangles with OpenCV's `cv::Rect` semantics.

use nalgebra::Point2;

/// An axis-aligned rectangle of whole pixels: columns `x .. x + width`, rows `y .. y + height`
/// (OpenCV's `cv::Rect`: top-left corner and size, in pixels). Pixel centres are at integer
/// coordinates (`docs/conventions.md`), so the rectangle's geometric centre is at
/// `(x + (width - 1) / 2, y + (height - 1) / 2)`, see [`PixelRect::center`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct PixelRect {
    /// Left column.
    pub x: i32,
    /// Top row.
    pub y: i32,
    /// Width in pixels.
    pub width: i32,
    /// Height in pixels.
    pub height: i32,
}

impl PixelRect {
    /// A rectangle from its top-left corner and size.
    pub const fn new(x: i32, y: i32, width: i32, height: i32) -> Self {
        Self {
            x,
            y,
            width,
            height,
        }
    }

    /// The whole of a `width` x `height` image.
    pub fn image(width: u32, height: u32) -> Self {
        Self::new(0, 0, clamp_i32(width), clamp_i32(height))
    }

    /// True when the rectangle has no area (OpenCV's `Rect::empty`).
    pub const fn is_empty(&self) -> bool {
        self.width <= 0 || self.height <= 0
    }

    /// Number of pixels (0 when empty).
    pub fn area(&self) -> u64 {
        if self.is_empty() {
            0
        } else {
            self.width as u64 * self.height as u64
        }
    }

    /// One past the last column (`x + width`), without overflow.
    pub fn right(&self) -> i64 {
        i64::from(self.x) + i64::from(self.width)
    }

    /// One past the last row (`y + height`), without overflow.
    pub fn bottom(&self) -> i64 {
        i64::from(self.y) + i64::from(self.height)
    }

    /// Intersection exactly as OpenCV's `Rect & Rect`: an empty operand or disjoint rectangles
    /// give `Rect()` (all zero); rectangles that only touch give a zero-width (or -height)
    /// rectangle at the touching edge.
    pub fn intersect(&self, other: &PixelRect) -> PixelRect {
        if self.is_empty() || other.is_empty() {
            return PixelRect::default();
        }
        let (x_min, x_max) = if self.x < other.x {
            (self, other)
        } else {
            (other, self)
        };
        let (y_min, y_max) = if self.y < other.y {
            (self, other)
        } else {
            (other, self)
        };
        let dx = i64::from(x_max.x) - i64::from(x_min.x);
        let dy = i64::from(y_max.y) - i64::from(y_min.y);
        if i64::from(x_min.width) < dx || i64::from(y_min.height) < dy {
            return PixelRect::default();
        }
        PixelRect {
            x: x_max.x,
            y: y_max.y,
            width: (i64::from(x_min.width) - dx).min(i64::from(x_max.width)) as i32,
            height: (i64::from(y_min.height) - dy).min(i64::from(y_max.height)) as i32,
        }
    }

    /// True when pixel `(x, y)` lies in `self`.
    pub fn contains(&self, x: i32, y: i32) -> bool {
        x >= self.x && y >= self.y && i64::from(x) < self.right() && i64::from(y) < self.bottom()
    }

    /// True when every pixel of `self` lies in `other` (an empty `self` is never contained).
    pub fn is_inside(&self, other: &PixelRect) -> bool {
        !self.is_empty()
            && self.x >= other.x
            && self.y >= other.y
            && self.right() <= other.right()
            && self.bottom() <= other.bottom()
    }

    /// Geometric centre in pixel coordinates (pixel centres at integers).
    pub fn center(&self) -> Point2<f64> {
        Point2::new(
            f64::from(self.x) + (f64::from(self.width) - 1.0) * 0.5,
            f64::from(self.y) + (f64::from(self.height) - 1.0) * 0.5,
        )
    }

    /// The rectangle of this size whose geometric centre is nearest to `center` (ties go to
    /// the lower coordinate). Saturates at the `i32` range.
    pub fn centered_at(center: Point2<f64>, width: i32, height: i32) -> PixelRect {
        let corner = |c: f64, size: i32| {
            let v = (c - (f64::from(size) - 1.0) * 0.5 - 0.5).ceil();
            if v.is_nan() {
                0
            } else {
                v.clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
            }
        };
        PixelRect::new(
            corner(center.x, width),
            corner(center.y, height),
            width,
            height,
        )
    }

    /// The rectangle grown by `dx` columns on the left and right and `dy` rows on top and
    /// bottom (shrunk for negative values). Saturates at the `i32` range.
    pub fn grown(&self, dx: i32, dy: i32) -> PixelRect {
        PixelRect::new(
            self.x.saturating_sub(dx),
            self.y.saturating_sub(dy),
            self.width.saturating_add(dx.saturating_mul(2)),
            self.height.saturating_add(dy.saturating_mul(2)),
        )
    }

    /// The same rectangle moved by `(dx, dy)`, saturating at the `i32` range.
    pub fn shifted(&self, dx: i32, dy: i32) -> PixelRect {
        PixelRect::new(
            self.x.saturating_add(dx),
            self.y.saturating_add(dy),
            self.width,
            self.height,
        )
    }
}

pub(crate) fn clamp_i32(v: u32) -> i32 {
    i32::try_from(v).unwrap_or(i32::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intersection_follows_opencv() {
        let a = PixelRect::new(-5, -4, 20, 16);
        let image = PixelRect::image(96, 72);
        assert_eq!(a.intersect(&image), PixelRect::new(0, 0, 15, 12));
        // Touching rectangles: zero width at the shared edge, not Rect().
        let b = PixelRect::new(10, 0, 5, 5);
        assert_eq!(
            b.intersect(&PixelRect::new(15, 0, 5, 5)),
            PixelRect::new(15, 0, 0, 5)
        );
        // Disjoint: Rect().
        assert_eq!(
            b.intersect(&PixelRect::new(30, 0, 5, 5)),
            PixelRect::default()
        );
        assert_eq!(
            b.intersect(&PixelRect::new(0, 0, 0, 5)),
            PixelRect::default()
        );
        // Contained.
        assert_eq!(
            PixelRect::new(3, 4, 5, 6).intersect(&image),
            PixelRect::new(3, 4, 5, 6)
        );
    }

    #[test]
    fn centre_round_trips_through_centered_at() {
        for (w, h) in [(12, 12), (7, 9), (1, 1), (10, 3)] {
            for (cx, cy) in [(40.0, 30.0), (40.25, 29.75), (3.5, 7.5), (0.0, 0.0)] {
                let r = PixelRect::centered_at(Point2::new(cx, cy), w, h);
                let c = r.center();
                assert!(
                    (c.x - cx).abs() <= 0.5 && (c.y - cy).abs() <= 0.5,
                    "{r:?} {cx} {cy}"
                );
                assert_eq!((r.width, r.height), (w, h));
            }
        }
        let r = PixelRect::new(7, 9, 12, 10);
        assert_eq!(PixelRect::centered_at(r.center(), 12, 10), r);
    }

    #[test]
    fn extreme_values_do_not_overflow() {
        let r = PixelRect::new(i32::MAX - 1, i32::MIN, i32::MAX, i32::MAX);
        assert_eq!(r.intersect(&PixelRect::image(10, 10)), PixelRect::default());
        let g = r.grown(i32::MAX, i32::MAX);
        assert!(g.width == i32::MAX && g.x == -1 && g.y == i32::MIN);
        assert!(PixelRect::centered_at(Point2::new(f64::NAN, 1e300), 3, 3).y == i32::MAX);
    }
}
