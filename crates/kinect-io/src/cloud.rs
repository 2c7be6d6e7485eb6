//! Organized textured point clouds: one entry per depth pixel, with its colour.
//!
//! Depth is converted from raw sensor units to metres here, at this boundary, and nowhere
//! else. A pixel without valid depth has no point; a point that the colour camera does not
//! see (outside its image, or occluded by a nearer surface) has `rgb: None`.
//!
//! The layout is packed: per pixel the point's depth along the source camera's axis (8 bytes)
//! and its colour with a "seen" flag (4 bytes). Every point of an organized cloud lies on its
//! pixel's ray, so its position is that ray (shared by every cloud of one camera) times its
//! depth, moved by the cloud's transform; positions are computed when they are asked for.
//! That is 12 bytes written per pixel where a `Vec<Option<TexturedPoint>>` wrote 32, and a
//! transform of the whole cloud costs nothing until the points are read.

use std::sync::Arc;

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
use crate::occlusion::WindowSweep;
use crate::zbuffer;

/// One point of a textured cloud.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TexturedPoint {
    /// Position in metres, in the cloud's frame.
    pub position_m: Point3<f64>,
    /// Colour, or `None` when the colour camera does not see the point.
    pub rgb: Option<[u8; 3]>,
}

/// The colour entry of a pixel the colour camera does not see (or that has no point).
const NO_COLOR: [u8; 4] = [0; 4];

/// The fourth byte of a colour entry the colour camera sees.
const SEEN: u8 = 255;

/// An organized textured point cloud: `width * height` entries, row-major, one per depth
/// pixel of its source camera, packed (see the module docs).
#[derive(Debug, Clone)]
pub struct TexturedCloud {
    width: u32,
    height: u32,
    /// Depth along the source camera's axis per pixel, metres; 0 where there is no point.
    depth_m: Vec<f64>,
    /// Colour per pixel, the fourth byte [`SEEN`] when the colour camera sees the point.
    rgb: Vec<[u8; 4]>,
    /// The source camera's rays, shared with the builder that made the cloud.
    rays: Arc<Rays>,
    source_camera: CameraModel,
    camera_to_cloud: Isometry3<f64>,
    /// `camera_to_cloud` as a matrix and translation; `None` for the identity.
    to_cloud: Option<(Matrix3<f64>, Vector3<f64>)>,
}

impl PartialEq for TexturedCloud {
    /// Equal when they have the same size, camera and transform, and every pixel has the
    /// same point (position and colour).
    fn eq(&self, other: &Self) -> bool {
        (self.width, self.height) == (other.width, other.height)
            && self.source_camera == other.source_camera
            && self.camera_to_cloud == other.camera_to_cloud
            && (0..self.depth_m.len()).all(|i| self.point(i) == other.point(i))
    }
}

impl TexturedCloud {
    /// An organized cloud of `source_camera`'s pixels (row-major) from each pixel's depth
    /// along the camera's axis (metres, 0 where there is no point) and colour (`None` where
    /// the colour camera does not see it), with the transform from the camera's frame to the
    /// cloud's frame (identity when the points are in the camera frame). Each point lies on
    /// its pixel's ray; a pixel whose ray the camera's distortion cannot give has no point.
    ///
    /// # Errors
    /// [`KinectError::SizeMismatch`] when the counts do not match the camera;
    /// [`KinectError::InvalidParameter`] for an invalid camera or a depth that is negative or
    /// not finite.
    pub fn new(
        source_camera: CameraModel,
        depth_m: Vec<f64>,
        rgb: &[Option<[u8; 3]>],
        camera_to_cloud: Isometry3<f64>,
    ) -> Result<Self> {
        source_camera.validate()?;
        let n = source_camera.pixel_count();
        for (what, len) in [("depths", depth_m.len()), ("colours", rgb.len())] {
            if len != n {
                return Err(KinectError::SizeMismatch {
                    what: format!("organized cloud {what} vs. source camera"),
                    expected_width: source_camera.width,
                    expected_height: source_camera.height,
                    found_width: source_camera.width,
                    found_height: (len / source_camera.width.max(1) as usize) as u32,
                });
            }
        }
        if let Some((i, z)) = depth_m
            .iter()
            .enumerate()
            .find(|(_, z)| !(z.is_finite() && **z >= 0.0))
        {
            return Err(KinectError::param(
                "organized cloud depth",
                format!("{z} m at pixel {i} must be finite and non-negative (0: no point)"),
            ));
        }
        let rays = Arc::new(Rays::new(&source_camera));
        let mut depth_m = depth_m;
        for (i, z) in depth_m.iter_mut().enumerate() {
            if rays.is_void(i) {
                *z = 0.0;
            }
        }
        let rgb = rgb
            .iter()
            .zip(&depth_m)
            .map(|(c, &z)| match c {
                Some([r, g, b]) if z > 0.0 => [*r, *g, *b, SEEN],
                _ => NO_COLOR,
            })
            .collect();
        let mut cloud = Self::empty(source_camera, rays);
        cloud.depth_m = depth_m;
        cloud.rgb = rgb;
        cloud.set_camera_to_cloud(camera_to_cloud);
        Ok(cloud)
    }

