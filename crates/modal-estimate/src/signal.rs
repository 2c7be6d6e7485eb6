//! The input: timestamps and values with explicit missing samples.

use crate::error::{ModalError, Result};

/// A record to analyse: timestamps in seconds (finite, strictly increasing, not necessarily
/// uniform) and one value per timestamp, `None` where the sample is missing. The unit of the
/// values is the caller's (radians for a branch angle, strain, metres); every amplitude this
/// crate returns is in that unit.
///
/// Irregular sampling is kept: the parametric fit runs on the timestamps as given; only the
/// spectrum and the matrix pencil's starting values use a uniform grid (see
/// [`Signal::resample_uniform`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Signal {
    times_s: Vec<f64>,
    values: Vec<Option<f64>>,
}

/// A signal on a uniform time grid: what an FFT or a matrix pencil takes.
#[derive(Debug, Clone, PartialEq)]
pub struct UniformSignal {
    /// Time of the first sample, seconds.
    pub start_s: f64,
    /// Sample interval, seconds.
    pub interval_s: f64,
    /// The samples.
    pub values: Vec<f64>,
    /// How many grid samples were interpolated across a missing sample (a grid point more
    /// than a tenth of an interval from any measured sample).
    pub interpolated: usize,
}

impl UniformSignal {
    /// Sample rate, hertz.
    #[must_use]
    pub fn sample_rate_hz(&self) -> f64 {
        1.0 / self.interval_s
    }
}

/// A uniform grid may hold at most this many samples per measured one: more means the
/// timestamps are mostly gaps or the interval asked for is far below the record's.
const MAX_GRID_PER_SAMPLE: usize = 64;

/// Largest uniform grid, samples (512 MB of `f64`): a day at 700 Hz.
const MAX_GRID_SAMPLES: usize = 1 << 26;

impl Signal {
    /// Validate and build.
    ///
    /// # Errors
    /// [`ModalError::LengthMismatch`], [`ModalError::NonFiniteTime`],
    /// [`ModalError::NonIncreasingTime`] or [`ModalError::NonFiniteValue`] (a NaN is not a
    /// missing sample: say `None`).
    pub fn new(times_s: Vec<f64>, values: Vec<Option<f64>>) -> Result<Self> {
        if times_s.len() != values.len() {
            return Err(ModalError::LengthMismatch {
                times: times_s.len(),
                values: values.len(),
            });
        }
        for (index, &time_s) in times_s.iter().enumerate() {
            if !time_s.is_finite() {
                return Err(ModalError::NonFiniteTime { index, time_s });
            }
            if index > 0 && time_s <= times_s[index - 1] {
                return Err(ModalError::NonIncreasingTime {
                    index,
                    previous_s: times_s[index - 1],
                    time_s,
                });
            }
        }
        for (index, value) in values.iter().enumerate() {
            if let Some(value) = *value
                && !value.is_finite()
            {
                return Err(ModalError::NonFiniteValue {
                    index,
                    time_s: times_s[index],
                    value,
                });
            }
        }
        Ok(Self { times_s, values })
    }

