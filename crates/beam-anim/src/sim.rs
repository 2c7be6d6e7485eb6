//! The animation: forces on the segments, one oscillator per branch, bending, poses.

use nalgebra::{Point3, Quaternion, UnitQuaternion, Vector3};
use serde::Serialize;

use crate::error::{AnimError, Result};
use crate::oscillator::{Dynamics, Integrator, Step, step_for};
use crate::rotation::{cross2, qmul2, rotate2, rotation, rotation2};
use crate::tree::{BeamBranch, BeamTree, GREEN_WOOD_DENSITY_KG_M3, SEGMENTS};
use crate::wind::{WindConfig, WindField, drag_on_area_n};

mod pose;

/// How the wind force drives a branch's oscillator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
#[non_exhaustive]
pub enum Forcing {
    /// Two oscillators per branch, driven by the force's u and w components (the paper
    /// decomposes F into (F_u, 0, F_w)). The default.
    #[default]
    Components,
    /// The paper's eq. (7) as written: one oscillator driven by |F|, deflecting along F.
    Magnitude,
}

/// Animation settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnimConfig {
    /// Integrator of eq. (7). Default [`Integrator::ExactZoh`].
    pub integrator: Integrator,
    /// Forcing. Default [`Forcing::Components`].
    pub forcing: Forcing,
    /// Wood density for the branch masses, kg/m³. Default [`GREEN_WOOD_DENSITY_KG_M3`].
    pub wood_density_kg_m3: f64,
    /// The wind (its direction is also every branch's u reference).
    pub wind: WindConfig,
}

impl Default for AnimConfig {
    fn default() -> Self {
        Self {
            integrator: Integrator::ExactZoh,
            forcing: Forcing::Components,
            wood_density_kg_m3: GREEN_WOOD_DENSITY_KG_M3,
            wind: WindConfig::default(),
        }
    }
}

impl AnimConfig {
    /// The paper's choices: explicit Euler (sub-stepped: without it the paper's parameters
    /// diverge at display rates) and |F| forcing.
    pub fn paper() -> Self {
        Self {
            integrator: Integrator::ExplicitEuler,
            forcing: Forcing::Magnitude,
            ..Self::default()
        }
    }
}

/// Per-segment data the frame loop reads (kept small: 56 bytes).
#[derive(Debug, Clone, Copy)]
struct Segment {
    /// Unit rest direction start → end.
    dir: Vector3<f64>,
    length_m: f64,
    /// Bending lever: (l / r⁴)(P4 − M), the moment arm of a tip load per unit stiffness.
    lever: Vector3<f64>,
}

/// Per-branch precomputation and state.
#[derive(Debug, Clone, Copy)]
struct BranchState {
    step: Step,
    /// 1 / mass, 1/kg.
    inv_mass_per_kg: f64,
    /// δ(x̂) = x̂ᵀ K x̂ in the (u, w) basis: tip deflection per unit bending scale.
    k: [[f64; 2]; 2],
    /// The beam's u and w axes (copied from the tree for locality).
    u: Vector3<f64>,
    w: Vector3<f64>,
    /// The bending angle about v × u is scale · (x_u, x_w) · `angle_uw`: with
    /// c = (v × u) × Σ lever, `angle_uw` = (u · c, w · c).
    angle_uw: [f64; 2],
    /// Rest start relative to the start of the parent's attachment segment (the origin
    /// for the trunk).
    base_offset: Vector3<f64>,
    x: [f64; 2],
    vel: [f64; 2],
    /// Magnitude forcing: scalar displacement, velocity, direction in (u, w).
    xs: f64,
    vs: f64,
    dir: [f64; 2],
}

