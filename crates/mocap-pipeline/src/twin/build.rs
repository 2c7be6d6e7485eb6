//! Building a twin, step by step: the configuration checked, the tree with its beams, true
//! dynamics and camera ([`Parts`]), the marked chains chosen as a field crew would, each
//! marked branch's pull, and the filmed timeline of pull-and-release tests.

use beam_anim::{AnimConfig, BeamTree, Dynamics, GREEN_WOOD_DENSITY_KG_M3, SEGMENTS, Simulation};
use kinect_io::synth::{Scene, SensorNoise, SynthConfig};
use nalgebra::{Point2, Point3, UnitQuaternion, Vector3};
use space_colonize::Skeleton;

use super::{
    HOLD_S, MARKER_ALONG, MARKER_STANDOFF_M, MAX_PULL_RAD, MIN_MARKER_GAP_PX, PROBE_RAD,
    PULL_RAMP_S, Place, ROOT_MARKER_HEIGHT_M, STILL_S, TwinConfig, TwinMarker, marker_name, scene,
    smoothstep, swing_target_rad, tree, true_dynamics,
};

/// Segment poses of a simulation (rotation, start), as `Simulation::segment_frames` gives.
type Frames = [(UnitQuaternion<f64>, Point3<f64>)];

/// Every configuration value in its range.
pub(super) fn check(config: &TwinConfig) -> Result<(), String> {
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
    Ok(())
}

/// The Kinect V2 of the twin: its distance and height, the colour camera scaled, the sensor
/// noise scaled.
fn camera(config: &TwinConfig) -> Result<SynthConfig, String> {
    let mut synth = SynthConfig::kinect_v2(config.distance_m, config.camera_height_m, config.seed);
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
    Ok(synth)
}

/// Every skeleton node rides on the beam segment that holds it: its branch's segment by arc
/// length along the branch (nodes of a curved branch lie off the segment's chord; they move
/// rigidly with it). Returns each node's global segment and its arc length along its branch.
fn node_segments(skeleton: &Skeleton, beam: &BeamTree) -> Result<(Vec<usize>, Vec<f64>), String> {
    let nodes = skeleton.nodes();
    let mut node_segment = vec![0usize; nodes.len()];
    let mut node_arc = vec![0.0f64; nodes.len()];
    for sb in skeleton.branches() {
        let i = beam
            .index_of(sb.id)
            .map_err(|e| format!("twin beams: {e}"))?;
        let mut last = sb
            .base_node
            .map_or(nodes[sb.nodes[0]].position, |n| nodes[n].position);
        let mut arc = 0.0;
        for &n in &sb.nodes {
            let p = nodes[n].position;
            arc += (p - last).norm();
            last = p;
            node_arc[n] = arc;
        }
        for &n in &sb.nodes {
            let frac = node_arc[n] / arc.max(1e-12);
            // A node at a segment's end belongs to that segment (its edge lies in it).
            let s = ((frac * SEGMENTS as f64 - 1e-9).floor().max(0.0) as usize).min(SEGMENTS - 1);
            node_segment[n] = i * SEGMENTS + s;
        }
    }
    Ok((node_segment, node_arc))
}

/// Where a place is in a pose.
fn at(frames: &Frames, place: &Place) -> Point3<f64> {
    frames[place.0].1 + frames[place.0].0 * place.1
}

/// The tree, its beams and true dynamics, the camera, and where each node rides.
pub(super) struct Parts {
    pub(super) skeleton: Skeleton,
    pub(super) beam: BeamTree,
    pub(super) dynamics: Vec<Dynamics>,
    pub(super) synth: SynthConfig,
    node_segment: Vec<usize>,
    node_arc: Vec<f64>,
}

impl Parts {
    pub(super) fn new(config: &TwinConfig) -> Result<Self, String> {
        let skeleton = tree(config.seed)?;
        let beam = BeamTree::with_density(&skeleton, GREEN_WOOD_DENSITY_KG_M3, &Vector3::x())
            .map_err(|e| format!("twin beams: {e}"))?;
        let dynamics = beam
            .branches()
            .iter()
            .enumerate()
            .map(|(i, b)| true_dynamics(b.order, config.seed, i as u64))
            .collect();
        let synth = camera(config)?;
        let (node_segment, node_arc) = node_segments(&skeleton, &beam)?;
        Ok(Self {
            skeleton,
            beam,
            dynamics,
            synth,
            node_segment,
            node_arc,
        })
    }

