//! Raw depth images (16-bit, sensor units) and the image files that hold them and colour.
//!
//! Depth stays in the sensor's integer units (`u16`, 0 = no measurement) until a point cloud is
//! built; the image carries the size of one unit in metres, so that millimetre depth (Kinect,
//! value 1000 = 1 m) and TUM's 1/5000 m depth are never mixed up.

use std::io::Write;
use std::path::Path;

use image::{ImageBuffer, Luma, RgbImage};

use crate::error::{KinectError, MEMORY_LABEL, Result};

/// Size of one depth unit for millimetre depth (Kinect V1/V2, Azure Kinect, the native layout).
pub const DEPTH_UNIT_MM_M: f64 = 0.001;
/// Size of one depth unit in the TUM RGB-D benchmark: a value of 5000 is one metre
/// (Sturm et al. 2012, "file formats" page of the benchmark).
pub const DEPTH_UNIT_TUM_M: f64 = 1.0 / 5000.0;

/// A depth image in sensor units, row-major, `0` = no measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthImage {
    width: u32,
    height: u32,
    unit_m: f64,
    values: Vec<u16>,
}

impl DepthImage {
    /// A depth image from raw values (`width * height` of them, row-major) and the size of one
    /// unit in metres.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] when the value count does not match the size or the
    /// unit is not positive and finite.
    pub fn new(width: u32, height: u32, unit_m: f64, values: Vec<u16>) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(KinectError::param(
                "depth image size",
                format!("{width}x{height} px has no pixels"),
            ));
        }
        if values.len() != width as usize * height as usize {
            return Err(KinectError::param(
                "depth values",
                format!(
                    "{} values for a {width}x{height} px image (needs {})",
                    values.len(),
                    width as usize * height as usize
                ),
            ));
        }
        if !(unit_m.is_finite() && unit_m > 0.0) {
            return Err(KinectError::param(
                "depth unit",
                format!("{unit_m} m must be finite and positive"),
            ));
        }
        Ok(Self {
            width,
            height,
            unit_m,
            values,
        })
    }

    /// An image of zeros (no measurement anywhere).
    ///
    /// # Errors
    /// As [`DepthImage::new`]; [`KinectError::InvalidParameter`] above
    /// [`crate::MAX_IMAGE_SIDE_PX`] a side (checked before allocating).
    pub fn zeros(width: u32, height: u32, unit_m: f64) -> Result<Self> {
        if width > crate::camera::MAX_IMAGE_SIDE_PX || height > crate::camera::MAX_IMAGE_SIDE_PX {
            return Err(KinectError::param(
                "depth image size",
                format!(
                    "{width}x{height} px; at most {} px a side",
                    crate::camera::MAX_IMAGE_SIDE_PX
                ),
            ));
        }
        Self::new(
            width,
            height,
            unit_m,
            vec![0; width as usize * height as usize],
        )
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Size of one unit in metres.
    pub fn unit_m(&self) -> f64 {
        self.unit_m
    }

    /// Raw values, row-major.
    pub fn values(&self) -> &[u16] {
        &self.values
    }

    /// Raw values, row-major, mutable (the size cannot change).
    pub fn values_mut(&mut self) -> &mut [u16] {
        &mut self.values
    }

    /// Raw value at pixel `(u, v)`, `None` outside the image.
    pub fn get(&self, u: u32, v: u32) -> Option<u16> {
        (u < self.width && v < self.height)
            .then(|| self.values[v as usize * self.width as usize + u as usize])
    }

    /// Depth in metres at pixel `(u, v)`; `None` outside the image or where there is no
    /// measurement.
    pub fn depth_m(&self, u: u32, v: u32) -> Option<f64> {
        self.get(u, v)
            .filter(|&d| d > 0)
            .map(|d| f64::from(d) * self.unit_m)
    }

    /// Number of pixels with a measurement.
    pub fn valid_count(&self) -> usize {
        self.values.iter().filter(|&&d| d > 0).count()
    }
}

/// Read a 16-bit depth image: PNG (single channel, 16 bit) or PGM (`P5` binary with
/// maxval > 255, or `P2` ASCII), chosen by the file's magic bytes.
///
/// # Errors
/// [`KinectError::Io`] when the file cannot be read; [`KinectError::DepthNot16Bit`] for an
/// 8-bit or multi-channel image; [`KinectError::Format`] for a truncated or malformed file.
pub fn read_depth_image(path: &Path, unit_m: f64) -> Result<DepthImage> {
    let bytes = std::fs::read(path).map_err(|e| KinectError::io(path, e))?;
    decode_depth_image(&bytes, path, unit_m)
}

