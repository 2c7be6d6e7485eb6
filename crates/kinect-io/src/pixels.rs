//! Raw colour layouts of RGB-D cameras, converted to RGB: BGRA32 and BGR8 (Azure Kinect,
//! RealSense), NV12 and YUY2 (Azure Kinect's 720p raw modes, RealSense `yuyv`), with every
//! buffer length checked against the image size before a pixel is read.

use image::RgbImage;

use crate::error::{KinectError, Result};

/// A raw colour layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum RawColor {
    /// 8-bit R, G, B.
    Rgb8,
    /// 8-bit B, G, R.
    Bgr8,
    /// 8-bit R, G, B, A.
    Rgba8,
    /// 8-bit B, G, R, A (Azure Kinect `BGRA32`).
    Bgra8,
    /// Y plane, then interleaved U, V at half resolution (4:2:0).
    Nv12,
    /// Y0, U, Y1, V per pixel pair (4:2:2; ROS `yuv422_yuy2`, RealSense `yuyv`).
    Yuy2,
    /// U, Y0, V, Y1 per pixel pair (4:2:2; ROS `uyvy` / `yuv422`).
    Uyvy,
}

impl RawColor {
    /// Bytes of one frame of `width` x `height` pixels with rows of `stride` bytes (`None`:
    /// packed rows), or `None` on overflow.
    fn frame_bytes(self, width: u32, height: u32, stride: Option<usize>) -> Option<usize> {
        let (w, h) = (width as usize, height as usize);
        let row = stride.unwrap_or(w.checked_mul(self.packed_row_factor())?);
        match self {
            Self::Nv12 => row.checked_mul(h)?.checked_add(row.checked_mul(h / 2)?),
            _ => row.checked_mul(h),
        }
    }

    fn packed_row_factor(self) -> usize {
        match self {
            Self::Rgb8 | Self::Bgr8 => 3,
            Self::Rgba8 | Self::Bgra8 => 4,
            Self::Nv12 => 1,
            Self::Yuy2 | Self::Uyvy => 2,
        }
    }
}

/// ITU-R BT.601 limited-range ("studio swing") YCbCr to RGB, the conversion libyuv (and so
/// the Azure Kinect SDK) and OpenCV's `COLOR_YUV2RGB_NV12` / `_YUY2` use.
#[inline]
fn yuv_to_rgb(y: u8, u: u8, v: u8) -> [u8; 3] {
    let c = 1.164_383 * (f32::from(y) - 16.0);
    let d = f32::from(u) - 128.0;
    let e = f32::from(v) - 128.0;
    let q = |x: f32| x.round().clamp(0.0, 255.0) as u8;
    [
        q(c + 1.596_027 * e),
        q(c - 0.391_762 * d - 0.812_968 * e),
        q(c + 2.017_232 * d),
    ]
}

