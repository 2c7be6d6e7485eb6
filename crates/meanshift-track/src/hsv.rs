//! 8-bit colour conversions exactly as OpenCV computes them: RGB/BGR to HSV (`COLOR_RGB2HSV`,
//! hue 0..179) and RGB to gray (`COLOR_RGB2GRAY`), and `inRange`-style masks.
//!
//! OpenCV's 8-bit HSV uses fixed-point arithmetic with 12 fractional bits and division tables;
//! reproducing that (rather than converting through floating point) is what makes the results
//! equal bit for bit, which the parity fixtures check. Note that gray pixels (R = G = B) get
//! hue 0, which is red: a saturation mask is needed to keep them out of a red hue model.

use image::{GrayImage, ImageBuffer, Rgb, RgbImage};

use crate::error::{Result, TrackError};
use crate::rect::PixelRect;
use crate::view::ImageView;

/// Fractional bits of OpenCV's fixed-point HSV (`hsv_shift` in `color_hsv.simd.hpp`).
const HSV_SHIFT: u32 = 12;
/// Fractional bits of OpenCV's fixed-point gray conversion of 8-bit images (its vectorised
/// path, `color_rgb.simd.hpp`, which OpenCV 5 uses for every pixel; the older 14-bit table
/// gives different results for some colours, which the parity fixture catches).
const GRAY_SHIFT: u32 = 15;
/// ITU-R BT.601 luma weights 0.299, 0.587, 0.114 in 15-bit fixed point (`RY15`, `GY15`,
/// `BY15` in OpenCV).
const GRAY_WEIGHTS: [u32; 3] = [9798, 19235, 3735];
/// Hue range of 8-bit HSV: degrees / 2, so 0..179.
pub const HUE_RANGE: u32 = 180;

/// Order of the three colour channels of an 8-bit image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ChannelOrder {
    /// Red, green, blue (the `image` crate, PNG, JPEG).
    #[default]
    Rgb,
    /// Blue, green, red (OpenCV's `imread`).
    Bgr,
}

/// `255 << HSV_SHIFT`: OpenCV's saturation table holds `round(SATURATION_NUMERATOR / v)`
/// (`sdiv_table` in `color_hsv.simd.hpp`).
const SATURATION_NUMERATOR: f32 = (255 << HSV_SHIFT) as f32;
/// `(180 << HSV_SHIFT) / 6`: OpenCV's hue table holds `round((180 << 12) / (6 diff))`
/// (`hdiv_table180`), which is `round(HUE_NUMERATOR / diff)`.
const HUE_NUMERATOR: f32 = ((HUE_RANGE << HSV_SHIFT) / 6) as f32;
/// 1.5 * 2^23: adding it to an `f32` of magnitude below 2^22 leaves the value rounded half to
/// even to an integer in the low mantissa bits, plus `ROUNDING_OFFSET`.
const ROUNDING_MAGIC: f32 = 12_582_912.0;
/// The integer part of `ROUNDING_MAGIC`'s mantissa.
const ROUNDING_OFFSET: i32 = 0x40_0000;

/// `round_ties_even(numerator / denominator)` as an integer, for quotients below 2^22, without
/// a division table and without a float-to-integer conversion (the integer is read from the
/// bits of `quotient + 1.5 * 2^23`), so that a loop of it vectorises.
///
/// Exact wherever OpenCV uses its tables: for `numerator` = 255 * 4096 or 30 * 4096 and an
/// 8-bit `denominator`, the `f32` quotient is off the true one by at most 2^-24 of it
/// (below 0.07 / denominator), while a quotient that is not a half-integer is at least
/// 0.5 / denominator away from one, so the rounding goes the same way; half-integers are
/// represented exactly. The tests check every denominator against OpenCV's formula.
#[inline(always)]
fn rounded_quotient(numerator: f32, denominator: i32) -> i32 {
    let q = numerator / denominator.max(1) as f32;
    ((q + ROUNDING_MAGIC).to_bits() & 0x7F_FFFF) as i32 - ROUNDING_OFFSET
}

