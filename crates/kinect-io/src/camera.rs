//! Pinhole camera with Brown–Conrady distortion, OpenCV's model and conventions.
//!
//! Frame: OpenCV camera frame (x right, y down, z forward), metres. Pixel centres sit at
//! integer coordinates: pixel `(u, v)` covers `[u - 0.5, u + 0.5) x [v - 0.5, v + 0.5)`, so the
//! top-left pixel's centre is `(0.0, 0.0)`. This is OpenCV's convention for `cameraMatrix`
//! (and so for iai_kinect2 and ROS `CameraInfo` calibrations).

use nalgebra::{Point2, Point3, Vector2};
use serde::{Deserialize, Serialize};

use crate::error::{KinectError, Result};

/// Kinect V2 depth/IR image width in pixels (Microsoft Kinect for Windows v2 specification).
pub const KINECT_V2_DEPTH_WIDTH_PX: u32 = 512;
/// Kinect V2 depth/IR image height in pixels.
pub const KINECT_V2_DEPTH_HEIGHT_PX: u32 = 424;
/// Kinect V2 colour image width in pixels.
pub const KINECT_V2_COLOR_WIDTH_PX: u32 = 1920;
/// Kinect V2 colour image height in pixels.
pub const KINECT_V2_COLOR_HEIGHT_PX: u32 = 1080;

/// Newton iterations allowed when inverting the distortion.
const UNDISTORT_MAX_ITERATIONS: usize = 30;
/// Convergence threshold of the undistortion, in normalised image units (about 1e-9 px).
const UNDISTORT_TOLERANCE: f64 = 1e-12;

/// Brown–Conrady lens distortion: radial `k1, k2, k3` and tangential `p1, p2`, in OpenCV's
/// definition (`distCoeffs = [k1, k2, p1, p2, k3]`), plus OpenCV's optional rational
/// denominator `k4, k5, k6` (`[k1, k2, p1, p2, k3, k4, k5, k6]`, the model Azure Kinect
/// calibrations use; zero for plain Brown–Conrady). All zero means no distortion.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Distortion {
    /// Radial coefficient of r².
    pub k1: f64,
    /// Radial coefficient of r⁴.
    pub k2: f64,
    /// Radial coefficient of r⁶.
    pub k3: f64,
    /// Tangential coefficient p1.
    pub p1: f64,
    /// Tangential coefficient p2.
    pub p2: f64,
    /// Rational denominator coefficient of r² (0 for plain Brown–Conrady).
    #[serde(default)]
    pub k4: f64,
    /// Rational denominator coefficient of r⁴.
    #[serde(default)]
    pub k5: f64,
    /// Rational denominator coefficient of r⁶.
    #[serde(default)]
    pub k6: f64,
}

