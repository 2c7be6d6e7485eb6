//! Orbbec SDK v2 recordings: the ROS 1 bags that Orbbec's own recorder writes (OrbbecViewer,
//! `ob_record`; Gemini 2/330, Femto Bolt/Mega and the other cameras of SDK v2). They are
//! read by `bag.rs` like a RealSense bag; this module knows the Orbbec layout (OrbbecSDK_v2,
//! `src/media/ros/RosFileFormat.hpp` and `RosbagWriter.cpp`, MIT):
//!
//! - images on `/cam/sensor_{sensor}/frameType_{frame}`: depth is sensor 3, frame type 3,
//!   colour is sensor 2, frame type 2 (`OBSensorType`, `OBFrameType`). The message is a
//!   `sensor_msgs/Image` whose standard fields come first; Orbbec's extra fields after
//!   `data` (frame number, three timestamps, metadata, in versions that differ) are not read.
//! - one `custom_msg/OBStreamProfileInfo` per stream on `/cam/streamProfileType_{stream}`
//!   (written when the recording stops): pixel format (`OBFormat`), size, intrinsics
//!   `fx, fy, cx, cy`, distortion `k1..k6, p1, p2` with its model, and on the depth stream the
//!   depth-to-colour rotation (row-major) and translation in millimetres, all `float32`.
//! - `custom_msg/OBProperty` messages on `/cam/property` (`uint32` id, `uint8[]` value):
//!   the depth unit (`OB_PROP_DEPTH_UNIT_FLEXIBLE_ADJUSTMENT_FLOAT`, millimetres, or
//!   `OB_PROP_DEPTH_PRECISION_LEVEL_INT`), whether depth was converted from disparity, and
//!   the mirror/flip switches and hardware depth-to-colour alignment. As in the SDK's playback, the unit is 1 mm when neither unit
//!   property was recorded.
//!
//! Refused with a typed error rather than guessed: compressed or packed depth (RLE, RVL,
//! Y10–Y14), depth recorded as disparity or aligned to colour in the camera, mirrored or
//! flipped streams, H.264/H.265 colour,
//! and distortion models other than Brown–Conrady (with k6 or without) with nonzero
//! coefficients.

use std::path::Path;

use crate::bag_msgs::Reader;
use crate::calibration::{Calibration, Extrinsics, RegistrationModel};
use crate::camera::{CameraModel, Distortion};
use crate::error::{KinectError, Result};
use crate::pixels::RawColor;

/// The depth image topic (`OB_SENSOR_DEPTH` = 3, `OB_FRAME_DEPTH` = 3).
pub(crate) const DEPTH_TOPIC: &str = "/cam/sensor_3/frameType_3";
/// The colour image topic (`OB_SENSOR_COLOR` = 2, `OB_FRAME_COLOR` = 2).
pub(crate) const COLOR_TOPIC: &str = "/cam/sensor_2/frameType_2";
/// The depth stream's profile (`OB_STREAM_DEPTH` = 3).
const DEPTH_PROFILE_TOPIC: &str = "/cam/streamProfileType_3";
/// The colour stream's profile (`OB_STREAM_COLOR` = 2).
const COLOR_PROFILE_TOPIC: &str = "/cam/streamProfileType_2";
/// The device properties recorded at the start.
const PROPERTY_TOPIC: &str = "/cam/property";

/// `OB_PROP_DEPTH_MIRROR_BOOL`, `OB_PROP_DEPTH_FLIP_BOOL` (SDK v2 `Property.h`).
const PROP_DEPTH_MIRROR: u32 = 14;
const PROP_DEPTH_FLIP: u32 = 15;
/// `OB_PROP_DEPTH_ALIGN_HARDWARE_BOOL`: depth aligned to colour in the camera.
const PROP_DEPTH_ALIGN_HARDWARE: u32 = 42;
/// `OB_PROP_DEPTH_PRECISION_LEVEL_INT`: an `OBDepthPrecisionLevel`.
const PROP_DEPTH_PRECISION_LEVEL: u32 = 75;
/// `OB_PROP_COLOR_MIRROR_BOOL`, `OB_PROP_COLOR_FLIP_BOOL`.
const PROP_COLOR_MIRROR: u32 = 81;
const PROP_COLOR_FLIP: u32 = 82;
/// `OB_PROP_DISPARITY_TO_DEPTH_BOOL`: false means the depth stream carries disparity.
const PROP_DISPARITY_TO_DEPTH: u32 = 85;
/// `OB_PROP_DEPTH_UNIT_FLEXIBLE_ADJUSTMENT_FLOAT`: the depth unit in millimetres (Gemini 330).
const PROP_DEPTH_UNIT_MM: u32 = 176;