/// HSV of one 8-bit RGB colour, exactly as OpenCV's `COLOR_RGB2HSV`: hue 0..179 (degrees / 2),
/// saturation and value 0..255.
#[inline(always)]
pub fn rgb_to_hsv([r, g, b]: [u8; 3]) -> [u8; 3] {
    let (r, g, b) = (i32::from(r), i32::from(g), i32::from(b));
    let v = r.max(g).max(b);
    let diff = v - r.min(g).min(b);
    let round = 1 << (HSV_SHIFT - 1);
    // OpenCV's fixed point: s = (diff * sdiv_table[v] + round) >> 12, the tables computed.
    // Where v or diff is 0 the table holds 0 and so does the product's other factor.
    let s = (diff * rounded_quotient(SATURATION_NUMERATOR, v) + round) >> HSV_SHIFT;
    // OpenCV's three cases (red, green or blue the largest, in that order of precedence),
    // written as selects rather than branches: on a noisy image which channel is largest
    // is a coin toss, and mispredicted branches cost more than the arithmetic.
    let from_green = b - r + 2 * diff;
    let from_blue = r - g + 4 * diff;
    let h = if v == g { from_green } else { from_blue };
    let h = if v == r { g - b } else { h };
    let h = (h * rounded_quotient(HUE_NUMERATOR, diff) + round) >> HSV_SHIFT;
    let h = h + (HUE_RANGE as i32 & (h >> 31));
    [h as u8, s as u8, v as u8]
}

/// Gray level of one 8-bit RGB colour, exactly as OpenCV's `COLOR_RGB2GRAY`
/// (0.299 R + 0.587 G + 0.114 B in 15-bit fixed point, rounded).
pub fn rgb_to_gray([r, g, b]: [u8; 3]) -> u8 {
    let sum = u32::from(r) * GRAY_WEIGHTS[0]
        + u32::from(g) * GRAY_WEIGHTS[1]
        + u32::from(b) * GRAY_WEIGHTS[2]
        + (1 << (GRAY_SHIFT - 1));
    (sum >> GRAY_SHIFT) as u8
}

/// Largest image side accepted where this crate allocates an image from a size it is given,
/// pixels (four times the widest RGB-D colour camera, 4096 px).
pub const MAX_IMAGE_SIDE_PX: u32 = 16_384;

/// An 8-bit HSV image: channel 0 hue (0..179), 1 saturation, 2 value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HsvImage(ImageBuffer<Rgb<u8>, Vec<u8>>);

impl HsvImage {
    /// Convert a whole 8-bit colour image (`COLOR_RGB2HSV` or `COLOR_BGR2HSV`).
    pub fn from_image(image: &RgbImage, order: ChannelOrder) -> Self {
        let mut out = HsvImage(ImageBuffer::new(image.width(), image.height()));
        convert_into(image, order, image_rect(image), &mut out);
        out
    }

    /// Convert a whole 8-bit colour image into `self`, reusing its buffer: no allocation
    /// when `self` already has the image's size (reshaped otherwise). For per-frame use.
    pub fn from_image_into(&mut self, image: &RgbImage, order: ChannelOrder) {
        if self.0.dimensions() != image.dimensions() {
            self.0 = ImageBuffer::new(image.width(), image.height());
        }
        convert_into(image, order, image_rect(image), self);
    }

    /// An all-zero HSV image, to be filled by [`HsvImage::convert_region`].
    ///
    /// # Errors
    /// [`TrackError::InvalidParameter`] for a side above [`MAX_IMAGE_SIDE_PX`] (checked
    /// before allocating).
    pub fn new(width: u32, height: u32) -> Result<Self> {
        if width > MAX_IMAGE_SIDE_PX || height > MAX_IMAGE_SIDE_PX {
            return Err(TrackError::InvalidParameter {
                name: "HSV image size".into(),
                reason: format!("{width}x{height} px; at most {MAX_IMAGE_SIDE_PX} px a side"),
            });
        }
        Ok(HsvImage(ImageBuffer::new(width, height)))
    }

    /// Convert only the pixels of `region` (clipped to the image) of `image` into `self`,
    /// leaving the rest untouched: trackers need HSV only around their markers.
    ///
    /// # Errors
    /// [`TrackError::SizeMismatch`] when `image` and `self` differ in size.
    pub fn convert_region(
        &mut self,
        image: &RgbImage,
        order: ChannelOrder,
        region: PixelRect,
    ) -> Result<()> {
        if image.dimensions() != self.0.dimensions() {
            return Err(TrackError::SizeMismatch {
                what: "HSV target".into(),
                expected_width: image.width(),
                expected_height: image.height(),
                found_width: self.0.width(),
                found_height: self.0.height(),
            });
        }
        convert_into(image, order, region.intersect(&image_rect(image)), self);
        Ok(())
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.0.width()
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.0.height()
    }

    /// `[h, s, v]` of pixel `(x, y)`, or `None` outside the image.
    pub fn get(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        self.0.get_pixel_checked(x, y).map(|p| p.0)
    }

