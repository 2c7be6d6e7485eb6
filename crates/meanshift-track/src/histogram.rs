//! Histograms of 8-bit images with OpenCV's `calcHist` binning, and min–max normalisation
//! (`normalize(.., NORM_MINMAX)`).
//!
//! Binning (OpenCV `calcHistLookupTables_8u`, uniform ranges): value `j` of a channel with
//! range `[low, high)` and `n` bins falls in bin `floor(j * t - t * low)` with
//! `t = n / (high - low)` (in `f64`), clamped to `0..n`; values outside `[low, high)` are not
//! counted. Counts are stored as `f32`, as OpenCV's histograms are.

use image::GrayImage;

use crate::error::{Result, TrackError};
use crate::rect::PixelRect;
use crate::view::ImageView;

/// Marks a channel value outside the histogram's range in the lookup table.
const OUT_OF_RANGE: u32 = u32::MAX;
/// Largest number of bins a histogram may have in all (OpenCV's `CV_MAX_DIM`-independent
/// practical limit; 2^24 bins of `f32` are 64 MiB).
const MAX_TOTAL_BINS: usize = 1 << 24;

/// Which channels a histogram counts, with how many bins and over which value range.
#[derive(Debug, Clone, PartialEq)]
pub struct HistogramSpec {
    /// Channel index per dimension (e.g. `[0]` for the hue of an HSV image).
    pub channels: Vec<usize>,
    /// Bins per dimension (OpenCV's `histSize`).
    pub bins: Vec<usize>,
    /// `[low, high)` value range per dimension (OpenCV's `ranges`, uniform).
    pub ranges: Vec<[f32; 2]>,
}

impl HistogramSpec {
    /// Hue of an HSV image: `bins` bins over `[0, 180)` (the paper's model; OpenCV's CamShift
    /// sample uses 16 bins).
    pub fn hue(bins: usize) -> Self {
        Self {
            channels: vec![0],
            bins: vec![bins],
            ranges: vec![[0.0, 180.0]],
        }
    }

    /// Hue and saturation of an HSV image (`hue_bins` over `[0, 180)`, `saturation_bins`
    /// over `[0, 256)`).
    pub fn hue_saturation(hue_bins: usize, saturation_bins: usize) -> Self {
        Self {
            channels: vec![0, 1],
            bins: vec![hue_bins, saturation_bins],
            ranges: vec![[0.0, 180.0], [0.0, 256.0]],
        }
    }

    /// Three channels of a colour image, `bins` bins each over `[0, 256)`.
    pub fn rgb(bins: usize) -> Self {
        Self {
            channels: vec![0, 1, 2],
            bins: vec![bins; 3],
            ranges: vec![[0.0, 256.0]; 3],
        }
    }

    /// One channel of a gray image, `bins` bins over `[0, 256)`.
    pub fn gray(bins: usize) -> Self {
        Self {
            channels: vec![0],
            bins: vec![bins],
            ranges: vec![[0.0, 256.0]],
        }
    }

    /// Number of dimensions.
    pub fn dims(&self) -> usize {
        self.channels.len()
    }

    /// Check the spec.
    ///
    /// # Errors
    /// [`TrackError::InvalidParameter`] for no dimensions or more than 3, lists of different
    /// lengths, a zero bin count, too many bins in all, or a range that is not finite with
    /// `low < high`.
    pub fn validate(&self) -> Result<()> {
        let dims = self.channels.len();
        if !(1..=3).contains(&dims) {
            return Err(TrackError::param(
                "histogram channels",
                format!("{dims} dimensions; 1 to 3 are supported"),
            ));
        }
        if self.bins.len() != dims || self.ranges.len() != dims {
            return Err(TrackError::param(
                "histogram spec",
                format!(
                    "{} channels, {} bin counts and {} ranges; the three lists must have the same length",
                    dims,
                    self.bins.len(),
                    self.ranges.len()
                ),
            ));
        }
        let mut total = 1usize;
        for (&n, &[low, high]) in self.bins.iter().zip(&self.ranges) {
            if n == 0 {
                return Err(TrackError::param("histogram bins", "a bin count is 0"));
            }
            total = total.saturating_mul(n);
            if !(low.is_finite() && high.is_finite() && low < high) {
                return Err(TrackError::param(
                    "histogram range",
                    format!("[{low}, {high}) is not a finite range with low < high"),
                ));
            }
        }
        if total > MAX_TOTAL_BINS {
            return Err(TrackError::param(
                "histogram bins",
                format!("{total} bins in all; at most {MAX_TOTAL_BINS}"),
            ));
        }
        Ok(())
    }
}

/// A dense histogram (row-major over the dimensions, the first channel slowest, as OpenCV's
/// `Mat` histograms), with the lookup tables that map channel values to bins.
#[derive(Debug, Clone, PartialEq)]
pub struct Histogram {
    spec: HistogramSpec,
    values: Vec<f32>,
    /// Per dimension, per channel value: the bin's offset into `values`, or [`OUT_OF_RANGE`].
    lut: Vec<[u32; 256]>,
}