/// Decode a 16-bit depth image from bytes (PNG or PGM); `path` only names it in errors.
///
/// # Errors
/// As [`read_depth_image`].
pub fn decode_depth_image(bytes: &[u8], path: &Path, unit_m: f64) -> Result<DepthImage> {
    if bytes.starts_with(b"P5") || bytes.starts_with(b"P2") {
        return decode_pgm(bytes, path, unit_m);
    }
    if !bytes.starts_with(b"\x89PNG") {
        return Err(KinectError::format(
            path,
            "not a PNG or PGM file (unknown magic bytes)",
        ));
    }
    if let Some(what) = png_end_error(bytes) {
        return Err(KinectError::format(path, format!("corrupt PNG: {what}")));
    }
    let decoded = image::load_from_memory_with_format(bytes, image::ImageFormat::Png)
        .map_err(|e| image_error(path, e))?;
    match decoded {
        image::DynamicImage::ImageLuma16(buffer) => {
            let (width, height) = buffer.dimensions();
            DepthImage::new(width, height, unit_m, buffer.into_raw())
        }
        other => Err(KinectError::DepthNot16Bit {
            path: path.to_path_buf(),
            found: format!("{:?}", other.color()),
        }),
    }
}

/// Write a depth image as a 16-bit single-channel PNG (raw units, lossless).
///
/// # Errors
/// [`KinectError::Io`] or [`KinectError::Image`] when the file cannot be written.
pub fn write_depth_png(depth: &DepthImage, path: &Path) -> Result<()> {
    let buffer: ImageBuffer<Luma<u16>, Vec<u16>> =
        ImageBuffer::from_raw(depth.width, depth.height, depth.values.clone())
            .ok_or_else(|| KinectError::format(path, "depth buffer does not match its size"))?;
    buffer.save(path).map_err(|e| image_error(path, e))
}

/// Write a depth image as a binary 16-bit PGM (`P5`, maxval 65535, big-endian as the format
/// requires).
///
/// # Errors
/// [`KinectError::Io`] when the file cannot be written.
pub fn write_depth_pgm(depth: &DepthImage, path: &Path) -> Result<()> {
    let mut bytes = format!("P5\n{} {}\n65535\n", depth.width, depth.height).into_bytes();
    bytes.reserve(depth.values.len() * 2);
    for v in &depth.values {
        bytes.extend_from_slice(&v.to_be_bytes());
    }
    let mut file = std::fs::File::create(path).map_err(|e| KinectError::io(path, e))?;
    file.write_all(&bytes).map_err(|e| KinectError::io(path, e))
}

/// Read a colour image (PNG or JPEG, 8-bit; grey and alpha are converted to RGB).
///
/// # Errors
/// [`KinectError::Io`] when the file cannot be read, [`KinectError::Image`] when it cannot be
/// decoded, [`KinectError::Unsupported`] for a 16-bit colour image.
pub fn read_color_image(path: &Path) -> Result<RgbImage> {
    let bytes = std::fs::read(path).map_err(|e| KinectError::io(path, e))?;
    decode_color_image(&bytes, path)
}

/// Decode a colour image from bytes; `path` only names it in errors.
///
/// # Errors
/// As [`read_color_image`].
pub fn decode_color_image(bytes: &[u8], path: &Path) -> Result<RgbImage> {
    // The JPEG decoder fills what a truncated file lacks with grey and says nothing, and the
    // PNG decoder does not miss a cut end chunk: the structure is checked first, so a cut
    // file is an error and not data.
    if bytes.starts_with(&[0xFF, 0xD8])
        && let Some(what) = jpeg_structure_error(bytes)
    {
        return Err(KinectError::format(path, format!("corrupt JPEG: {what}")));
    }
    if bytes.starts_with(PNG_SIGNATURE)
        && let Some(what) = png_end_error(bytes)
    {
        return Err(KinectError::format(path, format!("corrupt PNG: {what}")));
    }
    // A UVC camera's MJPEG frame may leave out its Huffman tables (the standard ones).
    let with_tables = crate::mjpeg::with_standard_tables(bytes);
    let bytes = with_tables.as_deref().unwrap_or(bytes);
    let decoded = image::load_from_memory(bytes).map_err(|e| image_error(path, e))?;
    use image::DynamicImage as D;
    match decoded {
        D::ImageRgb8(rgb) => Ok(rgb),
        D::ImageRgba8(_) | D::ImageLuma8(_) | D::ImageLumaA8(_) => Ok(decoded.to_rgb8()),
        other => Err(KinectError::Unsupported {
            path: path.to_path_buf(),
            what: format!(
                "colour image with pixel format {:?} (8-bit RGB, RGBA or grey expected)",
                other.color()
            ),
        }),
    }
}

