//! The pipeline's one error type: each crate's error, with where in the method it happened.

use std::path::{Path, PathBuf};

use thiserror::Error;

/// Result with [`PipelineError`].
pub type Result<T, E = PipelineError> = std::result::Result<T, E>;

/// What went wrong running the method.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum PipelineError {
    /// A file or directory could not be read or written.
    #[error("cannot access {}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    /// The markers file is not valid (`docs/capture.md` describes it).
    #[error("markers file {}: {reason}", path.display())]
    Markers {
        /// The file (empty when the markers were given in memory).
        path: PathBuf,
        /// What is wrong, naming the marker and field.
        reason: String,
    },
    /// A configuration value is out of range.
    #[error("invalid {name}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: String,
        /// Why it is invalid, with its value.
        reason: String,
    },
    /// The recording cannot be measured as given (too short, no rigid calibration, a
    /// marker window outside it).
    #[error("recording {}: {reason}", path.display())]
    Recording {
        /// The recording's directory.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// One frame could not be read or processed.
    #[error("frame {index}: {stage}: {source}")]
    Frame {
        /// Index of the frame, from 0.
        index: usize,
        /// The step that failed (`read`, `cloud`, `projection image`, `tracking`).
        stage: &'static str,
        /// The cause.
        #[source]
        source: Box<PipelineError>,
    },
    /// The frame workers stopped before frame `index` arrived (a worker panicked or could
    /// not start).
    #[error("frame {index}: the frame workers stopped")]
    WorkersStopped {
        /// The frame waited for.
        index: usize,
    },
    /// No marker window lies on the first frame's projection image.
    #[error("no marker window lies on the first frame ({dropped})")]
    NoMarkerOnFirstFrame {
        /// Each marker and why it was left out.
        dropped: String,
    },
    /// A stage of the method failed as a whole.
    #[error("{stage}: {source}")]
    Stage {
        /// The stage (`marker hierarchy`, `branch angles`, `reconstruction`, `animation`, ...).
        stage: &'static str,
        /// The cause.
        #[source]
        source: Box<PipelineError>,
    },
    /// The digital twin could not be built or rendered.
    #[cfg(feature = "twin")]
    #[error("digital twin: {reason}")]
    Twin {
        /// What failed.
        reason: String,
    },
    /// Writing JSON failed.
    #[error("cannot encode {what} as JSON: {source}")]
    Json {
        /// What was encoded.
        what: &'static str,
        /// The encoder's error.
        #[source]
        source: serde_json::Error,
    },
    /// From kinect-io: calibration, recordings, clouds, projection, lifting.
    #[error(transparent)]
    Kinect(#[from] kinect_io::KinectError),
    /// From meanshift-track.
    #[error(transparent)]
    Track(#[from] meanshift_track::TrackError),
    /// From branch-angles.
    #[error(transparent)]
    Angles(#[from] branch_angles::AngleError),
    /// From modal-estimate.
    #[error(transparent)]
    Modal(#[from] modal_estimate::ModalError),
    /// From space-colonize.
    #[error(transparent)]
    Colonize(#[from] space_colonize::ColonizeError),
    /// From beam-anim.
    #[error(transparent)]
    Anim(#[from] beam_anim::AnimError),
}

impl PipelineError {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn frame(index: usize, stage: &'static str, source: impl Into<Self>) -> Self {
        Self::Frame {
            index,
            stage,
            source: Box::new(source.into()),
        }
    }

    pub(crate) fn param(name: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::InvalidParameter {
            name: name.into(),
            reason: reason.into(),
        }
    }
}

/// Name the stage of an error: `result.stage("branch angles")`.
pub(crate) trait StageExt<T> {
    fn stage(self, stage: &'static str) -> Result<T>;
}

impl<T, E: Into<PipelineError>> StageExt<T> for std::result::Result<T, E> {
    fn stage(self, stage: &'static str) -> Result<T> {
        self.map_err(|e| PipelineError::Stage {
            stage,
            source: Box::new(e.into()),
        })
    }
}
