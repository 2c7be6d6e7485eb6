//! The projection image (paper section 4 and 5.2): a textured cloud splatted onto the image
//! plane of any camera with a z-buffer, giving an RGB image to track markers on and, for every
//! pixel, the cloud point it shows; and [`ProjectionImage::lift`], which turns a tracked
//! sub-pixel position back into a 3D point.

use image::RgbImage;
use nalgebra::{Isometry3, Point2, Point3};

use crate::calibration::Calibration;
use crate::camera::CameraModel;
use crate::cloud::TexturedCloud;
use crate::depth::DepthImage;
use crate::error::{KinectError, Result};
use crate::zbuffer;

/// Largest splat half-size in pixels that [`Splat::Auto`] uses (a 13x13 square): beyond that a
/// cloud is being viewed from far closer than it was captured, and holes are the honest answer.
pub const MAX_AUTO_SPLAT_RADIUS_PX: u32 = 6;

/// Extra footprint for [`Splat::Auto`]: lens distortion makes the spacing of depth rays vary
/// by up to about 10 % over a Kinect V2 image, so squares are sized for 15 % more than the
/// nominal footprint.
const SPLAT_MARGIN: f64 = 0.15;
/// Half-size slack of [`Splat::Auto`] in pixels, so that a footprint of exactly one pixel (a
/// cloud seen from its own camera) stays one pixel.
const SPLAT_SLACK_PX: f64 = 0.1;

/// How large a square each point covers on the projection image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Splat {
    /// The point's own footprint: a depth pixel at depth `z` is `z / f_depth` metres wide, so
    /// `s = f_target z / (f_depth z_target)` pixels on the target image; the square is the
    /// smallest odd size covering `1.15 s` (margin for lens distortion; capped at
    /// [`MAX_AUTO_SPLAT_RADIUS_PX`]). Leaves no holes inside surfaces when magnifying (for
    /// example onto the 1920x1080 colour plane) and one pixel per point when `s = 1`.
    #[default]
    Auto,
    /// A fixed half-size: 0 is one pixel per point, 1 a 3x3 square, ...
    Radius(u32),
}

/// Options of [`project_cloud`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProjectionConfig {
    /// Point footprint (default [`Splat::Auto`]).
    pub splat: Splat,
    /// Colour of pixels that show no point (default black).
    pub background_rgb: [u8; 3],
    /// Colour drawn for points that have depth but no colour (default black). They still take
    /// part in the z-buffer: they are real surfaces.
    pub uncolored_rgb: [u8; 3],
}

impl Default for ProjectionConfig {
    fn default() -> Self {
        Self {
            splat: Splat::Auto,
            background_rgb: [0, 0, 0],
            uncolored_rgb: [0, 0, 0],
        }
    }
}

/// Options of [`ProjectionImage::lift`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiftConfig {
    /// Neighbourhood radius in projection-image pixels (default 2: up to 13 pixels).
    pub radius_px: f64,
    /// Absolute depth tolerance in metres around the reference depth (default 0.02 m): points
    /// further from the reference are on another surface and do not vote.
    pub depth_tolerance_m: f64,
    /// Relative depth tolerance (default 0.01, i.e. 2 cm at 2 m); the larger of the two
    /// tolerances is used, so that sensor noise growing with depth does not split a surface.
    pub depth_tolerance_ratio: f64,
}

impl LiftConfig {
    /// The default lift for a projection image drawn on `plane` from a cloud of
    /// `depth_camera`: the radius grows with the plane's resolution over the depth camera's
    /// (the default 2 px on the depth camera's own plane), so that the lift gathers about
    /// the same depth pixels on any plane.
    pub fn for_plane(plane: &CameraModel, depth_camera: &CameraModel) -> Self {
        let ratio = plane.fx / depth_camera.fx;
        let base = Self::default();
        Self {
            radius_px: base.radius_px
                * if ratio.is_finite() {
                    ratio.max(1.0)
                } else {
                    1.0
                },
            ..base
        }
    }
}

impl Default for LiftConfig {
    fn default() -> Self {
        Self {
            radius_px: 2.0,
            depth_tolerance_m: 0.02,
            depth_tolerance_ratio: 0.01,
        }
    }
}