    /// Samples at a constant rate starting at t = 0.
    ///
    /// # Errors
    /// [`ModalError::InvalidParameter`] for a rate that is not positive and finite; the errors
    /// of [`Signal::new`].
    pub fn uniform(sample_rate_hz: f64, values: Vec<Option<f64>>) -> Result<Self> {
        if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
            return Err(ModalError::InvalidParameter {
                name: "sample_rate_hz",
                reason: format!("{sample_rate_hz} (expected positive and finite)"),
            });
        }
        let times_s = (0..values.len())
            .map(|i| i as f64 / sample_rate_hz)
            .collect();
        Self::new(times_s, values)
    }

    /// From a series with a measured mask (branch-angles' `Series`): samples that are not
    /// measured (a filled gap contributed) become missing, so the estimate rests on
    /// measurements only.
    ///
    /// # Errors
    /// [`ModalError::LengthMismatch`] when the mask's length differs; the errors of
    /// [`Signal::new`].
    pub fn from_measured(
        times_s: Vec<f64>,
        values: Vec<Option<f64>>,
        measured: &[bool],
    ) -> Result<Self> {
        if measured.len() != times_s.len() {
            return Err(ModalError::LengthMismatch {
                times: times_s.len(),
                values: measured.len(),
            });
        }
        let values = values
            .into_iter()
            .zip(measured)
            .map(|(v, &m)| if m { v } else { None })
            .collect();
        Self::new(times_s, values)
    }

    /// Timestamps, seconds.
    #[must_use]
    pub fn times_s(&self) -> &[f64] {
        &self.times_s
    }

    /// Values, `None` where missing.
    #[must_use]
    pub fn values(&self) -> &[Option<f64>] {
        &self.values
    }

    /// Number of timestamps.
    #[must_use]
    pub fn len(&self) -> usize {
        self.times_s.len()
    }

    /// True when there is no timestamp.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.times_s.is_empty()
    }

    /// Number of samples with a value.
    #[must_use]
    pub fn present_count(&self) -> usize {
        self.values.iter().flatten().count()
    }

    /// The samples with a value, as (times, values).
    #[must_use]
    pub fn present(&self) -> (Vec<f64>, Vec<f64>) {
        self.times_s
            .iter()
            .zip(&self.values)
            .filter_map(|(&t, v)| v.map(|v| (t, v)))
            .unzip()
    }

    /// Time from the first to the last timestamp, seconds.
    #[must_use]
    pub fn duration_s(&self) -> f64 {
        match (self.times_s.first(), self.times_s.last()) {
            (Some(a), Some(b)) => b - a,
            _ => 0.0,
        }
    }

    /// Median interval between consecutive timestamps, seconds (`None` below two samples).
    #[must_use]
    pub fn median_interval_s(&self) -> Option<f64> {
        let mut d: Vec<f64> = self.times_s.windows(2).map(|w| w[1] - w[0]).collect();
        if d.is_empty() {
            return None;
        }
        d.sort_by(f64::total_cmp);
        Some(d[d.len() / 2])
    }

    /// Half the median sample rate, hertz (`None` below two samples).
    #[must_use]
    pub fn nyquist_hz(&self) -> Option<f64> {
        self.median_interval_s().map(|dt| 0.5 / dt)
    }

    /// The samples with `start_s <= t <= end_s`.
    #[must_use]
    pub fn slice_time(&self, start_s: f64, end_s: f64) -> Self {
        let (times_s, values) = self
            .times_s
            .iter()
            .zip(&self.values)
            .filter(|(t, _)| **t >= start_s && **t <= end_s)
            .map(|(&t, &v)| (t, v))
            .unzip();
        Self { times_s, values }
    }

    /// Checks shared by every estimator: enough present samples, not all missing, not
    /// constant.
    pub(crate) fn check_usable(&self, what: &'static str, needed: usize) -> Result<()> {
        let present = self.present_count();
        if present == 0 {
            return Err(ModalError::AllMissing {
                samples: self.len(),
            });
        }
        if present < needed {
            return Err(ModalError::TooFewSamples {
                what,
                present,
                needed,
            });
        }
        let mut values = self.values.iter().flatten();
        if let Some(&first) = values.next()
            && values.all(|&v| v == first)
        {
            return Err(ModalError::Constant { value: first });
        }
        Ok(())
    }

    /// The record on a uniform grid from its first to its last present sample, at
    /// `interval_s` (the median interval when `None`), by linear interpolation between the
    /// present samples on either side of each grid point.
    ///
    /// # Errors
    /// [`ModalError::TooFewSamples`] below two present samples; [`ModalError::InvalidParameter`]
    /// for an interval that is not positive and finite; [`ModalError::TooLarge`] when the
    /// grid would hold more than 64 samples per present one or 2^26 in all.
    pub fn resample_uniform(&self, interval_s: Option<f64>) -> Result<UniformSignal> {
        let (t, y) = self.present();
        if t.len() < 2 {
            return Err(ModalError::TooFewSamples {
                what: "resampling",
                present: t.len(),
                needed: 2,
            });
        }
        let interval_s = match interval_s.or_else(|| self.median_interval_s()) {
            Some(dt) if dt.is_finite() && dt > 0.0 => dt,
            other => {
                return Err(ModalError::InvalidParameter {
                    name: "interval_s",
                    reason: format!(
                        "{} (expected positive and finite)",
                        other.unwrap_or(f64::NAN)
                    ),
                });
            }
        };
        let start_s = t[0];
        let span = t[t.len() - 1] - start_s;
        let grid = (span / interval_s + 1e-9).floor() + 1.0;
        let limit = (MAX_GRID_PER_SAMPLE * t.len()).min(MAX_GRID_SAMPLES);
        if grid.is_nan() || grid > limit as f64 {
            return Err(ModalError::TooLarge {
                what: format!(
                    "a uniform grid at {interval_s} s over the record's {span} s (from {} present samples)",
                    t.len()
                ),
                count: grid,
                limit,
            });
        }
        let n = grid as usize;
        let mut values = Vec::with_capacity(n);
        let mut interpolated = 0;
        let mut j = 0;
        for i in 0..n {
            let ti = start_s + i as f64 * interval_s;
            while j + 2 < t.len() && t[j + 1] <= ti {
                j += 1;
            }
            let (t0, t1) = (t[j], t[j + 1]);
            let w = ((ti - t0) / (t1 - t0)).clamp(0.0, 1.0);
            values.push(y[j] + w * (y[j + 1] - y[j]));
            let near = (ti - t0).abs().min((t1 - ti).abs());
            if near > 0.1 * interval_s && t1 - t0 > 1.5 * interval_s {
                interpolated += 1;
            }
        }
        Ok(UniformSignal {
            start_s,
            interval_s,
            values,
            interpolated,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_time_bases_and_values() {
        assert!(matches!(
            Signal::new(vec![0.0, 1.0], vec![Some(1.0)]),
            Err(ModalError::LengthMismatch { .. })
        ));
        assert!(matches!(
            Signal::new(vec![0.0, 0.0], vec![Some(1.0), Some(2.0)]),
            Err(ModalError::NonIncreasingTime { index: 1, .. })
        ));
        assert!(matches!(
            Signal::new(vec![0.0, f64::NAN], vec![Some(1.0), Some(2.0)]),
            Err(ModalError::NonFiniteTime { index: 1, .. })
        ));
        assert!(matches!(
            Signal::new(vec![0.0, 1.0], vec![Some(1.0), Some(f64::INFINITY)]),
            Err(ModalError::NonFiniteValue { index: 1, .. })
        ));
    }

    #[test]
    fn resampling_is_exact_for_a_line_and_counts_bridged_gaps() {
        let times: Vec<f64> = (0..11).map(|i| f64::from(i) * 0.1).collect();
        let mut values: Vec<Option<f64>> = times.iter().map(|t| Some(3.0 * t - 1.0)).collect();
        values[4] = None;
        values[5] = None;
        let s = Signal::new(times, values).unwrap_or_else(|e| unreachable!("{e}"));
        let u = s
            .resample_uniform(None)
            .unwrap_or_else(|e| unreachable!("{e}"));
        assert_eq!(u.values.len(), 11);
        assert_eq!(u.interpolated, 2);
        for (i, v) in u.values.iter().enumerate() {
            assert!((v - (3.0 * i as f64 * 0.1 - 1.0)).abs() < 1e-12);
        }
    }

    #[test]
    fn measured_mask_turns_filled_samples_into_gaps() {
        let s = Signal::from_measured(
            vec![0.0, 1.0, 2.0],
            vec![Some(1.0), Some(2.0), Some(3.0)],
            &[true, false, true],
        )
        .unwrap_or_else(|e| unreachable!("{e}"));
        assert_eq!(s.values(), &[Some(1.0), None, Some(3.0)]);
        assert!(matches!(
            Signal::new(vec![0.0, 1.0], vec![Some(2.0), Some(2.0)])
                .unwrap_or_else(|e| unreachable!("{e}"))
                .check_usable("x", 2),
            Err(ModalError::Constant { .. })
        ));
    }
}
