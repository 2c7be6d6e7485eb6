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
    /// with the libfreenect2 model when this is `Some`.) Not used for an already-registered
    /// calibration: the driver that registered the depth resolved occlusion, and every
    /// point takes its own pixel's colour.
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
    /// Already registered: every depth pixel takes the colour of its own pixel.
    Registered {
        /// Undistorted normalised ray per depth pixel, as separable factors when the camera
        /// has no distortion (x per column, y per row) or a full table.
        rays: Rays,
    },
    /// Rigid: per-pixel undistorted rays and the transform.
    Rigid {
        /// The depth camera's undistorted normalised rays.
        rays: Rays,
        /// Depth-to-colour rotation matrix and translation.
        depth_to_color: (Matrix3<f64>, Vector3<f64>),
    },
    Freenect2 {
        registration: Box<Freenect2Registration>,
        frame: Freenect2Frame,
        depth_mm: Vec<f32>,
    },
}

/// A depth camera's undistorted normalised rays.
enum Rays {
    /// No distortion: `x = columns[u]`, `y = rows[v]`.
    Separable { columns: Vec<f64>, rows: Vec<f64> },
    /// One ray per pixel, x and y apart (NaN where the distortion cannot be inverted).
    Table { xs: Vec<f64>, ys: Vec<f64> },
}

impl Rays {
    fn new(camera: &CameraModel) -> Self {
        if camera.distortion.is_zero() {
            return Self::Separable {
                columns: (0..camera.width)
                    .map(|u| (f64::from(u) - camera.cx) / camera.fx)
                    .collect(),
                rows: (0..camera.height)
                    .map(|v| (f64::from(v) - camera.cy) / camera.fy)
                    .collect(),
            };
        }
        let table = camera.ray_table();
        Self::Table {
            xs: table.iter().map(|r| r.map_or(f64::NAN, |r| r.x)).collect(),
            ys: table.iter().map(|r| r.map_or(f64::NAN, |r| r.y)).collect(),
        }
    }

    /// The rays of row `v` (`width` pixels), x and y; `y_fill` holds the row's y when the
    /// rays are separable.
    #[inline]
    fn row<'a>(
        &'a self,
        v: usize,
        width: usize,
        y_fill: &'a mut Vec<f64>,
    ) -> (&'a [f64], &'a [f64]) {
        match self {
            Self::Separable { columns, rows } => {
                y_fill.clear();
                y_fill.resize(width, rows[v]);
                (columns, y_fill)
            }
            Self::Table { xs, ys } => {
                let range = v * width..(v + 1) * width;
                (&xs[range.clone()], &ys[range])
            }
        }
    }

    /// Call `f(index, raw depth, ray, slot)` for every pixel, row-major (`depth` and
    /// `points` have the camera's pixel count).
    #[inline]
    fn for_each(
        &self,
        depth: &[u16],
        points: &mut [Option<TexturedPoint>],
        mut f: impl FnMut(usize, u16, [f64; 2], &mut Option<TexturedPoint>),
    ) {
        match self {
            Self::Separable { columns, rows } => {
                let w = columns.len();
                for (v, ((&y, depth_row), point_row)) in rows
                    .iter()
                    .zip(depth.chunks_exact(w))
                    .zip(points.chunks_exact_mut(w))
                    .enumerate()
                {
                    for (u, ((&x, &raw), slot)) in columns
                        .iter()
                        .zip(depth_row)
                        .zip(point_row.iter_mut())
                        .enumerate()
                    {
                        f(v * w + u, raw, [x, y], slot);
                    }
                }
            }
            Self::Table { xs, ys } => {
                for (i, (((&x, &y), &raw), slot)) in xs
                    .iter()
                    .zip(ys)
                    .zip(depth)
                    .zip(points.iter_mut())
                    .enumerate()
                {
                    f(i, raw, [x, y], slot);
                }
            }
        }
    }
}

/// Builds organized textured clouds from depth + colour frames of one calibrated camera.
///
/// All per-camera work (undistortion tables, libfreenect2 maps) is done once in
/// [`CloudBuilder::new`]; [`CloudBuilder::build_into`] then allocates nothing.
pub struct CloudBuilder {
    calibration: Calibration,
    config: CloudConfig,
    engine: Engine,
    /// The occlusion filter's buffers, reused between frames.
    occlusion: Occlusion,
}