impl LiftConfig {
    /// Check the ranges.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] for a negative or non-finite radius or tolerance.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("lift radius_px", self.radius_px),
            ("lift depth_tolerance_m", self.depth_tolerance_m),
            ("lift depth_tolerance_ratio", self.depth_tolerance_ratio),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(KinectError::param(
                    name,
                    format!("{v} must be finite and >= 0"),
                ));
            }
        }
        Ok(())
    }
}

/// A textured cloud seen from a camera: the RGB image, and per pixel the index of the cloud
/// point it shows and that point's depth in the projection camera.
#[derive(Debug, Clone)]
pub struct ProjectionImage {
    camera: CameraModel,
    cloud_to_camera: Isometry3<f64>,
    image: RgbImage,
    /// Per pixel: `age (8 bits) | depth (24 bits, 0.1 mm) | point index (32 bits)`. A key of
    /// an earlier render has a larger age, so one unsigned `min` is the z-test and replaces
    /// stale keys alike, and the buffer (16 MB at 1920x1080) is never cleared.
    keys: Vec<u64>,
    age: u64,
}

const KEY_AGE_SHIFT: u32 = 32 + zbuffer::DEPTH_BITS;

impl ProjectionImage {
    #[inline]
    fn key(&self, z_m: f64, index: usize) -> u64 {
        (self.age << KEY_AGE_SHIFT) | (u64::from(zbuffer::quantise(z_m)) << 32) | index as u64
    }

    /// `(depth in metres, point index)` of a key of this render.
    #[inline]
    fn decode(&self, key: u64) -> Option<(f64, u32)> {
        (key >> KEY_AGE_SHIFT == self.age)
            .then(|| (zbuffer::dequantise((key >> 32) as u32), key as u32))
    }
}

/// Splat `cloud` onto `camera`, placed by `cloud_to_camera` (the transform from the cloud's
/// frame to the camera's frame; identity to view a camera-frame cloud from its own depth
/// camera).
///
/// # Errors
/// [`KinectError::InvalidParameter`] for an invalid camera or a cloud of more than 2³²
/// entries.
pub fn project_cloud(
    cloud: &TexturedCloud,
    camera: &CameraModel,
    cloud_to_camera: &Isometry3<f64>,
    config: &ProjectionConfig,
) -> Result<ProjectionImage> {
    camera.validate()?;
    let mut out = ProjectionImage {
        camera: *camera,
        cloud_to_camera: *cloud_to_camera,
        image: RgbImage::new(camera.width, camera.height),
        keys: Vec::new(),
        age: 0,
    };
    out.render(cloud, config)?;
    Ok(out)
}

/// A two-camera frame with its depth registered to the colour camera: the frame's cloud
/// (built with `calibration`) projected onto the colour camera, as a depth image on its
/// pixels in `unit_m` steps ([`ProjectionImage::depth_image`]), with the calibration of
/// such frames ([`Calibration::registered_to_color`]). This is what the Azure Kinect SDK's
/// `k4a_transformation_depth_image_to_color_camera` gives, and what tools that take depth
/// and colour on the same pixels need.
///
/// # Errors
/// [`KinectError::InvalidParameter`] for libfreenect2's polynomial model (not a rigid
/// transform), an invalid colour camera or unit; as [`project_cloud`].
pub fn register_to_color(
    cloud: &TexturedCloud,
    calibration: &Calibration,
    unit_m: f64,
) -> Result<(Calibration, DepthImage)> {
    let depth_to_color = calibration.depth_to_color()?.ok_or_else(|| {
        KinectError::param(
            "registration",
            "libfreenect2's model has no rigid depth-to-colour transform",
        )
    })?;
    let image = project_cloud(
        cloud,
        &calibration.color_camera,
        &depth_to_color,
        &ProjectionConfig::default(),
    )?;
    Ok((
        calibration.registered_to_color(unit_m),
        image.depth_image(unit_m)?,
    ))
}

impl ProjectionImage {
    /// Re-render for a new cloud with the same camera and placement, reusing every buffer.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] for a cloud of more than 2³² entries.
    pub fn update(&mut self, cloud: &TexturedCloud, config: &ProjectionConfig) -> Result<()> {
        self.render(cloud, config)
    }

