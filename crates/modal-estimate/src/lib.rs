//! Natural frequency and damping ratio of a branch from its angle series (paper, sections
//! 5.3–5.4 and Table 1), at the Cramér–Rao bound, with the paper's FFT method as baseline.
//!
//! Place in the pipeline: branch-angles turns 3D marker trajectories into one angle series
//! per branch; this crate measures each series' modes; beam-anim animates the tree with them.
//!
//! - [`Signal`]: timestamps (seconds, strictly increasing, irregular allowed) and values with
//!   explicit missing samples ([`Signal::from_measured`] takes branch-angles' `Series` with its
//!   measured mask). [`csv`] reads and writes `t,value` files.
//! - [`estimate`] with [`EstimateConfig`]:
//!   - [`Method::Pencil`], free decay: the release of a pull-and-release is found (a held
//!     stretch, then motion), the fit starts half a cycle later and ends where the decay
//!     sinks below half the noise ([`SegmentConfig`]); a matrix pencil on the signal
//!     subspace of a Hankel matrix gives starting poles, then bounded Levenberg–Marquardt
//!     fits `offset + drift + sum of damped sines` on the measured samples at their own
//!     timestamps. Each [`Mode`] has f_n, xi, f_d, amplitude, phase and standard errors from
//!     the Jacobian; the number of modes is chosen by BIC (or fixed).
//!   - [`Method::Ambient`], wind-driven records: Welch peak, zero-phase band-pass, random
//!     decrement, then the free-decay fit of the signature; uncertainties and the warning
//!     for a record too short for damping from Au's uncertainty law
//!     (c.o.v.(xi) = 1/sqrt(2 pi xi N_cycles)).
//!   - [`Method::Paper`] ([`EstimateConfig::paper`]): rectangular-window FFT from the release,
//!     the peak bin, the half-power band interpolated between bins, xi = delta_f / (2 f)
//!     (eq. 6). Its frequencies are multiples of the bin width (30/409 Hz for the paper's
//!     records).
//!   - [`Method::Auto`] (default): free decay unless the record is long and its motion does
//!     not die out.
//! - [`spectrum`]: detrend, window, zero-padding, amplitude or PSD with units, peaks with
//!   prominence; [`welch`].
//! - [`ModalTable`]: Table 1 across branches and tests, the frequency most branches share,
//!   damping by level and the fill for unmeasured branches.
//! - [`cramer_rao_bound`] and [`synthetic`] records with known modes, for validation.
//!
//! Units: seconds, hertz, radians; amplitudes in the signal's unit. Nothing here panics on
//! input: bad records are [`ModalError`]s, doubtful ones carry [`Warning`]s.
//!
//! ```
//! use modal_estimate::{EstimateConfig, estimate, synthetic::DecaySpec};
//!
//! // The paper's branch C: 1.46 Hz, xi 0.086, 409 frames at 30 fps with jitter, drops,
//! // an offset, a drift, held still for 1 s before the release, 30 dB.
//! let spec = DecaySpec::paper_branch();
//! let signal = spec.generate()?;
//! let ours = estimate(&signal, &EstimateConfig::default())?;
//! let paper = estimate(&signal, &EstimateConfig::paper())?;
//! let (m, p) = (ours.modes[0], paper.modes[0]);
//! assert!((m.frequency_hz - 1.46).abs() < 3.0 * m.frequency_std_hz.unwrap());
//! assert!((m.damping_ratio - 0.086).abs() < 0.01);
//! // The paper's method reports an FFT bin: a multiple of 30 / 409 Hz (from the release on).
//! let bins = p.frequency_hz / paper.half_power.unwrap().bin_width_hz;
//! assert!((bins - bins.round()).abs() < 1e-9);
//! # Ok::<(), modal_estimate::ModalError>(())
//! ```

mod ambient;
pub mod csv;
mod error;
mod estimate;
mod fit;
mod paper;
mod pencil;
mod segment;
mod signal;
mod spectrum;
pub mod synthetic;
mod table;

pub use ambient::{
    RandomDecrement, au_cycles_needed, au_uncertainty, band_pass, random_decrement, welch,
};
pub use error::{ModalError, Result};
pub use estimate::{
    Estimate, EstimateConfig, Estimator, MIN_SWING_CYCLES, Method, OWN_MODE_TOLERANCE, Warning,
    estimate,
};
pub use fit::{Mode, cramer_rao_bound};
pub use paper::{HalfPower, half_power, paper_half_power};
pub use segment::{Release, Segment, SegmentConfig};
pub use signal::{Signal, UniformSignal};
pub use spectrum::{
    Detrend, Peak, Scaling, Spectrum, SpectrumConfig, Window, spectrum, spectrum_uniform,
};
pub use table::{BranchRow, DampingFill, LevelDamping, ModalTable, SharedFrequency};

/// The types most programs need.
pub mod prelude {
    pub use crate::{
        Estimate, EstimateConfig, Method, ModalError, ModalTable, Mode, SegmentConfig, Signal,
        Warning, estimate,
    };
}
