//! Marker trajectories on a common time base, with explicit gaps, and the filling of short
//! gaps.

use nalgebra::{Point3, Vector3};

use crate::error::{AngleError, Result};
use crate::hierarchy::valid_id;

/// One marker's positions (metres), one per timestamp of its [`Trajectories`]; `None` where the
/// marker was lost.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerTrack {
    /// The marker's id.
    pub id: String,
    /// Position per timestamp, metres; `None` for a lost frame.
    pub positions_m: Vec<Option<Point3<f64>>>,
}

/// The trajectories of a set of markers on one time base: strictly increasing, finite
/// timestamps in seconds (not necessarily uniform), and per marker a position or a gap at each.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectories {
    times_s: Vec<f64>,
    markers: Vec<MarkerTrack>,
}

/// Check that `times_s` is finite and strictly increasing.
pub(crate) fn check_times(what: &str, times_s: &[f64]) -> Result<()> {
    for (k, &t) in times_s.iter().enumerate() {
        if !t.is_finite() {
            return Err(AngleError::NonFiniteTimestamp {
                what: what.to_string(),
                t_s: t,
            });
        }
        if k > 0 {
            let previous_s = times_s[k - 1];
            if t == previous_s {
                return Err(AngleError::DuplicateTimestamp {
                    what: what.to_string(),
                    t_s: t,
                });
            }
            if t < previous_s {
                return Err(AngleError::UnsortedTimestamps {
                    what: what.to_string(),
                    t_s: t,
                    previous_s,
                });
            }
        }
    }
    Ok(())
}

/// Largest coordinate accepted, metres: 10,000 km, more than the Earth's radius, so any
/// georeferenced frame (UTM northings reach 1e7 m) fits, while a corrupt 1e300 (whose squares
/// overflow into angles of exactly 0 or 180 degrees) does not.
pub const MAX_COORDINATE_M: f64 = 1e7;

impl Trajectories {
    /// Validate and build.
    ///
    /// # Errors
    /// [`AngleError::NonFiniteTimestamp`], [`AngleError::UnsortedTimestamps`],
    /// [`AngleError::DuplicateTimestamp`] for the time base; [`AngleError::InvalidId`] and
    /// [`AngleError::DuplicateId`] for the markers; [`AngleError::LengthMismatch`] for a marker
    /// with another number of positions; [`AngleError::NonFiniteCoordinate`] for a NaN or
    /// infinite coordinate; [`AngleError::CoordinateOutOfRange`] beyond
    /// [`MAX_COORDINATE_M`].
    pub fn new(times_s: Vec<f64>, markers: Vec<MarkerTrack>) -> Result<Self> {
        check_times("time base", &times_s)?;
        for (k, m) in markers.iter().enumerate() {
            if !valid_id(&m.id) {
                return Err(AngleError::InvalidId { id: m.id.clone() });
            }
            if markers[..k].iter().any(|o| o.id == m.id) {
                return Err(AngleError::DuplicateId { id: m.id.clone() });
            }
            if m.positions_m.len() != times_s.len() {
                return Err(AngleError::LengthMismatch {
                    what: format!("marker {:?}", m.id),
                    expected: times_s.len(),
                    found: m.positions_m.len(),
                });
            }
            for (i, p) in m.positions_m.iter().enumerate() {
                if let Some(p) = p
                    && let Some(&bad) = p.coords.iter().find(|v| !v.is_finite())
                {
                    return Err(AngleError::NonFiniteCoordinate {
                        what: format!("marker {:?} at t = {} s", m.id, times_s[i]),
                        value: bad,
                    });
                }
                if let Some(p) = p
                    && let Some(&far) = p.coords.iter().find(|v| v.abs() > MAX_COORDINATE_M)
                {
                    return Err(AngleError::CoordinateOutOfRange {
                        what: format!("marker {:?} at t = {} s", m.id, times_s[i]),
                        value: far,
                        limit_m: MAX_COORDINATE_M,
                    });
                }
            }
        }
        Ok(Self { times_s, markers })
    }

    /// The time base, seconds.
    pub fn times_s(&self) -> &[f64] {
        &self.times_s
    }

    /// The markers, in the order given.
    pub fn markers(&self) -> &[MarkerTrack] {
        &self.markers
    }

    /// The track of `id`.
    pub fn marker(&self, id: &str) -> Option<&MarkerTrack> {
        self.markers.iter().find(|m| m.id == id)
    }

    /// Apply `f` to every known position (a rigid motion, a change of frame).
    #[must_use]
    pub fn map_positions(&self, f: impl Fn(Point3<f64>) -> Point3<f64>) -> Self {
        let markers = self
            .markers
            .iter()
            .map(|m| MarkerTrack {
                id: m.id.clone(),
                positions_m: m.positions_m.iter().map(|p| p.map(&f)).collect(),
            })
            .collect();
        Self {
            times_s: self.times_s.clone(),
            markers,
        }
    }