    fn render(&mut self, cloud: &TexturedCloud, config: &ProjectionConfig) -> Result<()> {
        if u32::try_from(cloud.len()).is_err() {
            return Err(KinectError::param(
                "cloud",
                format!(
                    "{} entries; a projection image indexes at most 2^32",
                    cloud.len()
                ),
            ));
        }
        let cam = self.camera;
        let n = cam.pixel_count();
        if self.keys.len() != n || self.age == 0 {
            self.keys.clear();
            self.keys.resize(n, u64::MAX);
            self.age = (1 << (64 - KEY_AGE_SHIFT)) - 1;
        }
        self.age -= 1;
        let source = cloud.source_camera();
        let source_f = 0.5 * (source.fx + source.fy);
        let target_f = 0.5 * (cam.fx + cam.fy);
        // The cloud seen from its own camera (the paper's projection image on the capture's
        // image plane): every point lands on its own pixel, one pixel wide.
        // Checked on a sample of points, in case a hand-made cloud breaks that contract.
        let own_view = cam == *source
            && matches!(config.splat, Splat::Auto | Splat::Radius(0))
            && is_identity(&(self.cloud_to_camera * cloud.camera_to_cloud()))
            && sample_on_own_pixels(cloud, &self.cloud_to_camera, &cam);
        if own_view {
            // Seen from its own camera, a point's depth is the one the cloud stores.
            for (i, &z) in cloud.depths_m().iter().enumerate() {
                if z > 0.0 {
                    self.keys[i] = self.key(z, i);
                }
            }
        } else {
            self.splat(cloud, config, (source_f, target_f));
        }
        let age = self.age;
        for (px, &key) in self.image.pixels_mut().zip(self.keys.iter()) {
            px.0 = if key >> KEY_AGE_SHIFT != age {
                config.background_rgb
            } else {
                cloud
                    .color(key as u32 as usize)
                    .unwrap_or(config.uncolored_rgb)
            };
        }
        Ok(())
    }

    /// Splat every point of `cloud` into the keys (a view other than the cloud's own).
    fn splat(
        &mut self,
        cloud: &TexturedCloud,
        config: &ProjectionConfig,
        (source_f, target_f): (f64, f64),
    ) {
        let cam = self.camera;
        let (w, h) = (i64::from(cam.width), i64::from(cam.height));
        for (i, p) in cloud.iter_valid() {
            let pc = self.cloud_to_camera * p.position_m;
            let Some(px) = cam.project(&pc) else { continue };
            let radius = match config.splat {
                Splat::Radius(r) => i64::from(r),
                Splat::Auto => {
                    // The point's depth in the camera whose pixel it is.
                    let z_source = cloud.depths_m()[i];
                    let size = target_f * z_source / (source_f * pc.z);
                    let r = (size * (1.0 + SPLAT_MARGIN) - 1.0) * 0.5 - SPLAT_SLACK_PX;
                    ceil_non_negative(r).min(i64::from(MAX_AUTO_SPLAT_RADIUS_PX))
                }
            };
            // The nearest pixel centre, floor(x + 0.5); one off the image still splats onto it.
            let (fu, fv) = (px.x + 0.5, px.y + 0.5);
            let reach = radius as f64;
            if !(fu >= -reach
                && fv >= -reach
                && fu < (w + radius) as f64
                && fv < (h + radius) as f64)
            {
                continue;
            }
            let (cu, cv) = (floor_small(fu), floor_small(fv));
            let key = self.key(pc.z, i);
            let (x0, x1) = (
                (cu - radius).max(0) as usize,
                (cu + radius).min(w - 1) as usize,
            );
            for y in (cv - radius).max(0)..=(cv + radius).min(h - 1) {
                let row = (y * w) as usize;
                for cell in &mut self.keys[row + x0..=row + x1] {
                    *cell = (*cell).min(key);
                }
            }
        }
    }

    /// The camera of this image.
    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    /// The transform from the cloud's frame to the camera's frame.
    pub fn cloud_to_camera(&self) -> &Isometry3<f64> {
        &self.cloud_to_camera
    }

    /// The RGB image (for tracking; write it with `image`'s `save`).
    pub fn image(&self) -> &RgbImage {
        &self.image
    }

