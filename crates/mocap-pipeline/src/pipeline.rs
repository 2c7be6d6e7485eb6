//! The method composed: a recording and its markers in, a [`Report`] out.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use beam_anim::{
    AnimConfig, BeamTree, DynamicsSource, DynamicsSpec, MeasuredDynamics, PAPER_DYNAMICS, Pose,
    Simulation, WindConfig,
};
use kinect_io::{Calibration, Recording, camera_to_world_z_up};
use nalgebra::{Isometry3, Point2, Point3, Vector3};
use space_colonize::{ColonizeConfig, Skeleton, cylinders, reconstruct};

use crate::analysis::{self, BranchResult};
use crate::capture::{self, Capture, CaptureSetup, DroppedMarker, MarkerSpec, RawFrame};
use crate::error::{PipelineError, Result, StageExt};
use crate::markers::{DEFAULT_CAMERA_HEIGHT_M, MarkersFile};
use crate::report::{
    AnimationSummary, BVH_FILE, BranchRow, GLB_FILE, MarkerTracking, Products,
    ReconstructionSummary, Report, Timing, TrackingSummary,
};

/// Most worker threads accepted (a guard against a typo, not a tuning).
pub const MAX_THREADS: usize = 1024;
/// Longest wind animation accepted, seconds.
pub const MAX_ANIMATION_S: f64 = 3600.0;

/// How to run the method. Every field has a documented default.
#[derive(Debug, Clone, PartialEq)]
pub struct PipelineConfig {
    /// Worker threads producing frames and clouds (default: the machine's).
    pub threads: usize,
    /// Frames of the still tree, from the first, accumulated for the reconstruction
    /// (default 5).
    pub static_frames: usize,
    /// The projection image the markers are tracked on is the colour camera's, scaled down
    /// to this width when the colour image is wider, pixels (default 1920: the Kinect V2's
    /// full resolution, where 3 cm markers are 15 px wide at 2.2 m).
    pub plane_max_width_px: u32,
    /// Points lower than this above the ground are the ground, metres (default 0.04).
    pub ground_clearance_m: f64,
    /// Points kept for the reconstruction lie within this distance (along the camera's view)
    /// of the nearest and furthest marker, metres (default 0.5).
    pub crop_margin_m: f64,
    /// Length of the wind animation, seconds (default 10).
    pub animation_s: f64,
    /// Frame rate of the animation, hertz (default 30).
    pub animation_fps_hz: f64,
    /// Mean wind speed of the animation, m/s (default 4).
    pub wind_speed_m_s: f64,
    /// The reconstruction's parameters (default: derived from the cloud).
    pub colonize: ColonizeConfig,
}

impl Default for PipelineConfig {
    fn default() -> Self {
        Self {
            threads: std::thread::available_parallelism().map_or(2, std::num::NonZero::get),
            static_frames: 5,
            plane_max_width_px: 1920,
            ground_clearance_m: 0.04,
            crop_margin_m: 0.5,
            animation_s: 10.0,
            animation_fps_hz: 30.0,
            wind_speed_m_s: 4.0,
            colonize: ColonizeConfig::default(),
        }
    }
}

impl PipelineConfig {
    /// Check every field.
    ///
    /// # Errors
    /// [`PipelineError::InvalidParameter`] naming the field and its value.
    pub fn validate(&self) -> Result<()> {
        if !(1..=MAX_THREADS).contains(&self.threads) {
            return Err(PipelineError::param(
                "threads",
                format!("{}; 1..={MAX_THREADS}", self.threads),
            ));
        }
        if self.static_frames == 0 {
            return Err(PipelineError::param("static_frames", "0; at least 1"));
        }
        if self.plane_max_width_px < 16 {
            return Err(PipelineError::param(
                "plane_max_width_px",
                format!("{}; at least 16 px", self.plane_max_width_px),
            ));
        }
        for (name, v, hi) in [
            ("ground_clearance_m", self.ground_clearance_m, 100.0),
            ("crop_margin_m", self.crop_margin_m, 1e3),
            (
                "wind_speed_m_s",
                self.wind_speed_m_s,
                beam_anim::MAX_WIND_SPEED_M_S,
            ),
        ] {
            if !(v.is_finite() && (0.0..=hi).contains(&v)) {
                return Err(PipelineError::param(name, format!("{v}; 0..={hi}")));
            }
        }
        if !(self.animation_s.is_finite() && (0.0..=MAX_ANIMATION_S).contains(&self.animation_s)) {
            return Err(PipelineError::param(
                "animation_s",
                format!("{} s; 0..={MAX_ANIMATION_S} s", self.animation_s),
            ));
        }
        if !(self.animation_fps_hz.is_finite() && (1.0..=1000.0).contains(&self.animation_fps_hz)) {
            return Err(PipelineError::param(
                "animation_fps_hz",
                format!("{} Hz; 1..=1000 Hz", self.animation_fps_hz),
            ));
        }
        Ok(())
    }

