//! The crate's error type.

use std::path::PathBuf;

/// Everything that can go wrong in beam-anim.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AnimError {
    /// A skeleton that is empty, has no root or two, or a parent that does not exist.
    #[error("invalid skeleton: {reason}")]
    InvalidSkeleton {
        /// What is wrong.
        reason: String,
    },
    /// Following parents from this node comes back to it.
    #[error("skeleton node {node} is on a cycle of parent links")]
    Cycle {
        /// A node on the cycle.
        node: usize,
    },
    /// This node's parents never reach the root.
    #[error("skeleton node {node} is not connected to the root")]
    Disconnected {
        /// The node.
        node: usize,
    },
    /// The segment from a node's parent to the node has no length.
    #[error("the segment ending at skeleton node {node} has zero length")]
    ZeroLengthSegment {
        /// The segment's end node.
        node: usize,
    },
    /// A natural frequency that is not positive and finite.
    #[error("{what}: frequency {frequency_hz:e} Hz; must be positive and at most 1000 Hz")]
    InvalidFrequency {
        /// Which branch or entry.
        what: String,
        /// The value given.
        frequency_hz: f64,
    },
    /// A damping ratio outside [0, 1) (the model is an underdamped oscillator).
    #[error("{what}: damping ratio {damping_ratio}; must be in [0, 1)")]
    InvalidDamping {
        /// Which branch or entry.
        what: String,
        /// The value given.
        damping_ratio: f64,
    },
    /// A wind velocity that is not finite.
    #[error("wind velocity {what} is not finite")]
    NonFiniteWind {
        /// Where (segment, time).
        what: String,
    },
    /// A time step that is not positive and finite.
    #[error("time step {dt_s} s; must be positive and finite")]
    InvalidTimeStep {
        /// The value given.
        dt_s: f64,
    },
    /// A parameter that cannot work.
    #[error("{name}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Why.
        reason: String,
    },
    /// A branch id that names no branch of the tree.
    #[error("no branch starts at skeleton node {id}")]
    UnknownBranch {
        /// The id given.
        id: usize,
    },
    /// Explicit Euler cannot keep this branch stable within the sub-step bound.
    #[error(
        "explicit Euler is unstable for branch {branch} (f = {frequency_hz} Hz, damping ratio \
         {damping_ratio}) even with {substeps} sub-steps of the {dt_s} s frame"
    )]
    Unstable {
        /// The branch id.
        branch: usize,
        /// Its frequency.
        frequency_hz: f64,
        /// Its damping ratio.
        damping_ratio: f64,
        /// Sub-steps tried.
        substeps: usize,
        /// The frame step.
        dt_s: f64,
    },
    /// More segments than a glTF skin can address with 16-bit joint indices.
    #[error("{joints} segments need {joints} joints; a glTF export allows at most {max}")]
    TooManyJoints {
        /// Joints needed (one per segment).
        joints: usize,
        /// The limit.
        max: usize,
    },
    /// A size computed from the user's numbers beyond what is accepted (checked before
    /// anything is allocated).
    #[error("{what}: {count} is more than the limit of {limit}")]
    TooLarge {
        /// What would be that large.
        what: String,
        /// The size asked for.
        count: f64,
        /// The largest accepted.
        limit: f64,
    },
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A file's content is not what it should be.
    #[error("{path}: {reason}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

/// Results of this crate.
pub type Result<T> = std::result::Result<T, AnimError>;

impl AnimError {
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn format(path: &std::path::Path, reason: impl Into<String>) -> Self {
        Self::Format {
            path: path.to_path_buf(),
            reason: reason.into(),
        }
    }

    pub(crate) fn param(name: &'static str, reason: impl Into<String>) -> Self {
        Self::InvalidParameter {
            name,
            reason: reason.into(),
        }
    }
}