    /// Index into the cloud's points of the point shown at pixel `(u, v)`; `None` for
    /// background or outside the image.
    pub fn point_index(&self, u: u32, v: u32) -> Option<usize> {
        if u >= self.camera.width || v >= self.camera.height {
            return None;
        }
        let key = self.keys[v as usize * self.camera.width as usize + u as usize];
        self.decode(key).map(|(_, i)| i as usize)
    }

    /// Depth (metres, along the projection camera's axis, to 0.1 mm) of the point shown at
    /// `(u, v)`.
    pub fn depth_m(&self, u: u32, v: u32) -> Option<f64> {
        if u >= self.camera.width || v >= self.camera.height {
            return None;
        }
        let key = self.keys[v as usize * self.camera.width as usize + u as usize];
        self.decode(key).map(|(z, _)| z)
    }

    /// The depth this image shows, as a depth image on its camera's pixels: each pixel's
    /// depth in `unit_m` steps, rounded (0 where no point shows, and where the depth is
    /// beyond 65,535 steps). With a cloud projected onto its colour camera this is the depth
    /// registered to colour, as the Azure Kinect SDK's
    /// `k4a_transformation_depth_image_to_color_camera` gives it, for tools that take depth
    /// and colour on the same pixels (Open3D's `create_from_rgbd_image`).
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] for a unit that is not positive and finite.
    pub fn depth_image(&self, unit_m: f64) -> Result<DepthImage> {
        if !(unit_m.is_finite() && unit_m > 0.0) {
            return Err(KinectError::param(
                "depth unit",
                format!("{unit_m} m must be positive and finite"),
            ));
        }
        let (w, h) = (self.camera.width, self.camera.height);
        let values = (0..h)
            .flat_map(|v| (0..w).map(move |u| (u, v)))
            .map(|(u, v)| {
                self.depth_m(u, v).map_or(0, |z| {
                    let steps = (z / unit_m).round();
                    if steps <= f64::from(u16::MAX) {
                        steps as u16
                    } else {
                        0
                    }
                })
            })
            .collect();
        DepthImage::new(w, h, unit_m, values)
    }

    /// Number of pixels that show a point.
    pub fn covered_pixels(&self) -> usize {
        self.keys
            .iter()
            .filter(|&&k| k >> KEY_AGE_SHIFT == self.age)
            .count()
    }

    /// Lift a sub-pixel position of this image to a 3D point of `cloud` (the cloud this image
    /// was rendered from), in the cloud's frame.
    ///
    /// Robust by construction: it gathers the points shown within `radius_px` of `pixel`, takes
    /// the depth of the one nearest to `pixel` as the reference surface, drops points beyond
    /// the depth tolerance of that surface (no averaging across a depth edge: a marker in front
    /// of a trunk stays on the marker), takes the median depth of the distinct points left, and
    /// returns the point at that depth on this camera's ray through `pixel`. So the sub-pixel
    /// precision of a tracked centre is kept (the per-axis median of the points would snap to
    /// the depth-pixel grid, about 6 mm at 2 m for a Kinect V2), and one noisy or flying pixel
    /// does not move the result. `None` when no point is shown near `pixel`, when `pixel` is
    /// not finite, or when the image was rendered from a different cloud (index out of
    /// range).
    pub fn lift(
        &self,
        cloud: &TexturedCloud,
        pixel: &Point2<f64>,
        config: &LiftConfig,
    ) -> Option<Point3<f64>> {
        let mut scratch = Vec::new();
        self.lift_with(cloud, pixel, config, &mut scratch)
    }

    /// [`ProjectionImage::lift`] reusing a scratch buffer (no allocation once it has grown).
    pub fn lift_with(
        &self,
        cloud: &TexturedCloud,
        pixel: &Point2<f64>,
        config: &LiftConfig,
        scratch: &mut Vec<(f64, f64, u32)>,
    ) -> Option<Point3<f64>> {
        let finite = pixel.x.is_finite() && pixel.y.is_finite() && config.radius_px.is_finite();
        if !finite || config.radius_px < 0.0 {
            return None;
        }
        let r = config.radius_px;
        let (w, h) = (f64::from(self.camera.width), f64::from(self.camera.height));
        let x0 = (pixel.x - r).ceil().max(0.0);
        let x1 = (pixel.x + r).floor().min(w - 1.0);
        let y0 = (pixel.y - r).ceil().max(0.0);
        let y1 = (pixel.y + r).floor().min(h - 1.0);
        scratch.clear();
        let mut y = y0;
        while y <= y1 {
            let mut x = x0;
            while x <= x1 {
                let d2 = (x - pixel.x).powi(2) + (y - pixel.y).powi(2);
                if d2 <= r * r {
                    let key = self.keys[y as usize * self.camera.width as usize + x as usize];
                    if let Some((z, i)) = self.decode(key) {
                        scratch.push((d2, z, i));
                    }
                }
                x += 1.0;
            }
            y += 1.0;
        }
        if scratch.is_empty() {
            // No pixel centre within the radius shows a point (or the radius is below the
            // distance to any centre): the point of the pixel holding the position, if any.
            let (u, v) = self.camera.pixel_at(pixel)?;
            let i = self.point_index(u, v)?;
            return cloud.position_m(i);
        }
        let reference = scratch
            .iter()
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)))
            .map(|c| c.1)?;
        let tolerance = config
            .depth_tolerance_m
            .max(config.depth_tolerance_ratio * reference);
        scratch.retain(|c| (c.1 - reference).abs() <= tolerance);
        scratch.sort_unstable_by_key(|c| c.2);
        scratch.dedup_by_key(|c| c.2);
        // Median depth (along this camera's axis) of the distinct points on the surface.
        let mut depths = Vec::with_capacity(scratch.len());
        let mut points = Vec::with_capacity(scratch.len());
        for c in scratch.iter() {
            let p = cloud.position_m(c.2 as usize)?;
            depths.push((self.cloud_to_camera * p).z);
            points.push(p);
        }
        let z = median(&mut depths)?;
        match self.camera.unproject(pixel, z) {
            // The point on the ray through the sub-pixel position at that depth: sub-pixel
            // tracking keeps its precision instead of snapping to the depth-pixel grid.
            Some(on_ray) => Some(self.cloud_to_camera.inverse() * on_ray),
            // Distortion not invertible there: the per-axis median of the points.
            None => {
                let axis = |k: usize| median(&mut points.iter().map(|p| p[k]).collect::<Vec<_>>());
                Some(Point3::new(axis(0)?, axis(1)?, axis(2)?))
            }
        }
    }
}