    /// Fill the short gaps of every marker as `config` says; report every gap, filled or not.
    ///
    /// # Errors
    /// As [`GapConfig::validate`].
    pub fn fill_gaps(&self, config: &GapConfig) -> Result<Filled> {
        config.validate()?;
        let mut markers = Vec::with_capacity(self.markers.len());
        let mut measured = Vec::with_capacity(self.markers.len());
        let mut gaps = Vec::new();
        for m in &self.markers {
            let mut positions = m.positions_m.clone();
            let real: Vec<bool> = positions.iter().map(Option::is_some).collect();
            let n = positions.len();
            let mut i = 0;
            while i < n {
                if positions[i].is_some() {
                    i += 1;
                    continue;
                }
                let start = i;
                while i < n && positions[i].is_none() {
                    i += 1;
                }
                let end = i; // exclusive
                let samples = end - start;
                let inside = start > 0 && end < n;
                let filled = inside && samples <= config.max_gap_samples;
                if filled {
                    fill(
                        &self.times_s,
                        &mut positions,
                        start,
                        end,
                        config.interpolation,
                    );
                }
                gaps.push(Gap {
                    marker: m.id.clone(),
                    start_s: self.times_s[start],
                    end_s: self.times_s[end - 1],
                    samples,
                    filled,
                });
            }
            markers.push(MarkerTrack {
                id: m.id.clone(),
                positions_m: positions,
            });
            measured.push(real);
        }
        Ok(Filled {
            trajectories: Self {
                times_s: self.times_s.clone(),
                markers,
            },
            measured,
            gaps,
        })
    }
}

/// Fill `positions[start..end]` (all `None`, with known neighbours at `start - 1` and `end`).
fn fill(
    times_s: &[f64],
    positions: &mut [Option<Point3<f64>>],
    start: usize,
    end: usize,
    interpolation: Interpolation,
) {
    let (l, r) = (start - 1, end);
    let (Some(pl), Some(pr)) = (positions[l], positions[r]) else {
        return;
    };
    let (tl, tr) = (times_s[l], times_s[r]);
    let h = tr - tl;
    let chord = (pr - pl) / h;
    // Tangents (velocities): the derivative of the parabola through the end point, its outer
    // neighbour and the other end of the gap (exact for a parabola on any spacing);
    // the chord where the outer neighbour is missing.
    let three_point =
        |slope_before: Vector3<f64>, h_before: f64, slope_after: Vector3<f64>, h_after: f64| {
            (slope_before * h_after + slope_after * h_before) / (h_before + h_after)
        };
    let (ml, mr) = match interpolation {
        Interpolation::Linear => (chord, chord),
        Interpolation::CubicHermite => {
            let ml = match l.checked_sub(1).and_then(|o| positions[o].map(|p| (o, p))) {
                Some((o, po)) => {
                    let h1 = tl - times_s[o];
                    three_point((pl - po) / h1, h1, chord, h)
                }
                None => chord,
            };
            let mr = match positions.get(r + 1).copied().flatten() {
                Some(po) => {
                    let h2 = times_s[r + 1] - tr;
                    three_point(chord, h, (po - pr) / h2, h2)
                }
                None => chord,
            };
            (ml, mr)
        }
    };
    for k in start..end {
        let s = (times_s[k] - tl) / h;
        let (s2, s3) = (s * s, s * s * s);
        let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
        let h10 = s3 - 2.0 * s2 + s;
        let h01 = -2.0 * s3 + 3.0 * s2;
        let h11 = s3 - s2;
        let p = pl.coords * h00 + ml * (h10 * h) + pr.coords * h01 + mr * (h11 * h);
        positions[k] = Some(Point3::from(p));
    }
}

/// How the short gaps are filled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Interpolation {
    /// Straight line between the two known neighbours.
    Linear,
    /// Cubic Hermite on the actual timestamps with finite-difference tangents (Catmull–Rom on
    /// uniform sampling): follows a swinging branch through a few lost frames where a straight
    /// line cuts the arc.
    #[default]
    CubicHermite,
}

/// Gap filling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GapConfig {
    /// Longest gap filled, in samples (lost frames in a row). Longer gaps, and gaps at the
    /// start or end of a record, stay gaps. Default 3 (0.1 s at 30 fps, a fifth of a period at
    /// 2 Hz). 0 fills nothing.
    pub max_gap_samples: usize,
    /// Interpolation. Default [`Interpolation::CubicHermite`].
    pub interpolation: Interpolation,
}

impl Default for GapConfig {
    fn default() -> Self {
        Self {
            max_gap_samples: DEFAULT_MAX_GAP_SAMPLES,
            interpolation: Interpolation::CubicHermite,
        }
    }
}

/// Default longest filled gap (samples).
const DEFAULT_MAX_GAP_SAMPLES: usize = 3;
/// A gap this long is certainly not "short": it spans seconds at any frame rate.
const MAX_FILLABLE_GAP_SAMPLES: usize = 1000;

