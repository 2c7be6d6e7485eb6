//! Synthetic Kinect-like captures with ground truth: a scene of primitives (capsules for
//! branches, spheres, discs for markers, a ground plane, sky) ray-cast through the calibrated
//! depth and colour cameras, with the sensor's artefacts: depth noise growing with distance,
//! flying pixels at depth edges, dropped pixels, the working range, colour noise. Seeded:
//! the same scene, config and seed give the same frame bit for bit.
//!
//! Later stages test against it end to end: [`render`] returns the true 3D position of each
//! marker and its true pixel in both cameras.

mod demo;
mod raycast;

pub use demo::{MARKER_RADIUS_M, MARKER_RGB, demo_tree};
use image::RgbImage;
use nalgebra::{Isometry3, Point2, Point3, Translation3, Vector3};
use rand_xoshiro::rand_core::{RngCore, SeedableRng};
use raycast::*;

use crate::calibration::{Calibration, RegistrationModel, camera_to_world_z_up};
use crate::camera::CameraModel;
use crate::depth::DepthImage;
use crate::error::{KinectError, Result};

/// Kinect V2 working range, nearest depth (Microsoft Kinect for Windows v2 specification).
pub const KINECT_V2_MIN_DEPTH_M: f64 = 0.5;
/// Kinect V2 working range, furthest depth.
pub const KINECT_V2_MAX_DEPTH_M: f64 = 4.5;
/// Axial noise model of the Kinect V2 (Fankhauser et al. 2015, "Kinect v2 for mobile robot
/// navigation: evaluation and modeling", ICAR; angle term omitted):
/// sigma(z) = 1.5 - 0.5 z + 0.3 z² millimetres, z in metres.
const NOISE_MM: [f64; 3] = [1.5, -0.5, 0.3];
/// Depth jump between neighbouring pixels above which a pixel is at a depth edge (metres).
const EDGE_JUMP_M: f64 = 0.05;
/// Ambient share of the Lambert shading of the colour image.
const AMBIENT: f64 = 0.35;

/// A shape of the scene, in the world frame (metres, Z up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// A cylinder with hemispherical ends around the segment `a`–`b` (a branch).
    Capsule {
        /// One end of the axis.
        a: Point3<f64>,
        /// The other end of the axis.
        b: Point3<f64>,
        /// Radius in metres.
        radius_m: f64,
    },
    /// A sphere.
    Sphere {
        /// Centre.
        center: Point3<f64>,
        /// Radius in metres.
        radius_m: f64,
    },
    /// A flat disc, visible from both sides (a pasted marker).
    Disc {
        /// Centre.
        center: Point3<f64>,
        /// Normal (any length but zero).
        normal: Vector3<f64>,
        /// Radius in metres.
        radius_m: f64,
    },
}

/// A coloured shape.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Primitive {
    /// Geometry.
    pub shape: Shape,
    /// Surface colour.
    pub rgb: [u8; 3],
}

/// A marker: a disc whose true centre is reported by [`render`].
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    /// Name (the paper's A..J).
    pub id: String,
    /// Centre in the world frame.
    pub center_m: Point3<f64>,
    /// Normal of the disc (facing the camera).
    pub normal: Vector3<f64>,
    /// Radius in metres (the paper's markers are about 3 cm wide).
    pub radius_m: f64,
    /// Colour.
    pub rgb: [u8; 3],
}

/// A scene in the world frame (Z up).
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Shapes.
    pub primitives: Vec<Primitive>,
    /// Markers.
    pub markers: Vec<Marker>,
    /// Ground plane `z = height`, with its colour, if any.
    pub ground: Option<(f64, [u8; 3])>,
    /// Colour where a ray hits nothing (depth: no measurement).
    pub sky_rgb: [u8; 3],
    /// Direction towards the light (world frame).
    pub light_direction: Vector3<f64>,
}