/// Depth unit per `OBDepthPrecisionLevel` (1 mm, 0.8, 0.4, 0.1, 0.2, 0.5, 0.05 mm), metres.
const PRECISION_LEVEL_UNIT_M: [f64; 7] = [1e-3, 0.8e-3, 0.4e-3, 0.1e-3, 0.2e-3, 0.5e-3, 0.05e-3];

/// `OBFormat` values read here (SDK v2 `ObTypes.h`).
const FORMAT_YUYV: u8 = 0;
const FORMAT_YUY2: u8 = 1;
const FORMAT_UYVY: u8 = 2;
const FORMAT_NV12: u8 = 3;
const FORMAT_MJPG: u8 = 5;
const FORMAT_Y16: u8 = 8;
const FORMAT_RGB: u8 = 22;
const FORMAT_BGR: u8 = 23;
const FORMAT_BGRA: u8 = 25;
const FORMAT_Z16: u8 = 28;
const FORMAT_RGBA: u8 = 31;

/// `OBCameraDistortionModel` values read with nonzero coefficients.
const DISTORTION_NONE: u8 = 0;
const DISTORTION_BROWN_CONRADY: u8 = 3;
const DISTORTION_BROWN_CONRADY_K6: u8 = 4;

/// Largest rotation-matrix error accepted in the recorded extrinsics (`float32` rounding of
/// a rotation is ~1e-7).
const ROTATION_TOLERANCE: f64 = 1e-4;

/// How a colour image of the recording is decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ColorCodec {
    /// Raw pixels in this layout.
    Raw(RawColor),
    /// One JPEG per frame.
    Jpeg,
}

/// The connections of an Orbbec recording.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Topics {
    pub depth_image: u32,
    pub color_image: u32,
    pub depth_profile: Option<u32>,
    pub color_profile: Option<u32>,
    pub property: Option<u32>,
}

/// The Orbbec topics among a bag's `(id, topic, type)` connections, when both image topics
/// are there.
pub(crate) fn topics(connections: &[(u32, String, String)]) -> Option<Topics> {
    let find = |name: &str| connections.iter().find(|c| c.1 == name).map(|c| c.0);
    Some(Topics {
        depth_image: find(DEPTH_TOPIC)?,
        color_image: find(COLOR_TOPIC)?,
        depth_profile: find(DEPTH_PROFILE_TOPIC),
        color_profile: find(COLOR_PROFILE_TOPIC),
        property: find(PROPERTY_TOPIC),
    })
}

/// One `OBStreamProfileInfo`.
#[derive(Debug, Clone, PartialEq)]
struct Profile {
    format: u8,
    camera: CameraModel,
    rotation: [f32; 9],
    translation_mm: [f32; 3],
}

fn parse_profile(bytes: &[u8], path: &Path, what: &str) -> Result<Profile> {
    let bad = |w: String| KinectError::calibration(path, format!("{what} stream profile: {w}"));
    let mut r = Reader::new(bytes, path);
    r.header()?;
    let _stream = r.u8()?;
    let format = r.u8()?;
    let mut rotation = [0f32; 9];
    for v in &mut rotation {
        *v = r.f32()?;
    }
    let mut translation_mm = [0f32; 3];
    for v in &mut translation_mm {
        *v = r.f32()?;
    }
    let width = u32::from(r.u16()?);
    let height = u32::from(r.u16()?);
    let _fps = r.u16()?;
    let mut k = [0f64; 4];
    for v in &mut k {
        *v = f64::from(r.f32()?);
    }
    // k1..k6, p1, p2.
    let mut d = [0f64; 8];
    for v in &mut d {
        *v = f64::from(r.f32()?);
    }
    let model = r.u8()?;
    let distortion = distortion(model, &d, path, what)?;
    let camera = CameraModel {
        width,
        height,
        fx: k[0],
        fy: k[1],
        cx: k[2],
        cy: k[3],
        distortion,
    };
    camera.validate().map_err(|e| bad(e.to_string()))?;
    Ok(Profile {
        format,
        camera,
        rotation,
        translation_mm,
    })
}

