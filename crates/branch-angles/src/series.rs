//! A time series with explicit gaps: what modal estimation takes.

use std::ops::Range;

use crate::error::{AngleError, Result};
use crate::trajectory::check_times;

/// Samples at timestamps (seconds, strictly increasing, not necessarily uniform), each a value
/// or a gap, and whether it comes from measured positions only (false where a filled gap
/// contributed). The unit is in [`Series::name`]'s owner: angles are radians, displacements
/// metres.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// What the series is (a branch's child id, `D_u`, a marker id).
    pub name: String,
    /// Timestamps, seconds.
    pub times_s: Vec<f64>,
    /// The value per timestamp; `None` where it is unknown.
    pub values: Vec<Option<f64>>,
    /// Per timestamp: true where the value is computed from measured positions only.
    pub measured: Vec<bool>,
}

impl Series {
    /// Validate and build.
    ///
    /// # Errors
    /// [`AngleError::LengthMismatch`] when the three sequences differ in length; the time
    /// base errors of [`crate::Trajectories::new`]; [`AngleError::NonFiniteCoordinate`] for a
    /// value that is not finite.
    pub fn new(
        name: impl Into<String>,
        times_s: Vec<f64>,
        values: Vec<Option<f64>>,
        measured: Vec<bool>,
    ) -> Result<Self> {
        let name = name.into();
        check_times(&format!("series {name:?}"), &times_s)?;
        for (what, found) in [("values", values.len()), ("measured", measured.len())] {
            if found != times_s.len() {
                return Err(AngleError::LengthMismatch {
                    what: format!("series {name:?} {what}"),
                    expected: times_s.len(),
                    found,
                });
            }
        }
        if let Some(bad) = values.iter().flatten().find(|v| !v.is_finite()) {
            return Err(AngleError::NonFiniteCoordinate {
                what: format!("series {name:?}"),
                value: *bad,
            });
        }
        Ok(Self {
            name,
            times_s,
            values,
            measured,
        })
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.times_s.len()
    }

    /// True without samples.
    pub fn is_empty(&self) -> bool {
        self.times_s.is_empty()
    }

    /// Number of known values.
    pub fn known(&self) -> usize {
        self.values.iter().filter(|v| v.is_some()).count()
    }

    /// The runs of consecutive known values (index ranges), in time order: the pieces a gap
    /// splits the series into.
    pub fn segments(&self) -> Vec<Range<usize>> {
        let mut out = Vec::new();
        let mut start = None;
        for (k, v) in self.values.iter().enumerate() {
            match (v.is_some(), start) {
                (true, None) => start = Some(k),
                (false, Some(s)) => {
                    out.push(s..k);
                    start = None;
                }
                _ => {}
            }
        }
        if let Some(s) = start {
            out.push(s..self.values.len());
        }
        out
    }

    /// The longest run of known values (the first of equal ones); empty when nothing is known.
    pub fn longest_segment(&self) -> Range<usize> {
        self.segments()
            .into_iter()
            .fold(0..0, |best, r| if r.len() > best.len() { r } else { best })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_split_at_gaps() {
        let s = Series::new(
            "x",
            vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0],
            vec![None, Some(1.0), Some(2.0), None, Some(3.0), Some(4.0)],
            vec![false, true, true, false, true, false],
        )
        .expect("valid");
        assert_eq!(s.segments(), vec![1..3, 4..6]);
        assert_eq!(s.longest_segment(), 1..3);
        assert_eq!(s.known(), 4);
        assert!(Series::new("x", vec![0.0], vec![Some(f64::NAN)], vec![true]).is_err());
        assert!(Series::new("x", vec![0.0], vec![], vec![true]).is_err());
    }
}