/// Sensor artefacts. [`SensorNoise::kinect_v2`] is the default; [`SensorNoise::none`] gives
/// exact depth (quantised to the depth unit) and exact colour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorNoise {
    /// Multiplies the Kinect V2 axial noise sigma (1 = Fankhauser et al. 2015; 0 = none).
    pub depth_noise_scale: f64,
    /// Probability that a pixel at a depth edge becomes a flying pixel (a depth between the
    /// two surfaces). Default 0.5.
    pub flying_pixel_probability: f64,
    /// Probability that any valid pixel is dropped (reads 0). Default 0.002.
    pub dropout_probability: f64,
    /// Standard deviation of the colour noise per channel, in 8-bit levels. Default 2.
    pub color_noise_sigma: f64,
    /// Nearest measurable depth (default 0.5 m).
    pub min_depth_m: f64,
    /// Furthest measurable depth (default 4.5 m).
    pub max_depth_m: f64,
}

impl SensorNoise {
    /// Kinect V2-like artefacts (the defaults documented field by field).
    pub fn kinect_v2() -> Self {
        Self {
            depth_noise_scale: 1.0,
            flying_pixel_probability: 0.5,
            dropout_probability: 0.002,
            color_noise_sigma: 2.0,
            min_depth_m: KINECT_V2_MIN_DEPTH_M,
            max_depth_m: KINECT_V2_MAX_DEPTH_M,
        }
    }

    /// No artefacts (range limits kept).
    pub fn none() -> Self {
        Self {
            depth_noise_scale: 0.0,
            flying_pixel_probability: 0.0,
            dropout_probability: 0.0,
            color_noise_sigma: 0.0,
            ..Self::kinect_v2()
        }
    }

    /// Check the ranges.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] for a probability outside 0..=1, a negative scale or
    /// sigma, or an empty depth range.
    pub fn validate(&self) -> Result<()> {
        for (name, p) in [
            ("flying_pixel_probability", self.flying_pixel_probability),
            ("dropout_probability", self.dropout_probability),
        ] {
            if !(0.0..=1.0).contains(&p) {
                return Err(KinectError::param(name, format!("{p} is not in 0..=1")));
            }
        }
        for (name, v) in [
            ("depth_noise_scale", self.depth_noise_scale),
            ("color_noise_sigma", self.color_noise_sigma),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(KinectError::param(
                    name,
                    format!("{v} must be finite and >= 0"),
                ));
            }
        }
        if !(self.min_depth_m >= 0.0 && self.max_depth_m > self.min_depth_m) {
            return Err(KinectError::param(
                "depth range",
                format!("{} m .. {} m is empty", self.min_depth_m, self.max_depth_m),
            ));
        }
        Ok(())
    }
}

impl Default for SensorNoise {
    fn default() -> Self {
        Self::kinect_v2()
    }
}

/// What to render with.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthConfig {
    /// Cameras and registration (rigid or already registered; not libfreenect2's model).
    pub calibration: Calibration,
    /// Transform from the world frame to the depth camera's frame.
    pub world_to_depth: Isometry3<f64>,
    /// Sensor artefacts.
    pub noise: SensorNoise,
    /// Random seed.
    pub seed: u64,
}

impl SynthConfig {
    /// A Kinect V2 ([`Calibration::kinect_v2`]) level at `camera_height_m`, `distance_m` in
    /// front of the world origin (on the -y side, looking along +y), Kinect V2 noise.
    pub fn kinect_v2(distance_m: f64, camera_height_m: f64, seed: u64) -> Self {
        let camera_to_world =
            Translation3::new(0.0, -distance_m, 0.0) * camera_to_world_z_up(camera_height_m, 0.0);
        Self {
            calibration: Calibration::kinect_v2(),
            world_to_depth: camera_to_world.inverse(),
            noise: SensorNoise::kinect_v2(),
            seed,
        }
    }
}

/// Ground truth of a marker in a rendered frame.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerTruth {
    /// Marker name.
    pub id: String,
    /// Centre in the world frame.
    pub world_m: Point3<f64>,
    /// Centre in the depth camera frame (the frame of the clouds built from this frame).
    pub depth_camera_m: Point3<f64>,
    /// Centre's sub-pixel position on the depth image (may lie off the image).
    pub depth_pixel: Option<Point2<f64>>,
    /// Centre's sub-pixel position on the colour image (may lie off the image).
    pub color_pixel: Option<Point2<f64>>,
    /// True when the depth camera sees the marker's centre (not occluded, on the image).
    pub visible: bool,
}

