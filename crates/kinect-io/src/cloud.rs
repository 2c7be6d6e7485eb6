//! Organized textured point clouds: one point per depth pixel, with its colour.
//!
//! Depth is converted from raw sensor units to metres here, at this boundary, and nowhere
//! else. A pixel without valid depth is `None`; a point that the colour camera does not see
//! (outside its image, or occluded by a nearer surface) has `rgb: None`.

use image::RgbImage;
use nalgebra::{Isometry3, Matrix3, Point3, Vector3};

use crate::calibration::{Calibration, RegistrationModel};
use crate::camera::CameraModel;
use crate::depth::DepthImage;
use crate::error::{KinectError, Result};
use crate::freenect2::{
    FREENECT2_FILTER_HALF_HEIGHT_PX, FREENECT2_FILTER_HALF_WIDTH_PX, FREENECT2_FILTER_TOLERANCE,
    Freenect2Frame, Freenect2Registration,
};
use crate::occlusion::MinDepthMap;
use crate::zbuffer;

/// One point of a textured cloud.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TexturedPoint {
    /// Position in metres, in the cloud's frame.
    pub position_m: Point3<f64>,
    /// Colour, or `None` when the colour camera does not see the point.
    pub rgb: Option<[u8; 3]>,
}

/// An organized textured point cloud: `width * height` entries, row-major, one per depth pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct TexturedCloud {
    width: u32,
    height: u32,
    points: Vec<Option<TexturedPoint>>,
    source_camera: CameraModel,
    camera_to_cloud: Isometry3<f64>,
}

impl TexturedCloud {
    /// An organized cloud from its points (`width * height`, row-major), the camera whose
    /// pixels they are, and the transform from that camera's frame to the cloud's frame
    /// (identity when the points are in the camera frame).
    ///
    /// # Errors
    /// [`KinectError::SizeMismatch`] when the point count or camera size does not match.
    pub fn new(
        width: u32,
        height: u32,
        points: Vec<Option<TexturedPoint>>,
        source_camera: CameraModel,
        camera_to_cloud: Isometry3<f64>,
    ) -> Result<Self> {
        if points.len() != width as usize * height as usize
            || (source_camera.width, source_camera.height) != (width, height)
        {
            return Err(KinectError::SizeMismatch {
                what: "organized cloud points vs. source camera".into(),
                expected_width: source_camera.width,
                expected_height: source_camera.height,
                found_width: width,
                found_height: (points.len() / width.max(1) as usize) as u32,
            });
        }
        Ok(Self {
            width,
            height,
            points,
            source_camera,
            camera_to_cloud,
        })
    }

    /// Width (depth pixels).
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height (depth pixels).
    pub fn height(&self) -> u32 {
        self.height
    }

    /// All entries, row-major.
    pub fn points(&self) -> &[Option<TexturedPoint>] {
        &self.points
    }

    /// The entry of depth pixel `(u, v)`; `None` outside the grid or where there is no depth.
    pub fn get(&self, u: u32, v: u32) -> Option<&TexturedPoint> {
        if u < self.width && v < self.height {
            self.points[v as usize * self.width as usize + u as usize].as_ref()
        } else {
            None
        }
    }

    /// The camera whose pixels the entries are (the depth camera).
    pub fn source_camera(&self) -> &CameraModel {
        &self.source_camera
    }

    /// The transform from the source camera's frame to the cloud's frame.
    pub fn camera_to_cloud(&self) -> &Isometry3<f64> {
        &self.camera_to_cloud
    }

    /// Number of points with depth.
    pub fn valid_count(&self) -> usize {
        self.points.iter().filter(|p| p.is_some()).count()
    }

    /// The points with depth, with their flat index.
    pub fn iter_valid(&self) -> impl Iterator<Item = (usize, &TexturedPoint)> {
        self.points
            .iter()
            .enumerate()
            .filter_map(|(i, p)| p.as_ref().map(|p| (i, p)))
    }