    /// Scale of the tracking plane for a colour camera `color_width_px` wide.
    pub fn plane_scale(&self, color_width_px: u32) -> f64 {
        if color_width_px > self.plane_max_width_px {
            f64::from(self.plane_max_width_px) / f64::from(color_width_px)
        } else {
            1.0
        }
    }
}

/// A stage of a run, for progress reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Stage {
    /// Frames read, clouds built, markers tracked and lifted.
    Capture,
    /// Wind animation steps.
    Animate,
    /// Frames written (the twin's recording).
    Record,
}

impl Stage {
    /// A short name for a progress line.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Capture => "capture",
            Stage::Animate => "animate",
            Stage::Record => "record",
        }
    }
}

/// Progress of a long stage: `done` of `total` steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress {
    /// The stage.
    pub stage: Stage,
    /// Steps done.
    pub done: usize,
    /// Steps in all.
    pub total: usize,
}

/// A progress callback; the library never prints.
pub type ProgressFn = Arc<dyn Fn(Progress) + Send + Sync>;

/// The method, configured.
#[derive(Clone)]
pub struct Pipeline {
    config: PipelineConfig,
    progress: Option<ProgressFn>,
}

impl std::fmt::Debug for Pipeline {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pipeline")
            .field("config", &self.config)
            .field("progress", &self.progress.is_some())
            .finish()
    }
}

/// What the capture chain measured, ready for the report.
pub(crate) struct Measured {
    pub(crate) capture: Capture,
    pub(crate) branches: Vec<BranchResult>,
    pub(crate) dropped: Vec<DroppedMarker>,
    pub(crate) cloud_to_tree: Isometry3<f64>,
    /// The markers' first-frame windows on the tracking plane.
    pub(crate) markers: Vec<MarkerSpec>,
}

/// What only a twin knows: the truth to compare with.
#[derive(Default)]
pub(crate) struct Truth<'a> {
    /// Per marker, the tracked centre's share of frames within 3 px of the truth.
    pub(crate) within_3px: BTreeMap<String, f64>,
    /// The true skeleton.
    pub(crate) skeleton: Option<&'a Skeleton>,
    /// Per branch, the true `(f, xi)`.
    pub(crate) dynamics: BTreeMap<String, (f64, f64)>,
    /// Median lift error, millimetres.
    pub(crate) median_lift_error_mm: Option<f64>,
}

impl Pipeline {
    /// A pipeline with a checked configuration.
    ///
    /// # Errors
    /// [`PipelineError::InvalidParameter`] as [`PipelineConfig::validate`].
    pub fn new(config: PipelineConfig) -> Result<Self> {
        config.validate()?;
        Ok(Self {
            config,
            progress: None,
        })
    }

    /// Report progress of long stages to `callback` (called from the calling thread).
    #[must_use]
    pub fn with_progress(mut self, callback: impl Fn(Progress) + Send + Sync + 'static) -> Self {
        self.progress = Some(Arc::new(callback));
        self
    }

    /// The configuration.
    pub fn config(&self) -> &PipelineConfig {
        &self.config
    }

    pub(crate) fn report_progress(&self, stage: Stage, done: usize, total: usize) {
        if let Some(p) = &self.progress {
            p(Progress { stage, done, total });
        }
    }