impl BranchState {
    /// Branch `b` at rest with its time `step`, bending stiffness matrix `k` and the sum of
    /// its segments' lever vectors.
    fn at_rest(
        step: Step,
        b: &BeamBranch,
        k: [[f64; 2]; 2],
        lever_sum: Vector3<f64>,
        tree: &BeamTree,
    ) -> Self {
        let c = b.v.cross(&b.u).cross(&lever_sum);
        Self {
            step,
            inv_mass_per_kg: 1.0 / b.mass_kg.max(1e-12),
            k,
            u: b.u,
            w: b.w,
            angle_uw: [b.u.dot(&c), b.w.dot(&c)],
            base_offset: match b.parent_segment {
                Some(ps) => b.points[0] - tree.segment_start(ps),
                None => b.points[0].coords,
            },
            x: [0.0; 2],
            vel: [0.0; 2],
            xs: 0.0,
            vs: 0.0,
            dir: [1.0, 0.0],
        }
    }
}

/// The pose of the tree at one instant.
#[derive(Debug, Clone, PartialEq)]
pub struct Pose {
    /// Time, seconds.
    pub time_s: f64,
    /// Rotation of each segment relative to its parent segment (the joint at its start),
    /// global segment order (branch index × 4 + segment).
    /// (Global rotations and deformed positions: [`Simulation::segment_frames`].)
    pub local: Vec<UnitQuaternion<f64>>,
    /// Each branch's bending angle (rotation of its last segment relative to its base about
    /// v × u, the along-wind bending), radians.
    pub angle_rad: Vec<f64>,
    /// Each branch's displacement (u, w), metres.
    pub displacement_m: Vec<[f64; 2]>,
}

impl Pose {
    /// The tree at rest at time 0: `segments` identity joints, `branches` zero angles and
    /// displacements.
    fn at_rest(segments: usize, branches: usize) -> Self {
        Self {
            time_s: 0.0,
            local: vec![UnitQuaternion::identity(); segments],
            angle_rad: vec![0.0; branches],
            displacement_m: vec![[0.0; 2]; branches],
        }
    }
}

/// What the integrator does to each branch at this frame rate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IntegratorReport {
    /// The integrator.
    pub integrator: Integrator,
    /// Sub-steps per frame.
    pub substeps: usize,
    /// Largest relative error of an effective damping ratio over the branches.
    pub worst_damping_error: f64,
    /// Largest relative error of an effective frequency.
    pub worst_frequency_error: f64,
}

/// A running animation.
pub struct Simulation {
    tree: BeamTree,
    config: AnimConfig,
    dt_s: f64,
    segments: Vec<Segment>,
    /// Rest distance of each segment's midpoint along the wind from the most upstream
    /// point, metres.
    downstream_m: Vec<f64>,
    /// Frontal area of each segment, 2 r l, m².
    area_m2: Vec<f64>,
    parent_segment: Vec<Option<usize>>,
    branches: Vec<BranchState>,
    /// Each branch's attachment frame.
    attach: Vec<Attach>,
    /// Whether branch `i + 1` can be bent together with branch `i` (it does not hang on it).
    pairable: Vec<bool>,
    /// Branches hanging on branch `i`, as (its segment, child branch):
    /// `children[children_at[i]..children_at[i + 1]]`.
    children_at: Vec<usize>,
    children: Vec<(usize, usize)>,
    /// Each branch's wind force in its rest frame (its parent's rotation undone), newtons.
    forces: Vec<Vector3<f64>>,
    dir: Vec<Vector3<f64>>,
    delays: Vec<(usize, f64)>,
    delays_for: (f64, usize),
    pose: Pose,
    report: IntegratorReport,
}