    /// Axis-aligned bounding box `(min, max)` of the valid points; `None` when there are none.
    pub fn bounding_box(&self) -> Option<(Point3<f64>, Point3<f64>)> {
        let mut it = self.iter_valid();
        let first = it.next()?.1.position_m;
        let (mut lo, mut hi) = (first, first);
        for (_, p) in it {
            lo = lo.inf(&p.position_m);
            hi = hi.sup(&p.position_m);
        }
        Some((lo, hi))
    }

    /// The same cloud with every point moved by `transform` (for example
    /// [`crate::camera_to_world_z_up`] to go to a Z-up world frame).
    pub fn transformed(&self, transform: &Isometry3<f64>) -> Self {
        let mut out = self.clone();
        for p in out.points.iter_mut().flatten() {
            p.position_m = transform * p.position_m;
        }
        out.camera_to_cloud = transform * self.camera_to_cloud;
        out
    }
}

/// The occlusion filter of depth-to-colour registration: a depth pixel gets no colour when the
/// colour camera sees a nearer surface at (or next to) its colour pixel. Defaults are
/// libfreenect2's (5x3 colour pixels, 1 % depth tolerance).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OcclusionFilter {
    /// Half-width of the window in colour pixels (default 2).
    pub half_width_px: u32,
    /// Half-height of the window in colour pixels (default 1).
    pub half_height_px: u32,
    /// Relative depth margin: a point at depth `z` is occluded when the nearest depth `z_min`
    /// in its window has `(z - z_min) / z > tolerance` (libfreenect2's test; default 0.01).
    pub tolerance: f64,
}

impl Default for OcclusionFilter {
    fn default() -> Self {
        Self {
            half_width_px: FREENECT2_FILTER_HALF_WIDTH_PX as u32,
            half_height_px: FREENECT2_FILTER_HALF_HEIGHT_PX as u32,
            tolerance: f64::from(FREENECT2_FILTER_TOLERANCE),
        }
    }
}

/// Options of [`CloudBuilder`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CloudConfig {
    /// Occlusion filter for the colours; `None` to colour every point from wherever it
    /// projects. Default: libfreenect2's filter. (libfreenect2's own filter is always used
    /// with the libfreenect2 model when this is `Some`.)
    pub occlusion_filter: Option<OcclusionFilter>,
    /// Depths below this are dropped (metres, default 0: keep everything the sensor reports).
    pub min_depth_m: f64,
    /// Depths above this are dropped (metres, default infinity). Handy to cut away a wall
    /// behind the tree.
    pub max_depth_m: f64,
    /// Transform applied to every point, from the depth camera frame to the cloud's frame
    /// (default `None`: the depth camera frame). See [`crate::camera_to_world_z_up`].
    pub camera_to_world: Option<Isometry3<f64>>,
}

impl Default for CloudConfig {
    fn default() -> Self {
        Self {
            occlusion_filter: Some(OcclusionFilter::default()),
            min_depth_m: 0.0,
            max_depth_m: f64::INFINITY,
            camera_to_world: None,
        }
    }
}

impl CloudConfig {
    /// Check the ranges.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] for a negative or NaN depth range, an empty range,
    /// or a negative or NaN filter tolerance.
    pub fn validate(&self) -> Result<()> {
        if !(self.min_depth_m >= 0.0 && self.max_depth_m > self.min_depth_m) {
            return Err(KinectError::param(
                "depth range",
                format!(
                    "min {} m .. max {} m is empty or negative",
                    self.min_depth_m, self.max_depth_m
                ),
            ));
        }
        if let Some(f) = &self.occlusion_filter
            && !(f.tolerance >= 0.0 && f.tolerance.is_finite())
        {
            return Err(KinectError::param(
                "occlusion filter tolerance",
                format!("{} must be finite and non-negative", f.tolerance),
            ));
        }
        Ok(())
    }
}

