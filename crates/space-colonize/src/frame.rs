//! Which way is up: clouds in other frames than the tree frame's Z up.
//!
//! [`crate::reconstruct`] grows a tree from its lowest points upward, so a cloud must be Z up.
//! Two common sources are not: a depth camera's own frame (OpenCV: x right, **y down**, z
//! forward, which is how `kinect-io` writes a capture unless given a camera-to-world
//! transform) and Y-up exports of modelling tools. Grown as if Z were up, such a cloud
//! gives a model rooted at the front of the tree (or its side) that can still lie close to
//! the points, so nothing else would say it is wrong. [`UpAxis`] turns a cloud into the
//! tree frame and a model back, and [`looks_like_camera_frame`] recognises a cloud that is
//! still in a depth camera's frame ([`crate::Reconstruction::camera_frame_suspected`]).

use std::fmt;
use std::str::FromStr;

use nalgebra::{Point3, Rotation3, Vector3};
use serde::Serialize;

use crate::error::{ColonizeError, Result};
use crate::skeleton::Skeleton;

/// Nearest depth a depth camera's cloud starts at, metres (every RGB-D camera of the
/// recordings kinect-io reads has a minimum range of 0.2–0.5 m: Kinect v2 0.5 m, Azure
/// Kinect 0.25 m (WFOV), RealSense D4xx about 0.2 m at its default resolution).
pub const CAMERA_MIN_DEPTH_M: f64 = 0.1;
/// Farthest depth of a depth camera's cloud, metres (Kinect v2 8 m, Azure Kinect 5.46 m,
/// RealSense D455 about 10 m; with margin).
pub const CAMERA_MAX_DEPTH_M: f64 = 20.0;
/// Widest half field of view as the tangent |x| / z or |y| / z (the Azure Kinect's wide
/// depth mode is 120° across, tan 60° = 1.73; with margin).
pub const CAMERA_MAX_TAN: f64 = 1.9;
/// Share of points that must lie in that frustum (a few flying pixels and stray returns
/// aside) for a cloud to look like a camera's.
pub const CAMERA_FRUSTUM_SHARE: f64 = 0.995;

/// The direction of a cloud's frame that points up (against gravity): what
/// [`Self::to_z_up`] turns into +Z. Parsed from `x`, `+x`, `-x`, ..., `-z`.
///
/// ```
/// use nalgebra::Point3;
/// use space_colonize::UpAxis;
///
/// // A depth camera's frame (y down, z forward): up is -y.
/// let up: UpAxis = "-y".parse()?;
/// let p = up.to_z_up(&Point3::new(0.1, -1.5, 3.0));
/// assert_eq!(p, Point3::new(0.1, 3.0, 1.5)); // x right, y forward, z up
/// assert_eq!(up.from_z_up(&p), Point3::new(0.1, -1.5, 3.0));
/// # Ok::<(), space_colonize::ColonizeError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
pub enum UpAxis {
    /// +X is up.
    #[serde(rename = "+x")]
    PlusX,
    /// -X is up.
    #[serde(rename = "-x")]
    MinusX,
    /// +Y is up (Y-up exports).
    #[serde(rename = "+y")]
    PlusY,
    /// -Y is up (a level depth camera's own frame: y down).
    #[serde(rename = "-y")]
    MinusY,
    /// +Z is up: the tree frame already.
    #[default]
    #[serde(rename = "+z")]
    PlusZ,
    /// -Z is up (a cloud upside down).
    #[serde(rename = "-z")]
    MinusZ,
}

impl UpAxis {
    /// Every axis, in the order of [`fmt::Display`]'s names `+x -x +y -y +z -z`.
    pub const ALL: [Self; 6] = [
        Self::PlusX,
        Self::MinusX,
        Self::PlusY,
        Self::MinusY,
        Self::PlusZ,
        Self::MinusZ,
    ];

    /// The up direction as a unit vector in the cloud's frame.
    pub fn direction(self) -> Vector3<f64> {
        match self {
            Self::PlusX => Vector3::x(),
            Self::MinusX => -Vector3::x(),
            Self::PlusY => Vector3::y(),
            Self::MinusY => -Vector3::y(),
            Self::PlusZ => Vector3::z(),
            Self::MinusZ => -Vector3::z(),
        }
    }

