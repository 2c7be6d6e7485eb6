//! Calibration of an RGB-D camera: both cameras, how depth maps to colour, and depth units.
//!
//! Files: our own JSON ([`Calibration::read_json`], format in `docs/recording-format.md`) and
//! iai_kinect2's `calib_color.yaml`, `calib_ir.yaml`, `calib_pose.yaml` (+ optional
//! `calib_depth.yaml`) written by its `kinect2_calibration` tool
//! ([`Calibration::read_iai_kinect2`]).

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::camera::{CameraModel, Distortion};
use crate::depth::{DEPTH_UNIT_MM_M, DEPTH_UNIT_TUM_M};
use crate::error::{KinectError, MEMORY_LABEL, Result};
use crate::freenect2::{Freenect2ColorParams, Freenect2IrParams};
use crate::opencv_yaml;

/// Identifies our calibration JSON.
pub const CALIBRATION_FORMAT: &str = "treemocap-calibration";
/// Version of our calibration JSON that this crate writes (and the only one it reads).
pub const CALIBRATION_VERSION: u32 = 1;
/// How far a rotation matrix may be from orthonormal (max abs entry of `R Rᵀ - I`); calibration
/// tools write 16 significant digits, so real files are within 1e-12.
const ROTATION_TOLERANCE: f64 = 1e-6;
/// Kinect V2: the colour camera sits about 52 mm along +x of the depth camera (iai_kinect2
/// calibrations of real devices measure -51.6 mm to -52.0 mm for `translation.x`).
pub const KINECT_V2_BASELINE_M: f64 = 0.052;
/// TUM RGB-D default intrinsics for Kinect v1 data without a calibration (TUM benchmark,
/// "file formats" page: fx = fy = 525, cx = 319.5, cy = 239.5 for 640x480).
pub const TUM_DEFAULT_FOCAL_PX: f64 = 525.0;

/// A rigid transform from the depth camera's frame to the colour camera's frame:
/// `p_color = rotation * p_depth + translation_m` (the convention of OpenCV's
/// `stereoCalibrate(depth, colour)` and so of iai_kinect2's `calib_pose.yaml`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Extrinsics {
    /// Rotation matrix, row-major.
    pub rotation: [[f64; 3]; 3],
    /// Translation in metres.
    pub translation_m: [f64; 3],
}

impl Extrinsics {
    /// No rotation, no translation.
    pub fn identity() -> Self {
        Self {
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation_m: [0.0; 3],
        }
    }

