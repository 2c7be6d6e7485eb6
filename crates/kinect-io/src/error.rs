//! The one error type of this crate.

use std::path::{Path, PathBuf};

/// Everything that can go wrong in `kinect-io`.
///
/// Every variant that concerns a file names the file (`path`); data handed over in memory is
/// named by a short label in `path` instead (for example `<bytes>`). No function of this crate
/// panics on bad input: it returns one of these.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum KinectError {
    /// The operating system refused to read or write a file or directory.
    #[error("{path}: {source}", path = path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    /// A file's content does not follow its format.
    #[error("{path}: {what}", path = path.display())]
    Format {
        /// The file (or in-memory label).
        path: PathBuf,
        /// What is wrong, in words, with the line or byte offset where known.
        what: String,
    },
    /// A file's header declares more (or fewer) items than the file holds.
    #[error(
        "{path}: the header declares {declared} {what} but the file holds {found}",
        path = path.display()
    )]
    CountMismatch {
        /// The file (or in-memory label).
        path: PathBuf,
        /// What is counted (`"vertices"`, `"points"`, ...).
        what: &'static str,
        /// How many the header declares.
        declared: usize,
        /// How many were actually found (a lower bound when the file is truncated).
        found: usize,
    },
    /// A depth image is not a single-channel 16-bit image.
    #[error(
        "{path}: a depth image must be single-channel 16-bit, this one is {found}",
        path = path.display()
    )]
    DepthNot16Bit {
        /// The image file.
        path: PathBuf,
        /// The pixel format found, in words.
        found: String,
    },
    /// An image could not be decoded or encoded.
    #[error("{path}: image codec error: {what}", path = path.display())]
    Image {
        /// The image file.
        path: PathBuf,
        /// What the codec said.
        what: String,
    },
    /// Two things that must have the same size do not.
    #[error(
        "{what}: expected {expected_width}x{expected_height} px, found {found_width}x{found_height} px"
    )]
    SizeMismatch {
        /// What was compared (names the file where there is one).
        what: String,
        /// Expected width in pixels.
        expected_width: u32,
        /// Expected height in pixels.
        expected_height: u32,
        /// Actual width in pixels.
        found_width: u32,
        /// Actual height in pixels.
        found_height: u32,
    },
    /// A calibration file or value is malformed or physically impossible.
    #[error("calibration {path}: {what}", path = path.display())]
    Calibration {
        /// The calibration file (or in-memory label).
        path: PathBuf,
        /// What is wrong.
        what: String,
    },
    /// A parameter given in code is out of its valid range.
    #[error("invalid {name}: {reason}")]
    InvalidParameter {
        /// The parameter's name, as in the API.
        name: &'static str,
        /// Why it is invalid (with the value and its unit).
        reason: String,
    },
    /// A depth image holds no valid depth at all (all zero or out of range).
    #[error("{what}: no valid depth pixel (all zero, NaN or out of range)")]
    NoValidDepth {
        /// Names the frame or file.
        what: String,
    },
    /// A frame index beyond the end of a recording.
    #[error("frame {index} is out of range: the recording {path} has {count} frames", path = path.display())]
    FrameOutOfRange {
        /// The recording directory.
        path: PathBuf,
        /// The index asked for.
        index: usize,
        /// The number of frames in the recording.
        count: usize,
    },
    /// A directory is neither a native recording nor a TUM RGB-D sequence.
    #[error("{path}: not a recording: {what}", path = path.display())]
    UnknownLayout {
        /// The directory.
        path: PathBuf,
        /// What was looked for.
        what: String,
    },
    /// A feature of a file format that this crate does not read (named precisely).
    #[error("{path}: unsupported: {what}", path = path.display())]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// What is not supported.
        what: String,
    },
}

impl KinectError {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn format(path: &Path, what: impl Into<String>) -> Self {
        Self::Format {
            path: path.to_path_buf(),
            what: what.into(),
        }
    }

    pub(crate) fn calibration(path: &Path, what: impl Into<String>) -> Self {
        Self::Calibration {
            path: path.to_path_buf(),
            what: what.into(),
        }
    }

    pub(crate) fn param(name: &'static str, reason: impl Into<String>) -> Self {
        Self::InvalidParameter {
            name,
            reason: reason.into(),
        }
    }
}

/// Label used in errors for data parsed from memory rather than from a file.
pub(crate) const MEMORY_LABEL: &str = "<bytes>";

/// Result alias of this crate.
pub type Result<T, E = KinectError> = std::result::Result<T, E>;