/// A rendered frame.
#[derive(Debug, Clone)]
pub struct SynthFrame {
    /// Depth image in the calibration's unit.
    pub depth: DepthImage,
    /// Colour image.
    pub color: RgbImage,
    /// Truth per marker, in the scene's order.
    pub markers: Vec<MarkerTruth>,
}

/// SplitMix64 (Steele, Lea, Flood 2014): small, fast, and stable across versions of anything,
/// so a seed gives the same frame forever.
/// `rand_xoshiro`'s, the workspace's one generator.
#[derive(Debug, Clone)]
pub(crate) struct SplitMix64(rand_xoshiro::SplitMix64);

impl SplitMix64 {
    pub(crate) fn new(seed: u64) -> Self {
        Self(rand_xoshiro::SplitMix64::seed_from_u64(seed))
    }

    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in [0, 1).
    pub(crate) fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Standard normal (Box–Muller).
    pub(crate) fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// `v` rounded to the nearest integer in 0..=255 (halves up; `f64::round` is a library call
/// at the baseline x86-64 target and cost a fifth of a frame).
#[inline]
fn to_u8(v: f64) -> u8 {
    (v.clamp(0.0, 255.0) + 0.5) as u8
}

/// Quantiles of the standard normal at the centres of [`NORMAL_TABLE_LEN`] equal-probability
/// bins: a table draw is one of them, picked by 16 random bits (the colour noise needs six
/// million draws per Kinect V2 frame; Box–Muller's log, sqrt and cos cost more than the rest
/// of the frame).
const NORMAL_TABLE_LEN: usize = 1 << 16;

fn normal_table() -> &'static [f64] {
    static TABLE: std::sync::OnceLock<Vec<f64>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        // Invert the CDF, integrated with Simpson's rule on a fine grid over +-8 sigma.
        const STEPS: usize = 1 << 20;
        const SPAN: f64 = 8.0;
        let dx = 2.0 * SPAN / STEPS as f64;
        let pdf = |x: f64| (-0.5 * x * x).exp() / (2.0 * std::f64::consts::PI).sqrt();
        let mut table = Vec::with_capacity(NORMAL_TABLE_LEN);
        let mut cdf = 0.0;
        let mut x = -SPAN;
        for k in 0..NORMAL_TABLE_LEN {
            let target = (k as f64 + 0.5) / NORMAL_TABLE_LEN as f64;
            while x < SPAN {
                let step = dx / 6.0 * (pdf(x) + 4.0 * pdf(x + 0.5 * dx) + pdf(x + dx));
                if cdf + step >= target {
                    // Linear within the step.
                    table.push(x + dx * (target - cdf) / step);
                    break;
                }
                cdf += step;
                x += dx;
            }
            if table.len() <= k {
                table.push(SPAN);
            }
        }
        table
    })
}

/// A renderer for one camera set-up: the rays of both cameras are computed once and reused
/// for every frame (a capture of many frames renders several times faster than calling
/// [`render`] per frame).
#[derive(Debug, Clone)]
pub struct Renderer {
    config: SynthConfig,
    depth_to_color: Isometry3<f64>,
    depth_rays: RayGrid,
    color_rays: RayGrid,
}

impl Renderer {
    /// Check `config` and compute the rays of its cameras.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] for an invalid calibration or noise config, or a
    /// libfreenect2 calibration (not rendered: give the equivalent rigid calibration).
    pub fn new(config: &SynthConfig) -> Result<Self> {
        let cal = &config.calibration;
        cal.validate()?;
        config.noise.validate()?;
        let depth_to_color = match cal.registration {
            RegistrationModel::Freenect2 { .. } => {
                return Err(KinectError::param(
                    "synth calibration",
                    "libfreenect2's polynomial model cannot be ray-cast; use a rigid calibration",
                ));
            }
            _ => cal.depth_to_color()?.unwrap_or_else(Isometry3::identity),
        };
        Ok(Self {
            config: config.clone(),
            depth_to_color,
            depth_rays: RayGrid::new(&cal.depth_camera),
            color_rays: RayGrid::new(&cal.color_camera),
        })
    }