/// Branch `id`'s time step for `dynamics` at `dt_s` with `integrator` (its frequency below
/// the frames' Nyquist frequency, the step stable), its effective errors added to `report`.
fn branch_step(
    id: usize,
    d: &Dynamics,
    integrator: Integrator,
    dt_s: f64,
    report: &mut IntegratorReport,
) -> Result<Step> {
    d.validate(&format!("branch {}", id))?;
    let nyquist_hz = 0.5 / dt_s;
    if d.frequency_hz > nyquist_hz {
        return Err(AnimError::param(
            "dynamics",
            format!(
                "branch {}: {} Hz is above the frame rate's Nyquist frequency ({nyquist_hz} Hz); \
                 frames {dt_s} s apart cannot show it (raise the frame rate or check the dynamics)",
                id, d.frequency_hz
            ),
        ));
    }
    let (step, substeps) =
        step_for(d, integrator, dt_s).map_err(|substeps| AnimError::Unstable {
            branch: id,
            frequency_hz: d.frequency_hz,
            damping_ratio: d.damping_ratio,
            substeps,
            dt_s,
        })?;
    report.substeps = report.substeps.max(substeps);
    if let Some(e) = step.effective(dt_s) {
        report.worst_frequency_error = report
            .worst_frequency_error
            .max((e.frequency_hz / d.frequency_hz - 1.0).abs());
        if d.damping_ratio > 0.0 {
            report.worst_damping_error = report
                .worst_damping_error
                .max((e.damping_ratio / d.damping_ratio - 1.0).abs());
        }
    }
    Ok(step)
}

/// Per branch, the branches hanging on it as (its segment, child branch):
/// `children[children_at[i]..children_at[i + 1]]`.
fn children_of(tree: &BeamTree) -> (Vec<usize>, Vec<(usize, usize)>) {
    let nb = tree.branches().len();
    let mut children_at = vec![0usize; nb + 1];
    for b in tree.branches() {
        if let Some(ps) = b.parent_segment {
            children_at[ps / SEGMENTS + 1] += 1;
        }
    }
    for i in 0..nb {
        children_at[i + 1] += children_at[i];
    }
    let mut children = vec![(0usize, 0usize); children_at[nb]];
    let mut fill = children_at.clone();
    for (bi, b) in tree.branches().iter().enumerate() {
        if let Some(ps) = b.parent_segment {
            children[fill[ps / SEGMENTS]] = (ps % SEGMENTS, bi);
            fill[ps / SEGMENTS] += 1;
        }
    }
    (children_at, children)
}

/// The deformed frame a branch hangs on: its parent's attachment segment's global rotation
/// and start (identity and the origin for the trunk). Written by the parent as the frame
/// loop passes it, read in branch order: no scattered reads of the parent's pose.
#[derive(Debug, Clone, Copy)]
struct Attach {
    rotation: UnitQuaternion<f64>,
    start: Point3<f64>,
}

impl Default for Attach {
    fn default() -> Self {
        Self {
            rotation: UnitQuaternion::identity(),
            start: Point3::origin(),
        }
    }
}

/// Largest pull of [`Simulation::pull`]: a right angle. Past it the branch would fold back
/// on itself, which no beam model describes.
pub const MAX_PULL_RAD: f64 = std::f64::consts::FRAC_PI_2;

/// Bending angle up to which the linear (small-angle) beam model holds to a few per cent
/// (sin 30° = 0.500 against 30° = 0.524 rad: 4.5 %). Beyond it the shapes are not physical:
/// callers report it.
pub const SMALL_ANGLE_LIMIT_RAD: f64 = std::f64::consts::FRAC_PI_6;

/// Most frames one animation may hold (a day at 120 fps).
pub const MAX_FRAMES: usize = 10_000_000;

/// Most memory the poses of one animation may take, bytes (2 GiB).
pub const MAX_POSE_BYTES: f64 = 2.0 * 1024.0 * 1024.0 * 1024.0;