    /// From an isometry.
    pub fn from_isometry(iso: &Isometry3<f64>) -> Self {
        let m = iso.rotation.to_rotation_matrix().into_inner();
        Self {
            rotation: [
                [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
                [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
                [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
            ],
            translation_m: [iso.translation.x, iso.translation.y, iso.translation.z],
        }
    }

    /// As an isometry, after checking that the rotation is a proper rotation.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] when an entry is not finite, the matrix is not
    /// orthonormal within 1e-6, or it is a reflection.
    pub fn to_isometry(&self) -> Result<Isometry3<f64>> {
        let r = &self.rotation;
        let m = Matrix3::new(
            r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
        );
        if m.iter()
            .chain(self.translation_m.iter())
            .any(|v| !v.is_finite())
        {
            return Err(KinectError::param("extrinsics", "a value is not finite"));
        }
        let error = (m * m.transpose() - Matrix3::identity()).abs().max();
        if error > ROTATION_TOLERANCE {
            return Err(KinectError::param(
                "extrinsics rotation",
                format!("not orthonormal (|R Rᵀ - I| = {error:.3e})"),
            ));
        }
        if m.determinant() < 0.0 {
            return Err(KinectError::param(
                "extrinsics rotation",
                "is a reflection (det < 0)",
            ));
        }
        let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
        let t = self.translation_m;
        Ok(Isometry3::from_parts(
            Translation3::new(t[0], t[1], t[2]),
            rotation,
        ))
    }
}

/// How a depth pixel finds its colour.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum RegistrationModel {
    /// Two calibrated cameras and a rigid transform between them (iai_kinect2, Azure Kinect,
    /// any stereo calibration).
    Rigid(Extrinsics),
    /// Depth is already registered to colour: depth pixel `(u, v)` has the colour of colour
    /// pixel `(u, v)`, and both images have the same size (TUM RGB-D, Azure Kinect's
    /// "depth in colour" mode). The depth camera model is the colour camera model.
    AlreadyRegistered,
    /// libfreenect2's model from the Kinect V2's factory parameters.
    Freenect2 {
        /// The IR camera's factory parameters.
        ir: Freenect2IrParams,
        /// The colour camera's factory parameters.
        color: Freenect2ColorParams,
    },
}

/// Calibration of an RGB-D camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// The depth (IR) camera.
    pub depth_camera: CameraModel,
    /// The colour camera.
    pub color_camera: CameraModel,
    /// How depth pixels map to colour pixels.
    pub registration: RegistrationModel,
    /// Size of one raw depth unit in metres (0.001 for millimetres).
    pub depth_unit_m: f64,
    /// Offset added to every converted depth, in metres (iai_kinect2's `depthShift`, which it
    /// stores in millimetres). Zero by default.
    #[serde(default)]
    pub depth_offset_m: f64,
}

/// Largest distance between the two cameras of a rig, and largest depth offset, metres.
const MAX_RIG_M: f64 = 10.0;

/// The first key path of `input` that `parsed` (the same document parsed and written back)
/// does not have: a field the reader ignored.
fn unknown_field(
    input: &serde_json::Value,
    parsed: &serde_json::Value,
    at: &str,
) -> Option<String> {
    let (serde_json::Value::Object(i), serde_json::Value::Object(p)) = (input, parsed) else {
        return None;
    };
    for (key, value) in i {
        let here = if at.is_empty() {
            key.clone()
        } else {
            format!("{at}.{key}")
        };
        match p.get(key) {
            None => return Some(here),
            Some(written) => {
                if let Some(found) = unknown_field(value, written, &here) {
                    return Some(found);
                }
            }
        }
    }
    None
}

#[derive(Serialize, Deserialize)]
struct CalibrationFile {
    format: String,
    version: u32,
    #[serde(flatten)]
    calibration: Calibration,
}

impl Calibration {
    /// A Kinect V2 with its typical intrinsics ([`CameraModel::kinect_v2_depth`],
    /// [`CameraModel::kinect_v2_color`]) and the colour camera 52 mm along +x, no rotation.
    /// Depth in millimetres.
    pub fn kinect_v2() -> Self {
        Self {
            depth_camera: CameraModel::kinect_v2_depth(),
            color_camera: CameraModel::kinect_v2_color(),
            registration: RegistrationModel::Rigid(Extrinsics {
                translation_m: [-KINECT_V2_BASELINE_M, 0.0, 0.0],
                ..Extrinsics::identity()
            }),
            depth_unit_m: DEPTH_UNIT_MM_M,
            depth_offset_m: 0.0,
        }
    }

    /// The TUM RGB-D defaults for data without a calibration file: 640x480, fx = fy = 525,
    /// cx = 319.5, cy = 239.5, no distortion, depth already registered, 1/5000 m units.
    pub fn tum_default() -> Self {
        let camera = CameraModel {
            width: 640,
            height: 480,
            fx: TUM_DEFAULT_FOCAL_PX,
            fy: TUM_DEFAULT_FOCAL_PX,
            cx: 319.5,
            cy: 239.5,
            distortion: Distortion::default(),
        };
        Self {
            depth_camera: camera,
            color_camera: camera,
            registration: RegistrationModel::AlreadyRegistered,
            depth_unit_m: DEPTH_UNIT_TUM_M,
            depth_offset_m: 0.0,
        }
    }

    /// libfreenect2's registration from the device's factory parameters (depth in mm).
    pub fn freenect2(ir: Freenect2IrParams, color: Freenect2ColorParams) -> Self {
        Self {
            depth_camera: ir.camera(),
            color_camera: color.camera(),
            registration: RegistrationModel::Freenect2 { ir, color },
            depth_unit_m: DEPTH_UNIT_MM_M,
            depth_offset_m: 0.0,
        }
    }

    /// The calibration of this camera pair's frames once their depth is registered to the
    /// colour camera ([`crate::ProjectionImage::depth_image`] of the cloud projected onto
    /// it): the colour camera for both, already registered, depth in `depth_unit_m`.
    pub fn registered_to_color(&self, depth_unit_m: f64) -> Self {
        Self {
            depth_camera: self.color_camera,
            color_camera: self.color_camera,
            registration: RegistrationModel::AlreadyRegistered,
            depth_unit_m,
            depth_offset_m: 0.0,
        }
    }

    /// The depth-to-colour transform of a rigid or already-registered calibration (identity
    /// for the latter); `None` for libfreenect2's polynomial model.
    ///
    /// # Errors
    /// As [`Extrinsics::to_isometry`].
    pub fn depth_to_color(&self) -> Result<Option<Isometry3<f64>>> {
        match &self.registration {
            RegistrationModel::Rigid(e) => e.to_isometry().map(Some),
            RegistrationModel::AlreadyRegistered => Ok(Some(Isometry3::identity())),
            RegistrationModel::Freenect2 { .. } => Ok(None),
        }
    }