    /// Run the whole method on a recording (native or TUM folder, Azure Kinect `.mkv`; `kinect_io::Recording`)
    /// with the markers of its markers file.
    ///
    /// # Errors
    /// [`PipelineError::Recording`] when the recording cannot be measured as given (fewer
    /// than 2 frames, no rigid depth-to-colour calibration, a marker window outside the
    /// first image, a test window outside the recording), [`PipelineError::Frame`] naming a
    /// frame that cannot be read or processed, and the stages' errors.
    pub fn run(&self, recording: &Recording, markers: &MarkersFile) -> Result<Report> {
        let started = Instant::now();
        let bad = |reason: String| PipelineError::Recording {
            path: recording.path().to_path_buf(),
            reason,
        };
        markers.validate().map_err(|reason| markers.error(reason))?;
        let times: Vec<f64> = recording.timestamps_s().collect();
        let (Some(&t0), Some(&last)) = (times.first(), times.last()) else {
            return Err(bad("no frames".into()));
        };
        if times.len() < 2 {
            return Err(bad(format!(
                "{} frame; a capture needs at least 2",
                times.len()
            )));
        }
        let duration_s = last - t0;
        let frame_s = duration_s / (times.len() - 1) as f64;
        let calibration = recording.calibration().clone();
        let color = calibration.color_camera;
        check_windows(markers, color.width, color.height, duration_s, frame_s).map_err(
            |reason| {
                markers.error(format!(
                    "{reason} (recording {})",
                    recording.path().display()
                ))
            },
        )?;
        let setup = self.setup(calibration, markers, recording.path())?;
        let produce = |i: usize| -> Result<RawFrame> {
            let frame = recording
                .frame(i)
                .map_err(|e| PipelineError::frame(i, "read", e))?;
            Ok(RawFrame {
                time_s: frame.timestamp_s - t0,
                depth: frame.depth,
                color: frame.color,
            })
        };
        let height = markers.camera_height_m.unwrap_or(DEFAULT_CAMERA_HEIGHT_M);
        let pitch = markers.pitch_down_deg.unwrap_or(0.0).to_radians();
        let measured = self.measure(
            &setup,
            times.len(),
            &produce,
            camera_to_world_z_up(height, pitch),
            &markers.windows_s(),
        )?;
        self.finish(started, measured, &Truth::default())
    }

    /// How the capture is tracked: the projection image on the colour camera's plane (scaled
    /// as [`PipelineConfig::plane_scale`]), the markers with their first-frame windows.
    /// `path` names the recording in errors.
    pub(crate) fn setup(
        &self,
        calibration: Calibration,
        markers: &MarkersFile,
        path: &Path,
    ) -> Result<CaptureSetup> {
        let plane_scale = self.config.plane_scale(calibration.color_camera.width);
        let plane = calibration
            .color_camera
            .scaled(plane_scale)
            .stage("projection plane")?;
        let cloud_to_plane = calibration.depth_to_color()?.ok_or_else(|| {
            PipelineError::Recording {
                path: path.to_path_buf(),
                reason: "the calibration has no rigid depth-to-colour transform (libfreenect2's model): the projection image needs one".into(),
            }
        })?;
        let specs: Vec<MarkerSpec> = markers
            .markers
            .iter()
            .map(|m| {
                let [cx, cy] = m.center_px();
                MarkerSpec {
                    id: m.id.clone(),
                    parent: m.parent.clone(),
                    center: Point2::new(cx * plane_scale, cy * plane_scale),
                    size_px: (0.5 * (m.w + m.h) * plane_scale).round() as i32,
                }
            })
            .collect();
        Ok(CaptureSetup {
            calibration,
            plane,
            cloud_to_plane,
            markers: specs,
            static_frames: self.config.static_frames,
            threads: self.config.threads,
        })
    }

    /// The capture chain and the analysis: frames to each branch's modes.
    pub(crate) fn measure(
        &self,
        setup: &CaptureSetup,
        frames: usize,
        produce: &(dyn Fn(usize) -> Result<RawFrame> + Sync),
        cloud_to_tree: Isometry3<f64>,
        windows_s: &BTreeMap<String, (f64, f64)>,
    ) -> Result<Measured> {
        let capture = capture::capture(setup, frames, produce, &mut |d, n| {
            self.report_progress(Stage::Capture, d, n);
        })?;
        let mut dropped = capture.dropped.clone();
        let hierarchy = analysis::hierarchy(&setup.markers, &capture.ids, &mut dropped)?;
        let trajectories = analysis::trajectories(&capture, &hierarchy, &cloud_to_tree)?;
        let branches =
            analysis::analyse(&hierarchy, &trajectories, Vector3::z(), windows_s, &capture)?;
        Ok(Measured {
            capture,
            branches,
            dropped,
            cloud_to_tree,
            markers: setup.markers.clone(),
        })
    }

