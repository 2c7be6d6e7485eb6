//! Calibration files of the ROS world: a camera's `sensor_msgs/CameraInfo` as YAML (what
//! `camera_calibration` and the camera drivers write: `image_width`, `image_height`,
//! `camera_matrix`, `distortion_model`, `distortion_coefficients`), and a rigid transform
//! saved by NumPy as a 4x4 `float64` `.npy` (as datasets ship the depth-to-colour pose of
//! an RGB-D camera). With them a two-camera calibration can be put together:
//! [`Calibration::from_ros_camera_infos`].

use std::path::Path;

use crate::calibration::{Calibration, Extrinsics, RegistrationModel};
use crate::camera::{CameraModel, Distortion};
use crate::error::{KinectError, Result};

/// Largest file these readers take, bytes (a camera info is well under a kilobyte, a 4x4
/// `.npy` 256 bytes).
const MAX_FILE_BYTES: u64 = 1 << 20;

fn read_small(path: &Path) -> Result<Vec<u8>> {
    let size = std::fs::metadata(path)
        .map_err(|e| KinectError::io(path, e))?
        .len();
    if size > MAX_FILE_BYTES {
        return Err(KinectError::format(
            path,
            format!("{size} bytes; a calibration file is at most {MAX_FILE_BYTES}"),
        ));
    }
    std::fs::read(path).map_err(|e| KinectError::io(path, e))
}

/// The numbers of the flow list (`[a, b, ...]`, possibly over several lines) that follows
/// `key:` in a camera-info YAML text.
fn flow_list(text: &str, key: &str, path: &Path) -> Result<Vec<f64>> {
    let missing = || KinectError::calibration(path, format!("no `{key}` list"));
    let start = text
        .lines()
        .scan(0, |at, line| {
            let here = *at;
            *at += line.len() + 1;
            Some((here, line))
        })
        .find(|(_, line)| line.trim_start().starts_with(&format!("{key}:")))
        .map(|(at, _)| at)
        .ok_or_else(missing)?;
    let rest = &text[start..];
    let open = rest.find('[').ok_or_else(missing)?;
    let close = rest[open..].find(']').ok_or_else(missing)? + open;
    rest[open + 1..close]
        .split(',')
        .filter(|v| !v.trim().is_empty())
        .map(|v| {
            v.trim().parse::<f64>().map_err(|e| {
                KinectError::calibration(path, format!("`{key}`: {:?}: {e}", v.trim()))
            })
        })
        .collect()
}

/// The value after `key:` on its own line.
fn scalar<'a>(text: &'a str, key: &str, path: &Path) -> Result<&'a str> {
    text.lines()
        .find_map(|l| l.trim_start().strip_prefix(&format!("{key}:")))
        .map(str::trim)
        .ok_or_else(|| KinectError::calibration(path, format!("no `{key}`")))
}

/// Read a ROS camera info YAML file as a camera model. Distortion models
/// `plumb_bob` (5 coefficients) and `rational_polynomial` (8) are Brown–Conrady in
/// OpenCV's order; a file without distortion coefficients has none.
///
/// # Errors
/// [`KinectError::Io`] when it cannot be read, [`KinectError::Calibration`] naming the file
/// for a missing or malformed field or another distortion model (`equidistant`: fisheye),
/// [`KinectError::InvalidParameter`] for an invalid camera.
pub fn read_ros_camera_info(path: &Path) -> Result<CameraModel> {
    let bytes = read_small(path)?;
    let text = String::from_utf8(bytes).map_err(|_| KinectError::format(path, "not UTF-8 text"))?;
    let size = |key: &str| -> Result<u32> {
        let v = scalar(&text, key, path)?;
        v.parse()
            .map_err(|e| KinectError::calibration(path, format!("`{key}`: {v:?}: {e}")))
    };
    let k = flow_list(&text, "camera_matrix", path)?;
    let [fx, _, cx, _, fy, cy, ..] = k[..] else {
        return Err(KinectError::calibration(
            path,
            format!("`camera_matrix` has {} numbers, expected 9", k.len()),
        ));
    };
    let model = scalar(&text, "distortion_model", path).unwrap_or("plumb_bob");
    let d = if text.contains("distortion_coefficients:") {
        flow_list(&text, "distortion_coefficients", path)?
    } else {
        Vec::new()
    };
    let distortion = match (model, d.len()) {
        (_, 0) => Distortion::default(),
        ("plumb_bob" | "rational_polynomial", 4 | 5 | 8) => Distortion::from_opencv(&d)
            .map_err(|e| KinectError::calibration(path, e.to_string()))?,
        (model, n) => {
            return Err(KinectError::calibration(
                path,
                format!("distortion model {model:?} with {n} coefficients is not supported"),
            ));
        }
    };
    let camera = CameraModel {
        width: size("image_width")?,
        height: size("image_height")?,
        fx,
        fy,
        cx,
        cy,
        distortion,
    };
    camera
        .validate()
        .map_err(|e| KinectError::calibration(path, e.to_string()))?;
    Ok(camera)
}