impl Histogram {
    /// An all-zero histogram.
    ///
    /// # Errors
    /// As [`HistogramSpec::validate`].
    pub fn new(spec: HistogramSpec) -> Result<Self> {
        spec.validate()?;
        let total: usize = spec.bins.iter().product();
        let mut lut = Vec::with_capacity(spec.dims());
        let mut stride = total;
        for (&n, &[low, high]) in spec.bins.iter().zip(&spec.ranges) {
            stride /= n;
            let (low, high) = (f64::from(low), f64::from(high));
            let t = n as f64 / (high - low);
            let b = -t * low;
            let mut table = [OUT_OF_RANGE; 256];
            for (j, entry) in table.iter_mut().enumerate() {
                let value = j as f64;
                if value >= low && value < high {
                    let idx = (value * t + b).floor().clamp(0.0, (n - 1) as f64) as usize;
                    *entry = (idx * stride) as u32;
                }
            }
            lut.push(table);
        }
        Ok(Self {
            spec,
            values: vec![0.0; total],
            lut,
        })
    }

    /// OpenCV's `calcHist` of `image` restricted to `roi` (clipped to the image; `None` for
    /// the whole image), counting only pixels where `mask` (same size as the image) is
    /// non-zero.
    ///
    /// # Errors
    /// As [`Histogram::new`]; [`TrackError::ChannelCount`] when a channel of the spec does
    /// not exist in the image; [`TrackError::SizeMismatch`] for a mask of another size;
    /// [`TrackError::EmptyWindow`] / [`TrackError::WindowOutsideImage`] for a bad `roi`.
    pub fn calc(
        image: ImageView<'_>,
        spec: HistogramSpec,
        mask: Option<&GrayImage>,
        roi: Option<PixelRect>,
    ) -> Result<Self> {
        let mut hist = Self::new(spec)?;
        hist.accumulate(image, mask, roi)?;
        Ok(hist)
    }

    /// Add the pixels of `image` (see [`Histogram::calc`]) to the counts.
    ///
    /// # Errors
    /// As [`Histogram::calc`].
    pub fn accumulate(
        &mut self,
        image: ImageView<'_>,
        mask: Option<&GrayImage>,
        roi: Option<PixelRect>,
    ) -> Result<()> {
        self.check_channels(&image)?;
        if let Some(m) = mask {
            image.check_same_size("histogram mask", m.width(), m.height())?;
        }
        let roi = image.clip_roi(roi)?;
        let width = image.width() as usize;
        for y in roi.y as usize..roi.bottom() as usize {
            for x in roi.x as usize..roi.right() as usize {
                if let Some(m) = mask
                    && m.as_raw()[y * width + x] == 0
                {
                    continue;
                }
                if let Some(bin) = self.bin_at(&image, x, y) {
                    self.values[bin] += 1.0;
                }
            }
        }
        Ok(())
    }

    pub(crate) fn check_channels(&self, image: &ImageView<'_>) -> Result<()> {
        if let Some(&c) = self.spec.channels.iter().find(|&&c| c >= image.channels()) {
            return Err(TrackError::ChannelCount {
                what: format!("histogram channel {c}"),
                expected: format!("at least {}", c + 1),
                found: image.channels(),
            });
        }
        Ok(())
    }

    /// The bin of pixel `(x, y)` (indices in range, channels checked), or `None` when a
    /// channel value is outside its range.
    #[inline]
    pub(crate) fn bin_at(&self, image: &ImageView<'_>, x: usize, y: usize) -> Option<usize> {
        let mut bin = 0usize;
        for (table, &c) in self.lut.iter().zip(&self.spec.channels) {
            let offset = table[usize::from(image.at(x, y, c))];
            if offset == OUT_OF_RANGE {
                return None;
            }
            bin += offset as usize;
        }
        Some(bin)
    }

    /// Per histogram dimension: the image channel it reads and, per channel value, the bin's
    /// offset into the values with `out_of_range` for values outside the dimension's range.
    pub(crate) fn offset_tables(&self, out_of_range: u32) -> Vec<(usize, [u32; 256])> {
        self.lut
            .iter()
            .zip(&self.spec.channels)
            .map(|(table, &c)| {
                let mut t = *table;
                for v in &mut t {
                    if *v == OUT_OF_RANGE {
                        *v = out_of_range;
                    }
                }
                (c, t)
            })
            .collect()
    }

    /// The bin of a pixel given as its channel values, or `None` when a value is outside
    /// its range or a channel is missing.
    pub fn bin_of(&self, pixel: &[u8]) -> Option<usize> {
        let mut bin = 0usize;
        for (table, &c) in self.lut.iter().zip(&self.spec.channels) {
            let offset = table[usize::from(*pixel.get(c)?)];
            if offset == OUT_OF_RANGE {
                return None;
            }
            bin += offset as usize;
        }
        Some(bin)
    }