    /// The interleaved bytes.
    pub fn as_raw(&self) -> &[u8] {
        self.0.as_raw()
    }

    /// The underlying buffer (channels H, S, V), e.g. to save it as a PNG.
    pub fn as_buffer(&self) -> &ImageBuffer<Rgb<u8>, Vec<u8>> {
        &self.0
    }
}

fn image_rect(image: &RgbImage) -> PixelRect {
    PixelRect::image(image.width(), image.height())
}

fn convert_into(image: &RgbImage, order: ChannelOrder, region: PixelRect, out: &mut HsvImage) {
    match order {
        ChannelOrder::Rgb => convert_rows::<false>(image, region, out),
        ChannelOrder::Bgr => convert_rows::<true>(image, region, out),
    }
}

/// The conversion loop, one copy per channel order so that the order is not decided per
/// pixel. A plain loop over pixels of [`rgb_to_hsv`]: without table reads it vectorises.
fn convert_rows<const BGR: bool>(image: &RgbImage, region: PixelRect, out: &mut HsvImage) {
    if region.is_empty() {
        return;
    }
    let width = image.width() as usize;
    let (x0, x1) = (region.x as usize, region.right() as usize);
    let src = image.as_raw();
    let dst: &mut [u8] = &mut out.0;
    for y in region.y as usize..region.bottom() as usize {
        let start = (y * width + x0) * 3;
        let end = (y * width + x1) * 3;
        convert_run::<BGR>(&src[start..end], &mut dst[start..end]);
    }
}

/// [`rgb_to_hsv`] over a run of interleaved pixels (`src` and `dst` of one length).
#[inline]
pub(crate) fn convert_run<const BGR: bool>(src: &[u8], dst: &mut [u8]) {
    for (s, d) in src.chunks_exact(3).zip(dst.chunks_exact_mut(3)) {
        let rgb = if BGR {
            [s[2], s[1], s[0]]
        } else {
            [s[0], s[1], s[2]]
        };
        let [h, sat, v] = rgb_to_hsv(rgb);
        d[0] = h;
        d[1] = sat;
        d[2] = v;
    }
}

/// Gray image of a colour image (`COLOR_RGB2GRAY` or `COLOR_BGR2GRAY`).
pub fn gray_image(image: &RgbImage, order: ChannelOrder) -> GrayImage {
    let mut out = GrayImage::new(image.width(), image.height());
    for (s, d) in image.pixels().zip(out.pixels_mut()) {
        let rgb = match order {
            ChannelOrder::Rgb => s.0,
            ChannelOrder::Bgr => [s.0[2], s.0[1], s.0[0]],
        };
        d.0[0] = rgb_to_gray(rgb);
    }
    out
}

/// Inclusive per-channel bounds, as OpenCV's `inRange(src, lower, upper)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChannelRange {
    /// Lowest accepted value per channel.
    pub lower: [u8; 3],
    /// Highest accepted value per channel.
    pub upper: [u8; 3],
}

impl ChannelRange {
    /// The mask of OpenCV's CamShift sample (`camshiftdemo.cpp`): saturation >= 30 and value
    /// in 10..=255, any hue.
    pub const CAMSHIFT_DEMO: ChannelRange = ChannelRange {
        lower: [0, 30, 10],
        upper: [180, 255, 255],
    };

    /// True when every channel of `pixel` is within its bounds.
    #[inline]
    pub fn contains(&self, pixel: [u8; 3]) -> bool {
        (0..3).all(|c| self.lower[c] <= pixel[c] && pixel[c] <= self.upper[c])
    }
}