/// Read a 4x4 rigid transform saved by NumPy (`.npy` format 1.0–3.0, little-endian
/// `float64`, C or Fortran order), as given: the rotation is the upper-left 3x3, the
/// translation (metres) the last column.
///
/// # Errors
/// [`KinectError::Io`] when it cannot be read, [`KinectError::Format`] naming the file for
/// anything but a 4x4 `<f8` array, [`KinectError::Calibration`] when the matrix is not a
/// rigid transform.
pub fn read_npy_transform(path: &Path) -> Result<Extrinsics> {
    let bytes = read_small(path)?;
    let bad = |what: &str| KinectError::format(path, what.to_string());
    if bytes.get(..6) != Some(b"\x93NUMPY".as_slice()) {
        return Err(bad("not a .npy file (no \\x93NUMPY magic)"));
    }
    let major = bytes
        .get(6)
        .copied()
        .ok_or_else(|| bad("truncated header"))?;
    let (len, at) = match major {
        1 => (
            usize::from(u16::from_le_bytes([
                *bytes.get(8).ok_or_else(|| bad("truncated header"))?,
                *bytes.get(9).ok_or_else(|| bad("truncated header"))?,
            ])),
            10,
        ),
        2 | 3 => {
            let b = bytes.get(8..12).ok_or_else(|| bad("truncated header"))?;
            (u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize, 12)
        }
        v => return Err(bad(&format!(".npy format version {v} is not supported"))),
    };
    let header = bytes
        .get(at..at + len)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or_else(|| bad("truncated or non-text header"))?;
    let compact: String = header.chars().filter(|c| !c.is_whitespace()).collect();
    if !compact.contains("'descr':'<f8'") {
        return Err(bad(&format!(
            "dtype is not little-endian float64: {header}"
        )));
    }
    if !compact.contains("'shape':(4,4)") {
        return Err(bad(&format!("shape is not (4, 4): {header}")));
    }
    let fortran = compact.contains("'fortran_order':True");
    let data = &bytes[at + len..];
    if data.len() != 16 * 8 {
        return Err(bad(&format!("{} data bytes, expected 128", data.len())));
    }
    let value = |r: usize, c: usize| {
        let k = if fortran { c * 4 + r } else { r * 4 + c };
        let mut b = [0; 8];
        b.copy_from_slice(&data[8 * k..8 * k + 8]);
        f64::from_le_bytes(b)
    };
    let extrinsics = Extrinsics {
        rotation: [0, 1, 2].map(|r| [0, 1, 2].map(|c| value(r, c))),
        translation_m: [value(0, 3), value(1, 3), value(2, 3)],
    };
    extrinsics
        .to_isometry()
        .map_err(|e| KinectError::calibration(path, e.to_string()))?;
    Ok(extrinsics)
}