    /// Check every part: both cameras, the extrinsics, units, and that an already-registered
    /// calibration has one camera.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] naming what is wrong.
    pub fn validate(&self) -> Result<()> {
        self.depth_camera.validate()?;
        self.color_camera.validate()?;
        if !(self.depth_unit_m.is_finite() && self.depth_unit_m > 0.0 && self.depth_unit_m <= 1.0) {
            return Err(KinectError::param(
                "depth_unit_m",
                format!(
                    "{} m must be positive and at most 1 m (millimetres are 0.001)",
                    self.depth_unit_m
                ),
            ));
        }
        if !(self.depth_offset_m.is_finite() && self.depth_offset_m.abs() <= MAX_RIG_M) {
            return Err(KinectError::param(
                "depth_offset_m",
                format!(
                    "{} m; an offset beyond {MAX_RIG_M} m is no depth correction",
                    self.depth_offset_m
                ),
            ));
        }
        match &self.registration {
            RegistrationModel::Rigid(e) => {
                e.to_isometry()?;
                if !e.translation_m.iter().all(|t| t.abs() <= MAX_RIG_M) {
                    return Err(KinectError::param(
                        "registration translation_m",
                        format!(
                            "{:?} m; cameras more than {MAX_RIG_M} m apart are not one RGB-D camera",
                            e.translation_m
                        ),
                    ));
                }
            }
            RegistrationModel::AlreadyRegistered => {
                if (self.depth_camera.width, self.depth_camera.height)
                    != (self.color_camera.width, self.color_camera.height)
                {
                    return Err(KinectError::param(
                        "registration",
                        "already-registered depth needs depth and colour cameras of one size",
                    ));
                }
            }
            RegistrationModel::Freenect2 { ir, color } => {
                crate::freenect2::Freenect2Registration::new(*ir, *color)?;
            }
        }
        Ok(())
    }

    /// Parse our calibration JSON.
    ///
    /// # Errors
    /// [`KinectError::Calibration`] for malformed JSON, a wrong format tag or version, or
    /// values that fail [`Calibration::validate`].
    pub fn from_json(text: &str) -> Result<Self> {
        Self::from_json_at(text, Path::new(MEMORY_LABEL))
    }

    fn from_json_at(text: &str, path: &Path) -> Result<Self> {
        // `flatten` and unit variants of tagged enums cannot deny unknown fields in serde:
        // whatever the input holds that the parsed file does not write back is unknown.
        let value: serde_json::Value = serde_json::from_str(text)
            .map_err(|e| KinectError::calibration(path, e.to_string()))?;
        let file: CalibrationFile = serde_json::from_value(value.clone())
            .map_err(|e| KinectError::calibration(path, e.to_string()))?;
        let written = serde_json::to_value(&file).unwrap_or_default();
        if let Some(field) = unknown_field(&value, &written, "") {
            return Err(KinectError::calibration(
                path,
                format!("unknown field {field:?}"),
            ));
        }
        if file.format != CALIBRATION_FORMAT {
            return Err(KinectError::calibration(
                path,
                format!(
                    "format is {:?}, expected {CALIBRATION_FORMAT:?}",
                    file.format
                ),
            ));
        }
        if file.version != CALIBRATION_VERSION {
            return Err(KinectError::calibration(
                path,
                format!(
                    "version {} is not supported (this reader knows {CALIBRATION_VERSION})",
                    file.version
                ),
            ));
        }
        file.calibration
            .validate()
            .map_err(|e| KinectError::calibration(path, e.to_string()))?;
        Ok(file.calibration)
    }

    /// Serialise as our calibration JSON (pretty-printed).
    pub fn to_json(&self) -> String {
        let file = CalibrationFile {
            format: CALIBRATION_FORMAT.into(),
            version: CALIBRATION_VERSION,
            calibration: self.clone(),
        };
        // Serialising plain structs of numbers and strings cannot fail; non-finite floats
        // become `null`, which `from_json` then rejects.
        serde_json::to_string_pretty(&file).unwrap_or_default()
    }

    /// Read our calibration JSON from a file.
    ///
    /// # Errors
    /// [`KinectError::Io`] when it cannot be read; otherwise as [`Calibration::from_json`].
    pub fn read_json(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| KinectError::io(path, e))?;
        Self::from_json_at(&text, path)
    }

