//! The animation: forces on the segments, one oscillator per branch, bending, poses.

use nalgebra::{Point3, Quaternion, UnitQuaternion, Vector3};
use serde::Serialize;

use crate::error::{AnimError, Result};
use crate::oscillator::{Dynamics, Integrator, Step, step_for};
use crate::tree::{BeamTree, GREEN_WOOD_DENSITY_KG_M3, SEGMENTS};
use crate::wind::{WindConfig, WindField, drag_n};

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

/// Per-segment precomputation.
#[derive(Debug, Clone, Copy)]
struct Segment {
    /// Rest vector start → end.
    d: Vector3<f64>,
    /// Rest start relative to the parent node's rest start (for the first segment of a
    /// branch: relative to the parent's attachment segment start).
    offset: Vector3<f64>,
    /// Bending lever: (l / r⁴)(P4 − M), the moment arm of a tip load per unit stiffness.
    lever: Vector3<f64>,
    length_m: f64,
    radius_m: f64,
    /// Frontal area 2 r l, m².
    area_m2: f64,
    /// Rest distance along the wind from the most upstream point, metres.
    downstream_m: f64,
}

/// Per-branch precomputation and state.
#[derive(Debug, Clone, Copy)]
struct BranchState {
    step: Step,
    mass_kg: f64,
    /// δ(x̂) = x̂ᵀ K x̂ in the (u, w) basis: tip deflection per unit bending scale.
    k: [[f64; 2]; 2],
    /// Bending angle about v × u per unit u displacement.
    angle_per_u: f64,
    x: [f64; 2],
    vel: [f64; 2],
    /// Magnitude forcing: scalar displacement, velocity, direction in (u, w).
    xs: f64,
    vs: f64,
    dir: [f64; 2],
}

/// The pose of the tree at one instant.
#[derive(Debug, Clone, PartialEq)]
pub struct Pose {
    /// Time, seconds.
    pub time_s: f64,
    /// Rotation of each segment relative to its parent segment (the joint at its start),
    /// global segment order (branch index × 4 + segment).
    pub local: Vec<UnitQuaternion<f64>>,
    /// Rotation of each segment from rest, tree frame.
    pub global: Vec<UnitQuaternion<f64>>,
    /// Deformed start of each segment, metres.
    pub start: Vec<Point3<f64>>,
    /// Each branch's bending angle (rotation of its last segment relative to its base about
    /// v × u, the along-wind bending), radians.
    pub angle_rad: Vec<f64>,
    /// Each branch's displacement (u, w), metres.
    pub displacement_m: Vec<[f64; 2]>,
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
    parent_segment: Vec<Option<usize>>,
    branches: Vec<BranchState>,
    forces: Vec<Vector3<f64>>,
    dir: Vec<Vector3<f64>>,
    delays: Vec<(usize, f64)>,
    delays_for: (f64, usize),
    pose: Pose,
    report: IntegratorReport,
}