    /// The proper rotation (no mirroring) from the cloud's frame to the tree frame: a
    /// quarter or half turn about one axis that takes [`Self::direction`] to +Z. For
    /// [`Self::MinusY`] it is the level camera's camera-to-world rotation (x right stays,
    /// z forward becomes y forward, y down becomes z down).
    pub fn rotation(self) -> Rotation3<f64> {
        use std::f64::consts::{FRAC_PI_2, PI};
        match self {
            Self::PlusX => Rotation3::from_axis_angle(&Vector3::y_axis(), -FRAC_PI_2),
            Self::MinusX => Rotation3::from_axis_angle(&Vector3::y_axis(), FRAC_PI_2),
            Self::PlusY => Rotation3::from_axis_angle(&Vector3::x_axis(), FRAC_PI_2),
            Self::MinusY => Rotation3::from_axis_angle(&Vector3::x_axis(), -FRAC_PI_2),
            Self::PlusZ => Rotation3::identity(),
            Self::MinusZ => Rotation3::from_axis_angle(&Vector3::x_axis(), PI),
        }
    }

    /// A point of the cloud's frame in the tree frame. The rotations are signed swaps of
    /// coordinates, so no rounding is added.
    pub fn to_z_up(self, p: &Point3<f64>) -> Point3<f64> {
        let (x, y, z) = (p.x, p.y, p.z);
        match self {
            Self::PlusX => Point3::new(-z, y, x),
            Self::MinusX => Point3::new(z, y, -x),
            Self::PlusY => Point3::new(x, -z, y),
            Self::MinusY => Point3::new(x, z, -y),
            Self::PlusZ => *p,
            Self::MinusZ => Point3::new(x, -y, -z),
        }
    }

    /// A point of the tree frame back in the cloud's frame (the inverse of
    /// [`Self::to_z_up`]).
    pub fn from_z_up(self, p: &Point3<f64>) -> Point3<f64> {
        let (x, y, z) = (p.x, p.y, p.z);
        match self {
            Self::PlusX => Point3::new(z, y, -x),
            Self::MinusX => Point3::new(-z, y, x),
            Self::PlusY => Point3::new(x, z, -y),
            Self::MinusY => Point3::new(x, -z, y),
            Self::PlusZ => *p,
            Self::MinusZ => Point3::new(x, -y, -z),
        }
    }

    /// A skeleton of the tree frame back in the cloud's frame (positions turned, radii,
    /// ids and parents kept), so that it lies on the cloud it was grown from.
    ///
    /// # Errors
    /// None in practice (the turned skeleton has the same structure); the
    /// [`Skeleton::new`] checks are passed on.
    pub fn skeleton_from_z_up(self, skeleton: &Skeleton) -> Result<Skeleton> {
        skeleton.map_positions(|p| self.from_z_up(p))
    }
}

impl fmt::Display for UpAxis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::PlusX => "+x",
            Self::MinusX => "-x",
            Self::PlusY => "+y",
            Self::MinusY => "-y",
            Self::PlusZ => "+z",
            Self::MinusZ => "-z",
        })
    }
}

impl FromStr for UpAxis {
    type Err = ColonizeError;

    fn from_str(text: &str) -> Result<Self> {
        let t = text.trim().to_ascii_lowercase();
        let t = t.strip_prefix('+').unwrap_or(&t);
        Ok(match t {
            "x" => Self::PlusX,
            "-x" => Self::MinusX,
            "y" => Self::PlusY,
            "-y" => Self::MinusY,
            "z" => Self::PlusZ,
            "-z" => Self::MinusZ,
            _ => {
                return Err(ColonizeError::InvalidParameter {
                    name: "up",
                    reason: format!("{text:?} is not an axis: use x, y, z, -x, -y or -z"),
                });
            }
        })
    }
}