enum Engine {
    /// Rigid or already registered: per-pixel undistorted rays and the transform.
    Rays {
        /// Undistorted normalised ray per depth pixel; NaN where the distortion cannot be
        /// inverted.
        rays: Vec<[f64; 2]>,
        /// Depth-to-colour rotation matrix and translation (`None`: already registered).
        depth_to_color: Option<(Matrix3<f64>, Vector3<f64>)>,
    },
    Freenect2 {
        registration: Box<Freenect2Registration>,
        frame: Freenect2Frame,
        depth_mm: Vec<f32>,
    },
}

/// Builds organized textured clouds from depth + colour frames of one calibrated camera.
///
/// All per-camera work (undistortion tables, libfreenect2 maps) is done once in
/// [`CloudBuilder::new`]; [`CloudBuilder::build_into`] then allocates nothing.
pub struct CloudBuilder {
    calibration: Calibration,
    config: CloudConfig,
    engine: Engine,
    /// Nearest depth per colour pixel (occlusion filter), reused between frames.
    filter_map: MinDepthMap,
    /// The points that project onto the colour image, reused between frames.
    candidates: Vec<Candidate>,
    /// Positions in `candidates` that the occlusion test's block level could not clear.
    contested: Vec<u32>,
}

/// A point that projects onto the colour image: its depth pixel (flat index), its colour
/// pixel, and its quantised depth in the colour camera (for the occlusion filter).
#[derive(Debug, Clone, Copy)]
struct Candidate {
    index: u32,
    color_u: u32,
    color_v: u32,
    depth_q: u32,
}

impl CloudBuilder {
    /// Prepare for one calibration.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] when the calibration or the config is invalid.
    pub fn new(calibration: &Calibration, config: CloudConfig) -> Result<Self> {
        calibration.validate()?;
        config.validate()?;
        let engine = match &calibration.registration {
            RegistrationModel::Freenect2 { ir, color } => {
                let registration = Freenect2Registration::new(*ir, *color)?;
                let n = calibration.depth_camera.pixel_count();
                Engine::Freenect2 {
                    registration: Box::new(registration),
                    frame: Freenect2Frame {
                        undistorted_mm: vec![0.0; n],
                        registered: vec![None; n],
                    },
                    depth_mm: vec![0.0; n],
                }
            }
            RegistrationModel::Rigid(_) | RegistrationModel::AlreadyRegistered => Engine::Rays {
                rays: calibration
                    .depth_camera
                    .ray_table()
                    .into_iter()
                    .map(|r| r.map_or([f64::NAN; 2], |r| [r.x, r.y]))
                    .collect(),
                depth_to_color: match calibration.registration {
                    RegistrationModel::AlreadyRegistered => None,
                    _ => calibration.depth_to_color()?.map(|t| {
                        (
                            t.rotation.to_rotation_matrix().into_inner(),
                            t.translation.vector,
                        )
                    }),
                },
            },
        };
        Ok(Self {
            calibration: calibration.clone(),
            config,
            engine,
            filter_map: MinDepthMap::default(),
            candidates: Vec::with_capacity(calibration.depth_camera.pixel_count()),
            contested: Vec::new(),
        })
    }

    /// The calibration this builder uses.
    pub fn calibration(&self) -> &Calibration {
        &self.calibration
    }

    /// Build the cloud of one frame.
    ///
    /// # Errors
    /// [`KinectError::SizeMismatch`] when the depth or colour image does not have its camera's
    /// size; [`KinectError::NoValidDepth`] when no pixel has a valid depth.
    pub fn build(&mut self, depth: &DepthImage, color: &RgbImage) -> Result<TexturedCloud> {
        let camera = self.calibration.depth_camera;
        let mut cloud = TexturedCloud {
            width: camera.width,
            height: camera.height,
            points: vec![None; camera.pixel_count()],
            source_camera: camera,
            camera_to_cloud: Isometry3::identity(),
        };
        self.build_into(depth, color, &mut cloud)?;
        Ok(cloud)
    }