impl GapConfig {
    /// Fill nothing.
    pub const NONE: Self = Self {
        max_gap_samples: 0,
        interpolation: Interpolation::Linear,
    };

    /// Check the fields.
    ///
    /// # Errors
    /// [`AngleError::InvalidParameter`] for `max_gap_samples` above 1000.
    pub fn validate(&self) -> Result<()> {
        if self.max_gap_samples > MAX_FILLABLE_GAP_SAMPLES {
            return Err(AngleError::param(
                "max_gap_samples",
                format!(
                    "{} is more than {MAX_FILLABLE_GAP_SAMPLES}: that is not a short gap",
                    self.max_gap_samples
                ),
            ));
        }
        Ok(())
    }
}

/// One run of lost frames of one marker.
#[derive(Debug, Clone, PartialEq)]
pub struct Gap {
    /// The marker.
    pub marker: String,
    /// Timestamp of the first lost frame, seconds.
    pub start_s: f64,
    /// Timestamp of the last lost frame, seconds.
    pub end_s: f64,
    /// Lost frames in the run.
    pub samples: usize,
    /// Whether it was filled (short and between two known frames).
    pub filled: bool,
}

/// Trajectories after gap filling, with which samples were measured and the gap report.
#[derive(Debug, Clone, PartialEq)]
pub struct Filled {
    /// The trajectories with the short gaps filled.
    pub trajectories: Trajectories,
    /// Per marker (in order) and sample: true where the position was measured, false where it
    /// was filled or is still missing.
    pub measured: Vec<Vec<bool>>,
    /// Every gap, filled or not, per marker in time order.
    pub gaps: Vec<Gap>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn track(id: &str, xs: &[Option<f64>]) -> MarkerTrack {
        MarkerTrack {
            id: id.into(),
            positions_m: xs
                .iter()
                .map(|x| x.map(|x| Point3::new(x, 0.0, 0.0)))
                .collect(),
        }
    }

    #[test]
    fn short_inner_gaps_are_filled_long_and_edge_gaps_are_reported() {
        let times: Vec<f64> = (0..12).map(|k| f64::from(k) * 0.1).collect();
        // x = t^2 with a lost first frame, a 2-sample gap (filled) and a 4-sample gap (kept).
        let xs: Vec<Option<f64>> = times
            .iter()
            .enumerate()
            .map(|(k, &t)| (!matches!(k, 0 | 3 | 4 | 7..=10)).then_some(t * t))
            .collect();
        let tr = Trajectories::new(times.clone(), vec![track("A", &xs)]).expect("valid");
        let f = tr.fill_gaps(&GapConfig::default()).expect("valid config");
        let p = &f.trajectories.markers()[0].positions_m;
        assert!(p[0].is_none());
        // Cubic Hermite with three-point tangents reproduces a parabola when both outer
        // neighbours exist.
        assert_relative_eq!(p[3].expect("filled").x, 0.09, epsilon = 1e-12);
        assert_relative_eq!(p[4].expect("filled").x, 0.16, epsilon = 1e-12);
        assert!(p[7..=10].iter().all(Option::is_none));
        assert!(!f.measured[0][3]);
        assert!(f.measured[0][2]);
        let summary: Vec<(usize, bool)> = f.gaps.iter().map(|g| (g.samples, g.filled)).collect();
        assert_eq!(summary, vec![(1, false), (2, true), (4, false)]);
        assert_relative_eq!(f.gaps[2].start_s, 0.7);
        // Linear: on the chord.
        let lin = GapConfig {
            interpolation: Interpolation::Linear,
            ..GapConfig::default()
        };
        let p = tr.fill_gaps(&lin).expect("valid").trajectories.markers()[0].positions_m[3];
        assert_relative_eq!(
            p.expect("filled").x,
            0.04 + (0.25 - 0.04) / 3.0,
            epsilon = 1e-12
        );
        assert!(
            GapConfig {
                max_gap_samples: 5000,
                ..GapConfig::default()
            }
            .validate()
            .is_err()
        );
    }

    #[test]
    fn bad_time_bases_and_coordinates_are_named() {
        let one = |x: f64| vec![track("A", &[Some(x), Some(0.0)])];
        assert!(matches!(
            Trajectories::new(vec![0.0, 0.0], one(0.0)),
            Err(AngleError::DuplicateTimestamp { .. })
        ));
        assert!(matches!(
            Trajectories::new(vec![1.0, 0.0], one(0.0)),
            Err(AngleError::UnsortedTimestamps { .. })
        ));
        assert!(matches!(
            Trajectories::new(vec![0.0, f64::NAN], one(0.0)),
            Err(AngleError::NonFiniteTimestamp { .. })
        ));
        assert!(matches!(
            Trajectories::new(vec![0.0, 1.0], one(f64::NAN)),
            Err(AngleError::NonFiniteCoordinate { .. })
        ));
        assert!(matches!(
            Trajectories::new(vec![0.0], one(0.0)),
            Err(AngleError::LengthMismatch { .. })
        ));
    }
}
