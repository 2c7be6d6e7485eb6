//! A borrowed view of an 8-bit image with 1 to 4 interleaved channels: the input type of the
//! histogram and back-projection functions, built from `image` crate buffers or raw slices.

use image::{GrayImage, RgbImage};

use crate::error::{Result, TrackError};
use crate::hsv::HsvImage;
use crate::rect::{PixelRect, clamp_i32};

/// An 8-bit image with `channels` interleaved channels, row-major, no padding.
#[derive(Debug, Clone, Copy)]
pub struct ImageView<'a> {
    data: &'a [u8],
    width: u32,
    height: u32,
    channels: usize,
}

impl<'a> ImageView<'a> {
    /// A view of `data` (row-major, `channels` bytes per pixel).
    ///
    /// # Errors
    /// [`TrackError::ChannelCount`] for 0 or more than 4 channels;
    /// [`TrackError::SizeMismatch`] when `data` does not hold exactly `width * height` pixels.
    pub fn new(data: &'a [u8], width: u32, height: u32, channels: usize) -> Result<Self> {
        if !(1..=4).contains(&channels) {
            return Err(TrackError::ChannelCount {
                what: "image view".into(),
                expected: "1 to 4".into(),
                found: channels,
            });
        }
        let pixels = u64::from(width) * u64::from(height);
        if data.len() as u64 != pixels * channels as u64 {
            let found = data.len() / channels;
            return Err(TrackError::SizeMismatch {
                what: "image view data".into(),
                expected_width: width,
                expected_height: height,
                found_width: u32::try_from(found).unwrap_or(u32::MAX),
                found_height: 1,
            });
        }
        Ok(Self {
            data,
            width,
            height,
            channels,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Channels per pixel.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The raw interleaved bytes.
    pub fn data(&self) -> &'a [u8] {
        self.data
    }

    /// The whole image as a rectangle.
    pub fn rect(&self) -> PixelRect {
        PixelRect::image(self.width, self.height)
    }

    /// Channel `c` of pixel `(x, y)`; the caller guarantees the indices are in range.
    #[inline]
    pub(crate) fn at(&self, x: usize, y: usize, c: usize) -> u8 {
        self.data[(y * self.width as usize + x) * self.channels + c]
    }

    pub(crate) fn check_same_size(&self, what: &str, width: u32, height: u32) -> Result<()> {
        if (width, height) != (self.width, self.height) {
            return Err(TrackError::SizeMismatch {
                what: what.to_string(),
                expected_width: self.width,
                expected_height: self.height,
                found_width: width,
                found_height: height,
            });
        }
        Ok(())
    }

    /// `roi` clipped to the image, or the whole image for `None`.
    ///
    /// # Errors
    /// [`TrackError::EmptyWindow`] for an empty `roi`, [`TrackError::WindowOutsideImage`] when
    /// it does not overlap the image.
    pub(crate) fn clip_roi(&self, roi: Option<PixelRect>) -> Result<PixelRect> {
        let Some(roi) = roi else {
            return Ok(self.rect());
        };
        if roi.is_empty() {
            return Err(TrackError::EmptyWindow {
                what: "roi".into(),
                width: roi.width,
                height: roi.height,
            });
        }
        let clipped = roi.intersect(&self.rect());
        if clipped.is_empty() {
            return Err(TrackError::WindowOutsideImage {
                what: "roi".into(),
                x: roi.x,
                y: roi.y,
                width: roi.width,
                height: roi.height,
                image_width: self.width,
                image_height: self.height,
            });
        }
        Ok(clipped)
    }
}

impl<'a> From<&'a RgbImage> for ImageView<'a> {
    fn from(image: &'a RgbImage) -> Self {
        Self {
            data: image.as_raw(),
            width: image.width(),
            height: image.height(),
            channels: 3,
        }
    }
}

impl<'a> From<&'a GrayImage> for ImageView<'a> {
    fn from(image: &'a GrayImage) -> Self {
        Self {
            data: image.as_raw(),
            width: image.width(),
            height: image.height(),
            channels: 1,
        }
    }
}

impl<'a> From<&'a HsvImage> for ImageView<'a> {
    fn from(image: &'a HsvImage) -> Self {
        Self {
            data: image.as_raw(),
            width: image.width(),
            height: image.height(),
            channels: 3,
        }
    }
}

/// Width or height as `i32` for rectangle arithmetic.
pub(crate) fn dim_i32(v: u32) -> i32 {
    clamp_i32(v)
}
