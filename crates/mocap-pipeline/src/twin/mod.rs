//! The digital twin of a capture: a procedural tree whose every true value is known, its
//! per-branch dynamics, red markers on a chain of branches of levels 1–3 under each of a few
//! limbs, a pull-and-release simulated with beam-anim, and the scene of every frame for
//! kinect-io's `synth` renderer.
//!
//! Behind the feature `twin`. Errors are [`PipelineError::Twin`] with the reason.

use std::collections::BTreeMap;
use std::f64::consts::PI;

use beam_anim::{AnimConfig, BeamTree, Dynamics, Simulation};
use kinect_io::synth::{MARKER_RGB, Marker, Primitive, Renderer, Scene, Shape, SynthConfig};
use nalgebra::{Point2, Point3, UnitQuaternion, Vector3};
use space_colonize::{Skeleton, SkeletonNode};

use crate::capture::RawFrame;
use build::{Parts, check};

mod build;
mod run;
use crate::error::{PipelineError, Result};
pub use run::{TRACK_TOLERANCE_PX, TWIN_JPEG_QUALITY};

/// A twin failure as the pipeline's error.
pub(crate) fn twin_error(reason: String) -> PipelineError {
    PipelineError::Twin { reason }
}

/// The paper's dominant frequency (Table 1: more than 85 % of the branches at 1.46 Hz).
pub const SHARED_FREQUENCY_HZ: f64 = 1.46;
/// Bark colour (a brown in the range of the paper's Fig. 1).
const BARK_RGB: [u8; 3] = [112, 82, 58];
/// Grass under the tree.
const GRASS_RGB: [u8; 3] = [86, 118, 62];
/// Overcast sky.
const SKY_RGB: [u8; 3] = [172, 200, 232];
/// Still tree before the first pull, seconds.
const STILL_S: f64 = 0.3;
/// Ramp of a pull, seconds.
const PULL_RAMP_S: f64 = 0.7;
/// Hold of a pull before the release, seconds.
const HOLD_S: f64 = 1.0;
/// Node spacing along the procedural branches, metres.
const NODE_STEP_M: f64 = 0.05;
/// Where a branch's marker sits, as a share of the branch's length from its base.
const MARKER_ALONG: f64 = 0.8;
/// Fewest depth pixels between two markers' centres (about 7 cm at 2.2 m).
const MIN_MARKER_GAP_PX: f64 = 12.0;
/// Height of the trunk's marker, metres.
const ROOT_MARKER_HEIGHT_M: f64 = 0.4;
/// Gap between a marker disc and the bark it is pasted on, metres.
const MARKER_STANDOFF_M: f64 = 0.002;

/// What twin to build and how to film it.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinConfig {
    /// Seed of the tree's shape, its dynamics, the user's windows and the sensor noise.
    pub seed: u64,
    /// Frame rate, hertz (Kinect V2: 30).
    pub fps_hz: f64,
    /// Free decay after each level's release, seconds (levels 1, 2, 3); the recording holds
    /// the three tests one after the other.
    pub decay_s: [f64; 3],
    /// Camera distance from the trunk, metres.
    pub distance_m: f64,
    /// Camera height, metres.
    pub camera_height_m: f64,
    /// Marker radius, metres (the paper's markers are about 3 cm wide).
    pub marker_radius_m: f64,
    /// Scale of the Kinect V2 sensor noise (depth noise, flying pixels, dropouts, colour
    /// noise): 1 is the sensor, 0 exact.
    pub noise_scale: f64,
    /// Limbs (level-1 branches) with a marked chain of levels 1–3 (up to 4).
    pub chains: usize,
    /// Standard deviation of the user's error placing a window centre, colour pixels.
    pub window_error_px: f64,
    /// Scale of the colour camera (1: the Kinect V2's 1920x1080).
    pub color_scale: f64,
}

impl Default for TwinConfig {
    fn default() -> Self {
        Self {
            seed: 7,
            fps_hz: 30.0,
            decay_s: [6.0, 4.0, 3.0],
            distance_m: 2.2,
            camera_height_m: 1.0,
            marker_radius_m: 0.015,
            noise_scale: 1.0,
            chains: 3,
            window_error_px: 1.5,
            color_scale: 1.0,
        }
    }
}

