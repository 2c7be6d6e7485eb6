//! The twin through the pipeline: measured in memory against its truth, or written as a
//! native recording with its markers file, to run the recording path on.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use kinect_io::synth::Renderer;
use kinect_io::{ColorFormat, RecordingWriter};
use nalgebra::Point3;

use super::{Twin, twin_error};
use crate::capture::CaptureSetup;
use crate::error::{PipelineError, Result};
use crate::markers::{MarkerEntry, MarkersFile};
use crate::pipeline::{Measured, Pipeline, Stage, Truth};
use crate::report::Report;

/// A tracked centre within this distance of the truth is on the marker (pixels of the
/// tracking plane; the tracker's own accuracy goal, meanshift-track).
pub const TRACK_TOLERANCE_PX: f64 = 3.0;

/// JPEG quality for a twin recording like a Kinect V2's (which delivers JPEG).
pub const TWIN_JPEG_QUALITY: u8 = 95;

impl Pipeline {
    /// Run the method on a twin's frames in memory and compare every number with the
    /// truth: the report's rows carry the true frequency and damping, the tracking summary
    /// the share of frames within [`TRACK_TOLERANCE_PX`] and the median lift error, the
    /// reconstruction summary the skeleton error.
    ///
    /// # Errors
    /// [`PipelineError::Twin`] when the twin cannot be rendered, and the errors of
    /// [`Pipeline::run`].
    pub fn run_twin(&self, twin: &Twin) -> Result<Report> {
        let started = Instant::now();
        let renderer =
            Renderer::new(&twin.synth).map_err(|e| twin_error(format!("renderer: {e}")))?;
        // The same windows and the same set-up as the recording path: a twin written with
        // `write_twin_recording` in PNG and measured with `run` gives the same branches.
        let markers = twin.markers_file(&renderer)?;
        let setup = self.setup(
            twin.synth.calibration.clone(),
            &markers,
            Path::new("<twin>"),
        )?;
        let produce = |i: usize| twin.frame(&renderer, i);
        let tree_to_depth = twin.synth.world_to_depth;
        let measured = self.measure(
            &setup,
            twin.times_s.len(),
            &produce,
            tree_to_depth.inverse(),
            &twin.windows_s(),
        )?;
        let truth = Truth {
            within_3px: within_tolerance(twin, &setup, &measured),
            skeleton: Some(&twin.skeleton),
            dynamics: twin
                .markers
                .iter()
                .map(|m| (m.id.clone(), (m.truth.frequency_hz, m.truth.damping_ratio)))
                .collect(),
            median_lift_error_mm: lift_error_mm(twin, &measured),
        };
        self.finish(started, measured, &truth)
    }

    /// Write the twin's capture as a native recording in `dir` (colour as `color`: the
    /// Kinect V2 delivers JPEG, [`TWIN_JPEG_QUALITY`] is close to it; PNG keeps the frames
    /// exact; 16-bit depth) with its `markers.json` (the user's windows on the first colour
    /// image, each branch's test window). Returns the markers file written.
    ///
    /// # Errors
    /// [`PipelineError::Twin`] when the twin cannot be rendered, kinect-io's errors naming
    /// the file when the recording cannot be written.
    pub fn write_twin_recording(
        &self,
        twin: &Twin,
        dir: &Path,
        color: ColorFormat,
    ) -> Result<MarkersFile> {
        let renderer =
            Renderer::new(&twin.synth).map_err(|e| twin_error(format!("renderer: {e}")))?;
        let file = twin.markers_file(&renderer)?;
        let mut writer = RecordingWriter::create(dir, &twin.synth.calibration, color)?;
        let n = twin.scenes.len();
        for i in 0..n {
            let frame = twin.frame(&renderer, i)?;
            writer
                .write_frame(frame.time_s, &frame.color, &frame.depth)
                .map_err(|e| PipelineError::frame(i, "write", e))?;
            self.report_progress(Stage::Record, i + 1, n);
        }
        file.write(&dir.join("markers.json"))?;
        Ok(file)
    }
}

impl Twin {
    /// The markers file a user would write for the twin: each marker's window on the first
    /// colour image (its true centre with the user's placement error, rounded to whole
    /// pixels as a user draws it), each branch's test window, the camera's height.
    ///
    /// # Errors
    /// [`PipelineError::Twin`] when the first frame cannot be rendered or a marker is not
    /// visible on it.
    pub fn markers_file(&self, renderer: &Renderer) -> Result<MarkersFile> {
        let windows = self.windows(renderer, 1.0)?;
        let markers = self
            .markers
            .iter()
            .zip(&windows)
            .map(|(m, w)| {
                let side = f64::from(w.size_px);
                MarkerEntry {
                    id: m.id.clone(),
                    parent: m.parent.clone(),
                    x: (w.center.x - side / 2.0).round(),
                    y: (w.center.y - side / 2.0).round(),
                    w: side,
                    h: side,
                    window_s: (m.level > 0).then_some([m.window_s.0, m.window_s.1]),
                }
            })
            .collect();
        let camera = self.synth.world_to_depth.inverse() * Point3::origin();
        Ok(MarkersFile {
            markers,
            camera_height_m: Some(camera.z),
            pitch_down_deg: Some(0.0),
            source: None,
        })
    }
}

/// Per marker, the share of frames whose tracked centre lies within [`TRACK_TOLERANCE_PX`]
/// of the marker's true centre on the tracking plane.
fn within_tolerance(
    twin: &Twin,
    setup: &CaptureSetup,
    measured: &Measured,
) -> BTreeMap<String, f64> {
    let capture = &measured.capture;
    let tree_to_depth = twin.synth.world_to_depth;
    let mut out = BTreeMap::new();
    for (k, id) in capture.ids.iter().enumerate() {
        let Some(m) = twin.scenes[0].markers.iter().position(|m| m.id == *id) else {
            continue;
        };
        let near = capture.centers[k]
            .iter()
            .enumerate()
            .filter(|(f, c)| {
                let p =
                    setup.cloud_to_plane * (tree_to_depth * twin.scenes[*f].markers[m].center_m);
                match (c, setup.plane.project(&p)) {
                    (Some(c), Some(t)) => (c - t).norm() <= TRACK_TOLERANCE_PX,
                    _ => false,
                }
            })
            .count();
        out.insert(
            id.clone(),
            near as f64 / capture.times_s.len().max(1) as f64,
        );
    }
    out
}

/// Median distance of the lifted positions from the markers' true centres, millimetres.
fn lift_error_mm(twin: &Twin, measured: &Measured) -> Option<f64> {
    let capture = &measured.capture;
    let tree_to_depth = twin.synth.world_to_depth;
    let mut errors_mm = Vec::new();
    for (k, id) in capture.ids.iter().enumerate() {
        let Some(m) = twin.scenes[0].markers.iter().position(|m| m.id == *id) else {
            continue;
        };
        for (f, p) in capture.positions_m[k].iter().enumerate() {
            if let Some(p) = p {
                let truth = tree_to_depth * twin.scenes[f].markers[m].center_m;
                errors_mm.push((p - truth).norm() * 1e3);
            }
        }
    }
    crate::stats::median(&mut errors_mm)
}