/// The occlusion filter's buffers.
#[derive(Default)]
struct Occlusion {
    /// Nearest depth per colour pixel.
    map: MinDepthMap,
    /// The points that project onto the colour image.
    candidates: Vec<Candidate>,
    /// Positions in `candidates` that the test's block level could not clear.
    contested: Vec<u32>,
    /// Row scratch of the rigid engine.
    rows: RowBuffers,
    /// A row of y rays, for separable cameras.
    row_y: Vec<f64>,
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
            RegistrationModel::AlreadyRegistered => Engine::Registered {
                rays: Rays::new(&calibration.depth_camera),
            },
            RegistrationModel::Rigid(e) => {
                let t = e.to_isometry()?;
                Engine::Rigid {
                    rays: Rays::new(&calibration.depth_camera),
                    depth_to_color: (
                        t.rotation.to_rotation_matrix().into_inner(),
                        t.translation.vector,
                    ),
                }
            }
        };
        Ok(Self {
            calibration: calibration.clone(),
            config,
            engine,
            occlusion: Occlusion {
                candidates: Vec::with_capacity(calibration.depth_camera.pixel_count()),
                ..Occlusion::default()
            },
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
            Engine::Rigid { .. } | Engine::Registered { .. } => dcam,
        };
        cloud.camera_to_cloud = self
            .config
            .camera_to_world
            .unwrap_or_else(Isometry3::identity);
        if cloud.points.len() != dcam.pixel_count() {
            cloud.points.clear();
            cloud.points.resize(dcam.pixel_count(), None);
        }
        let range = DepthRange {
            unit_m: depth.unit_m(),
            offset_m: self.calibration.depth_offset_m,
            min_z: self.config.min_depth_m,
            max_z: self.config.max_depth_m,
        };
        let frame = Inputs {
            depth,
            color,
            range,
        };
        let valid = match &mut self.engine {
            Engine::Registered { rays } => build_registered(rays, &frame, &mut cloud.points),
            Engine::Rigid {
                rays,
                depth_to_color,
            } => {
                let rigid = Rigid {
                    rays,
                    depth_to_color: *depth_to_color,
                    camera: &ccam,
                    filter: self.config.occlusion_filter,
                };
                rigid.build(&frame, &mut self.occlusion, &mut cloud.points)
            }
            Engine::Freenect2 {
                registration,
                frame: registered,
                depth_mm,
            } => {
                let scale_mm = (range.unit_m * 1000.0) as f32;
                for (out, &raw) in depth_mm.iter_mut().zip(depth.values()) {
                    *out = f32::from(raw) * scale_mm;
                }
                registration.apply_into(
                    depth_mm,
                    color,
                    self.config.occlusion_filter.is_some(),
                    registered,
                )?;
                freenect2_points(&dcam, registered, range, &mut cloud.points)
            }
        };
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

/// How raw depth becomes metres, and which depths are kept.
#[derive(Debug, Clone, Copy)]
struct DepthRange {
    unit_m: f64,
    offset_m: f64,
    min_z: f64,
    max_z: f64,
}

impl DepthRange {
    /// The depth in metres of a raw value, when it is a measurement inside the range.
    #[inline]
    fn metres(&self, raw: u16) -> Option<f64> {
        let z = f64::from(raw) * self.unit_m + self.offset_m;
        (raw != 0 && z > self.min_z && z <= self.max_z).then_some(z)
    }
}

/// One frame's images and depth conversion.
struct Inputs<'a> {
    depth: &'a DepthImage,
    color: &'a RgbImage,
    range: DepthRange,
}

/// The colour of pixel `(u, v)` of a packed RGB buffer `width` pixels wide.
#[inline]
fn rgb_at(raw: &[u8], width: usize, u: usize, v: usize) -> [u8; 3] {
    let at = 3 * (v * width + u);
    [raw[at], raw[at + 1], raw[at + 2]]
}

/// Already registered: every point takes its own pixel's colour. Returns the valid count.
fn build_registered(
    rays: &Rays,
    frame: &Inputs<'_>,
    points: &mut [Option<TexturedPoint>],
) -> usize {
    // The camera's driver registered depth to colour (and so resolved occlusion): every
    // point takes its own pixel's colour, as TUM's tools and Open3D do.
    let rgb = frame.color.as_raw();
    let mut valid = 0;
    rays.for_each(frame.depth.values(), points, |i, raw, [rx, ry], slot| {
        *slot = match frame.range.metres(raw) {
            Some(z) if !rx.is_nan() => {
                valid += 1;
                Some(TexturedPoint {
                    position_m: Point3::new(rx * z, ry * z, z),
                    rgb: Some([rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]]),
                })
            }
            _ => None,
        };
    });
    valid
}