/// True when a sample of up to 64 valid points projects onto its own pixel.
fn sample_on_own_pixels(
    cloud: &TexturedCloud,
    cloud_to_camera: &Isometry3<f64>,
    cam: &CameraModel,
) -> bool {
    let n = cloud.len();
    let step = (n / 64).max(1);
    let w = cam.width as usize;
    (0..n).step_by(step).all(|i| match cloud.position_m(i) {
        None => true,
        Some(p) => cam
            .project(&(cloud_to_camera * p))
            .and_then(|px| cam.pixel_at(&px))
            .is_some_and(|(u, v)| v as usize * w + u as usize == i),
    })
}

/// True when `iso` is the identity up to rounding (1e-12 in rotation and metres).
fn is_identity(iso: &Isometry3<f64>) -> bool {
    iso.translation.vector.norm() < 1e-12 && iso.rotation.angle() < 1e-12
}

/// `floor(x)` for |x| well inside the `i64` range, without a libm call.
#[inline]
fn floor_small(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x { t - 1 } else { t }
}

/// `ceil(x)` for the splat radius, 0 for negative or NaN input (no libm call on the hot path).
#[inline]
fn ceil_non_negative(x: f64) -> i64 {
    if x.is_nan() || x <= 0.0 {
        return 0;
    }
    let t = x.min(1e9) as i64;
    if (t as f64) < x { t + 1 } else { t }
}