/// Convert one raw frame to RGB. `stride` is the row length in bytes when rows are padded
/// (ROS `step`), `None` for packed rows. `what` names the frame in errors.
pub(crate) fn to_rgb(
    layout: RawColor,
    width: u32,
    height: u32,
    stride: Option<usize>,
    bytes: &[u8],
    what: &std::path::Path,
) -> Result<RgbImage> {
    let (w, h) = (width as usize, height as usize);
    if stride.is_some_and(|s| s < w * layout.packed_row_factor())
        || (matches!(layout, RawColor::Nv12 | RawColor::Yuy2 | RawColor::Uyvy) && w % 2 != 0)
        || (layout == RawColor::Nv12 && h % 2 != 0)
    {
        return Err(KinectError::format(
            what,
            format!("{layout:?} frame of {width}x{height} px with row stride {stride:?} bytes"),
        ));
    }
    let need = layout.frame_bytes(width, height, stride);
    if need != Some(bytes.len()) {
        return Err(KinectError::format(
            what,
            format!(
                "{layout:?} frame of {width}x{height} px needs {need:?} bytes, found {}",
                bytes.len()
            ),
        ));
    }
    let row = stride.unwrap_or(w * layout.packed_row_factor());
    let mut out = vec![0u8; w * h * 3];
    for (y, out_row) in out.chunks_exact_mut(w * 3).enumerate() {
        let src = &bytes[y * row..y * row + w * layout.packed_row_factor()];
        match layout {
            RawColor::Rgb8 => out_row.copy_from_slice(src),
            RawColor::Bgr8 | RawColor::Bgra8 | RawColor::Rgba8 => {
                let n = layout.packed_row_factor();
                let swap = matches!(layout, RawColor::Bgr8 | RawColor::Bgra8);
                for (o, s) in out_row.chunks_exact_mut(3).zip(src.chunks_exact(n)) {
                    if swap {
                        o.copy_from_slice(&[s[2], s[1], s[0]]);
                    } else {
                        o.copy_from_slice(&s[..3]);
                    }
                }
            }
            RawColor::Yuy2 | RawColor::Uyvy => {
                let (y0, u, y1, v) = if layout == RawColor::Yuy2 {
                    (0, 1, 2, 3)
                } else {
                    (1, 0, 3, 2)
                };
                for (o, s) in out_row.chunks_exact_mut(6).zip(src.chunks_exact(4)) {
                    o[..3].copy_from_slice(&yuv_to_rgb(s[y0], s[u], s[v]));
                    o[3..].copy_from_slice(&yuv_to_rgb(s[y1], s[u], s[v]));
                }
            }
            RawColor::Nv12 => {
                let uv_start = row * h + (y / 2) * row;
                let uv = &bytes[uv_start..uv_start + w];
                for (x, o) in out_row.chunks_exact_mut(3).enumerate() {
                    let c = x & !1;
                    o.copy_from_slice(&yuv_to_rgb(src[x], uv[c], uv[c + 1]));
                }
            }
        }
    }
    RgbImage::from_raw(width, height, out)
        .ok_or_else(|| KinectError::format(what, "colour buffer size (internal)"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn layouts_convert_to_the_same_rgb() {
        let p = Path::new("<test>");
        let bgra = [10, 20, 30, 255, 40, 50, 60, 0];
        let img = to_rgb(RawColor::Bgra8, 2, 1, None, &bgra, p).unwrap();
        assert_eq!(img.as_raw(), &[30, 20, 10, 60, 50, 40]);
        // Grey in YUV is grey in RGB: Y 126, U = V = 128 -> 128.
        let yuy2 = [126, 128, 235, 128];
        let img = to_rgb(RawColor::Yuy2, 2, 1, None, &yuy2, p).unwrap();
        assert_eq!(img.as_raw(), &[128, 128, 128, 255, 255, 255]);
        let nv12 = [16, 235, 16, 235, 128, 128];
        let img = to_rgb(RawColor::Nv12, 2, 2, None, &nv12, p).unwrap();
        assert_eq!(img.get_pixel(1, 1).0, [255, 255, 255]);
        assert_eq!(img.get_pixel(0, 1).0, [0, 0, 0]);
        // Pure red in BT.601 limited range: Y 81, U 90, V 240.
        let red = to_rgb(RawColor::Uyvy, 2, 1, None, &[90, 81, 240, 81], p).unwrap();
        let px = red.get_pixel(0, 0).0;
        assert!(px[0] >= 253 && px[1] <= 2 && px[2] <= 2, "{px:?}");
        // Padded rows.
        let padded = [1, 2, 3, 9, 4, 5, 6, 9];
        let img = to_rgb(RawColor::Rgb8, 1, 2, Some(4), &padded, p).unwrap();
        assert_eq!(img.as_raw(), &[1, 2, 3, 4, 5, 6]);
    }

    #[test]
    fn wrong_lengths_are_errors() {
        let p = Path::new("<test>");
        assert!(to_rgb(RawColor::Bgra8, 2, 1, None, &[0; 7], p).is_err());
        assert!(to_rgb(RawColor::Nv12, 3, 2, None, &[0; 9], p).is_err());
        assert!(to_rgb(RawColor::Rgb8, 2, 1, Some(5), &[0; 10], p).is_err());
        assert!(to_rgb(RawColor::Rgb8, u32::MAX, u32::MAX, None, &[0; 3], p).is_err());
    }
}