/// One marker of the twin.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinMarker {
    /// Marker name (the paper's A, B, ...).
    pub id: String,
    /// Parent marker (`None` for the trunk's).
    pub parent: Option<String>,
    /// Level: 0 for the trunk, 1..=3 for the branches.
    pub level: usize,
    /// Index of the branch in the beam tree.
    pub branch: usize,
    /// Global index of the beam segment the marker sits on (at its start).
    pub segment: usize,
    /// Rest offset of the disc centre from the segment's start, metres.
    pub offset_m: Vector3<f64>,
    /// Rest normal of the disc (towards the camera).
    pub normal: Vector3<f64>,
    /// True dynamics of its branch.
    pub truth: Dynamics,
    /// Pull angle of its branch, radians (0 for the trunk).
    pub pull_rad: f64,
    /// Start and end of the pull's ramp, seconds.
    pub pull_s: (f64, f64),
    /// Time of the release, seconds.
    pub release_s: f64,
    /// The branch's test: from the end of the pull to the start of the next test, seconds.
    pub window_s: (f64, f64),
}

/// A built twin: the true tree, its markers, and the pose of every frame.
pub struct Twin {
    /// The configuration it was built from.
    pub config: TwinConfig,
    /// The true skeleton (tree frame, Z up, metres).
    pub skeleton: Skeleton,
    /// The markers, trunk first, parents before children.
    pub markers: Vec<TwinMarker>,
    /// Frame times, seconds.
    pub times_s: Vec<f64>,
    /// Time of the first release, seconds.
    pub release_s: f64,
    /// The scene of every frame.
    pub scenes: Vec<Scene>,
    /// Camera set-up.
    pub synth: SynthConfig,
}

/// Where a marker sits: global beam segment, rest offset from the segment's start, normal.
type Place = (usize, Vector3<f64>, Vector3<f64>);