    /// Write our calibration JSON to a file.
    ///
    /// # Errors
    /// [`KinectError::Io`] when it cannot be written.
    pub fn write_json(&self, path: &Path) -> Result<()> {
        std::fs::write(path, self.to_json()).map_err(|e| KinectError::io(path, e))
    }

    /// Read an iai_kinect2 calibration directory (`calib_color.yaml`, `calib_ir.yaml`,
    /// `calib_pose.yaml`, and `calib_depth.yaml` when present). Cameras are the Kinect V2's
    /// 512x424 IR and 1920x1080 colour; depth in millimetres.
    ///
    /// # Errors
    /// [`KinectError::Io`] for a missing file, [`KinectError::Format`] for a file that is not
    /// OpenCV YAML, [`KinectError::Calibration`] for missing or malformed matrices.
    pub fn read_iai_kinect2(dir: &Path) -> Result<Self> {
        let read = |name: &str| -> Result<(PathBuf, String)> {
            let path = dir.join(name);
            let text = std::fs::read_to_string(&path).map_err(|e| KinectError::io(&path, e))?;
            Ok((path, text))
        };
        let (color_path, color_text) = read("calib_color.yaml")?;
        let (ir_path, ir_text) = read("calib_ir.yaml")?;
        let (pose_path, pose_text) = read("calib_pose.yaml")?;
        let depth_camera = iai_camera(&ir_text, &ir_path, 512, 424)?;
        let color_camera = iai_camera(&color_text, &color_path, 1920, 1080)?;
        let pose = opencv_yaml::parse(&pose_text, &pose_path)?;
        let r = opencv_yaml::matrix(&pose, "rotation", (3, 3), &pose_path)?;
        let t = opencv_yaml::vector(&pose, "translation", &pose_path)?;
        if t.len() != 3 {
            return Err(KinectError::calibration(
                &pose_path,
                format!("`translation` has {} values, expected 3", t.len()),
            ));
        }
        let extrinsics = Extrinsics {
            rotation: [[r[0], r[1], r[2]], [r[3], r[4], r[5]], [r[6], r[7], r[8]]],
            translation_m: [t[0], t[1], t[2]],
        };
        extrinsics
            .to_isometry()
            .map_err(|e| KinectError::calibration(&pose_path, e.to_string()))?;
        let depth_path = dir.join("calib_depth.yaml");
        let depth_offset_m = if depth_path.exists() {
            let text = std::fs::read_to_string(&depth_path)
                .map_err(|e| KinectError::io(&depth_path, e))?;
            let doc = opencv_yaml::parse(&text, &depth_path)?;
            opencv_yaml::scalar(&doc, "depthShift", &depth_path)? * 1e-3
        } else {
            0.0
        };
        let calibration = Self {
            depth_camera,
            color_camera,
            registration: RegistrationModel::Rigid(extrinsics),
            depth_unit_m: DEPTH_UNIT_MM_M,
            depth_offset_m,
        };
        calibration
            .validate()
            .map_err(|e| KinectError::calibration(dir, e.to_string()))?;
        Ok(calibration)
    }

    /// Read a calibration from a path: a `.json` file (ours), or an iai_kinect2 directory (or
    /// one of its `calib_*.yaml` files, meaning its directory).
    ///
    /// # Errors
    /// As [`Calibration::read_json`] or [`Calibration::read_iai_kinect2`].
    pub fn read(path: &Path) -> Result<Self> {
        if path.is_dir() {
            return Self::read_iai_kinect2(path);
        }
        let is_yaml = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("yaml") || e.eq_ignore_ascii_case("yml"));
        if is_yaml {
            let dir = path.parent().unwrap_or_else(|| Path::new("."));
            return Self::read_iai_kinect2(dir);
        }
        Self::read_json(path)
    }
}

fn iai_camera(text: &str, path: &Path, width: u32, height: u32) -> Result<CameraModel> {
    let doc = opencv_yaml::parse(text, path)?;
    let k = opencv_yaml::matrix(&doc, "cameraMatrix", (3, 3), path)?;
    let d = opencv_yaml::vector(&doc, "distortionCoefficients", path)?;
    let distortion =
        Distortion::from_opencv(d).map_err(|e| KinectError::calibration(path, e.to_string()))?;
    if k[1] != 0.0 || k[3] != 0.0 || k[6] != 0.0 || k[7] != 0.0 || k[8] != 1.0 {
        return Err(KinectError::calibration(
            path,
            "cameraMatrix is not of the form [fx 0 cx; 0 fy cy; 0 0 1]",
        ));
    }
    CameraModel::new(width, height, k[0], k[4], k[2], k[5], distortion)
        .map_err(|e| KinectError::calibration(path, e.to_string()))
}