/// Our distortion for an `OBCameraDistortion` (`d` = k1..k6, p1, p2).
fn distortion(model: u8, d: &[f64; 8], path: &Path, what: &str) -> Result<Distortion> {
    let [k1, k2, k3, k4, k5, k6, p1, p2] = *d;
    if d.iter().all(|&c| c == 0.0) {
        return Ok(Distortion::default());
    }
    let list: Vec<f64> = match model {
        DISTORTION_BROWN_CONRADY => vec![k1, k2, p1, p2, k3],
        DISTORTION_BROWN_CONRADY_K6 => vec![k1, k2, p1, p2, k3, k4, k5, k6],
        _ => {
            let name = match model {
                DISTORTION_NONE => "none",
                1 => "modified Brown-Conrady",
                2 => "inverse Brown-Conrady",
                5 => "Kannala-Brandt",
                _ => "unknown",
            };
            return Err(KinectError::Unsupported {
                path: path.to_path_buf(),
                what: format!(
                    "{what} stream: distortion model {model} ({name}) with coefficients \
                     k1..k6, p1, p2 = {d:?} (Brown-Conrady with or without k6 is read)"
                ),
            });
        }
    };
    Distortion::from_opencv(&list)
        .map_err(|e| KinectError::calibration(path, format!("{what} stream profile: {e}")))
}

/// The colour decoding of an `OBFormat`.
fn color_codec(format: u8, path: &Path) -> Result<ColorCodec> {
    Ok(match format {
        FORMAT_MJPG => ColorCodec::Jpeg,
        FORMAT_RGB => ColorCodec::Raw(RawColor::Rgb8),
        FORMAT_BGR => ColorCodec::Raw(RawColor::Bgr8),
        FORMAT_BGRA => ColorCodec::Raw(RawColor::Bgra8),
        FORMAT_RGBA => ColorCodec::Raw(RawColor::Rgba8),
        FORMAT_YUYV | FORMAT_YUY2 => ColorCodec::Raw(RawColor::Yuy2),
        FORMAT_UYVY => ColorCodec::Raw(RawColor::Uyvy),
        FORMAT_NV12 => ColorCodec::Raw(RawColor::Nv12),
        other => {
            return Err(KinectError::Unsupported {
                path: path.to_path_buf(),
                what: format!(
                    "colour stream format {other} (OBFormat; MJPG, RGB, BGR, BGRA, RGBA, \
                     YUYV/YUY2, UYVY and NV12 are read)"
                ),
            });
        }
    })
}

/// The colour decoding when the colour profile is missing: by the image's encoding name.
pub(crate) fn color_codec_by_encoding(encoding: &str) -> Option<ColorCodec> {
    match encoding.to_ascii_lowercase().as_str() {
        "mjpg" | "mjpeg" | "jpeg" => Some(ColorCodec::Jpeg),
        "nv12" => Some(ColorCodec::Raw(RawColor::Nv12)),
        other => crate::bag::color_layout(other).map(ColorCodec::Raw),
    }
}

/// One `OBProperty`: its id and value bytes.
fn parse_property<'a>(bytes: &'a [u8], path: &'a Path) -> Result<(u32, &'a [u8])> {
    let mut r = Reader::new(bytes, path);
    r.header()?;
    let id = r.u32()?;
    let n = r.u32()? as usize;
    Ok((id, r.bytes(n)?))
}

/// A property's value as a 32-bit integer (an `OBPropertyValue`; a 1-byte bool also).
fn int_value(value: &[u8]) -> Option<i32> {
    match value.len() {
        0 => None,
        1..=3 => Some(i32::from(value[0])),
        _ => Some(i32::from_le_bytes([value[0], value[1], value[2], value[3]])),
    }
}

/// What the recorded properties say.
#[derive(Debug, Clone, PartialEq)]
struct Properties {
    depth_unit_m: f64,
}