    /// A cloud of `camera` with no storage yet.
    fn empty(camera: CameraModel, rays: Arc<Rays>) -> Self {
        Self {
            width: camera.width,
            height: camera.height,
            depth_m: Vec::new(),
            rgb: Vec::new(),
            rays,
            source_camera: camera,
            camera_to_cloud: Isometry3::identity(),
            to_cloud: None,
        }
    }

    fn set_camera_to_cloud(&mut self, transform: Isometry3<f64>) {
        self.camera_to_cloud = transform;
        self.to_cloud = (transform != Isometry3::identity()).then(|| {
            (
                transform.rotation.to_rotation_matrix().into_inner(),
                transform.translation.vector,
            )
        });
    }

    /// Width (depth pixels).
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height (depth pixels).
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Number of entries (`width * height`, valid or not).
    pub fn len(&self) -> usize {
        self.depth_m.len()
    }

    /// True when the cloud has no entries.
    pub fn is_empty(&self) -> bool {
        self.depth_m.is_empty()
    }

    /// Depth of every entry along the source camera's axis (its `z`), row-major, metres; 0
    /// where there is no point. The packed form, for code that wants to stream the cloud.
    pub fn depths_m(&self) -> &[f64] {
        &self.depth_m
    }

    /// The point of entry `index` (row-major); `None` outside the grid or where there is no
    /// depth.
    #[inline]
    pub fn point(&self, index: usize) -> Option<TexturedPoint> {
        let z = *self.depth_m.get(index)?;
        (z > 0.0).then(|| TexturedPoint {
            position_m: self.position(index, z),
            rgb: self.color_of(index),
        })
    }

    /// The position of entry `index` (row-major), metres in the cloud's frame; `None`
    /// outside the grid or where there is no depth.
    #[inline]
    pub fn position_m(&self, index: usize) -> Option<Point3<f64>> {
        let z = *self.depth_m.get(index)?;
        (z > 0.0).then(|| self.position(index, z))
    }

    /// The colour of entry `index`; `None` where there is no point or the colour camera does
    /// not see it.
    #[inline]
    pub fn color(&self, index: usize) -> Option<[u8; 3]> {
        (*self.depth_m.get(index)? > 0.0)
            .then(|| self.color_of(index))
            .flatten()
    }

    #[inline]
    fn color_of(&self, index: usize) -> Option<[u8; 3]> {
        let [r, g, b, seen] = self.rgb[index];
        (seen == SEEN).then_some([r, g, b])
    }

    /// The position of entry `index` with depth `z > 0`.
    #[inline]
    fn position(&self, index: usize, z: f64) -> Point3<f64> {
        self.place(self.rays.at(index, self.width as usize), z)
    }

    /// The point at depth `z` on ray `(x, y)`, in the cloud's frame.
    #[inline]
    fn place(&self, (x, y): (f64, f64), z: f64) -> Point3<f64> {
        let p = Vector3::new(x * z, y * z, z);
        match &self.to_cloud {
            None => Point3::from(p),
            Some((r, t)) => Point3::from(r * p + t),
        }
    }