    /// Reconstruction, animation and the report.
    pub(crate) fn finish(
        &self,
        started: Instant,
        measured: Measured,
        truth: &Truth<'_>,
    ) -> Result<Report> {
        let capture_s = started.elapsed().as_secs_f64();
        let t = Instant::now();
        let points = self.still_points(&measured);
        let recon = reconstruct(&points, &self.config.colonize).stage("reconstruction")?;
        let recon_s = t.elapsed().as_secs_f64();
        let error = truth
            .skeleton
            .map(|s| space_colonize::synthetic::skeleton_error(&recon.skeleton, s));
        let (animation, measured_branches) = self.animate(&measured, &recon.skeleton)?;

        let capture = &measured.capture;
        let tracked = analysis::tracked_fractions(capture);
        let rows: Vec<BranchRow> = measured
            .branches
            .iter()
            .map(|b| BranchRow::new(b, truth.dynamics.get(&b.id).copied()))
            .collect();
        let frames = capture.times_s.len();
        let markers = capture
            .ids
            .iter()
            .enumerate()
            .map(|(k, id)| MarkerTracking {
                id: id.clone(),
                tracked_fraction: tracked.get(id).copied().unwrap_or(0.0),
                // After the jump filter, as the angles saw them (the root's as lifted).
                lifted_fraction: rows.iter().find(|r| r.id == *id).map_or_else(
                    || {
                        capture.positions_m[k].iter().flatten().count() as f64
                            / frames.max(1) as f64
                    },
                    |r| r.lifted_fraction,
                ),
                within_3px_fraction: truth.within_3px.get(id).copied(),
            })
            .collect();
        Ok(Report {
            branches: rows,
            dropped_markers: measured.dropped.clone(),
            tracking: TrackingSummary {
                frames,
                markers,
                median_lift_error_mm: truth.median_lift_error_mm,
            },
            reconstruction: ReconstructionSummary {
                points: points.len(),
                nodes: recon.skeleton.nodes().len(),
                branches: recon.branches.len(),
                // Wood length as TreeQSM counts it: each branch from its parent's surface.
                total_length_m: cylinders(&recon.skeleton).iter().map(|c| c.length_m).sum(),
                mean_skeleton_error_m: error.map(|e| e.mean_skeleton_error_m),
                p95_skeleton_error_m: error.map(|e| e.p95_skeleton_error_m),
                truth_length_found: error.map(|e| e.truth_length_found),
                volume_l: 1e3
                    * cylinders(&recon.skeleton)
                        .iter()
                        .map(|c| std::f64::consts::PI * c.radius_m * c.radius_m * c.length_m)
                        .sum::<f64>(),
                volume_ratio: error.map(|e| e.volume_ratio),
                surface_noise_m: recon.surface_noise_m,
                volume_trusted: recon.volume_trusted(),
                seconds: recon_s,
            },
            animation: AnimationSummary {
                frames: animation.poses.len(),
                wind_speed_m_s: self.config.wind_speed_m_s,
                measured_branches,
                glb: GLB_FILE.into(),
                bvh: BVH_FILE.into(),
            },
            timing: Timing {
                capture_s,
                frames_and_clouds_cpu_s: capture.produce_s,
                tracking_and_lifting_s: capture.track_s,
            },
            seconds: started.elapsed().as_secs_f64(),
            products: Products {
                branch_results: measured.branches,
                skeleton: recon.skeleton,
                animation,
                projection: {
                    let mut image = measured.capture.first_projection;
                    let marks: Vec<(String, Point2<f64>, i32)> = measured
                        .markers
                        .iter()
                        .map(|m| (m.id.clone(), m.center, m.size_px))
                        .collect();
                    crate::report::annotate(&mut image, &marks);
                    image
                },
            },
        })
    }

    /// The still cloud in the tree frame, cropped to the tree: above the ground, and
    /// within reach of the markers along the view (points further in front or behind, the
    /// ground beyond, a wall, flying pixels mixing a branch with the background, are not
    /// the tree).
    fn still_points(&self, measured: &Measured) -> Vec<Point3<f64>> {
        let capture = &measured.capture;
        let depths: Vec<f64> = capture
            .positions_m
            .iter()
            .filter_map(|track| {
                track
                    .iter()
                    .take(self.config.static_frames)
                    .flatten()
                    .next()
            })
            .map(|p| (measured.cloud_to_tree * p).y)
            .collect();
        let margin = self.config.crop_margin_m;
        let near = depths.iter().copied().fold(f64::INFINITY, f64::min) - margin;
        let far = depths.iter().copied().fold(f64::NEG_INFINITY, f64::max) + margin;
        capture
            .static_points_m
            .iter()
            .map(|p| measured.cloud_to_tree * p)
            .filter(|p| p.z > self.config.ground_clearance_m && (near..=far).contains(&p.y))
            .collect()
    }

