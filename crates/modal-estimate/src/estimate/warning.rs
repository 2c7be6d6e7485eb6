//! The warnings that go with an estimate.

use std::fmt;

use serde::{Serialize, Serializer};

/// Something the caller should know about an estimate.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Warning {
    /// Missing samples or irregular timestamps were bridged by linear interpolation for the
    /// spectrum or the matrix pencil (the fit itself uses the measured samples only).
    Interpolated {
        /// Grid samples interpolated.
        samples: usize,
    },
    /// No held stretch before the motion: the decay is taken from the record's start.
    NoRelease,
    /// The segment holds few cycles of the dominant mode.
    ShortDecay {
        /// Cycles in the segment.
        cycles: f64,
    },
    /// Damping ratio too uncertain to trust.
    DampingUncertain {
        /// Coefficient of variation of the damping ratio.
        cov: f64,
        /// Cycles in the record.
        cycles: f64,
        /// Cycles that would bring the c.o.v. to the configured limit.
        cycles_needed: f64,
    },
    /// Fewer modes found than asked for.
    ModesNotResolved {
        /// Asked for.
        requested: usize,
        /// Found.
        found: usize,
    },
    /// The nonlinear fit stopped at its iteration limit.
    NotConverged {
        /// Iterations run.
        iterations: usize,
    },
    /// The half-power band did not close on one side: no damping ratio.
    HalfPowerOpen,
    /// The paper's method has no uncertainty model: the frequency standard error given is
    /// the bin quantisation (bin width / sqrt 12), the damping's is unknown.
    PaperUncertainty {
        /// Bin width, hertz.
        bin_width_hz: f64,
    },
    /// The record was judged ambient (no release, no decay).
    Ambient {
        /// Random-decrement segments averaged.
        triggers: usize,
    },
    /// The mode found is far from the record's spectral peak.
    FarFromPeak {
        /// The mode's frequency, hertz.
        frequency_hz: f64,
        /// The peak's, hertz.
        peak_hz: f64,
    },
    /// A mode outside the band searched (the fit or the spectrum's edge pulled it out).
    OutsideBand {
        /// The mode's frequency, hertz.
        frequency_hz: f64,
        /// Lower band edge, hertz.
        low_hz: f64,
        /// Upper band edge, hertz.
        high_hz: f64,
    },
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Interpolated { samples } => write!(
                f,
                "{samples} missing or irregular samples were interpolated for the spectrum and the matrix pencil; the fit uses measured samples only"
            ),
            Self::NoRelease => write!(
                f,
                "no held stretch before the motion: the decay is taken from the start of the record"
            ),
            Self::ShortDecay { cycles } => write!(
                f,
                "the decay segment holds only {cycles:.1} cycles; frequency and damping are uncertain"
            ),
            Self::DampingUncertain {
                cov,
                cycles,
                cycles_needed,
            } => write!(
                f,
                "damping ratio c.o.v. is {:.0} % with {cycles:.0} cycles (Au's rule 1/sqrt(2 pi xi N)); about {cycles_needed:.0} cycles are needed for a trustworthy damping",
                100.0 * cov
            ),
            Self::ModesNotResolved { requested, found } => {
                write!(f, "{requested} modes requested, {found} could be resolved")
            }
            Self::NotConverged { iterations } => write!(
                f,
                "the nonlinear fit stopped after {iterations} iterations without converging"
            ),
            Self::HalfPowerOpen => write!(
                f,
                "the half-power band does not close on both sides of the peak: no damping ratio"
            ),
            Self::PaperUncertainty { bin_width_hz } => write!(
                f,
                "the paper's method has no uncertainty model: frequency_std_hz is the bin quantisation ({bin_width_hz:.4} Hz / sqrt 12), damping_std is unknown"
            ),
            Self::Ambient { triggers } => write!(
                f,
                "no free decay: treated as an ambient record (random decrement over {triggers} triggers)"
            ),
            Self::FarFromPeak {
                frequency_hz,
                peak_hz,
            } => write!(
                f,
                "the mode found ({frequency_hz:.4} Hz) is far from the record's spectral peak ({peak_hz:.4} Hz): check the band (--band) and the column"
            ),
            Self::OutsideBand {
                frequency_hz,
                low_hz,
                high_hz,
            } => write!(
                f,
                "a mode at {frequency_hz:.4} Hz lies outside the band searched ({low_hz:.4}..{high_hz:.4} Hz)"
            ),
        }
    }
}

impl Serialize for Warning {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
    }
}