impl Distortion {
    /// From OpenCV's coefficient order `[k1, k2, p1, p2, k3, k4, k5, k6]` (4, 5 or 8 values;
    /// missing ones are zero).
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] for another count (OpenCV's thin-prism and tilted
    /// models, 12 and 14 values, are not supported) or a value that is not finite.
    pub fn from_opencv(coefficients: &[f64]) -> Result<Self> {
        if ![4, 5, 8].contains(&coefficients.len()) {
            return Err(KinectError::param(
                "distortion coefficients",
                format!(
                    "expected 4, 5 or 8 values [k1, k2, p1, p2, k3, k4, k5, k6], got {}",
                    coefficients.len()
                ),
            ));
        }
        if coefficients.iter().any(|c| !c.is_finite()) {
            return Err(KinectError::param(
                "distortion coefficients",
                format!("not finite: {coefficients:?}"),
            ));
        }
        Ok(Self {
            k1: coefficients[0],
            k2: coefficients[1],
            p1: coefficients[2],
            p2: coefficients[3],
            k3: coefficients.get(4).copied().unwrap_or(0.0),
            k4: coefficients.get(5).copied().unwrap_or(0.0),
            k5: coefficients.get(6).copied().unwrap_or(0.0),
            k6: coefficients.get(7).copied().unwrap_or(0.0),
        })
    }

    /// OpenCV's coefficient order `[k1, k2, p1, p2, k3, k4, k5, k6]`.
    pub fn to_opencv(&self) -> [f64; 8] {
        [
            self.k1, self.k2, self.p1, self.p2, self.k3, self.k4, self.k5, self.k6,
        ]
    }

    /// Radial factor and its derivative with respect to r².
    #[inline]
    fn radial(&self, r2: f64) -> (f64, f64) {
        let num = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let d_num = self.k1 + r2 * (2.0 * self.k2 + 3.0 * r2 * self.k3);
        if self.k4 == 0.0 && self.k5 == 0.0 && self.k6 == 0.0 {
            return (num, d_num);
        }
        let den = 1.0 + r2 * (self.k4 + r2 * (self.k5 + r2 * self.k6));
        let d_den = self.k4 + r2 * (2.0 * self.k5 + 3.0 * r2 * self.k6);
        (num / den, (d_num * den - num * d_den) / (den * den))
    }

    /// True when every coefficient is zero.
    pub fn is_zero(&self) -> bool {
        self.to_opencv().iter().all(|&c| c == 0.0)
    }

    /// The distorted normalised coordinates of the camera-frame point `(X, Y, Z)`, `Z > 0`:
    /// [`Distortion::apply`] of `(X/Z, Y/Z)`, computed with one division instead of two
    /// (the rational model's `num / den` and the perspective `1/Z` share a denominator
    /// `Z² · den · Z⁶ / Z⁶`). The cloud builder's hot path; equal to `apply` to rounding.
    #[inline]
    pub fn apply_to_point(&self, px: f64, py: f64, pz: f64) -> (f64, f64) {
        let z2 = pz * pz;
        let z4 = z2 * z2;
        let rho = px * px + py * py; // r² · Z²
        let num = z4 * z2 + rho * (self.k1 * z4 + rho * (self.k2 * z2 + rho * self.k3));
        let den = z4 * z2 + rho * (self.k4 * z4 + rho * (self.k5 * z2 + rho * self.k6));
        let tx = 2.0 * self.p1 * px * py + self.p2 * (rho + 2.0 * px * px);
        let ty = self.p1 * (rho + 2.0 * py * py) + 2.0 * self.p2 * px * py;
        let inv = 1.0 / (z2 * den);
        (
            (px * num * pz + tx * den) * inv,
            (py * num * pz + ty * den) * inv,
        )
    }

    /// Distort a normalised image point (`x = X/Z`, `y = Y/Z`).
    #[inline]
    pub fn apply(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let (radial, _) = self.radial(r2);
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
        (xd, yd)
    }

    /// Invert [`Distortion::apply`] by Newton's method, starting from the distorted point.
    ///
    /// Returns `None` when the iteration does not converge (a point outside the region where
    /// the polynomial is invertible, which strong barrel distortion has beyond the image).
    pub fn remove(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        if self.is_zero() {
            return Some((xd, yd));
        }
        let (mut x, mut y) = (xd, yd);
        for _ in 0..UNDISTORT_MAX_ITERATIONS {
            let (fx, fy) = self.apply(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            if ex.abs().max(ey.abs()) < UNDISTORT_TOLERANCE {
                return Some((x, y));
            }
            let r2 = x * x + y * y;
            let (radial, d_radial) = self.radial(r2);
            let j11 = radial + 2.0 * x * x * d_radial + 2.0 * self.p1 * y + 6.0 * self.p2 * x;
            let j12 = 2.0 * x * y * d_radial + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
            let j22 = radial + 2.0 * y * y * d_radial + 6.0 * self.p1 * y + 2.0 * self.p2 * x;
            let det = j11 * j22 - j12 * j12;
            if !det.is_finite() || det.abs() < 1e-12 {
                return None;
            }
            x -= (j22 * ex - j12 * ey) / det;
            y -= (j11 * ey - j12 * ex) / det;
            if !(x.is_finite() && y.is_finite()) {
                return None;
            }
        }
        let (fx, fy) = self.apply(x, y);
        ((fx - xd).abs().max((fy - yd).abs()) < 1e-9).then_some((x, y))
    }
}

/// Largest image side accepted, pixels: 16384, four times the widest RGB-D sensor (Azure
/// Kinect colour: 4096 px); anything larger is a corrupt calibration, and would allocate
/// gigabytes per frame.
pub const MAX_IMAGE_SIDE_PX: u32 = 16_384;

/// Largest focal length accepted, in image sides: 100 is a field of view of 0.6 degrees.
pub const MAX_FOCAL_SIDES: f64 = 100.0;

/// Largest distortion coefficient accepted (OpenCV's rational model stays within tens for
/// real lenses; Azure Kinect factory values are below 30).
pub const MAX_DISTORTION_COEFFICIENT: f64 = 1e3;

/// A pinhole camera with Brown–Conrady distortion and an image size.
///
/// Build it with [`CameraModel::new`] (which validates) or a preset; a hand-built value should
/// be checked with [`CameraModel::validate`], which every consumer in this crate also calls.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraModel {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along x, in pixels.
    pub fx: f64,
    /// Focal length along y, in pixels.
    pub fy: f64,
    /// Principal point x, in pixels (pixel centres at integers).
    pub cx: f64,
    /// Principal point y, in pixels (pixel centres at integers).
    pub cy: f64,
    /// Lens distortion (zero for an ideal or rectified camera).
    #[serde(default)]
    pub distortion: Distortion,
}