    /// The measured dynamics onto the rebuilt tree (the trusted ones, below the animation's
    /// Nyquist frequency), then the wind animation. Returns the animation and the number of
    /// its branches that got measured dynamics.
    fn animate(
        &self,
        measured: &Measured,
        skeleton: &Skeleton,
    ) -> Result<(crate::report::Animation, usize)> {
        let capture = &measured.capture;
        let rest_position = |id: &str| -> Option<[f64; 3]> {
            let k = capture.ids.iter().position(|x| x == id)?;
            let known: Vec<Point3<f64>> = capture.positions_m[k]
                .iter()
                .take(self.config.static_frames)
                .flatten()
                .map(|p| measured.cloud_to_tree * p)
                .collect();
            let n = known.len();
            (n > 0).then(|| {
                let c = known.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n as f64;
                [c.x, c.y, c.z]
            })
        };
        let spec = DynamicsSpec {
            default: PAPER_DYNAMICS,
            measured: measured
                .branches
                .iter()
                .filter_map(|b| {
                    // Only what the report trusts drives the animation, and only what its
                    // frame rate can show; the other branches take their level's or the
                    // paper's dynamics.
                    let m = b.ours.filter(|m| {
                        b.quality.ours_trusted
                            && m.frequency_hz < 0.5 * self.config.animation_fps_hz
                    })?;
                    Some(MeasuredDynamics {
                        position: rest_position(&b.id)?,
                        frequency_hz: m.frequency_hz,
                        damping_ratio: m.damping_ratio,
                    })
                })
                .collect(),
            ..DynamicsSpec::default()
        };
        let config = AnimConfig {
            wind: WindConfig {
                mean_speed_m_s: self.config.wind_speed_m_s,
                ..AnimConfig::default().wind
            },
            ..AnimConfig::default()
        };
        let beam = BeamTree::new(skeleton, &config).stage("animation beams")?;
        let assignment = spec.assign(&beam).stage("dynamics")?;
        let measured_branches = assignment
            .source
            .iter()
            .filter(|s| matches!(s, DynamicsSource::Measured(_)))
            .count();
        let fps = self.config.animation_fps_hz;
        let mut sim =
            Simulation::new(beam, &assignment.dynamics, config, 1.0 / fps).stage("animation")?;
        let mut wind = sim.wind_field().stage("wind")?;
        let frames = (self.config.animation_s * fps).round() as usize;
        let mut poses: Vec<Pose> = Vec::with_capacity(frames + 1);
        poses.push(sim.pose().clone());
        for k in 0..frames {
            sim.step(&mut wind).stage("animation")?;
            poses.push(sim.pose().clone());
            self.report_progress(Stage::Animate, k + 1, frames);
        }
        Ok((
            crate::report::Animation {
                simulation: sim,
                poses,
            },
            measured_branches,
        ))
    }
}

/// Each window on the first colour image, and each test window inside the recording.
fn check_windows(
    markers: &MarkersFile,
    width: u32,
    height: u32,
    duration_s: f64,
    frame_s: f64,
) -> std::result::Result<(), String> {
    let (w, h) = (f64::from(width), f64::from(height));
    for m in &markers.markers {
        if m.x < 0.0 || m.y < 0.0 || m.x + m.w > w || m.y + m.h > h {
            return Err(format!(
                "marker {}: window x {}, y {}, w {}, h {} is not inside the {width}x{height} px colour image",
                m.id,
                short(m.x),
                short(m.y),
                short(m.w),
                short(m.h)
            ));
        }
        if let Some([start, end]) = m.window_s
            && (start >= duration_s || end > duration_s + frame_s)
        {
            return Err(format!(
                "marker {}: window_s [{}, {}] s is not inside the recording (0 to {duration_s:.3} s)",
                m.id,
                short(start),
                short(end)
            ));
        }
    }
    Ok(())
}

/// A number as a user wrote it, in exponent form when it is huge or tiny (so that 1e300 is
/// not printed as 301 digits).
pub(crate) fn short(v: f64) -> String {
    if v != 0.0 && !(1e-6..1e9).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}