/// A uniform number in [0, 1) from a seed and a stream position (SplitMix64 finaliser).
pub fn unit(seed: u64, k: u64) -> f64 {
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(k.wrapping_mul(0xD1B5_4A32_D192_ED03));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// A standard normal number from a seed and a stream position (Box–Muller).
pub fn normal(seed: u64, k: u64) -> f64 {
    let u1 = 1.0 - unit(seed, 2 * k);
    let u2 = unit(seed, 2 * k + 1);
    (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
}

/// Smooth step from 0 to 1 over [0, 1].
fn smoothstep(u: f64) -> f64 {
    let u = u.clamp(0.0, 1.0);
    u * u * (3.0 - 2.0 * u)
}

struct Builder {
    nodes: Vec<SkeletonNode>,
}

impl Builder {
    /// A straight branch from node `from` along `direction` for `length_m`, radius tapering
    /// from `r0` to `r1`; returns its node ids (not including `from`).
    fn branch(
        &mut self,
        from: usize,
        direction: Vector3<f64>,
        length_m: f64,
        r0: f64,
        r1: f64,
    ) -> Vec<usize> {
        let d = direction.normalize();
        let steps = (length_m / NODE_STEP_M).ceil().max(2.0) as usize;
        let start = self.nodes[from].position;
        let mut ids = Vec::with_capacity(steps);
        let mut parent = from;
        for k in 1..=steps {
            let s = k as f64 / steps as f64;
            let id = self.nodes.len();
            self.nodes.push(SkeletonNode {
                id,
                parent: Some(parent),
                position: start + d * (length_m * s),
                radius_m: r0 + (r1 - r0) * s,
            });
            ids.push(id);
            parent = id;
        }
        ids
    }
}

/// Unit direction at `elevation` from the vertical toward azimuth `azimuth` (from +x, in the
/// x–y plane), radians.
fn direction(elevation: f64, azimuth: f64) -> Vector3<f64> {
    Vector3::new(
        elevation.sin() * azimuth.cos(),
        elevation.sin() * azimuth.sin(),
        elevation.cos(),
    )
}

/// The procedural tree: a 1.3 m trunk, five limbs alternating left and right in a crown
/// spread across the camera's view, two level-2 branches per limb and two level-3 twigs per
/// level-2 branch.
fn tree(seed: u64) -> Result<Skeleton, String> {
    let mut b = Builder {
        nodes: vec![SkeletonNode {
            id: 0,
            parent: None,
            position: Point3::origin(),
            radius_m: 0.035,
        }],
    };
    let jitter = |k: u64, span: f64| span * (2.0 * unit(seed, k) - 1.0);
    let trunk = b.branch(0, Vector3::new(0.0, 0.0, 1.0), 1.3, 0.035, 0.018);
    let mut k = 100;
    for (l, height_frac) in [0.36, 0.48, 0.6, 0.72, 0.84].into_iter().enumerate() {
        let at = trunk[((trunk.len() as f64 * height_frac) as usize).min(trunk.len() - 1)];
        let side = if l % 2 == 0 { 0.0 } else { PI };
        // Limbs lean 45–60 degrees from the vertical, within 25 degrees of the image plane.
        let limb_dir = direction(
            (50.0 + jitter(k, 8.0)).to_radians(),
            side + jitter(k + 1, 25.0).to_radians(),
        );
        k += 2;
        let limb_len = 0.62 + jitter(k, 0.08);
        let limb = b.branch(at, limb_dir, limb_len, 0.017, 0.009);
        for (m, frac) in [0.45, 0.75].into_iter().enumerate() {
            let at2 = limb[((limb.len() as f64 * frac) as usize).min(limb.len() - 1)];
            // Level 2 leaves its limb 30–45 degrees up or down within the crown.
            let turn = if m == 0 { 1.0 } else { -1.0 } * (38.0 + jitter(k + 1, 7.0)).to_radians();
            k += 2;
            let side_axis = Vector3::new(0.0, 1.0, 0.0);
            let d2 = nalgebra_rotate(&limb_dir, &side_axis, turn)
                + Vector3::new(0.0, jitter(k, 0.25), 0.0);
            k += 1;
            let len2 = 0.34 + jitter(k, 0.05);
            k += 1;
            let l2 = b.branch(at2, d2, len2, 0.009, 0.006);
            let twigs = 2;
            for t in 0..twigs {
                let at3 =
                    l2[((l2.len() as f64 * (0.5 + 0.25 * t as f64)) as usize).min(l2.len() - 1)];
                let turn3 = if t == 0 { -1.0 } else { 1.0 } * (35.0 + jitter(k, 8.0)).to_radians();
                k += 1;
                let d3 = nalgebra_rotate(&d2.normalize(), &side_axis, turn3)
                    + Vector3::new(0.0, jitter(k, 0.2), 0.0);
                k += 1;
                let len3 = 0.2 + jitter(k, 0.03);
                k += 1;
                b.branch(at3, d3, len3, 0.0055, 0.004);
            }
        }
    }
    Skeleton::new(b.nodes).map_err(|e| format!("twin tree: {e}"))
}

/// `v` rotated by `angle` about unit `axis` (Rodrigues).
fn nalgebra_rotate(v: &Vector3<f64>, axis: &Vector3<f64>, angle: f64) -> Vector3<f64> {
    let (s, c) = angle.sin_cos();
    v * c + axis.cross(v) * s + axis * axis.dot(v) * (1.0 - c)
}

/// True dynamics of a branch of `order`: level 1 shares the dominant frequency (within
/// 3 %), higher levels are stiffer for their mass (about 1.25x and 1.5x the dominant
/// frequency) and more damped (xi 0.06–0.09, 0.08–0.11, 0.10–0.13: inside the paper's
/// 0.07–0.24, rising with level).
fn true_dynamics(order: usize, seed: u64, k: u64) -> Dynamics {
    let u = unit(seed, 10_000 + 2 * k);
    let v = unit(seed, 10_001 + 2 * k);
    let (ratio, spread, xi_lo, xi_hi) = match order {
        0 => (1.0, 0.0, 0.05, 0.05),
        1 => (1.0, 0.03, 0.06, 0.09),
        2 => (1.25, 0.08, 0.08, 0.11),
        _ => (1.5, 0.08, 0.10, 0.13),
    };
    Dynamics {
        frequency_hz: SHARED_FREQUENCY_HZ * ratio * (1.0 + spread * (2.0 * u - 1.0)),
        damping_ratio: xi_lo + (xi_hi - xi_lo) * v,
    }
}

/// Swing of a marked branch's marker about its parent's marker at the pull, radians: large
/// beside the tracking noise (about 0.5 degrees on a 30 cm branch at 2 m).
fn swing_target_rad(level: usize) -> f64 {
    f64::to_radians(match level {
        1 => 5.0,
        2 => 8.0,
        _ => 12.0,
    })
}

/// Largest pull, radians of bending.
const MAX_PULL_RAD: f64 = 1.0;

/// Bending angle of the probe pull that calibrates each branch's pull, radians.
const PROBE_RAD: f64 = 0.05;

/// Where marker `m` is in the current pose of `sim`.
fn marker_position(frames: &[(UnitQuaternion<f64>, Point3<f64>)], m: &TwinMarker) -> Point3<f64> {
    let (rot, start) = frames[m.segment];
    start + rot * m.offset_m
}

/// Marker names in the paper's style: A, B, ..., Z, A2, B2, ...
pub fn marker_name(k: usize) -> String {
    let letter = char::from(b'A' + (k % 26) as u8);
    if k < 26 {
        letter.to_string()
    } else {
        format!("{letter}{}", k / 26 + 1)
    }
}

impl Twin {
    /// Build the tree, its dynamics and markers, and simulate the pull and release.
    ///
    /// # Errors
    /// A message when a configuration value cannot work or a library call fails.
    pub fn build(config: &TwinConfig) -> Result<Self> {
        Self::build_inner(config).map_err(twin_error)
    }

    fn build_inner(config: &TwinConfig) -> Result<Self, String> {
        check(config)?;
        let parts = Parts::new(config)?;
        // Only the rest pose is read from the probe: a millisecond step is short enough for
        // any branch frequency (the simulation refuses one above its Nyquist frequency).
        let mut probe = Simulation::new(
            parts.beam.clone(),
            &parts.dynamics,
            AnimConfig::default(),
            1e-3,
        )
        .map_err(|e| format!("twin simulation: {e}"))?;
        let rest = probe.segment_frames();
        let chains = parts.choose_chains(&mut probe, &rest, config.chains)?;
        let mut markers = parts.markers(&chains, &mut probe, &rest)?;
        let (times_s, release_s, scenes) = parts.film(&mut markers, config)?;
        Ok(Self {
            config: config.clone(),
            skeleton: parts.skeleton,
            markers,
            times_s,
            release_s,
            scenes,
            synth: parts.synth,
        })
    }

    /// The user's first-frame windows: each marker's true centre on the colour image with
    /// a placement error, a square about 1.4 marker diameters wide, on the plane of
    /// `renderer`'s colour camera scaled by `plane_scale`.
    ///
    /// # Errors
    /// [`PipelineError::Twin`] when the first frame cannot be rendered or a marker is not
    /// visible on it.
    pub fn windows(&self, renderer: &Renderer, plane_scale: f64) -> Result<Vec<Window>> {
        self.windows_inner(renderer, plane_scale)
            .map_err(twin_error)
    }

    fn windows_inner(&self, renderer: &Renderer, plane_scale: f64) -> Result<Vec<Window>, String> {
        let frame = renderer
            .render(&self.scenes[0], self.config.seed)
            .map_err(|e| format!("twin first frame: {e}"))?;
        let ccam = renderer.config().calibration.color_camera;
        let mut out = Vec::with_capacity(self.markers.len());
        for (k, (m, truth)) in self.markers.iter().zip(&frame.markers).enumerate() {
            let Some(c) = truth.color_pixel.filter(|_| truth.visible) else {
                return Err(format!(
                    "twin marker {} is not visible on the first frame",
                    m.id
                ));
            };
            let depth_m = truth.depth_camera_m.coords.norm();
            let diameter_px = 2.0 * self.config.marker_radius_m * ccam.fx / depth_m * plane_scale;
            let size = (1.4 * diameter_px).round().max(5.0) as i32;
            let e = self.config.window_error_px * plane_scale;
            let kk = 50_000 + 2 * k as u64;
            out.push(Window {
                id: m.id.clone(),
                center: Point2::new(
                    c.x * plane_scale + e * normal(self.config.seed, kk),
                    c.y * plane_scale + e * normal(self.config.seed, kk + 1),
                ),
                size_px: size,
            });
        }
        Ok(out)
    }
}

impl Twin {
    /// Frame `i` of the capture, with the sensor noise of its own seed.
    ///
    /// # Errors
    /// A message naming the frame when it cannot be rendered.
    pub fn frame(&self, renderer: &Renderer, i: usize) -> Result<RawFrame> {
        let scene = self.scenes.get(i).ok_or_else(|| {
            twin_error(format!(
                "frame {i}: the twin has {} frames",
                self.scenes.len()
            ))
        })?;
        let seed = self
            .config
            .seed
            .wrapping_mul(1_000_003)
            .wrapping_add(i as u64);
        let frame = renderer
            .render(scene, seed)
            .map_err(|e| PipelineError::frame(i, "render", e))?;
        Ok(RawFrame {
            time_s: self.times_s[i],
            depth: frame.depth,
            color: frame.color,
        })
    }

    /// Each marked branch's test window, seconds.
    pub fn windows_s(&self) -> BTreeMap<String, (f64, f64)> {
        self.markers
            .iter()
            .filter(|m| m.level > 0)
            .map(|m| (m.id.clone(), m.window_s))
            .collect()
    }
}

/// A first-frame window: centre and side, pixels of the tracking plane.
#[derive(Debug, Clone, PartialEq)]
pub struct Window {
    /// Marker name.
    pub id: String,
    /// Centre, pixels.
    pub center: Point2<f64>,
    /// Side of the square, pixels.
    pub size_px: i32,
}

/// The scene of the current pose: a capsule per skeleton edge, each node moved with its beam
/// segment, and the marker discs.
fn scene(
    sim: &Simulation,
    beam: &BeamTree,
    skeleton: &Skeleton,
    node_segment: &[usize],
    markers: &[TwinMarker],
    config: &TwinConfig,
) -> Scene {
    let frames = sim.segment_frames();
    let nodes = skeleton.nodes();
    let moved: Vec<Point3<f64>> = nodes
        .iter()
        .map(|n| {
            let s = node_segment[n.id];
            let (rot, start) = frames[s];
            start + rot * (n.position - beam.segment_start(s))
        })
        .collect();
    let primitives = nodes
        .iter()
        .filter_map(|n| {
            let p = n.parent?;
            Some(Primitive {
                shape: Shape::Capsule {
                    a: moved[p],
                    b: moved[n.id],
                    radius_m: n.radius_m,
                },
                rgb: BARK_RGB,
            })
        })
        .collect();
    let markers = markers
        .iter()
        .map(|m| Marker {
            id: m.id.clone(),
            center_m: marker_position(&frames, m),
            normal: frames[m.segment].0 * m.normal,
            radius_m: config.marker_radius_m,
            rgb: MARKER_RGB,
        })
        .collect();
    Scene {
        primitives,
        markers,
        ground: Some((0.0, GRASS_RGB)),
        sky_rgb: SKY_RGB,
        light_direction: Vector3::new(0.3, -0.6, 1.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn twin_config_that_cannot_work_is_an_error() {
        for bad in [
            TwinConfig {
                fps_hz: 0.0,
                ..TwinConfig::default()
            },
            TwinConfig {
                chains: 0,
                ..TwinConfig::default()
            },
            TwinConfig {
                marker_radius_m: f64::NAN,
                ..TwinConfig::default()
            },
        ] {
            let e = Twin::build(&bad).err().expect("an error").to_string();
            assert!(e.starts_with("digital twin: twin "), "{e}");
        }
    }
}