/// `inRange` on a 3-channel image: 255 where every channel is within `range`, else 0.
///
/// # Errors
/// [`TrackError::ChannelCount`] when the image does not have 3 channels.
pub fn in_range(image: ImageView<'_>, range: &ChannelRange) -> Result<GrayImage> {
    if image.channels() != 3 {
        return Err(TrackError::ChannelCount {
            what: "in_range".into(),
            expected: "3".into(),
            found: image.channels(),
        });
    }
    let mut out = GrayImage::new(image.width(), image.height());
    for (s, d) in image.data().chunks_exact(3).zip(out.iter_mut()) {
        *d = if range.contains([s[0], s[1], s[2]]) {
            255
        } else {
            0
        };
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primaries_and_grays() {
        assert_eq!(rgb_to_hsv([255, 0, 0]), [0, 255, 255]);
        assert_eq!(rgb_to_hsv([0, 255, 0]), [60, 255, 255]);
        assert_eq!(rgb_to_hsv([0, 0, 255]), [120, 255, 255]);
        // Gray is hue 0 (red) with zero saturation.
        assert_eq!(rgb_to_hsv([128, 128, 128]), [0, 0, 128]);
        assert_eq!(rgb_to_hsv([0, 0, 0]), [0, 0, 0]);
        // Magenta-ish reds wrap to the top of the hue range.
        assert_eq!(rgb_to_hsv([255, 0, 10])[0], 179);
        assert_eq!(rgb_to_gray([255, 255, 255]), 255);
        assert_eq!(rgb_to_gray([255, 0, 0]), 76);
    }

    /// OpenCV's division tables as it builds them (`saturate_cast<int>` of a double, round
    /// half to even).
    fn opencv_tables() -> ([i32; 256], [i32; 256]) {
        let mut saturation = [0; 256];
        let mut hue = [0; 256];
        for i in 1..256 {
            saturation[i] = (f64::from(255 << HSV_SHIFT) / i as f64).round_ties_even() as i32;
            hue[i] = (f64::from(180 << HSV_SHIFT) / (6.0 * i as f64)).round_ties_even() as i32;
        }
        (saturation, hue)
    }

    #[test]
    fn computed_divisions_equal_opencvs_tables() {
        let (saturation, hue) = opencv_tables();
        for i in 1..256 {
            assert_eq!(
                rounded_quotient(SATURATION_NUMERATOR, i),
                saturation[i as usize]
            );
            assert_eq!(rounded_quotient(HUE_NUMERATOR, i), hue[i as usize]);
        }
    }

    /// OpenCV's scalar code as written, with its branches and tables, for the branchless,
    /// table-free version to be checked against.
    fn reference_hsv(tables: &([i32; 256], [i32; 256]), [r, g, b]: [u8; 3]) -> [u8; 3] {
        let (saturation, hue) = tables;
        let (r, g, b) = (i32::from(r), i32::from(g), i32::from(b));
        let v = r.max(g).max(b);
        let diff = v - r.min(g).min(b);
        let round = 1 << (HSV_SHIFT - 1);
        let s = (diff * saturation[v as usize] + round) >> HSV_SHIFT;
        let h = if v == r {
            g - b
        } else if v == g {
            b - r + 2 * diff
        } else {
            r - g + 4 * diff
        };
        let mut h = (h * hue[diff as usize] + round) >> HSV_SHIFT;
        if h < 0 {
            h += HUE_RANGE as i32;
        }
        [h as u8, s as u8, v as u8]
    }

    #[test]
    fn branchless_conversion_equals_opencvs_branches_on_every_colour() {
        let tables = opencv_tables();
        // All 2^24 colours, one image row per red level, through the image loop (the
        // vectorised path) in both channel orders.
        let mut row = RgbImage::new(256 * 256, 1);
        let mut bgr = HsvImage::new(1, 1).unwrap();
        let mut rgb = HsvImage::new(1, 1).unwrap();
        for r in 0..=255u8 {
            for (i, p) in row.pixels_mut().enumerate() {
                p.0 = [r, (i >> 8) as u8, i as u8];
            }
            rgb.from_image_into(&row, ChannelOrder::Rgb);
            bgr.from_image_into(&row, ChannelOrder::Bgr);
            for (i, p) in row.pixels().enumerate() {
                let [r, g, b] = p.0;
                let x = i as u32;
                assert_eq!(rgb.get(x, 0), Some(reference_hsv(&tables, [r, g, b])));
                assert_eq!(bgr.get(x, 0), Some(reference_hsv(&tables, [b, g, r])));
            }
        }
        assert_eq!(
            rgb_to_hsv([12, 200, 7]),
            reference_hsv(&tables, [12, 200, 7])
        );
    }

    #[test]
    fn region_conversion_matches_the_whole_image() {
        let img = RgbImage::from_fn(9, 7, |x, y| Rgb([(x * 29) as u8, (y * 37) as u8, 90]));
        let full = HsvImage::from_image(&img, ChannelOrder::Rgb);
        let mut part = HsvImage::new(9, 7).unwrap();
        part.convert_region(&img, ChannelOrder::Rgb, PixelRect::new(2, 1, 30, 3))
            .expect("same size");
        assert_eq!(part.get(5, 2), full.get(5, 2));
        assert_eq!(part.get(1, 2), Some([0, 0, 0]));
        assert_eq!(part.get(5, 5), Some([0, 0, 0]));
        let other = RgbImage::new(3, 3);
        assert!(
            part.convert_region(&other, ChannelOrder::Rgb, PixelRect::new(0, 0, 1, 1))
                .is_err()
        );
    }
}
