//! The result of a run: per-branch rows with their quality, tracking, reconstruction and
//! animation summaries (`report.json`), the Markdown report, the figures, and the products
//! themselves (skeleton, animation, first projection image).

mod annotate;
mod figures;
mod table;

use std::fmt::Write as _;
use std::path::Path;

use beam_anim::{GlbOptions, Pose, Simulation, bvh_string, glb_bytes};
use image::RgbImage;
use serde::Serialize;
use space_colonize::Skeleton;

pub use annotate::annotate;
pub use figures::{series_svg, spectrum_svg, swing_svg};
pub use table::{BranchRow, table};

use crate::analysis::BranchResult;
use crate::capture::DroppedMarker;
use crate::error::{PipelineError, Result};

/// File names of the animation in a report folder (the values of `animation.glb` and
/// `animation.bvh` in `report.json`, relative to it).
pub const GLB_FILE: &str = "tree.glb";
/// See [`GLB_FILE`].
pub const BVH_FILE: &str = "tree.bvh";

/// Everything a run measured and made. `report.json` is its serialized form (the products
/// are written as their own files by [`Report::write_all`]).
#[derive(Debug, Serialize)]
pub struct Report {
    /// One row per marked branch: ours, the paper's method, their quality and notes.
    pub branches: Vec<BranchRow>,
    /// Markers left out, and why.
    pub dropped_markers: Vec<DroppedMarker>,
    /// How well the markers were followed.
    pub tracking: TrackingSummary,
    /// The static tree rebuilt from the still frames.
    pub reconstruction: ReconstructionSummary,
    /// The wind animation with the measured dynamics.
    pub animation: AnimationSummary,
    /// Where the time went.
    pub timing: Timing,
    /// Whole run, seconds.
    pub seconds: f64,
    /// The products behind the summaries.
    #[serde(skip)]
    pub products: Products,
}

/// How well the markers were followed.
#[derive(Debug, Clone, Serialize)]
pub struct TrackingSummary {
    /// Frames of the capture.
    pub frames: usize,
    /// Per marker.
    pub markers: Vec<MarkerTracking>,
    /// Median distance of the lifted 3D positions from the truth, millimetres (twin only).
    pub median_lift_error_mm: Option<f64>,
}

/// Tracking of one marker.
#[derive(Debug, Clone, Serialize)]
pub struct MarkerTracking {
    /// Marker name.
    pub id: String,
    /// Share of frames with a tracked centre.
    pub tracked_fraction: f64,
    /// Share of frames with a 3D position after the jump filter (as the angles saw them).
    pub lifted_fraction: f64,
    /// Share of frames whose centre lies within 3 px of the truth (twin only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub within_3px_fraction: Option<f64>,
}

/// The static tree rebuilt from the still frames.
#[derive(Debug, Clone, Serialize)]
pub struct ReconstructionSummary {
    /// Points of the still cloud used (after the crop).
    pub points: usize,
    /// Skeleton nodes.
    pub nodes: usize,
    /// Branches of the skeleton.
    pub branches: usize,
    /// Wood length, each branch from its parent's surface (as TreeQSM counts it), metres.
    pub total_length_m: f64,
    /// Mean distance of the skeleton from the true one, metres (twin only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mean_skeleton_error_m: Option<f64>,
    /// 95th percentile of that distance, metres (twin only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub p95_skeleton_error_m: Option<f64>,
    /// Share of the true skeleton's length found (twin only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth_length_found: Option<f64>,
    /// Wood volume, litres (each branch from its parent's surface).
    pub volume_l: f64,
    /// The model's volume over the true skeleton's (twin only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume_ratio: Option<f64>,
    /// The scan's noise about the model's surface (branches of 2 cm or more), metres.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub surface_noise_m: Option<f64>,
    /// Whether that noise leaves the volume trustworthy
    /// (`space_colonize::Reconstruction::volume_trusted`).
    pub volume_trusted: bool,
    /// Seconds.
    pub seconds: f64,
}

/// The wind animation.
#[derive(Debug, Clone, Serialize)]
pub struct AnimationSummary {
    /// Poses (frames).
    pub frames: usize,
    /// Mean wind speed, m/s.
    pub wind_speed_m_s: f64,
    /// Branches of the rebuilt tree animated with measured dynamics.
    pub measured_branches: usize,
    /// The glTF binary, relative to the report (see [`GLB_FILE`]).
    pub glb: String,
    /// The BVH motion file, relative to the report.
    pub bvh: String,
}

/// Where the time went, seconds.
#[derive(Debug, Clone, Serialize)]
pub struct Timing {
    /// The capture chain, wall clock.
    pub capture_s: f64,
    /// Producing frames and clouds, summed over the worker threads.
    pub frames_and_clouds_cpu_s: f64,
    /// Tracking and lifting.
    pub tracking_and_lifting_s: f64,
}

/// The products behind a [`Report`].
#[derive(Debug)]
pub struct Products {
    /// Every branch's full result (series, fitted stretch, modes), for figures.
    pub branch_results: Vec<BranchResult>,
    /// The rebuilt skeleton (tree frame, Z up, metres).
    pub skeleton: Skeleton,
    /// The wind animation.
    pub animation: Animation,
    /// The first frame's projection image with each marker's first window outlined and
    /// named.
    pub projection: RgbImage,
}