    /// A marker sits on the camera side of its branch 80 % along (the trunk's at 0.4 m):
    /// far enough out to swing, and its parent-to-child chord long beside the noise.
    fn marker_at(&self, branch: usize) -> Result<Place, String> {
        let nodes = self.skeleton.nodes();
        let id = self.beam.branches()[branch].id;
        let branches = self.skeleton.branches();
        let chain = &branches
            .iter()
            .find(|sb| sb.id == id)
            .ok_or("twin: a beam without its skeleton branch")?
            .nodes;
        let total = chain.last().map_or(0.0, |&n| self.node_arc[n]);
        let along = |n: usize| {
            if branch == 0 {
                (nodes[n].position.z - ROOT_MARKER_HEIGHT_M).abs()
            } else {
                (self.node_arc[n] - MARKER_ALONG * total).abs()
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
        let camera_world = self.synth.world_to_depth.inverse() * Point3::origin();
        let toward = camera_world - p;
        let n = (toward - axis * axis.dot(&toward)).normalize();
        // Clear the edges meeting at the node (the thicker one is the parent's side).
        let r = nodes[node]
            .radius_m
            .max(nodes[nodes[node].parent.unwrap_or(node)].radius_m);
        let segment = self.node_segment[node];
        let start = self.beam.segment_start(segment);
        Ok((segment, p - start + n * (r + MARKER_STANDOFF_M), n))
    }

    fn children(&self, parent: usize) -> Vec<usize> {
        let branches = self.beam.branches();
        (0..branches.len())
            .filter(|&i| branches[i].parent == Some(parent))
            .collect()
    }

    /// How far a marked chain swings across the view: the shortest parent-to-child marker
    /// distance (a short one makes a noisy angle, and markers side by side confuse
    /// trackers), times each marker's share of its swing across the view (a swing toward
    /// the camera shows only in the depth, the noisiest axis).
    fn chain_score(
        &self,
        probe: &mut Simulation,
        rest: &Frames,
        chain: [usize; 3],
    ) -> Result<f64, String> {
        let view = self
            .synth
            .world_to_depth
            .inverse_transform_vector(&Vector3::z());
        let mut places = vec![self.marker_at(0)?];
        for &b in &chain {
            places.push(self.marker_at(b)?);
        }
        let mut score = places
            .windows(2)
            .map(|w| (at(rest, &w[1]) - at(rest, &w[0])).norm())
            .fold(f64::INFINITY, f64::min);
        for (k, &b) in chain.iter().enumerate() {
            let id = self.beam.branches()[b].id;
            probe
                .pull(id, PROBE_RAD)
                .map_err(|e| format!("twin pull: {e}"))?;
            let d = at(&probe.segment_frames(), &places[k + 1]) - at(rest, &places[k + 1]);
            probe.pull(id, 0.0).map_err(|e| format!("twin pull: {e}"))?;
            score *= (d - view * view.dot(&d)).norm() / d.norm().max(1e-12);
        }
        Ok(score)
    }

    /// Marked chains (a limb, one of its level-2 branches, one of that branch's twigs),
    /// chosen as a field crew would: markers well apart and swinging across the view, and
    /// apart on the image too (a tracker's window holds one marker: at least
    /// `MIN_MARKER_GAP_PX` depth pixels between any two).
    pub(super) fn choose_chains(
        &self,
        probe: &mut Simulation,
        rest: &Frames,
        wanted: usize,
    ) -> Result<Vec<[usize; 3]>, String> {
        let mut candidates: Vec<(f64, [usize; 3])> = Vec::new();
        for l1 in self.children(0) {
            for l2 in self.children(l1) {
                for l3 in self.children(l2) {
                    let score = self.chain_score(probe, rest, [l1, l2, l3])?;
                    if score.is_finite() {
                        candidates.push((score, [l1, l2, l3]));
                    }
                }
            }
        }
        candidates.sort_by(|a, b| b.0.total_cmp(&a.0));
        let dcam = self.synth.calibration.depth_camera;
        let pixel = |place: &Place| dcam.project(&(self.synth.world_to_depth * at(rest, place)));
        let mut taken: Vec<Point2<f64>> = pixel(&self.marker_at(0)?).into_iter().collect();
        let mut chains: Vec<[usize; 3]> = Vec::new();
        for (_, chain) in &candidates {
            if chains.len() >= wanted || chains.iter().any(|c| c[0] == chain[0]) {
                continue;
            }
            let mut px = Vec::new();
            for &b in chain {
                px.extend(pixel(&self.marker_at(b)?));
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
        if chains.len() < wanted {
            return Err(format!(
                "twin tree has {} limbs with a marked chain, {wanted} asked for",
                chains.len()
            ));
        }
        Ok(chains)
    }

    /// The pull of a marked branch: as far as makes its marker swing by the level's angle
    /// about its parent's marker (a crew pulls until the swing is plain to see).
    fn swing_pull(
        &self,
        probe: &mut Simulation,
        rest: &Frames,
        branch: usize,
        places: &[Place; 2],
    ) -> Result<f64, String> {
        let b = &self.beam.branches()[branch];
        probe
            .pull(b.id, PROBE_RAD)
            .map_err(|e| format!("twin pull: {e}"))?;
        let moved = probe.segment_frames();
        probe
            .pull(b.id, 0.0)
            .map_err(|e| format!("twin pull: {e}"))?;
        let parent = at(rest, &places[0]);
        let before = at(rest, &places[1]) - parent;
        let after = at(&moved, &places[1]) - parent;
        let swing = before.cross(&after).norm().atan2(before.dot(&after));
        if swing.is_nan() || swing <= 0.0 {
            return Err(format!("twin branch {} does not swing when pulled", b.id));
        }
        Ok((PROBE_RAD * swing_target_rad(b.order) / swing).min(MAX_PULL_RAD))
    }

    /// The trunk's marker, then each chain's markers of levels 1–3 with their pulls.
    pub(super) fn markers(
        &self,
        chains: &[[usize; 3]],
        probe: &mut Simulation,
        rest: &Frames,
    ) -> Result<Vec<TwinMarker>, String> {
        let root_place = self.marker_at(0)?;
        let marker = |id: String, parent, level, branch, place: Place, pull_rad| TwinMarker {
            id,
            parent,
            level,
            branch,
            segment: place.0,
            offset_m: place.1,
            normal: place.2,
            truth: self.dynamics[branch],
            pull_rad,
            pull_s: (0.0, 0.0),
            release_s: f64::INFINITY,
            window_s: (0.0, 0.0),
        };
        let mut markers = vec![marker(marker_name(0), None, 0, 0, root_place, 0.0)];
        for chain in chains {
            let mut parent = (marker_name(0), root_place);
            for (level, &branch) in chain.iter().enumerate() {
                let id = marker_name(markers.len());
                let place = self.marker_at(branch)?;
                let pull = self.swing_pull(probe, rest, branch, &[parent.1, place])?;
                markers.push(marker(
                    id.clone(),
                    Some(parent.0),
                    level + 1,
                    branch,
                    place,
                    pull,
                ));
                parent = (id, place);
            }
        }
        Ok(markers)
    }

    /// The timeline and the film: one pull-and-release test per level, twigs first (a
    /// branch's test ends before its parent's begins, so its relative angle holds its own
    /// swing): pull (smooth ramp), hold, release, free decay; the scene of every frame.
    /// Returns the frame times, the first release and the scenes.
    pub(super) fn film(
        &self,
        markers: &mut [TwinMarker],
        config: &TwinConfig,
    ) -> Result<(Vec<f64>, f64, Vec<Scene>), String> {
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
        let mut sim = Simulation::new(self.beam.clone(), &self.dynamics, AnimConfig::default(), dt)
            .map_err(|e| format!("twin simulation: {e}"))?;
        let branches = self.beam.branches();
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
                &self.beam,
                &self.skeleton,
                &self.node_segment,
                markers,
                config,
            ));
        }
        Ok((times_s, first_release, scenes))
    }
}