/// A rigid two-camera registration, for one frame.
struct Rigid<'a> {
    rays: &'a Rays,
    depth_to_color: (Matrix3<f64>, Vector3<f64>),
    camera: &'a CameraModel,
    filter: Option<OcclusionFilter>,
}

impl Rigid<'_> {
    /// Points, and their colours where the colour camera sees them. Returns the valid count.
    fn build(
        &self,
        frame: &Inputs<'_>,
        occlusion: &mut Occlusion,
        points: &mut [Option<TexturedPoint>],
    ) -> usize {
        let ccam = self.camera;
        let (cw, ch) = (ccam.width as usize, ccam.height as usize);
        if self.filter.is_some() {
            occlusion.map.begin_frame(cw, ch);
        }
        occlusion.candidates.clear();
        let raw_rgb = frame.color.as_raw();
        let (cwf, chf) = (cw as f64, ch as f64);
        let w = frame.depth.width() as usize;
        let rows = &mut occlusion.rows;
        let mut valid = 0;
        for (v, (depth_row, point_row)) in frame
            .depth
            .values()
            .chunks_exact(w)
            .zip(points.chunks_exact_mut(w))
            .enumerate()
        {
            let (xs, ys) = self.rays.row(v, w, &mut occlusion.row_y);
            // The row's valid points, gathered; then their colour pixels without branches, so
            // that the compiler can vectorise the projection; then colours or candidates.
            rows.gather(frame.range, (xs, ys, depth_row), point_row);
            valid += rows.at.len();
            self.project(rows);
            for k in 0..rows.at.len() {
                let u = rows.at[k] as usize;
                let (cu, cv, zc) = (rows.u[k], rows.v[k], rows.z[k]);
                let mut rgb = None;
                // Truncation is rounding half up here: both are >= 0.
                if zc > 0.0 && cu >= 0.0 && cv >= 0.0 && cu < cwf && cv < chf {
                    let (cu, cv) = (cu as u32, cv as u32);
                    if self.filter.is_none() {
                        rgb = Some(rgb_at(raw_rgb, cw, cu as usize, cv as usize));
                    } else {
                        let depth_q = zbuffer::quantise(zc);
                        occlusion
                            .map
                            .lower_coarse((cu as usize, cv as usize), depth_q);
                        occlusion.candidates.push(Candidate {
                            index: (v * w + u) as u32,
                            color_u: cu,
                            color_v: cv,
                            depth_q,
                        });
                    }
                }
                point_row[u] = Some(TexturedPoint {
                    position_m: Point3::new(rows.px[k], rows.py[k], rows.pz[k]),
                    rgb,
                });
            }
        }
        if let Some(filter) = self.filter {
            occlusion.paint(filter, raw_rgb, cw, points);
        }
        valid
    }
}

impl Rigid<'_> {
    /// Colour-camera pixel coordinates (plus half a pixel) and depth of the gathered points.
    #[inline]
    fn project(&self, rows: &mut RowBuffers) {
        let (r, t) = self.depth_to_color;
        let c = self.camera;
        let (fx, fy, cx, cy) = (c.fx, c.fy, c.cx + 0.5, c.cy + 0.5);
        let d = c.distortion;
        let distorted = !d.is_zero();
        let n = rows.at.len();
        for buffer in [&mut rows.u, &mut rows.v, &mut rows.z] {
            buffer.resize(n, 0.0);
        }
        let inputs = rows.px.iter().zip(&rows.py).zip(&rows.pz);
        let outputs = rows
            .u
            .iter_mut()
            .zip(rows.v.iter_mut())
            .zip(rows.z.iter_mut());
        for (((&px, &py), &pz), ((u, v), z)) in inputs.zip(outputs) {
            let qx = r[(0, 0)] * px + r[(0, 1)] * py + r[(0, 2)] * pz + t.x;
            let qy = r[(1, 0)] * px + r[(1, 1)] * py + r[(1, 2)] * pz + t.y;
            let qz = r[(2, 0)] * px + r[(2, 1)] * py + r[(2, 2)] * pz + t.z;
            let (x, y) = if distorted {
                d.apply_to_point(qx, qy, qz)
            } else {
                (qx / qz, qy / qz)
            };
            *u = fx * x + cx;
            *v = fy * y + cy;
            *z = qz;
        }
    }
}

