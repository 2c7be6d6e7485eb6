//! What one depth camera sees of a cloud: the points on the surfaces facing it, with depth
//! noise along the view ray. Turns a full scan into the paper's situation (one Kinect, the
//! far half of every branch missing) so a reconstruction can be judged against the full
//! cloud it came from.
//!
//! Visibility is a z-buffer in angles around the camera: each point covers a disc of
//! [`ViewConfig::splat_m`] (about the cloud's point spacing) and hides the points more than
//! [`ViewConfig::occlusion_margin_m`] behind it in the pixels it covers.

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};
use rand_xoshiro::SplitMix64;
use rand_xoshiro::rand_core::{RngCore, SeedableRng};

use crate::error::{ColonizeError, Result};

/// Kinect v2 depth camera: 512 pixels across 70.6° (Microsoft's specification), radians
/// per pixel.
pub const KINECT_V2_PIXEL_RAD: f64 = 70.6 / 512.0 * std::f64::consts::PI / 180.0;
/// Kinect v2 depth noise near 3 m, metres (the 5–8 mm, from the paper's setting).
pub const KINECT_DEPTH_NOISE_M: f64 = 0.006;
/// Largest splat radius in pixels: at most 29 pixels per point, which bounds the z-buffer's
/// memory and work (a point nearer than `splat_m / (3 pixel_rad)`, 1.4 m for a Kinect and
/// 1 cm splats, hides a little less than its disc).
const MAX_SPLAT_PIXELS: i64 = 3;
/// Finest pixel accepted, radians (a thousandth of a Kinect's): finer grids only make the
/// z-buffer larger.
pub const MIN_PIXEL_RAD: f64 = 2e-6;