/// The first bytes of every PNG file.
const PNG_SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";

/// The last chunk of every PNG file: length 0, `IEND`, and its CRC.
const PNG_END: [u8; 12] = [0, 0, 0, 0, b'I', b'E', b'N', b'D', 0xAE, 0x42, 0x60, 0x82];

/// What is wrong with a PNG's end, or `None` when it closes with its `IEND` chunk (bytes
/// after it are allowed). The decoder accepts a file cut inside that chunk.
fn png_end_error(bytes: &[u8]) -> Option<String> {
    let whole = bytes
        .windows(PNG_END.len())
        .rev()
        .take(1 << 16)
        .any(|w| w == PNG_END);
    (!whole).then(|| {
        format!(
            "the file ends after {} bytes without its end chunk (IEND): truncated",
            bytes.len()
        )
    })
}

/// What is wrong with a JPEG's marker structure, or `None` when it is whole: SOI, then
/// segments whose lengths stay inside the file, each scan's entropy-coded data up to the next
/// marker, and an EOI marker. Bytes after the EOI are allowed (cameras append data there).
fn jpeg_structure_error(bytes: &[u8]) -> Option<String> {
    let len = bytes.len();
    let truncated = |_at: usize| {
        Some(format!(
            "the file ends after {len} bytes, before its end-of-image marker: truncated"
        ))
    };
    if !bytes.starts_with(&[0xFF, 0xD8]) {
        return Some("no start-of-image marker".to_owned());
    }
    let mut i = 2;
    let mut scans = 0usize;
    loop {
        if i >= len {
            return truncated(len);
        }
        if bytes[i] != 0xFF {
            return Some(format!(
                "byte {i}: expected a marker, found {:#04x}",
                bytes[i]
            ));
        }
        while i < len && bytes[i] == 0xFF {
            i += 1; // fill bytes
        }
        let Some(&marker) = bytes.get(i) else {
            return truncated(len);
        };
        i += 1;
        match marker {
            0xD9 if scans > 0 => return None,
            0xD9 => return Some("end-of-image marker before any image data".to_owned()),
            0xD0..=0xD7 | 0x01 => continue,
            0x00 => return Some(format!("byte {}: a stuffed zero outside image data", i - 1)),
            _ => {}
        }
        let Some(length) = bytes.get(i..i + 2) else {
            return truncated(len);
        };
        let length = usize::from(u16::from_be_bytes([length[0], length[1]]));
        if length < 2 {
            return Some(format!("byte {i}: segment length {length} (at least 2)"));
        }
        if i + length > len {
            return truncated(len);
        }
        i += length;
        if marker == 0xDA {
            scans += 1;
            // Entropy-coded data: up to a marker that is not a stuffed zero or a restart.
            loop {
                let Some(offset) = bytes[i..].iter().position(|&b| b == 0xFF) else {
                    return truncated(len);
                };
                i += offset;
                match bytes.get(i + 1) {
                    None => return truncated(len),
                    Some(0x00 | 0xD0..=0xD7) => i += 2,
                    Some(0xFF) => i += 1,
                    Some(_) => break,
                }
            }
        }
    }
}

pub(crate) fn image_error(path: &Path, error: image::ImageError) -> KinectError {
    match error {
        image::ImageError::IoError(source) => KinectError::io(path, source),
        other => KinectError::Image {
            path: path.to_path_buf(),
            what: other.to_string(),
        },
    }
}

/// Parse a PGM header token by token (whitespace and `#` comments between tokens).
struct PnmHeader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl PnmHeader<'_> {
    fn next_token(&mut self) -> Option<&[u8]> {
        loop {
            while self.pos < self.bytes.len() && self.bytes[self.pos].is_ascii_whitespace() {
                self.pos += 1;
            }
            if self.pos < self.bytes.len() && self.bytes[self.pos] == b'#' {
                while self.pos < self.bytes.len() && self.bytes[self.pos] != b'\n' {
                    self.pos += 1;
                }
                continue;
            }
            break;
        }
        let start = self.pos;
        while self.pos < self.bytes.len() && !self.bytes[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        (self.pos > start).then(|| &self.bytes[start..self.pos])
    }

    fn next_number(&mut self, path: &Path, what: &str) -> Result<u32> {
        let token = self
            .next_token()
            .ok_or_else(|| KinectError::format(path, format!("PGM header ends before {what}")))?;
        std::str::from_utf8(token)
            .ok()
            .and_then(|s| s.parse::<u32>().ok())
            .ok_or_else(|| {
                KinectError::format(
                    path,
                    format!(
                        "PGM {what} is not a number: {:?}",
                        String::from_utf8_lossy(token)
                    ),
                )
            })
    }
}