/// A wind animation: the simulation and its poses.
pub struct Animation {
    /// The simulation (tree, dynamics, wind) after its last step.
    pub simulation: Simulation,
    /// One pose per frame, the rest pose first.
    pub poses: Vec<Pose>,
}

impl std::fmt::Debug for Animation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Animation")
            .field("poses", &self.poses.len())
            .finish_non_exhaustive()
    }
}

impl Report {
    /// True when at least one branch has a measured frequency.
    pub fn measured_any(&self) -> bool {
        self.branches.iter().any(|b| b.frequency_hz.is_some())
    }

    /// `report.json`.
    ///
    /// # Errors
    /// [`PipelineError::Io`] naming the file.
    pub fn write_json(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self).map_err(|source| PipelineError::Json {
            what: "report",
            source,
        })? + "\n";
        write_atomic(path, text.as_bytes())
    }

    /// The Markdown report: the table, dropped markers, every note, and the summaries.
    pub fn markdown(&self) -> String {
        let mut md = String::from("# treemocap pipeline report\n\n");
        md.push_str(&table(&self.branches));
        md.push('\n');
        for d in &self.dropped_markers {
            let _ = writeln!(md, "- marker {} left out: {}", d.id, d.reason);
        }
        for r in &self.branches {
            for n in &r.notes {
                let _ = writeln!(md, "- branch {}: {n}", r.id);
            }
        }
        let rec = &self.reconstruction;
        let _ = write!(
            md,
            "\nFrames: {}. Reconstruction: {} points, {} nodes, {} branches, {:.2} m of wood",
            self.tracking.frames, rec.points, rec.nodes, rec.branches, rec.total_length_m
        );
        let _ = write!(md, ", {:.2} L", rec.volume_l);
        if let Some(e) = rec.mean_skeleton_error_m {
            let _ = write!(md, ", mean skeleton error {:.1} mm", e * 1e3);
        }
        if let Some(v) = rec.volume_ratio {
            let _ = write!(md, ", volume {v:.2} times the true one");
        }
        if !rec.volume_trusted {
            let _ = write!(
                md,
                " (the scan's noise, {:.1} mm, makes the volume run high)",
                1e3 * rec.surface_noise_m.unwrap_or(f64::NAN)
            );
        }
        let _ = writeln!(
            md,
            ". Animation: {} frames in {} m/s wind, {} branches with measured dynamics. Whole run: {:.1} s.\n\nFigures: `figures/branch_<id>.angle.svg` (the relative angle, the paper's signal), `figures/branch_<id>.swing.svg` (the signal ours is fitted on), `figures/branch_<id>.spectrum.svg` (its spectrum over the stretch the fit used); each marks the test window and that stretch.",
            self.animation.frames,
            self.animation.wind_speed_m_s,
            self.animation.measured_branches,
            self.seconds
        );
        md
    }

    /// Write everything into `dir` (created if needed): `report.json`, `report.md`,
    /// `figures/`, `projection.png`, `skeleton.json`, `tree.glb`, `tree.bvh`.
    ///
    /// # Errors
    /// [`PipelineError::Io`] naming the file, or the exporters' errors.
    pub fn write_all(&self, dir: &Path) -> Result<()> {
        let figures = dir.join("figures");
        std::fs::create_dir_all(&figures).map_err(|e| PipelineError::io(&figures, e))?;
        for (b, row) in self.products.branch_results.iter().zip(&self.branches) {
            let base = figures.join(format!("branch_{}", b.id));
            write_atomic(&base.with_extension("angle.svg"), series_svg(b).as_bytes())?;
            write_atomic(&base.with_extension("swing.svg"), swing_svg(b).as_bytes())?;
            write_atomic(
                &base.with_extension("spectrum.svg"),
                spectrum_svg(b, row.true_frequency_hz).as_bytes(),
            )?;
        }
        let anim = &self.products.animation;
        let glb = glb_bytes(&anim.simulation, &anim.poses, &GlbOptions::default())?;
        write_atomic(&dir.join(&self.animation.glb), &glb)?;
        let bvh = bvh_string(&anim.simulation, &anim.poses)?;
        write_atomic(&dir.join(&self.animation.bvh), bvh.as_bytes())?;
        let skeleton = dir.join("skeleton.json");
        self.products.skeleton.write_json(&skeleton)?;
        let png = dir.join("projection.png");
        self.products
            .projection
            .save(&png)
            .map_err(|e| PipelineError::io(&png, std::io::Error::other(e)))?;
        write_atomic(&dir.join("report.md"), self.markdown().as_bytes())?;
        self.write_json(&dir.join("report.json"))
    }
}

/// Write `bytes` to `path` through a temporary file and a rename, so that a failure never
/// leaves half a file.
///
/// # Errors
/// [`PipelineError::Io`] naming the file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = path.with_extension(format!(
        "{}.part",
        path.extension().and_then(|e| e.to_str()).unwrap_or("")
    ));
    std::fs::write(&tmp, bytes).map_err(|e| PipelineError::io(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| PipelineError::io(path, e))
}
