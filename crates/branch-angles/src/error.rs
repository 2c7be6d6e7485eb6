//! The crate's error type.

use thiserror::Error;

/// Everything that can go wrong in branch-angles. Each variant names what was wrong.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum AngleError {
    /// A hierarchy with no marker.
    #[error("the hierarchy has no marker")]
    EmptyHierarchy,
    /// A marker id that is empty or holds a comma, quote or line break (it could not be a CSV
    /// column name).
    #[error("marker id {id:?} is empty or holds a comma, quote or line break")]
    InvalidId {
        /// The id.
        id: String,
    },
    /// The same id twice.
    #[error("marker {id:?} appears more than once")]
    DuplicateId {
        /// The repeated id.
        id: String,
    },
    /// A parent that is not a marker of the hierarchy.
    #[error("marker {id:?} has parent {parent:?}, which is not in the hierarchy")]
    UnknownParent {
        /// The child.
        id: String,
        /// Its parent.
        parent: String,
    },
    /// No marker without a parent.
    #[error("no root: every marker has a parent")]
    NoRoot,
    /// More than one marker without a parent.
    #[error("more than one root: {ids:?} have no parent")]
    SeveralRoots {
        /// The markers without a parent.
        ids: Vec<String>,
    },
    /// Parents that form a cycle.
    #[error("the parents form a cycle: {ids:?}")]
    Cycle {
        /// The markers on the cycle, in parent order.
        ids: Vec<String>,
    },
    /// A marker that the hierarchy or the trajectories do not know.
    #[error("unknown marker {id:?}")]
    UnknownMarker {
        /// The id.
        id: String,
    },
    /// A timestamp that is not finite.
    #[error("{what}: timestamp {t_s} s is not finite")]
    NonFiniteTimestamp {
        /// Where.
        what: String,
        /// The timestamp.
        t_s: f64,
    },
    /// Timestamps that go backwards.
    #[error("{what}: timestamp {t_s} s comes after {previous_s} s")]
    UnsortedTimestamps {
        /// Where.
        what: String,
        /// The earlier timestamp, written second.
        t_s: f64,
        /// The timestamp before it.
        previous_s: f64,
    },
    /// The same timestamp twice for one marker.
    #[error("{what}: timestamp {t_s} s appears twice")]
    DuplicateTimestamp {
        /// Where.
        what: String,
        /// The timestamp.
        t_s: f64,
    },
    /// A coordinate that is NaN or infinite (a lost frame is an empty position, not a NaN).
    #[error("{what}: coordinate {value} is not finite (write a lost frame as an empty position)")]
    NonFiniteCoordinate {
        /// Where.
        what: String,
        /// The value.
        value: f64,
    },
    /// A coordinate farther from the origin than any position on Earth.
    #[error(
        "{what}: coordinate {value:e} m is beyond {limit_m:e} m (further than any point on Earth from any origin): a corrupt value?"
    )]
    CoordinateOutOfRange {
        /// Where.
        what: String,
        /// The value, metres.
        value: f64,
        /// The limit, metres.
        limit_m: f64,
    },
    /// A marker with a trajectory that the hierarchy does not name.
    #[error(
        "the trajectories hold marker {id:?}, which the hierarchy does not name (add it with its parent, or remove its rows)"
    )]
    NotInHierarchy {
        /// The id.
        id: String,
    },
    /// Parallel sequences of different lengths.
    #[error("{what}: {found} values for {expected} timestamps")]
    LengthMismatch {
        /// What.
        what: String,
        /// Expected length.
        expected: usize,
        /// Found length.
        found: usize,
    },
    /// A configuration field out of its range.
    #[error("invalid parameter {name}: {reason}")]
    InvalidParameter {
        /// The field.
        name: &'static str,
        /// Why.
        reason: String,
    },
    /// A JSON file that does not parse or does not have the expected shape.
    #[error("JSON, line {line}, column {column}: {message}")]
    Json {
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A CSV file with a malformed line.
    #[error("CSV line {line}: {message}")]
    Csv {
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

impl AngleError {
    pub(crate) fn param(name: &'static str, reason: impl Into<String>) -> Self {
        Self::InvalidParameter {
            name,
            reason: reason.into(),
        }
    }

    pub(crate) fn csv(line: usize, message: impl Into<String>) -> Self {
        Self::Csv {
            line,
            message: message.into(),
        }
    }
}

impl From<serde_json::Error> for AngleError {
    fn from(e: serde_json::Error) -> Self {
        Self::Json {
            line: e.line(),
            column: e.column(),
            message: e.to_string(),
        }
    }
}

/// Result with [`AngleError`].
pub type Result<T> = std::result::Result<T, AngleError>;