    /// The point of depth pixel `(u, v)`; `None` outside the grid or where there is no depth.
    pub fn get(&self, u: u32, v: u32) -> Option<TexturedPoint> {
        if u < self.width && v < self.height {
            self.point(v as usize * self.width as usize + u as usize)
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
        self.depth_m.iter().filter(|&&z| z > 0.0).count()
    }

    /// The points with depth, with their flat index.
    pub fn iter_valid(&self) -> impl Iterator<Item = (usize, TexturedPoint)> + '_ {
        let w = (self.width as usize).max(1);
        self.depth_m
            .chunks_exact(w)
            .enumerate()
            .flat_map(move |(v, row)| {
                row.iter()
                    .enumerate()
                    .filter(|(_, z)| **z > 0.0)
                    .map(move |(u, &z)| {
                        let i = v * w + u;
                        let point = TexturedPoint {
                            position_m: self.place(self.rays.at_uv(u, v, i), z),
                            rgb: self.color_of(i),
                        };
                        (i, point)
                    })
            })
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
    /// [`crate::camera_to_world_z_up`] to go to a Z-up world frame). The points are not
    /// touched: the transform is composed with the cloud's.
    pub fn transformed(&self, transform: &Isometry3<f64>) -> Self {
        let mut out = self.clone();
        out.set_camera_to_cloud(transform * self.camera_to_cloud);
        out
    }

    /// Make the storage fit `camera`'s pixels with `rays`, and set the transform.
    fn reset(&mut self, camera: CameraModel, rays: &Arc<Rays>, transform: Isometry3<f64>) {
        let n = camera.pixel_count();
        (self.width, self.height, self.source_camera) = (camera.width, camera.height, camera);
        self.depth_m.resize(n, 0.0);
        self.rgb.resize(n, NO_COLOR);
        if !Arc::ptr_eq(&self.rays, rays) {
            self.rays = Arc::clone(rays);
        }
        self.set_camera_to_cloud(transform);
    }
}

/// The occlusion filter of depth-to-colour registration: a depth pixel gets no colour when the
/// colour camera sees a nearer surface at (or next to) its colour pixel. Defaults are
/// libfreenect2's (5x3 colour pixels, 1 % depth tolerance).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OcclusionFilter {
    /// Half-width of the window in colour pixels (default 2; at most
    /// [`MAX_OCCLUSION_HALF_WINDOW_PX`]).
    pub half_width_px: u32,
    /// Half-height of the window in colour pixels (default 1; at most
    /// [`MAX_OCCLUSION_HALF_WINDOW_PX`]).
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

/// Largest half width or half height of the occlusion filter's window, colour pixels: 16
/// times libfreenect2's 2 x 1 at 1920x1080 (the test reads the whole window for every point,
/// so the bound also bounds its time: at most 65 x 65 reads a point).
pub const MAX_OCCLUSION_HALF_WINDOW_PX: u32 = 32;

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
    /// a negative or NaN filter tolerance, or a filter window above
    /// [`MAX_OCCLUSION_HALF_WINDOW_PX`].
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
        if let Some(f) = &self.occlusion_filter
            && f.half_width_px.max(f.half_height_px) > MAX_OCCLUSION_HALF_WINDOW_PX
        {
            return Err(KinectError::param(
                "occlusion filter window",
                format!(
                    "half width {} px, half height {} px; at most {MAX_OCCLUSION_HALF_WINDOW_PX} px each",
                    f.half_width_px, f.half_height_px
                ),
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
        rays: Arc<Rays>,
    },
    /// Rigid: per-pixel undistorted rays and the transform.
    Rigid {
        /// The depth camera's undistorted normalised rays.
        rays: Arc<Rays>,
        /// Depth-to-colour rotation matrix and translation.
        depth_to_color: (Matrix3<f64>, Vector3<f64>),
    },
    Freenect2 {
        /// The rays of libfreenect2's undistorted (pinhole) depth grid.
        rays: Arc<Rays>,
        registration: Box<Freenect2Registration>,
        frame: Freenect2Frame,
        depth_mm: Vec<f32>,
    },
}

/// A depth camera's undistorted normalised rays.
#[derive(Debug, PartialEq)]
pub(crate) enum Rays {
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

    /// True when pixel `index` has no ray (the distortion cannot be inverted there).
    fn is_void(&self, index: usize) -> bool {
        match self {
            Self::Separable { .. } => false,
            Self::Table { xs, .. } => xs.get(index).is_none_or(|x| x.is_nan()),
        }
    }

    /// The ray `(x, y)` of pixel `index` of a camera `width` pixels wide.
    #[inline]
    fn at(&self, index: usize, width: usize) -> (f64, f64) {
        self.at_uv(index % width, index / width, index)
    }

    /// The ray `(x, y)` of pixel `(u, v)`, whose flat index is `index`.
    #[inline]
    fn at_uv(&self, u: usize, v: usize, index: usize) -> (f64, f64) {
        match self {
            Self::Separable { columns, rows } => (columns[u], rows[v]),
            Self::Table { xs, ys } => (xs[index], ys[index]),
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

    /// The x rays of each row of a camera `width` pixels wide (all a pixel's validity
    /// needs: a ray that cannot be had is NaN in x).
    fn x_rows(&self, width: usize) -> impl Iterator<Item = &[f64]> {
        let (separable, table): (&[f64], &[f64]) = match self {
            Self::Separable { columns, .. } => (columns, &[]),
            Self::Table { xs, .. } => (&[], xs),
        };
        let rows = match self {
            Self::Separable { rows, .. } => rows.len(),
            Self::Table { .. } => 0,
        };
        std::iter::repeat_n(separable, rows).chain(table.chunks_exact(width.max(1)))
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
    /// The filter's test: the points that project onto the colour image, swept by rows.
    sweep: WindowSweep,
    /// Row scratch of the rigid engine.
    rows: RowBuffers,
    /// A row of y rays, for separable cameras.
    row_y: Vec<f64>,
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
                    rays: Arc::new(Rays::new(&freenect2_grid(&calibration.depth_camera))),
                    registration: Box::new(registration),
                    frame: Freenect2Frame {
                        undistorted_mm: vec![0.0; n],
                        registered: vec![None; n],
                    },
                    depth_mm: vec![0.0; n],
                }
            }
            RegistrationModel::AlreadyRegistered => Engine::Registered {
                rays: Arc::new(Rays::new(&calibration.depth_camera)),
            },
            RegistrationModel::Rigid(e) => {
                let t = e.to_isometry()?;
                Engine::Rigid {
                    rays: Arc::new(Rays::new(&calibration.depth_camera)),
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
            occlusion: Occlusion::default(),
        })
    }

    fn rays(&self) -> &Arc<Rays> {
        match &self.engine {
            Engine::Registered { rays }
            | Engine::Rigid { rays, .. }
            | Engine::Freenect2 { rays, .. } => rays,
        }
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
        let mut cloud =
            TexturedCloud::empty(self.calibration.depth_camera, Arc::clone(self.rays()));
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
        let source = match self.engine {
            Engine::Freenect2 { .. } => freenect2_grid(&dcam),
            Engine::Rigid { .. } | Engine::Registered { .. } => dcam,
        };
        let transform = self
            .config
            .camera_to_world
            .unwrap_or_else(Isometry3::identity);
        cloud.reset(source, self.rays(), transform);
        let out = Slots {
            depth_m: &mut cloud.depth_m,
            rgb: &mut cloud.rgb,
        };
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
            Engine::Registered { rays } => build_registered(rays, &frame, out),
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
                rigid.build(&frame, &mut self.occlusion, out)
            }
            Engine::Freenect2 {
                registration,
                frame: registered,
                depth_mm,
                ..
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
                freenect2_points(registered, range, out)
            }
        };
        if valid == 0 {
            return Err(KinectError::NoValidDepth {
                what: format!("depth frame {}x{} px", depth.width(), depth.height()),
            });
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
    /// The depth in metres of a raw value when it is a measurement inside the range, else 0
    /// (`min_z >= 0`, so a kept depth is > 0).
    #[inline]
    fn metres(&self, raw: u16) -> f64 {
        let z = f64::from(raw) * self.unit_m + self.offset_m;
        if raw != 0 && z > self.min_z && z <= self.max_z {
            z
        } else {
            0.0
        }
    }
}

/// One frame's images and depth conversion.
struct Inputs<'a> {
    depth: &'a DepthImage,
    color: &'a RgbImage,
    range: DepthRange,
}

/// The colour entry (seen) of pixel `(u, v)` of a packed RGB buffer `width` pixels wide.
#[inline]
fn rgb_at(raw: &[u8], width: usize, u: usize, v: usize) -> [u8; 4] {
    let at = 3 * (v * width + u);
    [raw[at], raw[at + 1], raw[at + 2], SEEN]
}

/// The packed storage a builder writes: depth and colour entry per pixel.
struct Slots<'a> {
    depth_m: &'a mut [f64],
    rgb: &'a mut [[u8; 4]],
}