    /// Min–max normalisation exactly as OpenCV's `normalize(h, h, a, b, NORM_MINMAX)` on a
    /// `CV_32F` histogram: the smallest bin becomes `min(a, b)`, the largest `max(a, b)`.
    /// A constant histogram becomes all `min(a, b)`.
    ///
    /// # Errors
    /// [`TrackError::InvalidParameter`] when `a` or `b` is not finite.
    pub fn normalize_min_max(&mut self, a: f64, b: f64) -> Result<()> {
        if !(a.is_finite() && b.is_finite()) {
            return Err(TrackError::param(
                "normalize range",
                format!("[{a}, {b}] is not finite"),
            ));
        }
        let (dmin, dmax) = (a.min(b), a.max(b));
        let (mut smin, mut smax) = (f64::INFINITY, f64::NEG_INFINITY);
        for &v in &self.values {
            smin = smin.min(f64::from(v));
            smax = smax.max(f64::from(v));
        }
        let scale = (dmax - dmin)
            * if smax - smin > f64::EPSILON {
                1.0 / (smax - smin)
            } else {
                0.0
            };
        // OpenCV, rtype CV_32F: scale and shift rounded to float, shift = dmin - smin*scale.
        let scale = f64::from(scale as f32);
        let shift = f64::from(dmin as f32) - f64::from((smin * scale) as f32);
        let (scale, shift) = (scale as f32, shift as f32);
        for v in &mut self.values {
            // OpenCV converts with a fused multiply-add (`v_fma` in `cvt_32f`).
            *v = v.mul_add(scale, shift);
        }
        Ok(())
    }

    /// The spec.
    pub fn spec(&self) -> &HistogramSpec {
        &self.spec
    }

    /// The bin values, row-major (first channel slowest).
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// Mutable bin values (e.g. to zero a bin by hand).
    pub fn values_mut(&mut self) -> &mut [f32] {
        &mut self.values
    }

    /// Sum of all bins.
    pub fn total(&self) -> f64 {
        self.values.iter().map(|&v| f64::from(v)).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Luma;

    #[test]
    fn binning_of_hue_16() {
        let hist = Histogram::new(HistogramSpec::hue(16)).expect("valid");
        // 180 / 16 = 11.25 hue units per bin.
        assert_eq!(hist.bin_of(&[0]), Some(0));
        assert_eq!(hist.bin_of(&[11]), Some(0));
        assert_eq!(hist.bin_of(&[12]), Some(1));
        assert_eq!(hist.bin_of(&[179]), Some(15));
        assert_eq!(hist.bin_of(&[180]), None);
        assert_eq!(hist.bin_of(&[]), None);
    }

    #[test]
    fn counts_respect_mask_and_roi() {
        let img = GrayImage::from_fn(4, 3, |x, _| Luma([(x * 64) as u8]));
        let mask = GrayImage::from_fn(4, 3, |_, y| Luma([if y == 0 { 0 } else { 255 }]));
        let h = Histogram::calc(
            ImageView::from(&img),
            HistogramSpec::gray(4),
            Some(&mask),
            Some(PixelRect::new(1, -5, 10, 10)),
        )
        .expect("valid");
        assert_eq!(h.values(), &[0.0, 2.0, 2.0, 2.0]);
        let bad = GrayImage::new(2, 2);
        assert!(
            Histogram::calc(
                ImageView::from(&img),
                HistogramSpec::gray(4),
                Some(&bad),
                None
            )
            .is_err()
        );
        assert!(Histogram::calc(ImageView::from(&img), HistogramSpec::hue(4), None, None).is_ok());
        assert!(matches!(
            Histogram::calc(ImageView::from(&img), HistogramSpec::rgb(4), None, None),
            Err(TrackError::ChannelCount { .. })
        ));
    }

    #[test]
    fn normalisation_maps_min_and_max() {
        let mut h = Histogram::new(HistogramSpec::gray(3)).expect("valid");
        h.values_mut().copy_from_slice(&[2.0, 6.0, 4.0]);
        h.normalize_min_max(0.0, 255.0).expect("finite");
        assert_eq!(h.values(), &[0.0, 255.0, 127.5]);
        h.values_mut().copy_from_slice(&[3.0, 3.0, 3.0]);
        h.normalize_min_max(255.0, 10.0).expect("finite");
        assert_eq!(h.values(), &[10.0, 10.0, 10.0]);
        assert!(h.normalize_min_max(f64::NAN, 1.0).is_err());
    }

    #[test]
    fn bad_specs_are_rejected() {
        for spec in [
            HistogramSpec {
                channels: vec![],
                bins: vec![],
                ranges: vec![],
            },
            HistogramSpec {
                channels: vec![0],
                bins: vec![0],
                ranges: vec![[0.0, 1.0]],
            },
            HistogramSpec {
                channels: vec![0],
                bins: vec![4],
                ranges: vec![[5.0, 5.0]],
            },
            HistogramSpec {
                channels: vec![0, 1],
                bins: vec![4],
                ranges: vec![[0.0, 5.0]],
            },
            HistogramSpec::rgb(1 << 9),
        ] {
            assert!(Histogram::new(spec).is_err());
        }
    }
}