fn read_properties(messages: &[Vec<u8>], path: &Path) -> Result<Properties> {
    let mut flexible_mm = None;
    let mut level = None;
    for bytes in messages {
        let (id, value) = parse_property(bytes, path)?;
        let refuse = |what: &str| KinectError::Unsupported {
            path: path.to_path_buf(),
            what: what.to_owned(),
        };
        let on = int_value(value).is_some_and(|v| v != 0);
        match id {
            PROP_DEPTH_MIRROR | PROP_DEPTH_FLIP | PROP_COLOR_MIRROR | PROP_COLOR_FLIP if on => {
                return Err(refuse(&format!(
                    "a stream recorded mirrored or flipped (property {id}); the calibration \
                     is for unmirrored images: record with mirror and flip off"
                )));
            }
            PROP_DEPTH_ALIGN_HARDWARE if on => {
                return Err(refuse(
                    "depth recorded aligned to colour in the camera (hardware D2C on): the \
                     recorded profiles do not say which intrinsics it then has; record with \
                     hardware D2C off (the depth is registered here)",
                ));
            }
            PROP_DISPARITY_TO_DEPTH if int_value(value) == Some(0) => {
                return Err(refuse(
                    "depth recorded as disparity (hardware disparity-to-depth off); record \
                     with it on",
                ));
            }
            PROP_DEPTH_UNIT_MM if value.len() >= 4 => {
                flexible_mm = Some(f32::from_le_bytes([value[0], value[1], value[2], value[3]]));
            }
            PROP_DEPTH_PRECISION_LEVEL => level = int_value(value),
            _ => {}
        }
    }
    let depth_unit_m = match (flexible_mm, level) {
        (Some(mm), _) => {
            let mm = f64::from(mm);
            // The SDK stores a float: read back its shortest decimal (0.1, not 0.100000001).
            let mm = format!("{}", mm as f32).parse::<f64>().unwrap_or(mm);
            if !(mm.is_finite() && mm > 0.0 && mm <= 10.0) {
                return Err(KinectError::calibration(
                    path,
                    format!("recorded depth unit {mm} mm is not a unit a camera uses"),
                ));
            }
            mm * 1e-3
        }
        (None, Some(level)) => usize::try_from(level)
            .ok()
            .and_then(|l| PRECISION_LEVEL_UNIT_M.get(l).copied())
            .ok_or_else(|| {
                KinectError::calibration(path, format!("unknown depth precision level {level}"))
            })?,
        (None, None) => 1e-3,
    };
    Ok(Properties { depth_unit_m })
}

/// What is read from an Orbbec recording's profiles and properties: its calibration and
/// how its colour images are decoded.
pub(crate) struct Decoded {
    pub calibration: Calibration,
    /// `None` without a colour profile: each image is then decoded by its encoding name.
    pub color: Option<ColorCodec>,
}

/// The calibration and colour codec the recording's profile and property messages give.
/// `given` replaces the calibration (the profiles are then only used for the colour format,
/// when there).
pub(crate) fn decode(
    path: &Path,
    depth_profile: Option<&[u8]>,
    color_profile: Option<&[u8]>,
    properties: &[Vec<u8>],
    given: Option<Calibration>,
) -> Result<Decoded> {
    let missing = |what: &str| {
        KinectError::calibration(
            path,
            format!(
                "no {what} stream profile message; the recorder writes them when the recording \
                 stops (a recording not closed?); give a calibration"
            ),
        )
    };
    let props = read_properties(properties, path)?;
    let color = color_profile
        .map(|b| parse_profile(b, path, "colour"))
        .transpose()?;
    let depth = depth_profile
        .map(|b| parse_profile(b, path, "depth"))
        .transpose()?;
    if let Some(d) = &depth
        && !matches!(d.format, FORMAT_Y16 | FORMAT_Z16)
    {
        return Err(KinectError::Unsupported {
            path: path.to_path_buf(),
            what: format!(
                "depth stream format {} (OBFormat; 16-bit Y16/Z16 depth is read, not packed or \
                 compressed depth)",
                d.format
            ),
        });
    }
    let codec = color
        .as_ref()
        .map(|c| color_codec(c.format, path))
        .transpose()?;
    let calibration = match given {
        Some(c) => c,
        None => {
            let depth = depth.ok_or_else(|| missing("depth"))?;
            let color = color.ok_or_else(|| missing("colour"))?;
            Calibration {
                depth_camera: depth.camera,
                color_camera: color.camera,
                registration: RegistrationModel::Rigid(extrinsics(&depth, path)?),
                depth_unit_m: props.depth_unit_m,
                depth_offset_m: 0.0,
            }
        }
    };
    calibration
        .validate()
        .map_err(|e| KinectError::calibration(path, e.to_string()))?;
    Ok(Decoded {
        calibration,
        color: codec,
    })
}