/// Whether a cloud looks like it is still in a depth camera's own frame (OpenCV: x right, y
/// down, z forward) rather than Z up: at least [`CAMERA_FRUSTUM_SHARE`] of its points lie
/// in front of the origin between [`CAMERA_MIN_DEPTH_M`] and [`CAMERA_MAX_DEPTH_M`] along
/// +Z, inside the frustum |x|, |y| ≤ [`CAMERA_MAX_TAN`] · z. A tree in the tree frame
/// stands on its base near z = 0 (or at its survey height, often hundreds of metres), with
/// its base points well beside the Z axis for their height, so it fails the test; a capture
/// written in the camera frame passes it. Its up is then [`UpAxis::MinusY`] for a camera
/// held level (`kinect_io::camera_to_world_z_up` for a tilted one). A cloud deliberately
/// placed in such a frustum above the origin would be taken for a capture: this is a hint
/// for a warning, not a proof.
pub fn looks_like_camera_frame(points: &[Point3<f64>]) -> bool {
    if points.is_empty() {
        return false;
    }
    let inside = points
        .iter()
        .filter(|p| {
            (CAMERA_MIN_DEPTH_M..=CAMERA_MAX_DEPTH_M).contains(&p.z)
                && p.x.abs() <= CAMERA_MAX_TAN * p.z
                && p.y.abs() <= CAMERA_MAX_TAN * p.z
        })
        .count();
    inside as f64 >= CAMERA_FRUSTUM_SHARE * points.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_axis_turns_its_up_to_plus_z_and_back_without_mirroring() {
        let p = Point3::new(0.3, -1.7, 2.9);
        for up in UpAxis::ALL {
            let r = up.rotation();
            assert!((r * up.direction() - Vector3::z()).norm() < 1e-12, "{up}");
            assert!((r.matrix().determinant() - 1.0).abs() < 1e-12, "{up}");
            // The exact swaps are the rotation.
            assert!((up.to_z_up(&p) - r * p).norm() < 1e-12, "{up}");
            assert_eq!(up.from_z_up(&up.to_z_up(&p)), p, "{up}");
            assert_eq!(up.to_string().parse::<UpAxis>().ok(), Some(up));
        }
        assert_eq!("Y".parse::<UpAxis>().ok(), Some(UpAxis::PlusY));
        assert!(matches!(
            "up".parse::<UpAxis>(),
            Err(ColonizeError::InvalidParameter { name: "up", .. })
        ));
    }

    #[test]
    fn a_level_cameras_frame_becomes_the_camera_to_world_frame() {
        // x right stays, z forward becomes y forward, y down becomes z down.
        let up = UpAxis::MinusY;
        assert_eq!(
            up.to_z_up(&Point3::new(1.0, 0.0, 0.0)),
            Point3::new(1.0, 0.0, 0.0)
        );
        assert_eq!(
            up.to_z_up(&Point3::new(0.0, 0.0, 1.0)),
            Point3::new(0.0, 1.0, 0.0)
        );
        assert_eq!(
            up.to_z_up(&Point3::new(0.0, 1.0, 0.0)),
            Point3::new(0.0, 0.0, -1.0)
        );
    }

    #[test]
    fn a_capture_in_front_of_the_camera_is_told_from_a_standing_tree() {
        // A tree 3 m in front of a camera, trunk along -y (up), in the camera frame.
        let mut capture: Vec<Point3<f64>> = (0..400)
            .map(|i| {
                let t = f64::from(i) / 400.0;
                Point3::new(0.05 * (t * 40.0).sin(), 1.2 - 2.4 * t, 3.0 + 0.05 * t)
            })
            .collect();
        assert!(looks_like_camera_frame(&capture));
        // The same tree turned Z up, standing on z = 0.
        let standing: Vec<Point3<f64>> = capture
            .iter()
            .map(|p| UpAxis::MinusY.to_z_up(p) + Vector3::new(0.0, -3.0, 1.2))
            .collect();
        assert!(!looks_like_camera_frame(&standing));
        // A few flying pixels behind the camera do not hide a capture; many do.
        capture.push(Point3::new(0.0, 0.0, -1.0));
        assert!(looks_like_camera_frame(&capture));
        capture.extend((0..20).map(|_| Point3::new(0.0, 0.0, -1.0)));
        assert!(!looks_like_camera_frame(&capture));
        assert!(!looks_like_camera_frame(&[]));
    }
}