    /// [`CloudBuilder::build`] into an existing cloud (reusing its storage).
    ///
    /// # Errors
    /// As [`CloudBuilder::build`].
    #[allow(clippy::too_many_lines)] // longer than 100 lines; to be split by concept (issue 21)
    pub fn build_into(
        &mut self,
        depth: &DepthImage,
        color: &RgbImage,
        cloud: &mut TexturedCloud,
    ) -> Result<()> {
        let dcam = self.calibration.depth_camera;
        let ccam = self.calibration.color_camera;
        dcam.check_image_size(
            "depth image vs. its calibrated camera",
            depth.width(),
            depth.height(),
        )?;
        ccam.check_image_size(
            "colour image vs. its calibrated camera",
            color.width(),
            color.height(),
        )?;
        cloud.width = dcam.width;
        cloud.height = dcam.height;
        cloud.source_camera = match self.engine {
            // libfreenect2's points lie on its undistorted grid: a pinhole image.
            Engine::Freenect2 { .. } => CameraModel {
                distortion: crate::camera::Distortion::default(),
                ..dcam
            },
            Engine::Rays { .. } => dcam,
        };
        cloud.camera_to_cloud = self
            .config
            .camera_to_world
            .unwrap_or_else(Isometry3::identity);
        if cloud.points.len() != dcam.pixel_count() {
            cloud.points.clear();
            cloud.points.resize(dcam.pixel_count(), None);
        }
        let unit_m = depth.unit_m();
        let offset_m = self.calibration.depth_offset_m;
        let (min_z, max_z) = (self.config.min_depth_m, self.config.max_depth_m);
        let mut valid = 0usize;
        match &mut self.engine {
            Engine::Rays {
                rays,
                depth_to_color,
            } => {
                let filter = self.config.occlusion_filter;
                let (filter_half, filter_tolerance) = filter.map_or(((0, 0), 0.0), |f| {
                    (
                        (f.half_width_px as usize, f.half_height_px as usize),
                        f.tolerance,
                    )
                });
                if filter.is_some() {
                    self.filter_map
                        .begin_frame(ccam.width as usize, ccam.height as usize);
                }
                let cw = ccam.width as i64;
                let ch = ccam.height as i64;
                let w = dcam.width as usize;
                self.candidates.clear();
                for (i, ((&raw, ray), slot)) in depth
                    .values()
                    .iter()
                    .zip(rays.iter())
                    .zip(cloud.points.iter_mut())
                    .enumerate()
                {
                    *slot = None;
                    let [rx, ry] = *ray;
                    if raw == 0 || rx.is_nan() {
                        continue;
                    }
                    let z = f64::from(raw) * unit_m + offset_m;
                    if !(z > min_z && z <= max_z) {
                        continue;
                    }
                    let p = Point3::new(rx * z, ry * z, z);
                    valid += 1;
                    *slot = Some(TexturedPoint {
                        position_m: p,
                        rgb: None,
                    });
                    // Colour pixel of this point.
                    let (cu, cv, zc) = match depth_to_color {
                        None => ((i % w) as i64, (i / w) as i64, z),
                        Some((r, t)) => {
                            let pc = Point3::from(*r * p.coords + *t);
                            let Some(px) = ccam.project(&pc) else {
                                continue;
                            };
                            // Truncation is rounding half up here: both are >= 0.
                            let (cu, cv) = (px.x + 0.5, px.y + 0.5);
                            if !(cu >= 0.0 && cv >= 0.0 && cu < cw as f64 && cv < ch as f64) {
                                continue;
                            }
                            (cu as i64, cv as i64, pc.z)
                        }
                    };
                    let depth_q = zbuffer::quantise(zc);
                    if filter.is_some() {
                        self.filter_map
                            .lower_coarse((cu as usize, cv as usize), depth_q);
                    }
                    self.candidates.push(Candidate {
                        index: i as u32,
                        color_u: cu as u32,
                        color_v: cv as u32,
                        depth_q,
                    });
                }
                // Colours. The occlusion test (libfreenect2's: the nearest depth the colour
                // camera sees within the window around the point's colour pixel, which
                // libfreenect2 spreads over the window and this gathers, the same for a
                // symmetric window) runs in two steps: the block level clears most points;
                // the fine level is filled and asked only around the contested ones.
                let raw = color.as_raw();
                let paint = |cloud: &mut TexturedCloud, c: &Candidate| {
                    if let Some(point) = cloud.points[c.index as usize].as_mut() {
                        let at = 3 * (c.color_v as usize * cw as usize + c.color_u as usize);
                        point.rgb = Some([raw[at], raw[at + 1], raw[at + 2]]);
                    }
                };
                let limit = |c: &Candidate| f64::from(c.depth_q) * (1.0 - filter_tolerance);
                let at = |c: &Candidate| (c.color_u as usize, c.color_v as usize);
                self.contested.clear();
                for (k, c) in self.candidates.iter().enumerate() {
                    if filter.is_some() && self.filter_map.contested(at(c), filter_half, limit(c)) {
                        self.contested.push(k as u32);
                    } else {
                        paint(cloud, c);
                    }
                }
                if !self.contested.is_empty() {
                    for c in &self.candidates {
                        self.filter_map.lower_fine_if_needed(at(c), c.depth_q);
                    }
                    for &k in &self.contested {
                        let c = &self.candidates[k as usize];
                        if !self.filter_map.occluded(at(c), filter_half, limit(c)) {
                            paint(cloud, c);
                        }
                    }
                }
            }
            Engine::Freenect2 {
                registration,
                frame,
                depth_mm,
            } => {
                let scale_mm = (unit_m * 1000.0) as f32;
                for (out, &raw) in depth_mm.iter_mut().zip(depth.values()) {
                    *out = f32::from(raw) * scale_mm;
                }
                registration.apply_into(
                    depth_mm,
                    color,
                    self.config.occlusion_filter.is_some(),
                    frame,
                )?;
                let (fx, fy, cx, cy) = (dcam.fx, dcam.fy, dcam.cx, dcam.cy);
                let w = dcam.width as usize;
                cloud.points.fill(None);
                for (i, (&z_mm, rgb)) in frame
                    .undistorted_mm
                    .iter()
                    .zip(frame.registered.iter())
                    .enumerate()
                {
                    if z_mm.is_nan() || z_mm <= 0.0 {
                        continue;
                    }
                    let z = f64::from(z_mm) * 1e-3 + offset_m;
                    if !(z > min_z && z <= max_z) {
                        continue;
                    }
                    let (u, v) = ((i % w) as f64, (i / w) as f64);
                    valid += 1;
                    cloud.points[i] = Some(TexturedPoint {
                        position_m: Point3::new((u - cx) / fx * z, (v - cy) / fy * z, z),
                        rgb: *rgb,
                    });
                }
            }
        }
        if valid == 0 {
            return Err(KinectError::NoValidDepth {
                what: format!("depth frame {}x{} px", depth.width(), depth.height()),
            });
        }
        if let Some(t) = &self.config.camera_to_world {
            for p in cloud.points.iter_mut().flatten() {
                p.position_m = t * p.position_m;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::Calibration;
    use approx::assert_relative_eq;

    fn flat_wall(calibration: &Calibration, depth_raw: u16) -> (DepthImage, RgbImage) {
        let d = calibration.depth_camera;
        let c = calibration.color_camera;
        let depth = DepthImage::new(
            d.width,
            d.height,
            calibration.depth_unit_m,
            vec![depth_raw; d.pixel_count()],
        )
        .expect("size");
        let color = RgbImage::from_fn(c.width, c.height, |u, v| {
            image::Rgb([(u % 256) as u8, (v % 256) as u8, 7])
        });
        (depth, color)
    }

    #[test]
    fn wall_points_have_the_wall_depth_and_the_colour_of_their_projection() {
        let calibration = Calibration::kinect_v2();
        let (depth, color) = flat_wall(&calibration, 2000);
        let mut builder = CloudBuilder::new(&calibration, CloudConfig::default()).expect("valid");
        let cloud = builder.build(&depth, &color).expect("valid depth");
        assert_eq!(cloud.valid_count(), calibration.depth_camera.pixel_count());
        let p = cloud.get(256, 207).expect("centre");
        assert_relative_eq!(p.position_m.z, 2.0, epsilon = 1e-12);
        // Its colour is the colour pixel it projects to.
        let t = calibration.depth_to_color().expect("rigid").expect("some");
        let px = calibration
            .color_camera
            .project(&(t * p.position_m))
            .expect("front");
        let expected = color.get_pixel((px.x + 0.5).floor() as u32, (px.y + 0.5).floor() as u32);
        assert_eq!(p.rgb, Some(expected.0));
    }

    #[test]
    fn all_zero_depth_is_an_error() {
        let calibration = Calibration::kinect_v2();
        let (depth, color) = flat_wall(&calibration, 0);
        let mut builder = CloudBuilder::new(&calibration, CloudConfig::default()).expect("valid");
        assert!(matches!(
            builder.build(&depth, &color),
            Err(KinectError::NoValidDepth { .. })
        ));
    }

    #[test]
    fn mismatched_sizes_are_errors() {
        let calibration = Calibration::kinect_v2();
        let (_, color) = flat_wall(&calibration, 1000);
        let depth = DepthImage::new(640, 480, 0.001, vec![1000; 640 * 480]).expect("size");
        let mut builder = CloudBuilder::new(&calibration, CloudConfig::default()).expect("valid");
        assert!(matches!(
            builder.build(&depth, &color),
            Err(KinectError::SizeMismatch {
                expected_width: 512,
                found_width: 640,
                ..
            })
        ));
    }

    #[test]
    fn occluded_background_loses_its_colour() {
        let calibration = Calibration::kinect_v2();
        let (mut depth, color) = flat_wall(&calibration, 3000);
        // A near post in front of the wall.
        for v in 0..424 {
            for u in 240..260 {
                depth.values_mut()[v * 512 + u] = 1000;
            }
        }
        let mut filtered = CloudBuilder::new(&calibration, CloudConfig::default()).expect("ok");
        let mut plain = CloudBuilder::new(
            &calibration,
            CloudConfig {
                occlusion_filter: None,
                ..CloudConfig::default()
            },
        )
        .expect("ok");
        let a = filtered.build(&depth, &color).expect("ok");
        let b = plain.build(&depth, &color).expect("ok");
        let coloured = |c: &TexturedCloud| c.iter_valid().filter(|(_, p)| p.rgb.is_some()).count();
        assert!(
            coloured(&a) < coloured(&b),
            "{} vs {}",
            coloured(&a),
            coloured(&b)
        );
        assert!(
            a.get(250, 200).and_then(|p| p.rgb).is_some(),
            "the post keeps its colour"
        );
    }

    #[test]
    fn occlusion_filter_matches_a_brute_force_reference() {
        use crate::synth;
        let mut config = synth::SynthConfig::kinect_v2(2.2, 1.1, 3);
        config.calibration.color_camera =
            config.calibration.color_camera.scaled(0.5).expect("valid");
        let frame = synth::render(&synth::demo_tree(3), &config).expect("renders");
        let calibration = &config.calibration;
        let filter = OcclusionFilter::default();
        let mut builder = CloudBuilder::new(calibration, CloudConfig::default()).expect("ok");
        // A first frame leaves stale cells behind; the second must not be misled by them.
        let d = calibration.depth_camera;
        let near_wall =
            DepthImage::new(d.width, d.height, 0.001, vec![900; d.pixel_count()]).expect("size");
        builder.build(&near_wall, &frame.color).expect("ok");
        let cloud = builder.build(&frame.depth, &frame.color).expect("ok");
        // Both steps of the test ran: some points were contested and went to the fine level.
        assert!(!builder.contested.is_empty());
        assert!(builder.contested.len() < builder.candidates.len());
        // Reference: every point's colour pixel and colour-camera depth, then for each point
        // the nearest depth of any point whose colour pixel is within the window.
        let t = calibration.depth_to_color().expect("ok").expect("rigid");
        let cam = calibration.color_camera;
        let projected: Vec<Option<(i64, i64, f64)>> = cloud
            .points()
            .iter()
            .map(|p| {
                let pc = t * p.as_ref()?.position_m;
                let px = cam.project(&pc)?;
                let (u, v) = cam.pixel_at(&px)?;
                Some((i64::from(u), i64::from(v), pc.z))
            })
            .collect();
        let mut nearest = std::collections::HashMap::<(i64, i64), f64>::new();
        for &(u, v, z) in projected.iter().flatten() {
            let e = nearest.entry((u, v)).or_insert(f64::INFINITY);
            *e = e.min(z);
        }
        let (hw, hh) = (
            i64::from(filter.half_width_px),
            i64::from(filter.half_height_px),
        );
        let mut checked = 0;
        for (p, proj) in cloud.points().iter().zip(&projected) {
            let (Some(p), Some((u, v, z))) = (p, proj) else {
                continue;
            };
            let mut m = f64::INFINITY;
            for y in v - hh..=v + hh {
                for x in u - hw..=u + hw {
                    m = m.min(nearest.get(&(x, y)).copied().unwrap_or(f64::INFINITY));
                }
            }
            let occluded = (z - m) / z > filter.tolerance;
            // Skip razor-edge cases where 0.1 mm quantisation may decide.
            if ((z - m) / z - filter.tolerance).abs() < 1e-4 {
                continue;
            }
            assert_eq!(
                p.rgb.is_none(),
                occluded,
                "point at {u},{v} z {z} nearest {m}"
            );
            checked += 1;
        }
        assert!(checked > 10_000, "{checked}");
    }

    #[test]
    fn freenect2_pinhole_model_matches_the_rigid_model() {
        use crate::freenect2::{Freenect2ColorParams, Freenect2IrParams};
        let ir = Freenect2IrParams {
            k1: 0.0,
            k2: 0.0,
            k3: 0.0,
            ..Freenect2IrParams::kinect_v2_typical()
        };
        let color = Freenect2ColorParams::from_pinhole_baseline(&ir, 1081.37, 959.5, 539.5, 52.0);
        let f2 = Calibration::freenect2(ir, color);
        let mut rigid = f2.clone();
        rigid.registration =
            crate::calibration::RegistrationModel::Rigid(crate::calibration::Extrinsics {
                translation_m: [0.052, 0.0, 0.0],
                ..crate::calibration::Extrinsics::identity()
            });
        let (depth, colour) = flat_wall(&f2, 1500);
        let config = CloudConfig {
            occlusion_filter: None,
            ..CloudConfig::default()
        };
        let a = CloudBuilder::new(&f2, config)
            .expect("ok")
            .build(&depth, &colour)
            .expect("ok");
        let b = CloudBuilder::new(&rigid, config)
            .expect("ok")
            .build(&depth, &colour)
            .expect("ok");
        let mut same = 0;
        let mut total = 0;
        for (pa, pb) in a.points().iter().zip(b.points()) {
            if let (Some(pa), Some(pb)) = (pa, pb) {
                assert_relative_eq!(pa.position_m, pb.position_m, epsilon = 1e-9);
                total += 1;
                same += usize::from(pa.rgb == pb.rgb);
            }
        }
        // Rounding of f32 vs f64 may move a colour pixel at exact half-pixel ties only.
        assert!(same * 1000 >= total * 999, "{same} of {total}");
    }
}