/// A camera for [`camera_view`].
#[derive(Debug, Clone, PartialEq)]
pub struct ViewConfig {
    /// Camera position, metres, in the cloud's frame.
    pub camera_m: Point3<f64>,
    /// Angular size of a pixel, radians. Default [`KINECT_V2_PIXEL_RAD`].
    pub pixel_rad: f64,
    /// Standard deviation of the noise added along each view ray, metres. Default
    /// [`KINECT_DEPTH_NOISE_M`].
    pub depth_noise_m: f64,
    /// Radius of the surface disc each point stands for, metres (about the point
    /// spacing). Default 1 cm.
    pub splat_m: f64,
    /// A point this far behind the nearest surface in its pixel is still seen, metres
    /// (a surface seen at a grazing angle falls away by about a splat within a pixel).
    /// Default 2 cm.
    pub occlusion_margin_m: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl ViewConfig {
    /// A Kinect v2 at `camera_m`.
    pub fn kinect(camera_m: Point3<f64>) -> Self {
        Self {
            camera_m,
            pixel_rad: KINECT_V2_PIXEL_RAD,
            depth_noise_m: KINECT_DEPTH_NOISE_M,
            splat_m: 0.01,
            occlusion_margin_m: 0.02,
            seed: 1,
        }
    }

    fn validate(&self) -> Result<()> {
        if !self.camera_m.iter().all(|c| c.is_finite()) {
            return Err(ColonizeError::param(
                "camera_m",
                format!("{:?} is not finite", self.camera_m),
            ));
        }
        if self.pixel_rad < MIN_PIXEL_RAD {
            return Err(ColonizeError::param(
                "pixel_rad",
                format!("{}; must be at least {MIN_PIXEL_RAD}", self.pixel_rad),
            ));
        }
        for (name, v, zero_ok) in [
            ("pixel_rad", self.pixel_rad, false),
            ("depth_noise_m", self.depth_noise_m, true),
            ("splat_m", self.splat_m, true),
            ("occlusion_margin_m", self.occlusion_margin_m, true),
        ] {
            if !(v.is_finite() && (v > 0.0 || (zero_ok && v == 0.0))) {
                return Err(ColonizeError::param(
                    name,
                    format!(
                        "{v}; must be {} and finite",
                        if zero_ok {
                            "zero or positive"
                        } else {
                            "positive"
                        }
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// Pixel of a direction: azimuth and elevation in units of `pixel_rad`.
pub(crate) fn pixel(d: &Vector3<f64>, pixel_rad: f64) -> (i64, i64) {
    let az = d.y.atan2(d.x);
    let el = d.z.atan2(d.x.hypot(d.y));
    (
        (az / pixel_rad).floor() as i64,
        (el / pixel_rad).floor() as i64,
    )
}

/// The z-buffer of `rays` (direction from the camera and range): per pixel of `pixel_rad`,
/// the range of the nearest point, each point a disc of `splat_m` (at most
/// [`MAX_SPLAT_PIXELS`] pixels in radius). Rays of zero range are skipped.
pub(crate) fn splat_nearest(
    rays: &[(Vector3<f64>, f64)],
    pixel_rad: f64,
    splat_m: f64,
) -> HashMap<(i64, i64), f64> {
    let mut nearest: HashMap<(i64, i64), f64> = HashMap::new();
    for (d, r) in rays.iter().filter(|(_, r)| *r > 0.0) {
        let (u, v) = pixel(d, pixel_rad);
        let k = ((splat_m / (r * pixel_rad)).round() as i64).min(MAX_SPLAT_PIXELS);
        for du in -k..=k {
            for dv in -k..=k {
                if du * du + dv * dv <= k * k {
                    let e = nearest.entry((u + du, v + dv)).or_insert(f64::INFINITY);
                    *e = e.min(*r);
                }
            }
        }
    }
    nearest
}

/// The points a camera sees (see the module docs), each moved along its view ray by
/// Gaussian noise. Points at the camera position are not seen.
///
/// # Errors
/// [`ColonizeError::InvalidParameter`] naming a bad field; [`ColonizeError::NonFinitePoint`]
/// for a point that is not finite.
pub fn camera_view(points: &[Point3<f64>], config: &ViewConfig) -> Result<Vec<Point3<f64>>> {
    config.validate()?;
    crate::cloud::all_finite(points)?;
    let rays: Vec<(Vector3<f64>, f64)> = points
        .iter()
        .map(|p| {
            let d = p - config.camera_m;
            let r = d.norm();
            (d, r)
        })
        .collect();
    let nearest = splat_nearest(&rays, config.pixel_rad, config.splat_m);
    let mut rng = SplitMix64::seed_from_u64(config.seed);
    let mut normal = || {
        let u1 = ((rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64).max(1e-300);
        let u2 = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    Ok(points
        .iter()
        .zip(&rays)
        .filter(|(_, (d, r))| {
            *r > 0.0
                && nearest
                    .get(&pixel(d, config.pixel_rad))
                    .is_some_and(|&front| *r <= front + config.occlusion_margin_m)
        })
        .map(|(p, (d, r))| p + d / *r * (config.depth_noise_m * normal()))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ring of points around the z axis seen from +x: the near half is seen, the far
    /// half hidden, and the noise moves points along the ray only.
    #[test]
    fn a_camera_sees_the_near_half_of_a_branch() {
        let ring: Vec<Point3<f64>> = (0..720)
            .map(|i| {
                let a = f64::from(i) / 720.0 * std::f64::consts::TAU;
                let z = f64::from(i % 10) * 0.003;
                Point3::new(0.05 * a.cos(), 0.05 * a.sin(), z)
            })
            .collect();
        let mut c = ViewConfig::kinect(Point3::new(3.0, 0.0, 0.015));
        c.depth_noise_m = 0.0;
        let seen = camera_view(&ring, &c).unwrap_or_else(|e| panic!("{e}"));
        // Near the silhouette the far side is within the occlusion margin of the near side.
        let far = seen.iter().filter(|p| p.x < -0.02).count();
        assert_eq!(far, 0, "{far} far-side points seen");
        // At most the near half (360) and a little of the silhouette; at grazing angles the
        // surface falls away by more than the margin within a pixel and is lost, as on a
        // real sensor.
        assert!(seen.len() > 150 && seen.len() < 400, "{}", seen.len());
        c.depth_noise_m = 0.006;
        let noisy = camera_view(&ring, &c).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(noisy.len(), seen.len());
        for (a, b) in seen.iter().zip(&noisy) {
            // Along the ray from the camera: the cross product with the ray is ~0.
            let ray = (a - c.camera_m).normalize();
            assert!((b - a).cross(&ray).norm() < 1e-9);
        }
    }

    #[test]
    fn bad_cameras_are_named() {
        let p = [Point3::new(0.0, 0.0, 0.0)];
        let mut c = ViewConfig::kinect(Point3::new(f64::NAN, 0.0, 0.0));
        assert!(camera_view(&p, &c).is_err_and(|e| e.to_string().contains("camera_m")));
        c.camera_m = Point3::new(1.0, 0.0, 0.0);
        c.pixel_rad = 0.0;
        assert!(camera_view(&p, &c).is_err_and(|e| e.to_string().contains("pixel_rad")));
    }
}