    /// The configuration (its `seed` is the default of [`render`]).
    pub fn config(&self) -> &SynthConfig {
        &self.config
    }

    /// Render one frame of `scene` with noise seeded by `seed`.
    ///
    /// # Errors
    /// [`KinectError::InvalidParameter`] for an invalid shape (non-positive radius, zero
    /// normal, ground height not finite).
    pub fn render(&self, scene: &Scene, seed: u64) -> Result<SynthFrame> {
        let config = &self.config;
        let cal = &config.calibration;
        let depth_to_color = self.depth_to_color;
        let light = scene
            .light_direction
            .try_normalize(1e-12)
            .unwrap_or_else(Vector3::z);
        let world_to_color = depth_to_color * config.world_to_depth;
        let mut rng = SplitMix64::new(seed);

        // Depth camera.
        let dcam = cal.depth_camera;
        let depth_objects = scene_objects(scene, &config.world_to_depth)?;
        let truth_z = raycast(
            &self.depth_rays,
            &depth_objects,
            &(config.world_to_depth * light),
            scene.sky_rgb,
            None,
        );
        let noise = &config.noise;
        let (w, h) = (dcam.width as usize, dcam.height as usize);
        let mut z_m: Vec<f64> = truth_z.iter().map(|z| z.unwrap_or(f64::NAN)).collect();
        flying_pixels(&mut z_m, (w, h), noise, &mut rng);
        let unit = cal.depth_unit_m;
        let raw = quantise_depth(&z_m, cal, noise, &mut rng);
        let depth = DepthImage::new(dcam.width, dcam.height, unit, raw)?;

        // Colour camera.
        let ccam = cal.color_camera;
        let color_objects = scene_objects(scene, &world_to_color)?;
        let mut color = RgbImage::new(ccam.width, ccam.height);
        raycast(
            &self.color_rays,
            &color_objects,
            &(world_to_color * light),
            scene.sky_rgb,
            Some(&mut color),
        );
        if noise.color_noise_sigma > 0.0 {
            let table = normal_table();
            let sigma = noise.color_noise_sigma;
            for chunk in color.chunks_mut(4) {
                let bits = rng.next_u64();
                for (k, c) in chunk.iter_mut().enumerate() {
                    let z = table[((bits >> (16 * k)) & 0xFFFF) as usize];
                    *c = to_u8(f64::from(*c) + sigma * z);
                }
            }
        }

        // Truth.
        let markers = scene
            .markers
            .iter()
            .map(|m| {
                let pd = config.world_to_depth * m.center_m;
                let depth_pixel = dcam.project(&pd);
                let color_pixel = ccam.project(&(depth_to_color * pd));
                let visible = depth_pixel
                    .and_then(|px| dcam.pixel_at(&px))
                    .and_then(|(u, v)| truth_z[v as usize * w + u as usize])
                    .is_some_and(|z| (z - pd.z).abs() < 0.01);
                MarkerTruth {
                    id: m.id.clone(),
                    world_m: m.center_m,
                    depth_camera_m: pd,
                    depth_pixel,
                    color_pixel,
                    visible,
                }
            })
            .collect();
        Ok(SynthFrame {
            depth,
            color,
            markers,
        })
    }
}

/// Flying pixels: with `noise`'s probability, a pixel at a depth edge takes a depth between
/// its own and its farthest neighbour's (the Kinect V2's mixed returns at edges).
fn flying_pixels(
    z_m: &mut [f64],
    (w, h): (usize, usize),
    noise: &SensorNoise,
    rng: &mut SplitMix64,
) {
    if noise.flying_pixel_probability > 0.0 {
        let original = z_m.to_vec();
        for v in 0..h {
            for u in 0..w {
                let i = v * w + u;
                let z = original[i];
                if z.is_nan() {
                    continue;
                }
                let mut far = None::<f64>;
                for (du, dv) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                    let (nu, nv) = (u as i64 + du, v as i64 + dv);
                    if nu < 0 || nv < 0 || nu >= w as i64 || nv >= h as i64 {
                        continue;
                    }
                    let zn = original[nv as usize * w + nu as usize];
                    let zn = if zn.is_nan() { noise.max_depth_m } else { zn };
                    if (zn - z).abs() > EDGE_JUMP_M
                        && far.is_none_or(|f| (zn - z).abs() > (f - z).abs())
                    {
                        far = Some(zn);
                    }
                }
                if let Some(zn) = far
                    && rng.uniform() < noise.flying_pixel_probability
                {
                    let mix = 0.2 + 0.6 * rng.uniform();
                    z_m[i] = z + mix * (zn - z);
                }
            }
        }
    }
}