/// libfreenect2's undistorted depth grid: the depth camera without distortion, on which its
/// points lie.
fn freenect2_grid(dcam: &CameraModel) -> CameraModel {
    CameraModel {
        distortion: crate::camera::Distortion::default(),
        ..*dcam
    }
}

/// Already registered: every point takes its own pixel's colour. Returns the valid count.
fn build_registered(rays: &Rays, frame: &Inputs<'_>, out: Slots<'_>) -> usize {
    // The camera's driver registered depth to colour (and so resolved occlusion): every
    // point takes its own pixel's colour, as TUM's tools and Open3D do.
    let w = frame.depth.width() as usize;
    let mut valid = 0;
    let rows = rays
        .x_rows(w)
        .zip(frame.depth.values().chunks_exact(w))
        .zip(frame.color.as_raw().chunks_exact(3 * w))
        .zip(
            out.depth_m
                .chunks_exact_mut(w)
                .zip(out.rgb.chunks_exact_mut(w)),
        );
    for (((xs, depth), color), (z_row, rgb_row)) in rows {
        let (xs, depth, color) = (&xs[..w], &depth[..w], &color[..3 * w]);
        let (z_row, rgb_row) = (&mut z_row[..w], &mut rgb_row[..w]);
        for u in 0..w {
            let z = frame.range.metres(depth[u]);
            let ok = z > 0.0 && !xs[u].is_nan();
            valid += usize::from(ok);
            z_row[u] = if ok { z } else { 0.0 };
            let c = [color[3 * u], color[3 * u + 1], color[3 * u + 2], SEEN];
            rgb_row[u] = if ok { c } else { NO_COLOR };
        }
    }
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
    fn build(&self, frame: &Inputs<'_>, occlusion: &mut Occlusion, out: Slots<'_>) -> usize {
        let ccam = self.camera;
        let (cw, ch) = (ccam.width as usize, ccam.height as usize);
        occlusion.sweep.begin(cw, ch);
        let raw_rgb = frame.color.as_raw();
        let (cwf, chf) = (cw as f64, ch as f64);
        let w = frame.depth.width() as usize;
        let rows = &mut occlusion.rows;
        let mut valid = 0;
        out.rgb.fill(NO_COLOR);
        for (v, ((depth_row, z_row), rgb_row)) in frame
            .depth
            .values()
            .chunks_exact(w)
            .zip(out.depth_m.chunks_exact_mut(w))
            .zip(out.rgb.chunks_exact_mut(w))
            .enumerate()
        {
            let (xs, ys) = self.rays.row(v, w, &mut occlusion.row_y);
            // The row's valid points, gathered; then their colour pixels without branches, so
            // that the compiler can vectorise the projection; then colours or candidates.
            rows.gather(frame.range, (xs, ys, depth_row), z_row);
            valid += rows.len;
            self.project(rows);
            for k in 0..rows.len {
                let u = rows.at[k] as usize;
                let (cu, cv, zc) = (rows.u[k], rows.v[k], rows.z[k]);
                // Truncation is rounding half up here: both are >= 0.
                if zc > 0.0 && cu >= 0.0 && cv >= 0.0 && cu < cwf && cv < chf {
                    let (cu, cv) = (cu as u32, cv as u32);
                    // Coloured now, while the colour row is in cache; the filter takes the
                    // colour of occluded points away afterwards.
                    rgb_row[u] = rgb_at(raw_rgb, cw, cu as usize, cv as usize);
                    if self.filter.is_some() {
                        occlusion
                            .sweep
                            .push((cu, cv), zbuffer::quantise(zc), (v * w + u) as u32);
                    }
                }
            }
        }
        if let Some(filter) = self.filter {
            occlusion.hide_occluded(filter, out.rgb);
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
        let n = rows.len;
        let inputs = rows.px[..n].iter().zip(&rows.py[..n]).zip(&rows.pz[..n]);
        let outputs = rows.u[..n]
            .iter_mut()
            .zip(rows.v[..n].iter_mut())
            .zip(rows.z[..n].iter_mut());
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
/// colour pixel coordinates and depths in the colour camera. Every buffer has the row's width;
/// the first `len` entries are this row's.
#[derive(Debug, Default)]
struct RowBuffers {
    len: usize,
    at: Vec<u32>,
    px: Vec<f64>,
    py: Vec<f64>,
    pz: Vec<f64>,
    u: Vec<f64>,
    v: Vec<f64>,
    z: Vec<f64>,
}

impl RowBuffers {
    /// Gather a row's valid points and write the row's depths (0 where there is no point).
    /// Branch-free: every pixel is written at the next free place, which only a valid pixel
    /// then takes (valid and invalid pixels mix unpredictably at edges and holes).
    #[inline]
    fn gather(
        &mut self,
        range: DepthRange,
        (xs, ys, depth): (&[f64], &[f64], &[u16]),
        z_row: &mut [f64],
    ) {
        let width = depth.len();
        if self.at.len() < width {
            self.at.resize(width, 0);
            for buffer in [
                &mut self.px,
                &mut self.py,
                &mut self.pz,
                &mut self.u,
                &mut self.v,
                &mut self.z,
            ] {
                buffer.resize(width, 0.0);
            }
        }
        let mut n = 0;
        for (u, (((&rx, &ry), &raw), slot)) in xs
            .iter()
            .zip(ys)
            .zip(depth)
            .zip(z_row.iter_mut())
            .enumerate()
        {
            let z = range.metres(raw);
            // A NaN ray (distortion not invertible there) is no point.
            let ok = z > 0.0 && !rx.is_nan();
            let z = if ok { z } else { 0.0 };
            *slot = z;
            // n <= u < width: always in bounds.
            if let (Some(at), Some(px), Some(py), Some(pz)) = (
                self.at.get_mut(n),
                self.px.get_mut(n),
                self.py.get_mut(n),
                self.pz.get_mut(n),
            ) {
                (*at, *px, *py, *pz) = (u as u32, rx * z, ry * z, z);
            }
            n += usize::from(ok);
        }
        self.len = n;
    }
}

impl Occlusion {
    /// Take the colour away from the points the colour camera does not see
    /// (libfreenect2's test: a nearer depth by more than the tolerance within the window
    /// around the point's colour pixel; see [`WindowSweep::hidden`]).
    fn hide_occluded(&mut self, filter: OcclusionFilter, rgb: &mut [[u8; 4]]) {
        let half = (
            filter.half_width_px as usize,
            filter.half_height_px as usize,
        );
        self.sweep.hidden(half, filter.tolerance, |pixel| {
            if let Some(c) = rgb.get_mut(pixel as usize) {
                *c = NO_COLOR;
            }
        });
    }
}

/// The points of libfreenect2's registered frame (on its undistorted grid). Returns the
/// valid count.
fn freenect2_points(registered: &Freenect2Frame, range: DepthRange, out: Slots<'_>) -> usize {
    let mut valid = 0;
    for (((&z_mm, rgb), z_out), entry) in registered
        .undistorted_mm
        .iter()
        .zip(registered.registered.iter())
        .zip(out.depth_m.iter_mut())
        .zip(out.rgb.iter_mut())
    {
        let z = f64::from(z_mm) * 1e-3 + range.offset_m;
        // NaN and non-positive depths fail the range test.
        if z_mm > 0.0 && z > range.min_z && z <= range.max_z {
            valid += 1;
            *z_out = z;
            *entry = rgb.map_or(NO_COLOR, |[r, g, b]| [r, g, b, SEEN]);
        } else {
            *z_out = 0.0;
            *entry = NO_COLOR;
        }
    }
    valid
}

#[cfg(test)]
mod tests;