/// Median of a non-empty slice (mean of the two middle values for an even count).
fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_unstable_by(f64::total_cmp);
    let n = values.len();
    Some(if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::{Calibration, RegistrationModel};
    use crate::cloud::{CloudBuilder, CloudConfig};
    use crate::depth::DepthImage;
    use approx::assert_relative_eq;

    /// The scene's cloud seen from its own depth camera.
    fn own_view(cloud: &TexturedCloud, calibration: &Calibration) -> ProjectionImage {
        project_cloud(
            cloud,
            &calibration.depth_camera,
            &Isometry3::identity(),
            &ProjectionConfig::default(),
        )
        .expect("valid")
    }

    /// A wall at 2 m with a 40x40 px square patch at 1 m.
    fn scene() -> (TexturedCloud, Calibration) {
        let calibration = Calibration::kinect_v2();
        let d = calibration.depth_camera;
        let mut values = vec![2000u16; d.pixel_count()];
        for v in 180..220 {
            for u in 230..270 {
                values[v * 512 + u] = 1000;
            }
        }
        (cloud_of(values, &calibration), calibration)
    }

    /// The cloud of millimetre depth `values` with a uniformly red colour image.
    fn cloud_of(values: Vec<u16>, calibration: &Calibration) -> TexturedCloud {
        let d = calibration.depth_camera;
        let depth = DepthImage::new(d.width, d.height, 0.001, values).expect("size");
        let color = RgbImage::from_pixel(1920, 1080, image::Rgb([200, 10, 10]));
        CloudBuilder::new(calibration, CloudConfig::default())
            .expect("ok")
            .build(&depth, &color)
            .expect("ok")
    }

    #[test]
    fn registering_to_colour_gives_depth_on_the_colour_pixels() {
        let (cloud, calibration) = scene();
        let (registered, depth) = register_to_color(&cloud, &calibration, 0.001).expect("ok");
        let c = calibration.color_camera;
        assert_eq!(registered.depth_camera, c);
        assert_eq!(
            registered.registration,
            RegistrationModel::AlreadyRegistered
        );
        assert_eq!((depth.width(), depth.height()), (c.width, c.height));
        // Every point the colour camera sees is on its pixel at its colour-camera depth
        // (the nearer surface where two land on one pixel).
        let t = calibration.depth_to_color().expect("ok").expect("rigid");
        let (mut checked, mut near) = (0, 0);
        for (_, p) in cloud.iter_valid() {
            let q = t * p.position_m;
            let Some((u, v)) = c.project(&q).and_then(|px| c.pixel_at(&px)) else {
                continue;
            };
            let shown = f64::from(depth.values()[(v * c.width + u) as usize]) * 1e-3;
            assert!(
                shown > 0.0 && shown <= q.z + 0.002,
                "{u},{v}: {shown} vs {}",
                q.z
            );
            checked += 1;
            near += usize::from((shown - q.z).abs() < 0.002);
        }
        assert!(
            checked > 100_000 && near * 10 > checked * 9,
            "{near} of {checked}"
        );
        let ir = crate::freenect2::Freenect2IrParams::kinect_v2_typical();
        let colour = crate::freenect2::Freenect2ColorParams::from_pinhole_baseline(
            &ir, 1081.37, 959.5, 539.5, 52.0,
        );
        let mut freenect2 = calibration.clone();
        freenect2.registration = Calibration::freenect2(ir, colour).registration;
        assert!(register_to_color(&cloud, &freenect2, 0.001).is_err());
        assert!(own_view(&cloud, &calibration).depth_image(0.0).is_err());
    }

    #[test]
    fn projecting_onto_the_depth_camera_reproduces_the_grid() {
        let (cloud, calibration) = scene();
        let image = project_cloud(
            &cloud,
            &calibration.depth_camera,
            &Isometry3::identity(),
            &ProjectionConfig {
                splat: Splat::Radius(0),
                ..ProjectionConfig::default()
            },
        )
        .expect("valid camera");
        assert_eq!(image.point_index(100, 50), Some(50 * 512 + 100));
        assert_eq!(image.covered_pixels(), 512 * 424);
    }

    #[test]
    fn an_update_leaves_nothing_of_the_previous_render() {
        let (cloud, calibration) = scene();
        let d = calibration.depth_camera;
        // The same scene with the left half of the depth missing.
        let mut values = vec![2000u16; d.pixel_count()];
        for v in 0..d.height as usize {
            values[v * 512..v * 512 + 256].fill(0);
        }
        let half = cloud_of(values, &calibration);
        let t = calibration.depth_to_color().expect("ok").expect("rigid");
        for (camera, pose) in [
            (calibration.depth_camera, Isometry3::identity()),
            (calibration.color_camera.scaled(0.5).expect("ok"), t),
        ] {
            let config = ProjectionConfig::default();
            let mut image = project_cloud(&cloud, &camera, &pose, &config).expect("valid");
            image.update(&half, &config).expect("ok");
            let fresh = project_cloud(&half, &camera, &pose, &config).expect("valid");
            assert_eq!(image.covered_pixels(), fresh.covered_pixels());
            assert_eq!(image.image(), fresh.image());
            for v in (0..camera.height).step_by(7) {
                for u in (0..camera.width).step_by(5) {
                    assert_eq!(image.point_index(u, v), fresh.point_index(u, v));
                    assert_eq!(image.depth_m(u, v), fresh.depth_m(u, v));
                }
            }
        }
    }

    #[test]
    fn own_view_fast_path_equals_the_general_path() {
        let (cloud, calibration) = scene();
        let fast = own_view(&cloud, &calibration);
        // A camera equal in all but a negligible principal-point shift takes the general path.
        let mut nudged = calibration.depth_camera;
        nudged.cx += 1e-9;
        let general = project_cloud(
            &cloud,
            &nudged,
            &Isometry3::identity(),
            &ProjectionConfig::default(),
        )
        .expect("valid");
        assert_eq!(fast.image(), general.image());
        for v in 0..424 {
            for u in 0..512 {
                assert_eq!(fast.point_index(u, v), general.point_index(u, v), "{u},{v}");
            }
        }
    }

    #[test]
    fn auto_splat_fills_a_magnified_view() {
        let (cloud, calibration) = scene();
        let t = calibration.depth_to_color().expect("ok").expect("rigid");
        let image = project_cloud(
            &cloud,
            &calibration.color_camera,
            &t,
            &ProjectionConfig::default(),
        )
        .expect("valid");
        let sparse = project_cloud(
            &cloud,
            &calibration.color_camera,
            &t,
            &ProjectionConfig {
                splat: Splat::Radius(0),
                ..ProjectionConfig::default()
            },
        )
        .expect("valid");
        // A region of the wall (away from the patch and its shadow) is fully covered with auto
        // splats only.
        let covered = |img: &ProjectionImage| {
            (200..300)
                .flat_map(|v| (300..400).map(move |u| (u, v)))
                .filter(|&(u, v)| img.point_index(u, v).is_some())
                .count()
        };
        assert_eq!(covered(&image), 100 * 100);
        assert!(covered(&sparse) < 100 * 100 / 4);
    }

    #[test]
    fn lift_stays_on_the_near_surface_at_an_edge() {
        let (cloud, calibration) = scene();
        let image = own_view(&cloud, &calibration);
        // On the patch's edge column: half the neighbourhood is wall at 2 m.
        let p = image
            .lift(&cloud, &Point2::new(230.2, 200.0), &LiftConfig::default())
            .expect("near points");
        assert_relative_eq!(p.z, 1.0, epsilon = 1e-9);
        // On the ray through the sub-pixel position.
        let back = calibration.depth_camera.project(&p).expect("front");
        assert_relative_eq!(back, Point2::new(230.2, 200.0), epsilon = 1e-6);
        let q = image
            .lift(&cloud, &Point2::new(229.4, 200.0), &LiftConfig::default())
            .expect("near points");
        assert_relative_eq!(q.z, 2.0, epsilon = 1e-9);
        // Off the image or not finite: nothing.
        assert!(
            image
                .lift(&cloud, &Point2::new(-10.0, 5.0), &LiftConfig::default())
                .is_none()
        );
        assert!(
            image
                .lift(&cloud, &Point2::new(f64::NAN, 5.0), &LiftConfig::default())
                .is_none()
        );
    }

    #[test]
    fn lift_of_a_pixel_centre_returns_that_point_on_a_plane() {
        let (cloud, calibration) = scene();
        let image = own_view(&cloud, &calibration);
        let p = image
            .lift(&cloud, &Point2::new(100.0, 300.0), &LiftConfig::default())
            .expect("wall");
        let truth = cloud.get(100, 300).expect("valid").position_m;
        // On a wall of one depth, the lifted point is exactly the point of that pixel.
        assert_relative_eq!(p, truth, epsilon = 1e-9);
    }
}