/// Frames for `seconds` at `fps` (at least 1), checked before anything is simulated or
/// allocated: finite positive inputs, at most [`MAX_FRAMES`] frames and at most
/// [`MAX_POSE_BYTES`] of poses for a tree of `segments` segments and `branches` branches.
///
/// # Errors
/// [`AnimError::InvalidParameter`] for a duration or rate that is not positive and finite;
/// [`AnimError::TooLarge`] naming the frames or the bytes and the limit.
pub fn frame_count(seconds: f64, fps: f64, segments: usize, branches: usize) -> Result<usize> {
    for (name, x) in [("seconds", seconds), ("fps", fps)] {
        if !(x.is_finite() && x > 0.0) {
            return Err(AnimError::param(
                name,
                format!("{x}; must be positive and finite"),
            ));
        }
    }
    let frames = (seconds * fps).round().max(1.0);
    if frames > MAX_FRAMES as f64 {
        return Err(AnimError::TooLarge {
            what: format!("{seconds} s at {fps} fps: frames"),
            count: frames,
            limit: MAX_FRAMES as f64,
        });
    }
    let per_pose = segments as f64 * std::mem::size_of::<UnitQuaternion<f64>>() as f64
        + branches as f64 * (std::mem::size_of::<f64>() + std::mem::size_of::<[f64; 2]>()) as f64
        + std::mem::size_of::<Pose>() as f64;
    let bytes = (frames + 1.0) * per_pose;
    if bytes > MAX_POSE_BYTES {
        return Err(AnimError::TooLarge {
            what: format!("{frames} frames of a tree of {segments} segments: bytes of poses"),
            count: bytes,
            limit: MAX_POSE_BYTES,
        });
    }
    Ok(frames as usize)
}

