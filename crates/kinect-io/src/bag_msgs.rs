//! ROS 1 message serialisation for the bag readers: a bounds-checked little-endian reader
//! and the standard messages RealSense bags hold (`sensor_msgs/Image`, `CameraInfo`,
//! `geometry_msgs/Transform`).

use std::path::Path;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

use crate::camera::{CameraModel, Distortion};
use crate::error::{KinectError, Result};

/// Little-endian ROS 1 serialisation, every read bounds-checked.
pub(crate) struct Reader<'a> {
    data: &'a [u8],
    pub pos: usize,
    path: &'a Path,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(data: &'a [u8], path: &'a Path) -> Self {
        Self { data, pos: 0, path }
    }

    pub(crate) fn left(&self) -> usize {
        self.data.len() - self.pos
    }

    pub(crate) fn bytes(&mut self, n: usize) -> Result<&'a [u8]> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.data.len());
        let Some(end) = end else {
            return Err(KinectError::format(
                self.path,
                format!(
                    "a message is cut off: {n} bytes asked for at byte {} of {}",
                    self.pos,
                    self.data.len()
                ),
            ));
        };
        let out = &self.data[self.pos..end];
        self.pos = end;
        Ok(out)
    }

    pub(crate) fn array<const N: usize>(&mut self) -> Result<[u8; N]> {
        let b = self.bytes(N)?;
        let mut out = [0u8; N];
        out.copy_from_slice(b);
        Ok(out)
    }

    pub(crate) fn u8(&mut self) -> Result<u8> {
        Ok(self.array::<1>()?[0])
    }

    pub(crate) fn u16(&mut self) -> Result<u16> {
        Ok(u16::from_le_bytes(self.array()?))
    }

    pub(crate) fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    pub(crate) fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_le_bytes(self.array()?))
    }

    pub(crate) fn f32(&mut self) -> Result<f32> {
        Ok(f32::from_le_bytes(self.array()?))
    }

    pub(crate) fn string(&mut self) -> Result<&'a str> {
        let n = self.u32()? as usize;
        let b = self.bytes(n)?;
        std::str::from_utf8(b)
            .map_err(|_| KinectError::format(self.path, "a message string is not UTF-8"))
    }

    pub(crate) fn f64s(&mut self, n: usize) -> Result<Vec<f64>> {
        (0..n).map(|_| self.f64()).collect()
    }

    /// `std_msgs/Header`: the stamp in nanoseconds.
    pub(crate) fn header(&mut self) -> Result<u64> {
        let _seq = self.u32()?;
        let sec = u64::from(self.u32()?);
        let nsec = u64::from(self.u32()?);
        let _frame = self.string()?;
        Ok(sec * 1_000_000_000 + nsec)
    }
}

/// A `sensor_msgs/Image`, borrowed.
pub(crate) struct ImageMsg<'a> {
    pub stamp_ns: u64,
    pub height: u32,
    pub width: u32,
    pub encoding: &'a str,
    pub big_endian: bool,
    pub step: u32,
    pub data: &'a [u8],
}

pub(crate) fn parse_image<'a>(bytes: &'a [u8], path: &'a Path) -> Result<ImageMsg<'a>> {
    let mut r = Reader::new(bytes, path);
    let stamp_ns = r.header()?;
    let height = r.u32()?;
    let width = r.u32()?;
    let encoding = r.string()?;
    let big_endian = r.u8()? != 0;
    let step = r.u32()?;
    let n = r.u32()? as usize;
    let data = r.bytes(n)?;
    Ok(ImageMsg {
        stamp_ns,
        height,
        width,
        encoding,
        big_endian,
        step,
        data,
    })
}

/// A `sensor_msgs/CameraInfo` as a camera model.
pub(crate) fn parse_camera_info(bytes: &[u8], path: &Path, what: &str) -> Result<CameraModel> {
    let bad = |w: String| KinectError::calibration(path, format!("{what} camera_info: {w}"));
    let mut r = Reader::new(bytes, path);
    r.header()?;
    let height = r.u32()?;
    let width = r.u32()?;
    let model = r.string()?.to_owned();
    let n = r.u32()? as usize;
    if n > r.left() / 8 {
        return Err(bad(format!(
            "{n} distortion coefficients in a short message"
        )));
    }
    let d = r.f64s(n)?;
    let k = r.f64s(9)?;
    let known = matches!(
        model.as_str(),
        "Brown Conrady" | "plumb_bob" | "rational_polynomial"
    );
    if !known && d.iter().any(|&c| c != 0.0) {
        return Err(KinectError::Unsupported {
            path: path.to_path_buf(),
            what: format!(
                "{what} camera_info: distortion model {model:?} with coefficients {d:?} (only \
                 Brown–Conrady / plumb_bob / rational_polynomial, or zero coefficients)"
            ),
        });
    }
    let distortion = if d.iter().all(|&c| c == 0.0) {
        Distortion::default()
    } else {
        let take = d.len().min(8);
        let list = if take > 5 && take < 8 {
            &d[..5]
        } else {
            &d[..take]
        };
        Distortion::from_opencv(list).map_err(|e| bad(e.to_string()))?
    };
    let camera = CameraModel {
        width,
        height,
        fx: k[0],
        fy: k[4],
        cx: k[2],
        cy: k[5],
        distortion,
    };
    camera.validate().map_err(|e| bad(e.to_string()))?;
    Ok(camera)
}

/// A `geometry_msgs/Transform` as an isometry.
pub(crate) fn parse_transform(bytes: &[u8], path: &Path, what: &str) -> Result<Isometry3<f64>> {
    let mut r = Reader::new(bytes, path);
    let v = r.f64s(7)?;
    let q = Quaternion::new(v[6], v[3], v[4], v[5]);
    let norm = q.norm();
    if !(v.iter().all(|x| x.is_finite()) && (norm - 1.0).abs() < 1e-3) {
        return Err(KinectError::calibration(
            path,
            format!("{what} tf: not a rigid transform: {v:?}"),
        ));
    }
    Ok(Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        UnitQuaternion::from_quaternion(q),
    ))
}
