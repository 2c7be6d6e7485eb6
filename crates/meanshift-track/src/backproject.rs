//! Back-projection exactly as OpenCV's `calcBackProject` on 8-bit images: each pixel gets the
//! value of its histogram bin times `scale`, rounded half to even and saturated to `0..=255`;
//! pixels outside the histogram's ranges get 0.

use image::GrayImage;

use crate::error::{Result, TrackError};
use crate::histogram::Histogram;
use crate::rect::PixelRect;
use crate::view::ImageView;

/// A histogram turned into one 8-bit back-projection value per bin, so back-projecting a pixel
/// is a lookup. Build it once per histogram and scale, use it for every frame.
#[derive(Debug, Clone, PartialEq)]
pub struct BackProjector {
    hist: Histogram,
    bin_value: Vec<u8>,
}

impl BackProjector {
    /// Precompute `saturate_cast<uchar>(bin * scale)` (OpenCV's float arithmetic) per bin.
    ///
    /// # Errors
    /// [`TrackError::InvalidParameter`] when `scale` is not finite.
    pub fn new(hist: Histogram, scale: f64) -> Result<Self> {
        if !scale.is_finite() {
            return Err(TrackError::param(
                "back-projection scale",
                format!("{scale} is not finite"),
            ));
        }
        let scale = scale as f32;
        let bin_value = hist
            .values()
            .iter()
            .map(|&v| saturate_u8(v * scale))
            .collect();
        Ok(Self { hist, bin_value })
    }

    /// The histogram.
    pub fn histogram(&self) -> &Histogram {
        &self.hist
    }

    /// Back-project the pixels of `region` (clipped to the image) of `image` into the same
    /// pixels of `out`, leaving the rest of `out` untouched.
    ///
    /// # Errors
    /// [`TrackError::ChannelCount`] when the image lacks a histogram channel;
    /// [`TrackError::SizeMismatch`] when `out` differs in size from `image`.
    pub fn project_region(
        &self,
        image: ImageView<'_>,
        region: PixelRect,
        out: &mut GrayImage,
    ) -> Result<()> {
        self.hist.check_channels(&image)?;
        image.check_same_size("back-projection output", out.width(), out.height())?;
        let region = region.intersect(&image.rect());
        if region.is_empty() {
            return Ok(());
        }
        let width = image.width() as usize;
        let dst: &mut [u8] = out;
        for y in region.y as usize..region.bottom() as usize {
            for x in region.x as usize..region.right() as usize {
                dst[y * width + x] = self.value_at(&image, x, y);
            }
        }
        Ok(())
    }

    /// Back-project a whole image (OpenCV's `calcBackProject`).
    ///
    /// # Errors
    /// [`TrackError::ChannelCount`] when the image lacks a histogram channel.
    pub fn project(&self, image: ImageView<'_>) -> Result<GrayImage> {
        let mut out = GrayImage::new(image.width(), image.height());
        self.project_region(image, image.rect(), &mut out)?;
        Ok(out)
    }

    /// The back-projection value of one pixel (indices in range, channels checked).
    #[inline]
    pub(crate) fn value_at(&self, image: &ImageView<'_>, x: usize, y: usize) -> u8 {
        self.hist
            .bin_at(image, x, y)
            .map_or(0, |bin| self.bin_value[bin])
    }

    /// The back-projection value of a pixel given as channel values.
    pub fn value_of(&self, pixel: &[u8]) -> u8 {
        self.hist.bin_of(pixel).map_or(0, |bin| self.bin_value[bin])
    }
}

/// OpenCV's `saturate_cast<uchar>(float)`: round half to even, clamp to 0..=255, NaN to 0.
pub(crate) fn saturate_u8(v: f32) -> u8 {
    let r = v.round_ties_even();
    if r.is_nan() || r <= 0.0 {
        0
    } else if r >= 255.0 {
        255
    } else {
        r as u8
    }
}

/// OpenCV's `calcBackProject(image, channels, hist, ranges, scale)` in one call.
///
/// # Errors
/// As [`BackProjector::new`] and [`BackProjector::project`].
pub fn back_project(image: ImageView<'_>, hist: &Histogram, scale: f64) -> Result<GrayImage> {
    BackProjector::new(hist.clone(), scale)?.project(image)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::histogram::HistogramSpec;
    use image::Luma;

    #[test]
    fn saturation_rounds_half_to_even() {
        assert_eq!(saturate_u8(0.5), 0);
        assert_eq!(saturate_u8(1.5), 2);
        assert_eq!(saturate_u8(2.5), 2);
        assert_eq!(saturate_u8(-3.0), 0);
        assert_eq!(saturate_u8(300.0), 255);
        assert_eq!(saturate_u8(f32::NAN), 0);
    }

    #[test]
    fn region_only_touches_its_pixels() {
        let img = GrayImage::from_fn(6, 4, |x, _| Luma([if x < 3 { 10 } else { 200 }]));
        let mut h = Histogram::new(HistogramSpec::gray(2)).expect("valid");
        h.values_mut().copy_from_slice(&[100.0, 7.0]);
        let bp = BackProjector::new(h, 1.0).expect("finite");
        let mut out = GrayImage::from_pixel(6, 4, Luma([1]));
        bp.project_region(ImageView::from(&img), PixelRect::new(2, 1, 2, 2), &mut out)
            .expect("same size");
        assert_eq!(out.get_pixel(2, 1).0[0], 100);
        assert_eq!(out.get_pixel(3, 2).0[0], 7);
        assert_eq!(out.get_pixel(0, 0).0[0], 1);
        assert_eq!(out.get_pixel(4, 1).0[0], 1);
        let mut wrong = GrayImage::new(2, 2);
        assert!(
            bp.project_region(
                ImageView::from(&img),
                PixelRect::new(0, 0, 1, 1),
                &mut wrong
            )
            .is_err()
        );
    }
}
