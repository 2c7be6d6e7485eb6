//! The crate's error type.

use thiserror::Error;

/// Everything that can go wrong in space-colonize. Each variant names what was wrong.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ColonizeError {
    /// Fewer points than a tree model needs.
    #[error("the cloud has {points} points; a tree model needs at least {needed}")]
    TooFewPoints {
        /// Points given (finite ones).
        points: usize,
        /// Minimum accepted.
        needed: usize,
    },
    /// A coordinate that is NaN or infinite.
    #[error("point {index} is ({x}, {y}, {z}), which is not finite")]
    NonFinitePoint {
        /// Index of the point in the input.
        index: usize,
        /// x, metres.
        x: f64,
        /// y, metres.
        y: f64,
        /// z, metres.
        z: f64,
    },
    /// A coordinate farther from the origin than any point on Earth.
    #[error(
        "point {index} is ({x:e}, {y:e}, {z:e}) m, beyond {limit_m:e} m (further than any point on Earth from any origin): a corrupt value?"
    )]
    PointOutOfRange {
        /// Index of the point in the input.
        index: usize,
        /// x, metres.
        x: f64,
        /// y, metres.
        y: f64,
        /// z, metres.
        z: f64,
        /// The limit, metres.
        limit_m: f64,
    },
    /// All points identical, on a line or in a plane: nothing three-dimensional to grow into.
    #[error(
        "the cloud is degenerate: its extents along its principal axes are {extents_m:?} m (a tree needs all three above {min_m} m)"
    )]
    Degenerate {
        /// Standard deviations along the three principal axes, largest first, metres.
        extents_m: [f64; 3],
        /// The smallest accepted, metres.
        min_m: f64,
    },
    /// A parameter outside its valid range, or parameters that cannot work together.
    #[error("invalid parameter {name}: {reason}")]
    InvalidParameter {
        /// Which parameter.
        name: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// Growth did not finish within its iteration bound.
    #[error(
        "growth stopped at its bound of {iterations} iterations with {nodes} nodes and {unreached} points still unreached (raise max_iterations, or check the step and kill distance)"
    )]
    IterationLimit {
        /// Iterations run.
        iterations: usize,
        /// Nodes grown.
        nodes: usize,
        /// Attraction points neither killed nor given up.
        unreached: usize,
    },
    /// Growth reached its node bound.
    #[error(
        "growth reached its bound of {nodes} nodes with {unreached} points still unreached (raise max_nodes or the step)"
    )]
    NodeLimit {
        /// Nodes grown.
        nodes: usize,
        /// Attraction points neither killed nor given up.
        unreached: usize,
    },
    /// Every point was within the kill distance of the root: nothing to grow.
    #[error(
        "nothing grew: all {points} points are within the kill distance ({kill_distance_m} m) of the root; set a smaller kill distance"
    )]
    NoGrowth {
        /// Points of the main cluster.
        points: usize,
        /// Kill distance used, metres.
        kill_distance_m: f64,
    },
    /// A skeleton that is not a tree (cycle, second root, dangling parent, bad id).
    #[error("invalid skeleton: {reason}")]
    InvalidSkeleton {
        /// What is wrong.
        reason: String,
    },
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A file that is not in the expected format.
    #[error("{}: {reason}", path.display())]
    Format {
        /// The file.
        path: std::path::PathBuf,
        /// What is wrong, with the line where known.
        reason: String,
    },
}

impl ColonizeError {
    pub(crate) fn param(name: &'static str, reason: impl Into<String>) -> Self {
        Self::InvalidParameter {
            name,
            reason: reason.into(),
        }
    }

    pub(crate) fn skeleton(reason: impl Into<String>) -> Self {
        Self::InvalidSkeleton {
            reason: reason.into(),
        }
    }

    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// Result with [`ColonizeError`].
pub type Result<T> = std::result::Result<T, ColonizeError>;