/// Depth in metres (NaN: no return) to the sensor's raw 16-bit values: axial noise growing
/// with depth, dropouts, the range limits and the depth unit (0: no depth).
fn quantise_depth(
    z_m: &[f64],
    cal: &Calibration,
    noise: &SensorNoise,
    rng: &mut SplitMix64,
) -> Vec<u16> {
    let (w, h) = (
        cal.depth_camera.width as usize,
        cal.depth_camera.height as usize,
    );
    let unit = cal.depth_unit_m;
    let mut raw = vec![0u16; w * h];
    for (i, z) in z_m.iter().enumerate() {
        if z.is_nan() {
            continue;
        }
        let sigma_mm = NOISE_MM[0] + NOISE_MM[1] * z + NOISE_MM[2] * z * z;
        let noisy = z + noise.depth_noise_scale * sigma_mm * 1e-3 * rng.normal();
        if noise.dropout_probability > 0.0 && rng.uniform() < noise.dropout_probability {
            continue;
        }
        if !(noisy >= noise.min_depth_m && noisy <= noise.max_depth_m) {
            continue;
        }
        let value = ((noisy - cal.depth_offset_m) / unit).round();
        if value >= 1.0 && value <= f64::from(u16::MAX) {
            raw[i] = value as u16;
        }
    }
    raw
}

