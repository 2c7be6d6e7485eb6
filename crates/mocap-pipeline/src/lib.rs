//! The paper's whole method as one library call: a recording (kinect-io) and its markers
//! file in; each marked branch's natural frequency and damping ratio (ours and the paper's
//! method side by side, each with its quality), the static tree rebuilt from the still
//! frames, and that tree animated in wind with the measured dynamics out, as a [`Report`].
//!
//! ```no_run
//! use std::path::Path;
//! use kinect_io::Recording;
//! use mocap_pipeline::{MarkersFile, Pipeline, PipelineConfig, Report};
//!
//! # fn main() -> Result<(), mocap_pipeline::PipelineError> {
//! let recording = Recording::open(Path::new("capture"))?;
//! let markers = MarkersFile::read(Path::new("capture/markers.json"))?;
//! let report: Report = Pipeline::new(PipelineConfig::default())?.run(&recording, &markers)?;
//! for b in &report.branches {
//!     println!("{}: {:?} Hz, damping ratio {:?}", b.id, b.frequency_hz, b.damping_ratio);
//! }
//! report.write_json(Path::new("report.json"))?;
//! # Ok(())
//! # }
//! ```
//!
//! The stages, in order (each crate's own docs say more):
//! 1. **capture** ([`capture`]): per frame, on worker threads, the textured cloud and its
//!    projection image on the colour camera's plane; on the calling thread, in frame order,
//!    the markers tracked on that image (meanshift-track) and lifted to 3D through it.
//! 2. **analysis** ([`analysis`]): the hierarchy of the tracked markers, the lifted
//!    trajectories in the tree frame with lifts that landed on another surface taken out,
//!    the relative angles of eq. (1), and each branch's modes: ours fitted on the child's
//!    displacement from its parent along its main direction of motion (free decay, at the
//!    Cramér–Rao bound), the paper's FFT peak and half-power damping on the angle; the
//!    branch's own mode is the strongest one that is none of its ancestors'.
//! 3. **reconstruction**: the still frames' steady pixels, cropped to the markers' reach
//!    and above the ground, through space colonization.
//! 4. **animation**: the measured dynamics onto the rebuilt tree's branches nearest each
//!    marker (beam-anim), the rest by the paper's defaults, in turbulent wind.
//!
//! With the feature `twin` (default), [`twin`] builds a digital twin whose every true
//! value is known, and [`Pipeline::run_twin`] measures it against that truth.
//!
//! The library never prints: long stages report through [`Pipeline::with_progress`].

#![forbid(unsafe_code)]

pub mod analysis;
pub mod capture;
mod error;
mod markers;
mod pipeline;
pub mod quality;
pub mod report;
mod stats;
#[cfg(feature = "twin")]
pub mod twin;

pub use analysis::BranchResult;
pub use capture::{DroppedMarker, RawFrame};
pub use error::{PipelineError, Result};
pub use markers::{DEFAULT_CAMERA_HEIGHT_M, MIN_WINDOW_PX, MarkerEntry, MarkersFile};
pub use pipeline::{
    MAX_ANIMATION_S, MAX_THREADS, Pipeline, PipelineConfig, Progress, ProgressFn, Stage,
};
pub use quality::BranchQuality;
pub use report::{BranchRow, Report};
pub use stats::median;