impl Simulation {
    /// Set up `tree` with one [`Dynamics`] per branch (in [`BeamTree::branches`] order),
    /// advancing `dt_s` per frame.
    ///
    /// # Errors
    /// [`AnimError::InvalidTimeStep`], bad dynamics ([`AnimError::InvalidFrequency`],
    /// [`AnimError::InvalidDamping`]), a wrong number of them
    /// ([`AnimError::InvalidParameter`]), a bad wind, or [`AnimError::Unstable`].
    pub fn new(
        tree: BeamTree,
        dynamics: &[Dynamics],
        config: AnimConfig,
        dt_s: f64,
    ) -> Result<Self> {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(AnimError::InvalidTimeStep { dt_s });
        }
        config.wind.validate()?;
        if dynamics.len() != tree.branches().len() {
            return Err(AnimError::param(
                "dynamics",
                format!(
                    "{} entries for {} branches",
                    dynamics.len(),
                    tree.branches().len()
                ),
            ));
        }
        let wind_dir = config.wind.direction;
        let (upstream, _) = tree.extent_along(&wind_dir);
        let mut segments = Vec::with_capacity(tree.segment_count());
        let mut downstream_m = Vec::with_capacity(tree.segment_count());
        let mut area_m2 = Vec::with_capacity(tree.segment_count());
        let mut parent_segment = Vec::with_capacity(tree.segment_count());
        let mut branches = Vec::with_capacity(tree.branches().len());
        let mut report = IntegratorReport {
            integrator: config.integrator,
            substeps: 1,
            worst_damping_error: 0.0,
            worst_frequency_error: 0.0,
        };
        for (bi, (b, d)) in tree.branches().iter().zip(dynamics).enumerate() {
            let step = branch_step(b.id, d, config.integrator, dt_s, &mut report)?;
            let tip = b.points[SEGMENTS];
            let mut k = [[0.0; 2]; 2];
            let mut lever_sum = Vector3::zeros();
            for j in 0..SEGMENTS {
                let d = b.points[j + 1] - b.points[j];
                let l = d.norm();
                let mid = b.points[j] + d * 0.5;
                let stiffness = b.radii_m[j].max(1e-6).powi(4);
                let lever = (tip - mid) * (l / stiffness);
                let q = tip - b.points[j];
                // δ(x̂) = Σ (e·q) − (e·x̂)(q·x̂).
                let eq = lever.dot(&q);
                let (eu, ew, qu, qw) = (lever.dot(&b.u), lever.dot(&b.w), q.dot(&b.u), q.dot(&b.w));
                k[0][0] += eq - eu * qu;
                k[1][1] += eq - ew * qw;
                k[0][1] -= 0.5 * (eu * qw + ew * qu);
                lever_sum += lever;
                segments.push(Segment {
                    dir: d / l,
                    length_m: l,
                    lever,
                });
                downstream_m.push(mid.coords.dot(&wind_dir) - upstream);
                area_m2.push(2.0 * b.radii_m[j] * l);
                parent_segment.push(if j == 0 {
                    b.parent_segment
                } else {
                    Some(bi * SEGMENTS + j - 1)
                });
            }
            k[1][0] = k[0][1];
            branches.push(BranchState::at_rest(step, b, k, lever_sum, &tree));
        }
        let n = segments.len();
        let nb = branches.len();
        let (children_at, children) = children_of(&tree);
        let pairable = (0..nb)
            .map(|i| {
                tree.branches()
                    .get(i + 1)
                    .is_some_and(|b| b.parent != Some(i))
            })
            .collect();
        let mut sim = Self {
            tree,
            config,
            dt_s,
            segments,
            downstream_m,
            area_m2,
            parent_segment,
            branches,
            attach: vec![Attach::default(); nb],
            pairable,
            children_at,
            children,
            forces: vec![Vector3::zeros(); nb],
            dir: vec![Vector3::zeros(); n],
            delays: Vec::new(),
            delays_for: (0.0, 0),
            pose: Pose::at_rest(n, nb),
            report,
        };
        sim.update_pose();
        Ok(sim)
    }

    /// The tree.
    pub fn tree(&self) -> &BeamTree {
        &self.tree
    }

    /// The frame step, seconds.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// The configuration.
    pub fn config(&self) -> &AnimConfig {
        &self.config
    }

    /// What the integrator does at this frame rate.
    pub fn integrator_report(&self) -> IntegratorReport {
        self.report
    }

    /// The current pose.
    pub fn pose(&self) -> &Pose {
        &self.pose
    }

    /// A wind field for this tree and frame rate, from the configuration's wind.
    ///
    /// # Errors
    /// A bad wind configuration.
    pub fn wind_field(&self) -> Result<WindField> {
        let (lo, hi) = self.tree.extent_along(&self.config.wind.direction);
        WindField::new(self.config.wind, self.dt_s, hi - lo)
    }

    /// Pull branch `id` so that its bending angle is `angle_rad` along its u axis, at rest
    /// velocity: the release test's initial condition.
    ///
    /// # Errors
    /// [`AnimError::UnknownBranch`], [`AnimError::InvalidParameter`] for an angle that is
    /// not finite.
    pub fn pull(&mut self, id: usize, angle_rad: f64) -> Result<()> {
        let i = self.tree.index_of(id)?;
        if !(angle_rad.is_finite() && angle_rad.abs() <= MAX_PULL_RAD) {
            return Err(AnimError::param(
                "angle_rad",
                format!(
                    "{angle_rad} rad ({:.1}°); a pull must be finite and at most 90° (beyond, a branch is not a beam)",
                    angle_rad.to_degrees()
                ),
            ));
        }
        let b = &mut self.branches[i];
        let angle_per_u = if b.k[0][0] > 0.0 {
            b.angle_uw[0] / b.k[0][0]
        } else {
            0.0
        };
        if angle_per_u == 0.0 {
            return Err(AnimError::param(
                "angle_rad",
                format!("branch {id} cannot bend"),
            ));
        }
        let x = angle_rad / angle_per_u;
        b.x = [x, 0.0];
        b.vel = [0.0, 0.0];
        b.xs = x;
        b.vs = 0.0;
        b.dir = [1.0, 0.0];
        self.update_pose();
        Ok(())
    }

    /// Advance one frame in `wind` (which advances too).
    ///
    /// # Errors
    /// [`AnimError::NonFiniteWind`] if the field gives a non-finite velocity.
    pub fn step(&mut self, wind: &mut WindField) -> Result<()> {
        let cfg = self.config.wind;
        if self.delays.len() != self.segments.len() || self.delays_for != wind.time_step_and_size()
        {
            self.delays = self.downstream_m.iter().map(|&d| wind.delay(d)).collect();
            self.delays_for = wind.time_step_and_size();
        }
        let per_branch = self
            .delays
            .chunks_exact(SEGMENTS)
            .zip(self.dir.chunks_exact(SEGMENTS))
            .zip(self.area_m2.chunks_exact(SEGMENTS));
        for (i, ((delays, dirs), areas)) in per_branch.enumerate() {
            let mut f = Vector3::zeros();
            for ((&delay, a), &area) in delays.iter().zip(dirs).zip(areas) {
                f += drag_on_area_n(&wind.velocity_delayed(delay), a, area, &cfg);
            }
            self.forces[i] = self.attach[i].rotation.inverse_transform_vector(&f);
        }
        if let Some(i) = self
            .forces
            .iter()
            .position(|f| !f.iter().all(|c| c.is_finite()))
        {
            return Err(AnimError::NonFiniteWind {
                what: format!(
                    "on branch {} at {} s",
                    self.tree.branches()[i].id,
                    wind.time_s()
                ),
            });
        }
        wind.advance();
        self.integrate();
        Ok(())
    }

    /// Advance one frame in a wind of `velocity_m_s` per segment (global order).
    ///
    /// # Errors
    /// [`AnimError::NonFiniteWind`], [`AnimError::InvalidParameter`] for a wrong length.
    pub fn step_with(&mut self, velocity_m_s: &[Vector3<f64>]) -> Result<()> {
        if velocity_m_s.len() != self.segments.len() {
            return Err(AnimError::param(
                "velocity_m_s",
                format!(
                    "{} velocities for {} segments",
                    velocity_m_s.len(),
                    self.segments.len()
                ),
            ));
        }
        if let Some(s) = velocity_m_s
            .iter()
            .position(|v| !v.iter().all(|c| c.is_finite()))
        {
            return Err(AnimError::NonFiniteWind {
                what: format!("at segment {s} at {} s", self.pose.time_s),
            });
        }
        let cfg = self.config.wind;
        let per_branch = velocity_m_s
            .chunks_exact(SEGMENTS)
            .zip(self.dir.chunks_exact(SEGMENTS))
            .zip(self.area_m2.chunks_exact(SEGMENTS));
        for (i, ((velocities, dirs), areas)) in per_branch.enumerate() {
            let mut f = Vector3::zeros();
            for ((u, a), &area) in velocities.iter().zip(dirs).zip(areas) {
                f += drag_on_area_n(u, a, area, &cfg);
            }
            self.forces[i] = self.attach[i].rotation.inverse_transform_vector(&f);
        }
        self.integrate();
        Ok(())
    }

    /// Advance one frame in still air.
    pub fn step_free(&mut self) {
        self.forces.fill(Vector3::zeros());
        self.integrate();
    }

    /// Rest start of each segment's parent joint, for exporters: the parent segment of
    /// every segment (`None` for the trunk's first).
    pub fn parent_segments(&self) -> &[Option<usize>] {
        &self.parent_segment
    }

    /// Each segment's rotation from rest (tree frame) and deformed start, metres, in the
    /// current pose: the local rotations composed root to tip.
    pub fn segment_frames(&self) -> Vec<(UnitQuaternion<f64>, Point3<f64>)> {
        let mut frames: Vec<(UnitQuaternion<f64>, Point3<f64>)> =
            Vec::with_capacity(self.segments.len());
        for (i, b) in self.branches.iter().enumerate() {
            let first = i * SEGMENTS;
            let (g0, start0) = match self.parent_segment[first] {
                Some(ps) => frames[ps],
                None => (UnitQuaternion::identity(), Point3::origin()),
            };
            let mut g = g0;
            let mut start = start0 + g0 * b.base_offset;
            for s in first..first + SEGMENTS {
                g *= self.pose.local[s];
                frames.push((g, start));
                start += self.dir[s] * self.segments[s].length_m;
            }
        }
        frames
    }

    /// Rest offset of each segment's start from its parent's start (tree frame; for the
    /// trunk's first segment, from the origin), metres.
    pub fn rest_offsets(&self) -> Vec<Vector3<f64>> {
        self.branches
            .iter()
            .zip(self.segments.chunks_exact(SEGMENTS))
            .flat_map(|(b, segs)| {
                std::iter::once(b.base_offset)
                    .chain(segs[..SEGMENTS - 1].iter().map(|s| s.dir * s.length_m))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests;