fn decode_pgm(bytes: &[u8], path: &Path, unit_m: f64) -> Result<DepthImage> {
    let binary = bytes.starts_with(b"P5");
    let mut header = PnmHeader { bytes, pos: 2 };
    let width = header.next_number(path, "width")?;
    let height = header.next_number(path, "height")?;
    let maxval = header.next_number(path, "maxval")?;
    if width == 0 || height == 0 {
        return Err(KinectError::format(
            path,
            format!("PGM size {width}x{height} px has no pixels"),
        ));
    }
    if maxval == 0 || maxval > 65535 {
        return Err(KinectError::format(
            path,
            format!("PGM maxval {maxval} outside 1..=65535"),
        ));
    }
    if maxval < 256 {
        return Err(KinectError::DepthNot16Bit {
            path: path.to_path_buf(),
            found: format!("8-bit PGM (maxval {maxval})"),
        });
    }
    let count = (width as usize)
        .checked_mul(height as usize)
        .ok_or_else(|| KinectError::format(path, "PGM size overflows"))?;
    let mut values = Vec::new();
    if binary {
        // Exactly one whitespace byte separates maxval from the raster.
        let start = header.pos + 1;
        let needed = count
            .checked_mul(2)
            .and_then(|n| n.checked_add(start))
            .ok_or_else(|| KinectError::format(path, "PGM size overflows"))?;
        if bytes.len() < needed {
            return Err(KinectError::CountMismatch {
                path: path.to_path_buf(),
                what: "pixels",
                declared: count,
                found: bytes.len().saturating_sub(start) / 2,
            });
        }
        values.reserve(count);
        values.extend(
            bytes[start..needed]
                .chunks_exact(2)
                .map(|c| u16::from_be_bytes([c[0], c[1]])),
        );
    } else {
        values.reserve(count.min(bytes.len()));
        while let Some(token) = header.next_token() {
            let value = std::str::from_utf8(token)
                .ok()
                .and_then(|s| s.parse::<u32>().ok())
                .filter(|&v| v <= maxval)
                .ok_or_else(|| {
                    KinectError::format(
                        path,
                        format!(
                            "PGM pixel {} is not a number in 0..={maxval}: {:?}",
                            values.len(),
                            String::from_utf8_lossy(token)
                        ),
                    )
                })?;
            values.push(value as u16);
        }
        if values.len() != count {
            return Err(KinectError::CountMismatch {
                path: path.to_path_buf(),
                what: "pixels",
                declared: count,
                found: values.len(),
            });
        }
    }
    DepthImage::new(width, height, unit_m, values)
}

/// Convenience for parsers used from memory.
pub(crate) fn memory_path() -> &'static Path {
    Path::new(MEMORY_LABEL)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binary_pgm_is_big_endian() {
        let mut bytes = b"P5\n# comment\n2 1\n65535\n".to_vec();
        bytes.extend_from_slice(&[0x03, 0xE8, 0x00, 0x01]);
        let depth = decode_pgm(&bytes, memory_path(), DEPTH_UNIT_MM_M).expect("valid");
        assert_eq!(depth.values(), &[1000, 1]);
        assert_eq!(depth.depth_m(0, 0), Some(1.0));
    }

    #[test]
    fn ascii_pgm_and_truncation() {
        let depth = decode_pgm(b"P2 2 2 65535 1 2 3 4", memory_path(), 0.001).expect("valid");
        assert_eq!(depth.values(), &[1, 2, 3, 4]);
        let err = decode_pgm(b"P2 2 2 65535 1 2 3", memory_path(), 0.001).expect_err("short");
        assert!(matches!(
            err,
            KinectError::CountMismatch {
                declared: 4,
                found: 3,
                ..
            }
        ));
        let err = decode_pgm(b"P5 2 2 65535\n\0\0\0", memory_path(), 0.001).expect_err("short");
        assert!(matches!(
            err,
            KinectError::CountMismatch {
                declared: 4,
                found: 1,
                ..
            }
        ));
    }

    #[test]
    fn eight_bit_pgm_is_not_depth() {
        let err = decode_pgm(b"P5 1 1 255\n\x10", memory_path(), 0.001).expect_err("8 bit");
        assert!(matches!(err, KinectError::DepthNot16Bit { .. }));
    }

    #[test]
    fn eight_bit_png_is_not_depth() {
        let img = image::GrayImage::from_raw(2, 2, vec![1, 2, 3, 4]).expect("size");
        let mut bytes = Vec::new();
        img.write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .expect("encode");
        let err = decode_depth_image(&bytes, memory_path(), 0.001).expect_err("8 bit");
        assert!(matches!(err, KinectError::DepthNot16Bit { .. }));
    }
}
