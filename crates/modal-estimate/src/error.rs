//! The crate's error type.

use thiserror::Error;

/// Everything that can go wrong in modal-estimate. Each variant names what was wrong.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ModalError {
    /// Timestamps and values of different lengths.
    #[error("{times} timestamps but {values} values")]
    LengthMismatch {
        /// Number of timestamps.
        times: usize,
        /// Number of values.
        values: usize,
    },
    /// A timestamp that is NaN or infinite.
    #[error("timestamp {index} is {time_s} s, which is not finite")]
    NonFiniteTime {
        /// Sample index.
        index: usize,
        /// The timestamp, seconds.
        time_s: f64,
    },
    /// A timestamp not later than the one before it.
    #[error("timestamp {index} ({time_s} s) is not after the one before it ({previous_s} s)")]
    NonIncreasingTime {
        /// Sample index.
        index: usize,
        /// The timestamp before, seconds.
        previous_s: f64,
        /// The offending timestamp, seconds.
        time_s: f64,
    },
    /// A value that is NaN or infinite (a missing sample is `None`, not NaN).
    #[error(
        "value {index} (t = {time_s} s) is {value}, which is not finite; use an empty value for a missing sample"
    )]
    NonFiniteValue {
        /// Sample index.
        index: usize,
        /// Its timestamp, seconds.
        time_s: f64,
        /// The value.
        value: f64,
    },
    /// Too few samples (present ones) for what was asked.
    #[error("{what} needs at least {needed} samples, the record has {present}")]
    TooFewSamples {
        /// What needed them.
        what: &'static str,
        /// Samples with a value.
        present: usize,
        /// Samples needed.
        needed: usize,
    },
    /// Every value is missing.
    #[error("every one of the {samples} samples is missing")]
    AllMissing {
        /// Number of samples.
        samples: usize,
    },
    /// Every present value is the same: there is nothing to oscillate.
    #[error("the signal is constant ({value}); there is no oscillation to measure")]
    Constant {
        /// The value.
        value: f64,
    },
    /// A record too short for the lowest frequency asked for.
    #[error(
        "the record lasts {duration_s} s, shorter than one cycle at {frequency_hz} Hz ({needed_s} s)"
    )]
    RecordTooShort {
        /// Record length, seconds.
        duration_s: f64,
        /// The frequency, hertz.
        frequency_hz: f64,
        /// Needed length, seconds.
        needed_s: f64,
    },
    /// A frequency band that is empty, negative or not finite.
    #[error("the band {low_hz}..{high_hz} Hz is not a band (need 0 <= low < high, finite)")]
    InvalidBand {
        /// Lower edge, hertz.
        low_hz: f64,
        /// Upper edge, hertz.
        high_hz: f64,
    },
    /// A frequency band that reaches past the Nyquist frequency of the record.
    #[error(
        "the band reaches {high_hz} Hz, beyond the Nyquist frequency {nyquist_hz} Hz of the record"
    )]
    BandAboveNyquist {
        /// Upper band edge, hertz.
        high_hz: f64,
        /// Nyquist frequency (half the median sample rate), hertz.
        nyquist_hz: f64,
    },
    /// A configuration value out of its range.
    #[error("invalid {name}: {reason}")]
    InvalidParameter {
        /// The field.
        name: &'static str,
        /// Its value and what it must be.
        reason: String,
    },
    /// No spectral peak in the band (the signal has no oscillation there).
    #[error("no spectral peak between {low_hz} and {high_hz} Hz")]
    NoPeak {
        /// Lower edge, hertz.
        low_hz: f64,
        /// Upper edge, hertz.
        high_hz: f64,
    },
    /// A numerical step failed (a singular system, a decomposition that did not converge).
    #[error("numerical failure in {what}")]
    Numerical {
        /// The step.
        what: &'static str,
    },
    /// A value so far from the rest of the record that it cannot be a measurement (a
    /// corrupt sample, a sentinel such as 1e308, a unit mix-up).
    #[error(
        "value {index} (t = {time_s} s) is {value:e}, {spreads:.1e} median absolute deviations from the record's median (at most 1e9 is taken as a measurement): a corrupt sample? Remove it or leave it empty (missing)"
    )]
    Outlier {
        /// Sample index.
        index: usize,
        /// Its timestamp, seconds.
        time_s: f64,
        /// The value.
        value: f64,
        /// Its distance from the median in median absolute deviations.
        spreads: f64,
    },
    /// A size computed from the input beyond what the routine accepts.
    #[error("{what}: {count} is more than the limit of {limit}")]
    TooLarge {
        /// What would be that large, and why.
        what: String,
        /// The size asked for.
        count: f64,
        /// The largest accepted.
        limit: usize,
    },
    /// A malformed line in a signal CSV file.
    #[error("line {line}: {message}")]
    Csv {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A file that could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
}

/// Result with [`ModalError`].
pub type Result<T> = std::result::Result<T, ModalError>;