/// Render one frame of `scene` as the configured camera sees it (noise seeded by
/// `config.seed`). For many frames with one set-up, [`Renderer`] computes the rays once.
///
/// # Errors
/// [`KinectError::InvalidParameter`] for an invalid calibration, noise config, or shape
/// (non-positive radius, zero normal), or a libfreenect2 calibration (not rendered: give the
/// equivalent rigid calibration).
pub fn render(scene: &Scene, config: &SynthConfig) -> Result<SynthFrame> {
    Renderer::new(config)?.render(scene, config.seed)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small_config(seed: u64) -> SynthConfig {
        let mut config = SynthConfig::kinect_v2(2.2, 1.1, seed);
        // Quarter-size colour camera keeps unit tests fast.
        config.calibration.color_camera =
            config.calibration.color_camera.scaled(0.25).expect("valid");
        config
    }

    #[test]
    fn tile_culling_matches_casting_every_object() {
        // The demo tree's capsules and markers, the ground, and spheres around and behind the
        // camera (a bound holding the camera must never be culled).
        let mut scene = demo_tree(4);
        let config = SynthConfig::kinect_v2(2.2, 1.1, 4);
        let camera_world = config.world_to_depth.inverse() * Point3::origin();
        scene.primitives.push(Primitive {
            shape: Shape::Sphere {
                center: camera_world + Vector3::new(0.1, 0.0, 0.0),
                radius_m: 0.3,
            },
            rgb: [1, 2, 3],
        });
        scene.primitives.push(Primitive {
            shape: Shape::Sphere {
                center: Point3::new(-1.2, 0.5, 1.9),
                radius_m: 0.05,
            },
            rgb: [4, 5, 6],
        });
        for camera in [
            config.calibration.depth_camera,
            config.calibration.color_camera.scaled(0.25).expect("valid"),
        ] {
            let grid = RayGrid::new(&camera);
            let objects = scene_objects(&scene, &config.world_to_depth).expect("valid");
            let culled = raycast(&grid, &objects, &Vector3::z(), [0, 0, 0], None);
            let mut hits = 0;
            for (i, z) in culled.iter().enumerate() {
                let brute = grid.rays[i]
                    .and_then(|(d, scale)| cast(&objects, &d).map(|(t, _, _)| t * scale));
                assert_eq!(*z, brute, "pixel {i}");
                hits += usize::from(z.is_some());
            }
            assert!(hits > 0);
        }
    }

    #[test]
    fn normal_table_has_unit_variance_and_symmetric_tails() {
        let t = normal_table();
        assert_eq!(t.len(), NORMAL_TABLE_LEN);
        let n = t.len() as f64;
        let mean = t.iter().sum::<f64>() / n;
        let var = t.iter().map(|x| x * x).sum::<f64>() / n;
        assert!(mean.abs() < 1e-9, "{mean}");
        // Bin centres lose a little of the tails: variance just under 1.
        assert!((var - 1.0).abs() < 2e-3, "{var}");
        assert!(t.windows(2).all(|w| w[0] < w[1]));
        assert!((t[0] + t[t.len() - 1]).abs() < 1e-9);
        // The median bin of the upper half: the quantile at 0.75 is 0.6745.
        assert!((t[3 * NORMAL_TABLE_LEN / 4] - 0.674_49).abs() < 1e-3);
    }

    #[test]
    fn rendering_is_deterministic_per_seed() {
        let scene = demo_tree(1);
        let a = render(&scene, &small_config(5)).expect("valid");
        let b = render(&scene, &small_config(5)).expect("valid");
        let c = render(&scene, &small_config(6)).expect("valid");
        assert_eq!(a.depth, b.depth);
        assert_eq!(a.color, b.color);
        assert_ne!(a.depth, c.depth);
    }

    #[test]
    fn noise_free_depth_matches_the_marker_truth() {
        let scene = demo_tree(1);
        let mut config = small_config(1);
        config.noise = SensorNoise::none();
        let frame = render(&scene, &config).expect("valid");
        let visible: Vec<_> = frame.markers.iter().filter(|m| m.visible).collect();
        assert!(visible.len() >= 8, "{} markers visible", visible.len());
        for m in visible {
            let (u, v) = config
                .calibration
                .depth_camera
                .pixel_at(&m.depth_pixel.expect("in front"))
                .expect("on image");
            let z = frame.depth.depth_m(u, v).expect("depth on a marker");
            // Within the disc's tilt over half a pixel plus the 1 mm quantisation.
            assert!(
                (z - m.depth_camera_m.z).abs() < 0.004,
                "{} {z} vs {}",
                m.id,
                m.depth_camera_m.z
            );
            // And the colour camera sees red there.
            let cp = m.color_pixel.expect("in front");
            let px = frame
                .color
                .get_pixel(cp.x.round() as u32, cp.y.round() as u32);
            assert!(px.0[0] > 150 && px.0[1] < 60, "{} colour {:?}", m.id, px.0);
        }
    }

    #[test]
    fn sky_has_no_depth_and_range_is_enforced() {
        let scene = demo_tree(1);
        let frame = render(&scene, &small_config(2)).expect("valid");
        // The top row looks at the sky.
        assert_eq!(frame.depth.get(5, 0), Some(0));
        assert!(
            frame
                .depth
                .values()
                .iter()
                .all(|&d| d == 0 || (500..=4500).contains(&d))
        );
    }

    #[test]
    fn bad_shapes_are_errors() {
        let mut scene = demo_tree(1);
        scene.primitives.push(Primitive {
            shape: Shape::Sphere {
                center: Point3::origin(),
                radius_m: -1.0,
            },
            rgb: [0, 0, 0],
        });
        assert!(render(&scene, &small_config(1)).is_err());
    }

    #[test]
    fn splitmix_normal_has_unit_variance() {
        let mut rng = SplitMix64::new(42);
        let n = 20_000;
        let samples: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
        let mean = samples.iter().sum::<f64>() / n as f64;
        let var = samples.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        // 5 standard errors of the mean and of the variance.
        assert!(mean.abs() < 5.0 / (n as f64).sqrt(), "{mean}");
        assert!((var - 1.0).abs() < 5.0 * (2.0 / n as f64).sqrt(), "{var}");
    }
}