/// Unit vector helper for the world transform.
fn axis(x: f64, y: f64, z: f64) -> Vector3<f64> {
    Vector3::new(x, y, z)
}

/// The transform from the OpenCV camera frame (x right, y down, z forward) to a Z-up world
/// frame (x right, y forward, z up) for a camera at height `camera_height_m` above the world
/// origin, pitched down by `pitch_down_rad` (0 = level, looking along +y).
pub fn camera_to_world_z_up(camera_height_m: f64, pitch_down_rad: f64) -> Isometry3<f64> {
    let (s, c) = pitch_down_rad.sin_cos();
    let m = Matrix3::from_columns(&[axis(1.0, 0.0, 0.0), axis(0.0, -s, -c), axis(0.0, c, -s)]);
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
    Isometry3::from_parts(Translation3::new(0.0, 0.0, camera_height_m), rotation)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::Point3;

    /// Issue 20: unknown fields were accepted silently in calibration files (a misspelt
    /// `depth_ofset_m` left the offset at zero without a word). Every level refuses them now.
    #[test]
    fn unknown_fields_are_errors_at_every_level() {
        for calibration in [Calibration::kinect_v2(), Calibration::tum_default(), {
            let ir = crate::freenect2::Freenect2IrParams::kinect_v2_typical();
            let color = crate::freenect2::Freenect2ColorParams::from_pinhole_baseline(
                &ir, 1081.37, 959.5, 539.5, 52.0,
            );
            Calibration::freenect2(ir, color)
        }] {
            let text = calibration.to_json();
            assert_eq!(Calibration::from_json(&text).unwrap(), calibration);
            let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
            value["depth_ofset_m"] = serde_json::json!(0.01);
            let e = Calibration::from_json(&value.to_string()).unwrap_err();
            assert!(e.to_string().contains("depth_ofset_m"), "{e}");
            let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
            value["depth_camera"]["skew"] = serde_json::json!(0.0);
            let e = Calibration::from_json(&value.to_string()).unwrap_err();
            assert!(e.to_string().contains("skew"), "{e}");
            let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
            value["registration"]["scale"] = serde_json::json!(1.0);
            let e = Calibration::from_json(&value.to_string()).unwrap_err();
            assert!(e.to_string().contains("scale"), "{e}");
        }
    }

    #[test]
    fn json_round_trip_for_every_model() {
        let ir = Freenect2IrParams::kinect_v2_typical();
        let color = Freenect2ColorParams::from_pinhole_baseline(&ir, 1081.37, 959.5, 539.5, 52.0);
        for calibration in [
            Calibration::kinect_v2(),
            Calibration::tum_default(),
            Calibration::freenect2(ir, color),
        ] {
            let back = Calibration::from_json(&calibration.to_json()).expect("round trip");
            assert_eq!(back, calibration);
        }
    }

    #[test]
    fn json_with_wrong_tag_or_bad_values_is_rejected() {
        let text = Calibration::kinect_v2().to_json();
        assert!(Calibration::from_json(&text.replace(CALIBRATION_FORMAT, "other")).is_err());
        assert!(Calibration::from_json(&text.replace("\"fx\": 365.5", "\"fx\": -1.0")).is_err());
        assert!(Calibration::from_json("{").is_err());
    }

    #[test]
    fn non_rotations_are_rejected() {
        let mut e = Extrinsics::identity();
        e.rotation[0][0] = 2.0;
        assert!(e.to_isometry().is_err());
        e.rotation = [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(e.to_isometry().is_err());
    }

    #[test]
    fn world_frame_is_z_up() {
        let level = camera_to_world_z_up(1.5, 0.0);
        // A point 2 m ahead of a level camera is 2 m along +y at camera height.
        let p = level * Point3::new(0.0, 0.0, 2.0);
        assert_relative_eq!(p, Point3::new(0.0, 2.0, 1.5), epsilon = 1e-12);
        // Image-down is world-down.
        let q = level * Point3::new(0.0, 1.0, 0.0);
        assert_relative_eq!(q.z, 0.5, epsilon = 1e-12);
        // Pitched down 90 degrees: forward is straight down.
        let down = camera_to_world_z_up(1.5, std::f64::consts::FRAC_PI_2);
        let r = down * Point3::new(0.0, 0.0, 1.0);
        assert_relative_eq!(r, Point3::new(0.0, 0.0, 0.5), epsilon = 1e-12);
    }
}
