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
    /// Per histogram dimension: the channel read and each channel value's bin offset, with
    /// values outside the range sent past the end of `bin_value` (see `padded`).
    offsets: Vec<(usize, [u32; 256])>,
    /// `bin_value` followed by zeros, long enough that any sum of offsets lands in it:
    /// a pixel with a value out of range reads a zero without a branch.
    padded: Vec<u8>,
    /// For a one-dimensional histogram: the channel read and the back-projection value of
    /// each of its 256 levels, so that a pixel costs one lookup.
    direct: Option<(usize, Box<[u8; 256]>)>,
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
        let bin_value: Vec<u8> = hist
            .values()
            .iter()
            .map(|&v| saturate_u8(v * scale))
            .collect();
        // Bins number at most 2^24 (the spec's limit), so `dims * total` fits in u32.
        let total = bin_value.len();
        let dims = hist.spec().dims();
        let offsets = hist.offset_tables(total as u32);
        let mut padded = bin_value.clone();
        padded.resize(total * dims + 1, 0);
        let direct = match offsets.as_slice() {
            [(channel, offset)] => Some((*channel, Box::new(offset.map(|k| padded[k as usize])))),
            _ => None,
        };
        Ok(Self {
            hist,
            bin_value,
            offsets,
            padded,
            direct,
        })
    }

    /// The 8-bit back-projection value of each bin.
    pub(crate) fn bin_values(&self) -> &[u8] {
        &self.bin_value
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
        let channels = image.channels();
        let (x0, x1) = (region.x as usize, region.right() as usize);
        let src = image.data();
        let dst: &mut [u8] = out;
        for y in region.y as usize..region.bottom() as usize {
            let row = y * width;
            let pixels = &src[(row + x0) * channels..(row + x1) * channels];
            self.project_row(pixels, channels, &mut dst[row + x0..row + x1]);
        }
        Ok(())
    }

    /// Back-project a whole image into `out`, reusing its buffer: no allocation when `out`
    /// already has the image's size (reshaped otherwise). For per-frame use.
    ///
    /// # Errors
    /// [`TrackError::ChannelCount`] when the image lacks a histogram channel.
    pub fn project_into(&self, image: ImageView<'_>, out: &mut GrayImage) -> Result<()> {
        self.hist.check_channels(&image)?;
        if out.dimensions() != (image.width(), image.height()) {
            *out = GrayImage::new(image.width(), image.height());
        }
        let channels = image.channels();
        self.project_row(image.data(), channels, out);
        Ok(())
    }

    /// One run of pixels: table lookups only, one copy of the loop per dimension count.
    fn project_row(&self, pixels: &[u8], channels: usize, out: &mut [u8]) {
        let table = self.padded.as_slice();
        if let Some((c0, levels)) = &self.direct {
            for (p, d) in pixels.chunks_exact(channels).zip(out.iter_mut()) {
                *d = levels[usize::from(p[*c0])];
            }
            return;
        }
        match self.offsets.as_slice() {
            [(c0, t0), (c1, t1)] => {
                for (p, d) in pixels.chunks_exact(channels).zip(out.iter_mut()) {
                    let k = t0[usize::from(p[*c0])] + t1[usize::from(p[*c1])];
                    *d = table[k as usize];
                }
            }
            _ => {
                for (p, d) in pixels.chunks_exact(channels).zip(out.iter_mut()) {
                    let k: u32 = self
                        .offsets
                        .iter()
                        .map(|(c, t)| t[usize::from(p[*c])])
                        .sum();
                    *d = table[k as usize];
                }
            }
        }
    }

    /// Back-project a whole image (OpenCV's `calcBackProject`).
    ///
    /// # Errors
    /// [`TrackError::ChannelCount`] when the image lacks a histogram channel.
    pub fn project(&self, image: ImageView<'_>) -> Result<GrayImage> {
        let mut out = GrayImage::new(image.width(), image.height());
        self.project_into(image, &mut out)?;
        Ok(out)
    }

    /// The back-projection value of one pixel (indices in range, channels checked).
    #[cfg(test)]
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
    fn table_projection_equals_the_bin_lookup_in_every_dimension_count() {
        let img = image::RgbImage::from_fn(23, 11, |x, y| {
            image::Rgb([(x * 11) as u8, (y * 23) as u8, ((x * y * 7) % 256) as u8])
        });
        let view = ImageView::from(&img);
        let specs = [
            HistogramSpec::hue(16),
            HistogramSpec::hue_saturation(30, 32),
            HistogramSpec::rgb(8),
        ];
        for mut spec in specs {
            // A narrower range than the values present, so that some pixels fall outside.
            spec.ranges[0] = [20.0, 160.0];
            let mut h = Histogram::new(spec).expect("valid");
            for (k, v) in h.values_mut().iter_mut().enumerate() {
                *v = ((k * 37) % 300) as f32;
            }
            let bp = BackProjector::new(h, 0.9).expect("finite");
            let mut out = GrayImage::new(2, 2);
            bp.project_into(view, &mut out).expect("3 channels");
            let mut outside = 0;
            for y in 0..11 {
                for x in 0..23 {
                    let expected = bp.value_at(&view, x, y);
                    outside += usize::from(bp.histogram().bin_at(&view, x, y).is_none());
                    assert_eq!(out.get_pixel(x as u32, y as u32).0[0], expected);
                }
            }
            assert!(outside > 0, "the test needs pixels out of range");
        }
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
