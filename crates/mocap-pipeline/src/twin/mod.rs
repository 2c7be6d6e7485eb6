//! The digital twin of a capture: a procedural tree whose every true value is known, its
//! per-branch dynamics, red markers on a chain of branches of levels 1–3 under each of a few
//! limbs, a pull-and-release simulated with beam-anim, and the scene of every frame for
//! kinect-io's `synth` renderer.
//!
//! Behind the feature `twin`. Errors are [`PipelineError::Twin`] with the reason.

use std::collections::BTreeMap;
use std::f64::consts::PI;

use beam_anim::{AnimConfig, BeamTree, Dynamics, GREEN_WOOD_DENSITY_KG_M3, SEGMENTS, Simulation};
use kinect_io::synth::{
    MARKER_RGB, Marker, Primitive, Renderer, Scene, SensorNoise, Shape, SynthConfig,
};
use nalgebra::{Point2, Point3, UnitQuaternion, Vector3};
use space_colonize::{Skeleton, SkeletonNode};

use crate::capture::RawFrame;

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
        let checks = [
            ("fps_hz", config.fps_hz, 5.0, 240.0),
            ("decay_s[0]", config.decay_s[0], 1.0, 120.0),
            ("decay_s[1]", config.decay_s[1], 1.0, 120.0),
            ("decay_s[2]", config.decay_s[2], 1.0, 120.0),
            ("distance_m", config.distance_m, 1.0, 4.0),
            ("camera_height_m", config.camera_height_m, 0.2, 2.0),
            ("marker_radius_m", config.marker_radius_m, 0.003, 0.05),
            ("noise_scale", config.noise_scale, 0.0, 10.0),
            ("window_error_px", config.window_error_px, 0.0, 20.0),
            ("color_scale", config.color_scale, 0.1, 1.0),
        ];
        for (name, v, lo, hi) in checks {
            if !(v.is_finite() && (lo..=hi).contains(&v)) {
                return Err(format!("twin {name} = {v}: must lie in {lo}..={hi}"));
            }
        }
        if !(1..=4).contains(&config.chains) {
            return Err(format!(
                "twin chains = {}: must lie in 1..=4",
                config.chains
            ));
        }
        let skeleton = tree(config.seed)?;
        let beam = BeamTree::with_density(&skeleton, GREEN_WOOD_DENSITY_KG_M3, &Vector3::x())
            .map_err(|e| format!("twin beams: {e}"))?;
        let branches = beam.branches();
        let dynamics: Vec<Dynamics> = branches
            .iter()
            .enumerate()
            .map(|(i, b)| true_dynamics(b.order, config.seed, i as u64))
            .collect();

        let mut synth =
            SynthConfig::kinect_v2(config.distance_m, config.camera_height_m, config.seed);
        synth.calibration.color_camera = synth
            .calibration
            .color_camera
            .scaled(config.color_scale)
            .map_err(|e| format!("twin colour camera: {e}"))?;
        let s = config.noise_scale;
        let kinect = SensorNoise::kinect_v2();
        synth.noise = SensorNoise {
            depth_noise_scale: kinect.depth_noise_scale * s,
            flying_pixel_probability: (kinect.flying_pixel_probability * s).min(1.0),
            dropout_probability: (kinect.dropout_probability * s).min(1.0),
            color_noise_sigma: kinect.color_noise_sigma * s,
            ..kinect
        };
        let camera_world = synth.world_to_depth.inverse() * Point3::origin();

        // Every skeleton node rides on the beam segment that holds it: its branch's segment
        // by arc length along the branch (nodes of a curved branch lie off the segment's
        // chord; they move rigidly with it).
        let mut node_segment = vec![0usize; skeleton.nodes().len()];
        let mut node_arc = vec![0.0f64; skeleton.nodes().len()];
        for sb in skeleton.branches() {
            let i = beam
                .index_of(sb.id)
                .map_err(|e| format!("twin beams: {e}"))?;
            let mut last = sb
                .base_node
                .map_or(skeleton.nodes()[sb.nodes[0]].position, |n| {
                    skeleton.nodes()[n].position
                });
            let mut arc = 0.0;
            for &n in &sb.nodes {
                let p = skeleton.nodes()[n].position;
                arc += (p - last).norm();
                last = p;
                node_arc[n] = arc;
            }
            for &n in &sb.nodes {
                let frac = node_arc[n] / arc.max(1e-12);
                // A node at a segment's end belongs to that segment (its edge lies in it).
                let s =
                    ((frac * SEGMENTS as f64 - 1e-9).floor().max(0.0) as usize).min(SEGMENTS - 1);
                node_segment[n] = i * SEGMENTS + s;
            }
        }
        // A marker sits on the camera side of its branch 80 % along (the trunk's at 0.4 m):
        // far enough out to swing, and its parent-to-child chord long beside the noise.
        let nodes = skeleton.nodes();
        let sk_branches = skeleton.branches();
        let marker_at = |branch: usize| -> Result<Place, String> {
            let chain = &sk_branches
                .iter()
                .find(|sb| sb.id == branches[branch].id)
                .ok_or("twin: a beam without its skeleton branch")?
                .nodes;
            let total = chain.last().map_or(0.0, |&n| node_arc[n]);
            let along = |n: usize| {
                if branch == 0 {
                    (nodes[n].position.z - ROOT_MARKER_HEIGHT_M).abs()
                } else {
                    (node_arc[n] - MARKER_ALONG * total).abs()
                }
            };
            let node = *chain
                .iter()
                .min_by(|&&a, &&b| along(a).total_cmp(&along(b)))
                .ok_or("twin: empty branch")?;
            let p = nodes[node].position;
            let axis = match nodes[node].parent {
                Some(q) => (p - nodes[q].position).normalize(),
                None => Vector3::z(),
            };
            let toward = camera_world - p;
            let n = (toward - axis * axis.dot(&toward)).normalize();
            // Clear the edges meeting at the node (the thicker one is the parent's side).
            let r = nodes[node]
                .radius_m
                .max(nodes[nodes[node].parent.unwrap_or(node)].radius_m);
            let segment = node_segment[node];
            let start = beam.segment_start(segment);
            Ok((segment, p - start + n * (r + MARKER_STANDOFF_M), n))
        };

        // Only the rest pose is read from the probe: a millisecond step is short enough for
        // any branch frequency (the simulation refuses one above its Nyquist frequency).
        let mut probe = Simulation::new(beam.clone(), &dynamics, AnimConfig::default(), 1e-3)
            .map_err(|e| format!("twin simulation: {e}"))?;
        let rest = probe.segment_frames();
        let at = |frames: &[(UnitQuaternion<f64>, Point3<f64>)], place: &Place| {
            frames[place.0].1 + frames[place.0].0 * place.1
        };
        // Marked chains (a limb, one of its level-2 branches, one of that branch's twigs),
        // chosen as a field crew would: markers well apart, swinging across the view.
        let children = |p: usize| -> Vec<usize> {
            (0..branches.len())
                .filter(|&i| branches[i].parent == Some(p))
                .collect()
        };
        let root_place = marker_at(0)?;
        // The camera's viewing direction in the tree frame.
        let view = synth.world_to_depth.inverse_transform_vector(&Vector3::z());
        let mut candidates: Vec<(f64, [usize; 3])> = Vec::new();
        for l1 in children(0) {
            for l2 in children(l1) {
                for l3 in children(l2) {
                    let chain = [l1, l2, l3];
                    let mut places = vec![root_place];
                    for &b in &chain {
                        places.push(marker_at(b)?);
                    }
                    // Shortest parent-to-child marker distance: a short one makes a noisy
                    // angle, and markers side by side confuse trackers.
                    let mut score = places
                        .windows(2)
                        .map(|w| (at(&rest, &w[1]) - at(&rest, &w[0])).norm())
                        .fold(f64::INFINITY, f64::min);
                    // A swing toward the camera shows only in the depth (the noisiest axis):
                    // weigh by the share of each marker's swing across the view.
                    for (k, &b) in chain.iter().enumerate() {
                        let id = branches[b].id;
                        probe
                            .pull(id, PROBE_RAD)
                            .map_err(|e| format!("twin pull: {e}"))?;
                        let d =
                            at(&probe.segment_frames(), &places[k + 1]) - at(&rest, &places[k + 1]);
                        probe.pull(id, 0.0).map_err(|e| format!("twin pull: {e}"))?;
                        let across = (d - view * view.dot(&d)).norm() / d.norm().max(1e-12);
                        score *= across;
                    }
                    if score.is_finite() {
                        candidates.push((score, chain));
                    }
                }
            }
        }
        candidates.sort_by(|a, b| b.0.total_cmp(&a.0));

        // Markers apart on the image too (a tracker's window holds one marker): at least
        // MIN_MARKER_GAP_PX depth pixels between any two.
        let dcam = synth.calibration.depth_camera;
        let pixel = |place: &Place| dcam.project(&(synth.world_to_depth * at(&rest, place)));
        let mut taken: Vec<Point2<f64>> = pixel(&root_place).into_iter().collect();
        let mut chains: Vec<[usize; 3]> = Vec::new();
        for (_, chain) in &candidates {
            if chains.len() >= config.chains || chains.iter().any(|c| c[0] == chain[0]) {
                continue;
            }
            let mut px = Vec::new();
            for &b in chain {
                px.extend(pixel(&marker_at(b)?));
            }
            let apart = |a: &Point2<f64>, b: &Point2<f64>| (a - b).norm() >= MIN_MARKER_GAP_PX;
            let clear = px.len() == chain.len()
                && px.iter().all(|p| taken.iter().all(|q| apart(p, q)))
                && px
                    .iter()
                    .enumerate()
                    .all(|(i, p)| px[..i].iter().all(|q| apart(p, q)));
            if clear {
                taken.extend(px);
                chains.push(*chain);
            }
        }
        if chains.len() < config.chains {
            return Err(format!(
                "twin tree has {} limbs with a marked chain, {} asked for",
                chains.len(),
                config.chains
            ));
        }
        // The pull of a marked branch: as far as makes its marker swing by the level's angle
        // about its parent's marker (a crew pulls until the swing is plain to see).
        let places_of = |chain: &[usize; 3], level: usize| -> Result<[Place; 2], String> {
            let parent = if level == 0 {
                root_place
            } else {
                marker_at(chain[level - 1])?
            };
            Ok([parent, marker_at(chain[level])?])
        };
        let mut swing_pull = |branch: usize, places: &[Place; 2]| -> Result<f64, String> {
            let id = branches[branch].id;
            probe
                .pull(id, PROBE_RAD)
                .map_err(|e| format!("twin pull: {e}"))?;
            let moved = probe.segment_frames();
            probe.pull(id, 0.0).map_err(|e| format!("twin pull: {e}"))?;
            let parent = at(&rest, &places[0]);
            let before = at(&rest, &places[1]) - parent;
            let after = at(&moved, &places[1]) - parent;
            let swing = before.cross(&after).norm().atan2(before.dot(&after));
            if swing.is_nan() || swing <= 0.0 {
                return Err(format!("twin branch {id} does not swing when pulled"));
            }
            Ok((PROBE_RAD * swing_target_rad(branches[branch].order) / swing).min(MAX_PULL_RAD))
        };
        let mut markers = Vec::new();
        let (segment, offset_m, normal) = root_place;
        markers.push(TwinMarker {
            id: marker_name(0),
            parent: None,
            level: 0,
            branch: 0,
            segment,
            offset_m,
            normal,
            truth: dynamics[0],
            pull_rad: 0.0,
            pull_s: (0.0, 0.0),
            release_s: f64::INFINITY,
            window_s: (0.0, 0.0),
        });
        for chain in &chains {
            let mut parent = marker_name(0);
            for (level, &branch) in chain.iter().enumerate() {
                let id = marker_name(markers.len());
                let (segment, offset_m, normal) = marker_at(branch)?;
                markers.push(TwinMarker {
                    id: id.clone(),
                    parent: Some(parent),
                    level: level + 1,
                    branch,
                    segment,
                    offset_m,
                    normal,
                    truth: dynamics[branch],
                    pull_rad: swing_pull(branch, &places_of(chain, level)?)?,
                    pull_s: (0.0, 0.0),
                    release_s: f64::INFINITY,
                    window_s: (0.0, 0.0),
                });
                parent = id;
            }
        }

        // Timeline: one pull-and-release test per level, twigs first (a branch's test ends
        // before its parent's begins, so its relative angle holds its own swing): pull
        // (smooth ramp), hold, release, free decay.
        let mut t = STILL_S;
        for level in (1..=3).rev() {
            let (start, end) = (t, t + PULL_RAMP_S);
            let release = end + HOLD_S;
            let stop = release + config.decay_s[level - 1];
            for m in markers.iter_mut().filter(|m| m.level == level) {
                m.pull_s = (start, end);
                m.release_s = release;
                m.window_s = (end, stop);
            }
            t = stop;
        }
        let frames = (t * config.fps_hz).floor() as usize + 1;
        let dt = 1.0 / config.fps_hz;
        let times_s: Vec<f64> = (0..frames).map(|k| k as f64 * dt).collect();
        let first_release = markers
            .iter()
            .filter(|m| m.level > 0)
            .map(|m| m.release_s)
            .fold(f64::INFINITY, f64::min);
        let mut sim = Simulation::new(beam.clone(), &dynamics, AnimConfig::default(), dt)
            .map_err(|e| format!("twin simulation: {e}"))?;
        let mut scenes = Vec::with_capacity(frames);
        for &t in &times_s {
            if t >= first_release {
                sim.step_free();
            }
            for m in markers.iter().filter(|m| m.level > 0 && t < m.release_s) {
                let ramp = smoothstep((t - m.pull_s.0) / (m.pull_s.1 - m.pull_s.0));
                sim.pull(branches[m.branch].id, m.pull_rad * ramp)
                    .map_err(|e| format!("twin pull: {e}"))?;
            }
            scenes.push(scene(
                &sim,
                &beam,
                &skeleton,
                &node_segment,
                &markers,
                config,
            ));
        }
        let release_s = first_release;
        Ok(Self {
            config: config.clone(),
            skeleton,
            markers,
            times_s,
            release_s,
            scenes,
            synth,
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