impl Calibration {
    /// A rigid two-camera calibration from the two cameras' ROS camera info files and the
    /// depth-to-colour transform (points in the depth camera's frame to the colour
    /// camera's), depth in `depth_unit_m` per raw unit.
    ///
    /// # Errors
    /// As [`read_ros_camera_info`]; [`KinectError::InvalidParameter`] for a depth unit that
    /// is not positive and finite.
    pub fn from_ros_camera_infos(
        depth_info: &Path,
        color_info: &Path,
        depth_to_color: Extrinsics,
        depth_unit_m: f64,
    ) -> Result<Self> {
        if !(depth_unit_m.is_finite() && depth_unit_m > 0.0) {
            return Err(KinectError::param(
                "depth unit",
                format!("{depth_unit_m} m must be positive and finite"),
            ));
        }
        Ok(Self {
            depth_camera: read_ros_camera_info(depth_info)?,
            color_camera: read_ros_camera_info(color_info)?,
            registration: RegistrationModel::Rigid(depth_to_color),
            depth_unit_m,
            depth_offset_m: 0.0,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scratch folder of one test, removed (with its files) when dropped.
    struct Scratch(std::path::PathBuf);

    impl Scratch {
        fn new(test: &str) -> Self {
            let dir =
                std::env::temp_dir().join(format!("kinect-io-ros-{}-{test}", std::process::id()));
            std::fs::create_dir_all(&dir).unwrap_or(());
            Scratch(dir)
        }

        fn file(&self, name: &str, bytes: &[u8]) -> std::path::PathBuf {
            let path = self.0.join(name);
            std::fs::write(&path, bytes).unwrap_or(());
            path
        }
    }

    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    const INFO: &str = "image_width: 1280\nimage_height: 720\ncamera_name: rgb\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [614.3,   0.     , 639.1,   0.     , 614.2 , 361.4,\n           0.     ,   0.     ,   1.     ]\ndistortion_model: rational_polynomial\ndistortion_coefficients:\n  rows: 1\n  cols: 8\n  data: [0.37, -2.45, 0.00004, -0.0002, 1.41, 0.25, -2.27, 1.34]\n";

    #[test]
    fn camera_info_is_read_with_its_rational_distortion() -> Result<()> {
        let scratch = Scratch::new("info");
        let c = read_ros_camera_info(&scratch.file("info.yaml", INFO.as_bytes()))?;
        assert_eq!((c.width, c.height), (1280, 720));
        assert_eq!((c.fx, c.fy, c.cx, c.cy), (614.3, 614.2, 639.1, 361.4));
        assert_eq!(c.distortion.to_opencv()[..2], [0.37, -2.45]);
        assert_eq!(c.distortion.to_opencv()[5], 0.25);
        for (name, text) in [
            ("nomatrix.yaml", INFO.replace("camera_matrix", "camera_mat")),
            ("short.yaml", INFO.replace("614.3,   0.     ,", "")),
            (
                "fisheye.yaml",
                INFO.replace("rational_polynomial", "equidistant"),
            ),
            ("word.yaml", INFO.replace("639.1", "x")),
            ("nosize.yaml", INFO.replace("image_width: 1280\n", "")),
        ] {
            let path = scratch.file(name, text.as_bytes());
            match read_ros_camera_info(&path) {
                Err(KinectError::Calibration { .. }) => {}
                other => panic!("{name}: {other:?}"),
            }
        }
        Ok(())
    }

    fn npy(matrix: &[f64; 16], header: &str) -> Vec<u8> {
        let mut h = header.to_string();
        while !(10 + h.len() + 1).is_multiple_of(64) {
            h.push(' ');
        }
        h.push('\n');
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        out.extend((h.len() as u16).to_le_bytes());
        out.extend(h.as_bytes());
        for v in matrix {
            out.extend(v.to_le_bytes());
        }
        out
    }

    #[test]
    fn npy_transform_is_read_in_either_order_and_checked() -> Result<()> {
        let scratch = Scratch::new("npy");
        // A rotation of 90° about z and a translation of (0.1, -0.2, 0.3) m.
        let c_order = [
            0.0, -1.0, 0.0, 0.1, 1.0, 0.0, 0.0, -0.2, 0.0, 0.0, 1.0, 0.3, 0.0, 0.0, 0.0, 1.0,
        ];
        let header = "{'descr': '<f8', 'fortran_order': False, 'shape': (4, 4), }";
        let e = read_npy_transform(&scratch.file("c.npy", &npy(&c_order, header)))?;
        assert_eq!(
            e.rotation,
            [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
        );
        assert_eq!(e.translation_m, [0.1, -0.2, 0.3]);
        let mut f_order = [0.0; 16];
        for r in 0..4 {
            for c in 0..4 {
                f_order[c * 4 + r] = c_order[r * 4 + c];
            }
        }
        let header_f = "{'descr': '<f8', 'fortran_order': True, 'shape': (4, 4), }";
        assert_eq!(
            read_npy_transform(&scratch.file("f.npy", &npy(&f_order, header_f)))?,
            e
        );
        let mut scaled = c_order;
        scaled[0] = 2.0;
        let cases = [
            ("scaled.npy", npy(&scaled, header)),
            ("f4.npy", npy(&c_order, &header.replace("<f8", "<f4"))),
            (
                "3x3.npy",
                npy(&c_order, &header.replace("(4, 4)", "(3, 3)")),
            ),
            ("cut.npy", npy(&c_order, header)[..100].to_vec()),
            ("text.npy", b"0 1 0\n".to_vec()),
        ];
        for (name, bytes) in cases {
            match read_npy_transform(&scratch.file(name, &bytes)) {
                Err(KinectError::Format { .. } | KinectError::Calibration { .. }) => {}
                other => panic!("{name}: {other:?}"),
            }
        }
        Ok(())
    }
}