/// sin and cos of a half angle; a short series for the small angles of bending.
#[inline]
fn rotation(phi: &Vector3<f64>) -> UnitQuaternion<f64> {
    let a2 = phi.norm_squared();
    let (s_over, c) = if a2 < 0.0625 {
        // |φ| < 0.25: sin(|φ|/2)/|φ| and cos(|φ|/2) by their series (error < 1e-16).
        let h2 = a2 / 4.0;
        let s = 0.5 * (1.0 - h2 / 6.0 * (1.0 - h2 / 20.0 * (1.0 - h2 / 42.0 * (1.0 - h2 / 72.0))));
        let c = 1.0
            - h2 / 2.0
                * (1.0 - h2 / 12.0 * (1.0 - h2 / 30.0 * (1.0 - h2 / 56.0 * (1.0 - h2 / 90.0))));
        (s, c)
    } else {
        let a = a2.sqrt();
        let (s, c) = (0.5 * a).sin_cos();
        (s / a, c)
    };
    UnitQuaternion::new_unchecked(Quaternion::new(
        c,
        phi.x * s_over,
        phi.y * s_over,
        phi.z * s_over,
    ))
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
        let mut parent_segment = Vec::with_capacity(tree.segment_count());
        let mut branches = Vec::with_capacity(tree.branches().len());
        let mut report = IntegratorReport {
            integrator: config.integrator,
            substeps: 1,
            worst_damping_error: 0.0,
            worst_frequency_error: 0.0,
        };
        for (bi, (b, d)) in tree.branches().iter().zip(dynamics).enumerate() {
            d.validate(&format!("branch {}", b.id))?;
            let (step, substeps) =
                step_for(d, config.integrator, dt_s).map_err(|substeps| AnimError::Unstable {
                    branch: b.id,
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
            let tip = b.points[SEGMENTS];
            let mut k = [[0.0; 2]; 2];
            let mut angle_axis_sum = 0.0;
            let ref_axis = b.v.cross(&b.u);
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
                angle_axis_sum += lever.cross(&b.u).dot(&ref_axis);
                let offset = if j == 0 {
                    match b.parent_segment {
                        Some(ps) => b.points[0] - tree.segment_start(ps),
                        None => b.points[0].coords,
                    }
                } else {
                    d_prev(&b.points, j)
                };
                segments.push(Segment {
                    d,
                    offset,
                    lever,
                    length_m: l,
                    radius_m: b.radii_m[j],
                    area_m2: 2.0 * b.radii_m[j] * l,
                    downstream_m: mid.coords.dot(&wind_dir) - upstream,
                });
                parent_segment.push(if j == 0 {
                    b.parent_segment
                } else {
                    Some(bi * SEGMENTS + j - 1)
                });
            }
            k[1][0] = k[0][1];
            branches.push(BranchState {
                step,
                mass_kg: b.mass_kg.max(1e-12),
                k,
                angle_per_u: if k[0][0] > 0.0 {
                    angle_axis_sum / k[0][0]
                } else {
                    0.0
                },
                x: [0.0; 2],
                vel: [0.0; 2],
                xs: 0.0,
                vs: 0.0,
                dir: [1.0, 0.0],
            });
        }
        let n = segments.len();
        let nb = branches.len();
        let mut sim = Self {
            tree,
            config,
            dt_s,
            segments,
            parent_segment,
            branches,
            forces: vec![Vector3::zeros(); nb],
            dir: vec![Vector3::zeros(); n],
            delays: Vec::new(),
            delays_for: (0.0, 0),
            pose: Pose {
                time_s: 0.0,
                local: vec![UnitQuaternion::identity(); n],
                global: vec![UnitQuaternion::identity(); n],
                start: vec![Point3::origin(); n],
                angle_rad: vec![0.0; nb],
                displacement_m: vec![[0.0; 2]; nb],
            },
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
        if !angle_rad.is_finite() {
            return Err(AnimError::param(
                "angle_rad",
                format!("{angle_rad}; must be finite"),
            ));
        }
        let b = &mut self.branches[i];
        if b.angle_per_u == 0.0 {
            return Err(AnimError::param(
                "angle_rad",
                format!("branch {id} cannot bend"),
            ));
        }
        let x = angle_rad / b.angle_per_u;
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
        for f in &mut self.forces {
            *f = Vector3::zeros();
        }
        if self.delays.len() != self.segments.len() || self.delays_for != wind.time_step_and_size()
        {
            self.delays = self
                .segments
                .iter()
                .map(|s| wind.delay(s.downstream_m))
                .collect();
            self.delays_for = wind.time_step_and_size();
        }
        let k = 0.5 * cfg.air_density_kg_m3 * cfg.drag_coefficient * 2.0;
        for (b, f) in self.forces.iter_mut().enumerate() {
            for s in b * SEGMENTS..(b + 1) * SEGMENTS {
                let u = wind.velocity_delayed(self.delays[s]);
                let a = &self.dir[s];
                let un = u - a * u.dot(a);
                *f += un * (k * self.segments[s].area_m2 * un.norm());
            }
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
        for f in &mut self.forces {
            *f = Vector3::zeros();
        }
        for (s, (seg, u)) in self.segments.iter().zip(velocity_m_s).enumerate() {
            self.forces[s / SEGMENTS] += drag_n(u, &self.dir[s], seg.radius_m, seg.length_m, &cfg);
        }
        self.integrate();
        Ok(())
    }

    /// Advance one frame in still air.
    pub fn step_free(&mut self) {
        for f in &mut self.forces {
            *f = Vector3::zeros();
        }
        self.integrate();
    }

    fn integrate(&mut self) {
        let magnitude = self.config.forcing == Forcing::Magnitude;
        for (i, b) in self.branches.iter_mut().enumerate() {
            let beam = &self.tree.branches()[i];
            // The force in the branch's rest frame: undo the parent's rotation.
            let f = match beam.parent_segment {
                Some(ps) => self.pose.global[ps].inverse_transform_vector(&self.forces[i]),
                None => self.forces[i],
            };
            let (fu, fw) = (f.dot(&beam.u), f.dot(&beam.w));
            if magnitude {
                let m = fu.hypot(fw);
                if m > 0.0 {
                    b.dir = [fu / m, fw / m];
                }
                (b.xs, b.vs) = b.step.apply(b.xs, b.vs, m / b.mass_kg);
                b.x = [b.xs * b.dir[0], b.xs * b.dir[1]];
            } else {
                for (c, fc) in [fu, fw].into_iter().enumerate() {
                    (b.x[c], b.vel[c]) = b.step.apply(b.x[c], b.vel[c], fc / b.mass_kg);
                }
            }
        }
        self.pose.time_s += self.dt_s;
        self.update_pose();
    }

    fn update_pose(&mut self) {
        let tree = &self.tree;
        for (i, beam) in tree.branches().iter().enumerate() {
            let b = &self.branches[i];
            let [xu, xw] = b.x;
            let x = beam.u * xu + beam.w * xw;
            let xn = xu.hypot(xw);
            let delta = if xn > 0.0 {
                let (a, c) = (xu / xn, xw / xn);
                a * a * b.k[0][0] + 2.0 * a * c * b.k[0][1] + c * c * b.k[1][1]
            } else {
                1.0
            };
            let scale = if delta > 0.0 { 1.0 / delta } else { 0.0 };
            let ref_axis = beam.v.cross(&beam.u);
            let mut angle = 0.0;
            let (mut g, mut start) = match beam.parent_segment {
                Some(ps) => (self.pose.global[ps], self.pose.start[ps]),
                None => (UnitQuaternion::identity(), Point3::origin()),
            };
            for j in 0..SEGMENTS {
                let s = i * SEGMENTS + j;
                let seg = &self.segments[s];
                let phi = seg.lever.cross(&x) * scale;
                angle += phi.dot(&ref_axis);
                let q = rotation(&phi);
                if j == 0 {
                    start += g * seg.offset;
                }
                g *= q;
                let end_vec = g * seg.d;
                self.pose.local[s] = q;
                self.pose.global[s] = g;
                self.pose.start[s] = start;
                self.dir[s] = end_vec / seg.length_m;
                start += end_vec;
            }
            self.pose.angle_rad[i] = angle;
            self.pose.displacement_m[i] = b.x;
        }
    }

    /// Rest start of each segment's parent joint, for exporters: the parent segment of
    /// every segment (`None` for the trunk's first).
    pub fn parent_segments(&self) -> &[Option<usize>] {
        &self.parent_segment
    }

    /// Rest offset of each segment's start from its parent's start (tree frame; for the
    /// trunk's first segment, from the origin), metres.
    pub fn rest_offsets(&self) -> Vec<Vector3<f64>> {
        self.segments.iter().map(|s| s.offset).collect()
    }
}

fn d_prev(points: &[Point3<f64>], j: usize) -> Vector3<f64> {
    points[j] - points[j - 1]
}