/// Per-row scratch of the rigid engine: the row's valid points (column, position) and their
/// colour pixel coordinates and depths in the colour camera.
#[derive(Debug, Default)]
struct RowBuffers {
    at: Vec<u32>,
    px: Vec<f64>,
    py: Vec<f64>,
    pz: Vec<f64>,
    u: Vec<f64>,
    v: Vec<f64>,
    z: Vec<f64>,
}

impl RowBuffers {
    /// Gather a row's valid points; every other slot of the row becomes `None`.
    #[inline]
    fn gather(
        &mut self,
        range: DepthRange,
        (xs, ys, depth): (&[f64], &[f64], &[u16]),
        point_row: &mut [Option<TexturedPoint>],
    ) {
        self.at.clear();
        self.px.clear();
        self.py.clear();
        self.pz.clear();
        for (u, (((&rx, &ry), &raw), slot)) in xs
            .iter()
            .zip(ys)
            .zip(depth)
            .zip(point_row.iter_mut())
            .enumerate()
        {
            *slot = None;
            if let Some(z) = range.metres(raw)
                && !rx.is_nan()
            {
                self.at.push(u as u32);
                self.px.push(rx * z);
                self.py.push(ry * z);
                self.pz.push(z);
            }
        }
    }
}

impl Occlusion {
    /// Colour the candidates the colour camera sees. The occlusion test (libfreenect2's: the
    /// nearest depth the colour camera sees within the window around the point's colour
    /// pixel, which libfreenect2 spreads over the window and this gathers, the same for a
    /// symmetric window) runs in two steps: the block level clears most points; the fine
    /// level is filled and asked only around the contested ones.
    fn paint(
        &mut self,
        filter: OcclusionFilter,
        raw_rgb: &[u8],
        width: usize,
        points: &mut [Option<TexturedPoint>],
    ) {
        let half = (
            filter.half_width_px as usize,
            filter.half_height_px as usize,
        );
        let limit = |c: &Candidate| f64::from(c.depth_q) * (1.0 - filter.tolerance);
        let at = |c: &Candidate| (c.color_u as usize, c.color_v as usize);
        let mut paint = |c: &Candidate| {
            if let Some(point) = points[c.index as usize].as_mut() {
                point.rgb = Some(rgb_at(raw_rgb, width, at(c).0, at(c).1));
            }
        };
        self.contested.clear();
        for (k, c) in self.candidates.iter().enumerate() {
            if self.map.contested(at(c), half, limit(c)) {
                self.contested.push(k as u32);
            } else {
                paint(c);
            }
        }
        if self.contested.is_empty() {
            return;
        }
        for c in &self.candidates {
            self.map.lower_fine_if_needed(at(c), c.depth_q);
        }
        for &k in &self.contested {
            let c = &self.candidates[k as usize];
            if !self.map.occluded(at(c), half, limit(c)) {
                paint(c);
            }
        }
    }
}

/// The points of libfreenect2's registered frame. Returns the valid count.
fn freenect2_points(
    dcam: &CameraModel,
    registered: &Freenect2Frame,
    range: DepthRange,
    points: &mut [Option<TexturedPoint>],
) -> usize {
    let (fx, fy, cx, cy) = (dcam.fx, dcam.fy, dcam.cx, dcam.cy);
    let w = dcam.width as usize;
    let mut valid = 0;
    points.fill(None);
    for (i, (&z_mm, rgb)) in registered
        .undistorted_mm
        .iter()
        .zip(registered.registered.iter())
        .enumerate()
    {
        if z_mm.is_nan() || z_mm <= 0.0 {
            continue;
        }
        let z = f64::from(z_mm) * 1e-3 + range.offset_m;
        if !(z > range.min_z && z <= range.max_z) {
            continue;
        }
        let (u, v) = ((i % w) as f64, (i / w) as f64);
        valid += 1;
        points[i] = Some(TexturedPoint {
            position_m: Point3::new((u - cx) / fx * z, (v - cy) / fy * z, z),
            rgb: *rgb,
        });
    }
    valid
}

#[cfg(test)]
mod tests;