impl CameraModel {
    /// A validated camera model.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] naming the first invalid field (see
    /// [`CameraModel::validate`]).
    pub fn new(
        width: u32,
        height: u32,
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        distortion: Distortion,
    ) -> Result<Self> {
        let camera = Self {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
            distortion,
        };
        camera.validate()?;
        Ok(camera)
    }

    /// Kinect V2 depth/IR camera (512x424), typical factory intrinsics.
    ///
    /// Values: the IR parameters a Kinect V2 reports through libfreenect2 are close to
    /// fx = fy = 365.5 px, cx = 256.0 px, cy = 207.0 px, k1 = 0.09, k2 = -0.27, k3 = 0.09
    /// (device to device they vary by about 1 %; calibrate for measurement work).
    pub fn kinect_v2_depth() -> Self {
        Self {
            width: KINECT_V2_DEPTH_WIDTH_PX,
            height: KINECT_V2_DEPTH_HEIGHT_PX,
            fx: 365.5,
            fy: 365.5,
            cx: 256.0,
            cy: 207.0,
            distortion: Distortion {
                k1: 0.09,
                k2: -0.27,
                k3: 0.09,
                ..Distortion::default()
            },
        }
    }

    /// Kinect V2 colour camera (1920x1080), typical factory intrinsics without distortion:
    /// fx = fy = 1081.37 px, cx = 959.5 px, cy = 539.5 px (libfreenect2's default colour
    /// parameters).
    pub fn kinect_v2_color() -> Self {
        Self {
            width: KINECT_V2_COLOR_WIDTH_PX,
            height: KINECT_V2_COLOR_HEIGHT_PX,
            fx: 1081.37,
            fy: 1081.37,
            cx: 959.5,
            cy: 539.5,
            distortion: Distortion::default(),
        }
    }