/// The depth-to-colour transform the depth profile records.
fn extrinsics(depth: &Profile, path: &Path) -> Result<Extrinsics> {
    let r = depth.rotation.map(f64::from);
    let rotation = [[r[0], r[1], r[2]], [r[3], r[4], r[5]], [r[6], r[7], r[8]]];
    let m = nalgebra::Matrix3::from_fn(|i, j| rotation[i][j]);
    let error = (m * m.transpose() - nalgebra::Matrix3::identity())
        .abs()
        .max();
    if !(error < ROTATION_TOLERANCE && (m.determinant() - 1.0).abs() < ROTATION_TOLERANCE) {
        return Err(KinectError::calibration(
            path,
            format!(
                "depth stream profile: the depth-to-colour rotation {:?} is not a rotation \
                 (a depth-only recording?)",
                depth.rotation
            ),
        ));
    }
    Ok(Extrinsics {
        rotation,
        translation_m: depth.translation_mm.map(|t| f64::from(t) * 1e-3),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A property message as the recorder serialises it.
    fn property(id: u32, value: &[u8]) -> Vec<u8> {
        let mut b = vec![0u8; 12]; // seq, sec, nsec
        b.extend(0u32.to_le_bytes()); // frame_id ""
        b.extend(id.to_le_bytes());
        b.extend((value.len() as u32).to_le_bytes());
        b.extend(value);
        b.extend((value.len() as u32).to_le_bytes());
        b
    }

    #[test]
    fn depth_unit_follows_the_sdk_playback() {
        let path = Path::new("x.bag");
        let unit = |props: &[Vec<u8>]| read_properties(props, path).map(|p| p.depth_unit_m);
        assert_eq!(unit(&[]).unwrap(), 1e-3);
        // Level 3 is 0.1 mm; the flexible unit wins over the level.
        assert_eq!(unit(&[property(75, &3i32.to_le_bytes())]).unwrap(), 0.1e-3);
        let both = [
            property(75, &0i32.to_le_bytes()),
            property(176, &0.5f32.to_le_bytes()),
        ];
        assert_eq!(unit(&both).unwrap(), 0.5e-3);
        assert!(unit(&[property(75, &9i32.to_le_bytes())]).is_err());
        let err = unit(&[property(85, &[0, 0, 0, 0])]).unwrap_err();
        assert!(err.to_string().contains("disparity"), "{err}");
        let err = unit(&[property(81, &[1])]).unwrap_err();
        assert!(err.to_string().contains("mirrored"), "{err}");
        let err = unit(&[property(42, &1i32.to_le_bytes())]).unwrap_err();
        assert!(err.to_string().contains("hardware D2C"), "{err}");
        // Switches that are off change nothing.
        let off = [
            property(81, &[0]),
            property(85, &[1]),
            property(42, &[0, 0, 0, 0]),
        ];
        assert_eq!(unit(&off).unwrap(), 1e-3);
    }

    #[test]
    fn distortion_models() {
        let path = Path::new("x.bag");
        let d = [0.1, -0.2, 0.03, 0.0, 0.0, 0.0, 0.001, -0.002];
        let bc = distortion(DISTORTION_BROWN_CONRADY, &d, path, "colour").unwrap();
        assert_eq!(
            bc,
            Distortion::from_opencv(&[0.1, -0.2, 0.001, -0.002, 0.03]).unwrap()
        );
        let zero = distortion(5, &[0.0; 8], path, "colour").unwrap();
        assert_eq!(zero, Distortion::default());
        assert!(distortion(5, &d, path, "colour").is_err());
        assert!(distortion(DISTORTION_NONE, &d, path, "colour").is_err());
    }
}