    /// Check that the model is usable: non-zero size, positive finite focal lengths, finite
    /// principal point and distortion coefficients.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] naming the first offending field and its value.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(KinectError::param(
                "camera size",
                format!("{}x{} px has no pixels", self.width, self.height),
            ));
        }
        if self.width > MAX_IMAGE_SIDE_PX || self.height > MAX_IMAGE_SIDE_PX {
            return Err(KinectError::param(
                "camera size",
                format!(
                    "{}x{} px; at most {MAX_IMAGE_SIDE_PX} px a side (no RGB-D camera comes near)",
                    self.width, self.height
                ),
            ));
        }
        let side = f64::from(self.width.max(self.height));
        for (name, value) in [("camera fx", self.fx), ("camera fy", self.fy)] {
            if !(value.is_finite() && value > 0.0 && value <= MAX_FOCAL_SIDES * side) {
                return Err(KinectError::param(
                    name,
                    format!(
                        "{value} px must be positive and at most {MAX_FOCAL_SIDES} image widths ({} px)",
                        MAX_FOCAL_SIDES * side
                    ),
                ));
            }
        }
        for (name, value, size) in [
            ("camera cx", self.cx, f64::from(self.width)),
            ("camera cy", self.cy, f64::from(self.height)),
        ] {
            if !(value.is_finite() && value >= -size && value <= 2.0 * size) {
                return Err(KinectError::param(
                    name,
                    format!(
                        "{value} px; the principal point must lie within one image size of the image ({} to {} px)",
                        -size,
                        2.0 * size
                    ),
                ));
            }
        }
        if self
            .distortion
            .to_opencv()
            .iter()
            .any(|c| !(c.is_finite() && c.abs() <= MAX_DISTORTION_COEFFICIENT))
        {
            return Err(KinectError::param(
                "camera distortion",
                format!(
                    "coefficients must be finite and at most {MAX_DISTORTION_COEFFICIENT} in size: {:?}",
                    self.distortion
                ),
            ));
        }
        Ok(())
    }

    /// The same camera at `factor` times the resolution (for example 0.5 for a half-size
    /// projection image). Pixel-centre convention is kept: `c' = (c + 0.5) * factor - 0.5`.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] when `factor` is not positive and finite or the
    /// scaled image would have no pixels.
    pub fn scaled(&self, factor: f64) -> Result<Self> {
        if !(factor.is_finite() && factor > 0.0) {
            return Err(KinectError::param(
                "scale factor",
                format!("{factor} must be finite and positive"),
            ));
        }
        let width = (f64::from(self.width) * factor).round();
        let height = (f64::from(self.height) * factor).round();
        if width < 1.0
            || height < 1.0
            || width > f64::from(u32::MAX)
            || height > f64::from(u32::MAX)
        {
            return Err(KinectError::param(
                "scale factor",
                format!("{factor} gives a {width}x{height} px image"),
            ));
        }
        Self::new(
            width as u32,
            height as u32,
            self.fx * factor,
            self.fy * factor,
            (self.cx + 0.5) * factor - 0.5,
            (self.cy + 0.5) * factor - 0.5,
            self.distortion,
        )
    }

    /// Project a point of the camera frame (metres) to a pixel position (pixels, sub-pixel).
    /// `None` when the point is not in front of the camera (`z <= 0`). The result may lie
    /// outside the image; see [`CameraModel::contains`].
    #[inline]
    pub fn project(&self, point: &Point3<f64>) -> Option<Point2<f64>> {
        if point.z.is_nan() || point.z <= 0.0 {
            return None;
        }
        let (x, y) = (point.x / point.z, point.y / point.z);
        let (xd, yd) = if self.distortion.is_zero() {
            (x, y)
        } else {
            self.distortion.apply(x, y)
        };
        let pixel = Point2::new(self.fx * xd + self.cx, self.fy * yd + self.cy);
        (pixel.x.is_finite() && pixel.y.is_finite()).then_some(pixel)
    }

    /// The normalised, undistorted ray `(x, y)` with `X = x Z, Y = y Z` seen at `pixel`.
    /// `None` when the distortion cannot be inverted there.
    pub fn unproject_normalized(&self, pixel: &Point2<f64>) -> Option<Vector2<f64>> {
        let xd = (pixel.x - self.cx) / self.fx;
        let yd = (pixel.y - self.cy) / self.fy;
        self.distortion
            .remove(xd, yd)
            .map(|(x, y)| Vector2::new(x, y))
    }

    /// The 3D point at depth `z_m` (along the optical axis, metres) seen at `pixel`.
    /// `None` when the distortion cannot be inverted there or `z_m` is not positive.
    pub fn unproject(&self, pixel: &Point2<f64>, z_m: f64) -> Option<Point3<f64>> {
        if !(z_m > 0.0 && z_m.is_finite()) {
            return None;
        }
        self.unproject_normalized(pixel)
            .map(|r| Point3::new(r.x * z_m, r.y * z_m, z_m))
    }

    /// True when the pixel position lies on the image (within half a pixel of a pixel centre).
    #[inline]
    pub fn contains(&self, pixel: &Point2<f64>) -> bool {
        pixel.x >= -0.5
            && pixel.y >= -0.5
            && pixel.x < f64::from(self.width) - 0.5
            && pixel.y < f64::from(self.height) - 0.5
    }

    /// The integer pixel holding a sub-pixel position, if it lies on the image.
    #[inline]
    pub fn pixel_at(&self, pixel: &Point2<f64>) -> Option<(u32, u32)> {
        if self.contains(pixel) {
            let u = (pixel.x + 0.5).floor() as u32;
            let v = (pixel.y + 0.5).floor() as u32;
            Some((u.min(self.width - 1), v.min(self.height - 1)))
        } else {
            None
        }
    }

    /// Check that an image of `width x height` pixels has this camera's size.
    ///
    /// # Errors
    /// [`KinectError::SizeMismatch`] naming `what` (say, the image file) when it has not.
    pub fn check_image_size(&self, what: &str, width: u32, height: u32) -> Result<()> {
        if (self.width, self.height) == (width, height) {
            return Ok(());
        }
        Err(KinectError::SizeMismatch {
            what: what.to_string(),
            expected_width: self.width,
            expected_height: self.height,
            found_width: width,
            found_height: height,
        })
    }

    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The undistorted normalised ray of every pixel centre, row-major, for fast repeated
    /// unprojection (`X = x Z, Y = y Z`). Pixels where the distortion cannot be inverted get
    /// `None`.
    pub fn ray_table(&self) -> Vec<Option<Vector2<f64>>> {
        let mut table = Vec::with_capacity(self.pixel_count());
        for v in 0..self.height {
            for u in 0..self.width {
                table.push(self.unproject_normalized(&Point2::new(f64::from(u), f64::from(v))));
            }
        }
        table
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// Round-trip tolerance in pixels: Newton converges to 1e-12 normalised units.
    const ROUND_TRIP_TOLERANCE_PX: f64 = 1e-6;

    #[test]
    fn one_division_distortion_equals_the_two_division_one() {
        let d = Distortion {
            k1: 0.375,
            k2: -2.45,
            k3: 1.41,
            p1: 4.5e-5,
            p2: -2.4e-4,
            k4: 0.255,
            k5: -2.27,
            k6: 1.34,
        };
        for (x, y, z) in [
            (0.3, -0.2, 1.7),
            (-0.9, 0.5, 0.6),
            (0.0, 0.0, 3.0),
            (1.2, 0.8, 4.5),
        ] {
            let (a, b) = d.apply(x / z, y / z);
            let (c, e) = d.apply_to_point(x, y, z);
            assert_relative_eq!(a, c, max_relative = 1e-12);
            assert_relative_eq!(b, e, max_relative = 1e-12);
        }
    }

    #[test]
    fn principal_point_projects_to_itself() {
        let camera = CameraModel::kinect_v2_depth();
        let p = camera
            .project(&Point3::new(0.0, 0.0, 2.0))
            .expect("in front");
        assert_relative_eq!(p.x, camera.cx);
        assert_relative_eq!(p.y, camera.cy);
    }

    #[test]
    fn distorted_round_trip_at_corners() {
        let camera = CameraModel::kinect_v2_depth();
        for (u, v) in [(0.0, 0.0), (511.0, 423.0), (0.0, 423.0), (300.5, 17.25)] {
            let pixel = Point2::new(u, v);
            let point = camera.unproject(&pixel, 1.7).expect("invertible");
            let back = camera.project(&point).expect("in front");
            assert!(
                (back - pixel).norm() < ROUND_TRIP_TOLERANCE_PX,
                "{pixel} -> {back}"
            );
        }
    }

    #[test]
    fn opencv_order_is_k1_k2_p1_p2_k3_k4_k5_k6() {
        let d = Distortion::from_opencv(&[1.0, 2.0, 3.0, 4.0, 5.0]).expect("five values");
        assert_eq!((d.k1, d.k2, d.p1, d.p2, d.k3), (1.0, 2.0, 3.0, 4.0, 5.0));
        let d = Distortion::from_opencv(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]).expect("eight");
        assert_eq!((d.k4, d.k5, d.k6), (6.0, 7.0, 8.0));
        assert_eq!(d.to_opencv(), [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]);
        assert!(Distortion::from_opencv(&[1.0, 2.0, 3.0]).is_err());
        assert!(Distortion::from_opencv(&[0.0; 12]).is_err());
    }

    #[test]
    fn rational_model_round_trip() {
        // Coefficients of the kind an Azure Kinect depth camera reports (rational model).
        let camera = CameraModel {
            distortion: Distortion::from_opencv(&[
                3.28, 2.07, 0.00004, -0.00002, 0.10, 3.61, 3.10, 0.54,
            ])
            .expect("eight values"),
            ..CameraModel::kinect_v2_depth()
        };
        for (u, v) in [(10.0, 10.0), (256.0, 207.0), (500.0, 400.0)] {
            let pixel = Point2::new(u, v);
            let point = camera.unproject(&pixel, 1.2).expect("invertible");
            let back = camera.project(&point).expect("front");
            assert!(
                (back - pixel).norm() < ROUND_TRIP_TOLERANCE_PX,
                "{pixel} -> {back}"
            );
        }
        // The rational factor differs from plain Brown-Conrady away from the centre.
        let plain = Distortion {
            k4: 0.0,
            k5: 0.0,
            k6: 0.0,
            ..camera.distortion
        };
        assert!((plain.apply(0.5, 0.3).0 - camera.distortion.apply(0.5, 0.3).0).abs() > 0.01);
    }

    #[test]
    fn invalid_models_are_rejected() {
        let mut camera = CameraModel::kinect_v2_color();
        camera.fx = 0.0;
        assert!(camera.validate().is_err());
        camera = CameraModel::kinect_v2_color();
        camera.cy = f64::NAN;
        assert!(camera.validate().is_err());
        assert!(CameraModel::new(0, 10, 1.0, 1.0, 0.0, 0.0, Distortion::default()).is_err());
    }

    #[test]
    fn scaling_keeps_the_pixel_centre_convention() {
        let camera = CameraModel::kinect_v2_color();
        let half = camera.scaled(0.5).expect("valid");
        assert_eq!((half.width, half.height), (960, 540));
        let point = Point3::new(0.3, -0.2, 2.0);
        let full = camera.project(&point).expect("front");
        let small = half.project(&point).expect("front");
        assert_relative_eq!((full.x + 0.5) * 0.5 - 0.5, small.x, epsilon = 1e-9);
        assert_relative_eq!((full.y + 0.5) * 0.5 - 0.5, small.y, epsilon = 1e-9);
    }

    #[test]
    fn pixel_at_rounds_to_the_nearest_centre() {
        let camera = CameraModel::kinect_v2_depth();
        assert_eq!(camera.pixel_at(&Point2::new(-0.49, 0.49)), Some((0, 0)));
        assert_eq!(camera.pixel_at(&Point2::new(0.5, 0.0)), Some((1, 0)));
        assert_eq!(camera.pixel_at(&Point2::new(-0.51, 0.0)), None);
        assert_eq!(
            camera.pixel_at(&Point2::new(511.49, 423.0)),
            Some((511, 423))
        );
        assert_eq!(camera.pixel_at(&Point2::new(511.5, 423.0)), None);
    }
}
