//! Which dynamics each branch gets: a default, explicit per-branch values, and measured
//! (position, f, ξ) triples mapped to the nearest branches, with unmeasured branches filled
//! from the measured ones of their level (as the paper does for damping).
//!
//! The file (`--dynamics` of the `animate_tree` example):
//!
//! ```json
//! {
//!   "default": {"frequency_hz": 1.46, "damping_ratio": 0.086},
//!   "branches": {"17": {"frequency_hz": 1.2, "damping_ratio": 0.1}},
//!   "measured": [{"position": [0.4, 0.1, 3.2], "frequency_hz": 1.46, "damping_ratio": 0.09}]
//! }
//! ```
//!
//! `branches` and `measured` are optional. Branch ids are the ids of the branches' first
//! skeleton nodes; positions are in the tree's frame, metres.

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use crate::error::{AnimError, Result};
use crate::oscillator::{Dynamics, PAPER_DYNAMICS};
use crate::tree::{BeamBranch, BeamTree, SEGMENTS};

/// A measurement at a point of the tree (e.g. a tracked marker).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeasuredDynamics {
    /// Where it was measured, tree frame, metres.
    pub position: [f64; 3],
    /// Natural frequency, Hz.
    pub frequency_hz: f64,
    /// Damping ratio.
    pub damping_ratio: f64,
}

/// The dynamics file: a default, explicit branches, measurements.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DynamicsSpec {
    /// For branches nothing else applies to.
    pub default: Dynamics,
    /// Explicit values by branch id (as a string, JSON object keys).
    #[serde(default)]
    pub branches: BTreeMap<String, Dynamics>,
    /// Measurements, each given to the branch nearest its position.
    #[serde(default)]
    pub measured: Vec<MeasuredDynamics>,
}

impl Default for DynamicsSpec {
    fn default() -> Self {
        Self {
            default: PAPER_DYNAMICS,
            branches: BTreeMap::new(),
            measured: Vec::new(),
        }
    }
}

/// Where a branch's dynamics came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DynamicsSource {
    /// Named in `branches`.
    Explicit,
    /// The nearest branch to a measurement (its index in `measured`).
    Measured(usize),
    /// The median of the measured branches of this level.
    Level(usize),
    /// The default.
    Default,
}

/// The dynamics of every branch, in [`BeamTree::branches`] order.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Assignment {
    /// One per branch.
    pub dynamics: Vec<Dynamics>,
    /// Where each came from.
    pub source: Vec<DynamicsSource>,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Distance from `p` to a branch's four-segment polyline, metres.
fn distance_to_branch(p: &Point3<f64>, b: &BeamBranch) -> f64 {
    (0..SEGMENTS)
        .map(|j| {
            let (a, e) = (b.points[j], b.points[j + 1]);
            let d = e - a;
            let t = ((p - a).dot(&d) / d.norm_squared()).clamp(0.0, 1.0);
            (p - (a + d * t)).norm()
        })
        .fold(f64::INFINITY, f64::min)
}

impl DynamicsSpec {
    /// Parse the JSON text of a dynamics file; `path` names it in errors.
    ///
    /// # Errors
    /// [`AnimError::Format`] for JSON that is not a dynamics file (unknown fields included).
    pub fn from_json(text: &str, path: &Path) -> Result<Self> {
        serde_json::from_str(text).map_err(|e| AnimError::format(path, e.to_string()))
    }

    /// Read a dynamics file.
    ///
    /// # Errors
    /// [`AnimError::Io`], and as [`Self::from_json`].
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| AnimError::io(path, e))?;
        Self::from_json(&text, path)
    }

    /// The dynamics of each branch of `tree`: explicit entries first, then measurements
    /// (each to the nearest branch; a branch with several takes the nearest one), then the
    /// median f and ξ of the measured and explicit branches of the same level, or of the
    /// nearest level that has any (the lower on a tie), then the default.
    ///
    /// # Errors
    /// [`AnimError::UnknownBranch`] or [`AnimError::InvalidParameter`] for a branch key that
    /// is not a branch id of `tree`, [`AnimError::InvalidFrequency`] /
    /// [`AnimError::InvalidDamping`] for bad values, [`AnimError::InvalidParameter`] for a
    /// measurement position that is not finite.
    pub fn assign(&self, tree: &BeamTree) -> Result<Assignment> {
        self.default.validate("dynamics default")?;
        let branches = tree.branches();
        let n = branches.len();
        let mut dynamics = vec![self.default; n];
        let mut source = vec![DynamicsSource::Default; n];
        for (key, d) in &self.branches {
            let id: usize = key.trim().parse().map_err(|_| {
                AnimError::param(
                    "branches",
                    format!("key {key:?} is not a branch id (a skeleton node number)"),
                )
            })?;
            d.validate(&format!("dynamics of branch {id}"))?;
            let i = tree.index_of(id)?;
            dynamics[i] = *d;
            source[i] = DynamicsSource::Explicit;
        }
        let mut nearest: Vec<Option<(f64, usize)>> = vec![None; n];
        for (k, m) in self.measured.iter().enumerate() {
            let what = format!("measurement {k}");
            Dynamics {
                frequency_hz: m.frequency_hz,
                damping_ratio: m.damping_ratio,
            }
            .validate(&what)?;
            if !m.position.iter().all(|c| c.is_finite()) {
                return Err(AnimError::param(
                    "measured",
                    format!("{what}: position {:?} is not finite", m.position),
                ));
            }
            let p = Point3::from(m.position);
            let (i, d) = branches
                .iter()
                .enumerate()
                .map(|(i, b)| (i, distance_to_branch(&p, b)))
                .fold(
                    (0, f64::INFINITY),
                    |best, c| if c.1 < best.1 { c } else { best },
                );
            if nearest[i].is_none_or(|(best, _)| d < best) {
                nearest[i] = Some((d, k));
            }
        }
        for (i, near) in nearest.iter().enumerate() {
            if let (Some((_, k)), false) = (near, source[i] == DynamicsSource::Explicit) {
                let m = &self.measured[*k];
                dynamics[i] = Dynamics {
                    frequency_hz: m.frequency_hz,
                    damping_ratio: m.damping_ratio,
                };
                source[i] = DynamicsSource::Measured(*k);
            }
        }
        // Level medians of what was given per branch.
        let mut by_level: BTreeMap<usize, (Vec<f64>, Vec<f64>)> = BTreeMap::new();
        for (i, b) in branches.iter().enumerate() {
            if source[i] != DynamicsSource::Default {
                let e = by_level.entry(b.order).or_default();
                e.0.push(dynamics[i].frequency_hz);
                e.1.push(dynamics[i].damping_ratio);
            }
        }
        let medians: BTreeMap<usize, Dynamics> = by_level
            .into_iter()
            .map(|(level, (f, xi))| {
                (
                    level,
                    Dynamics {
                        frequency_hz: median(f),
                        damping_ratio: median(xi),
                    },
                )
            })
            .collect();
        for (i, b) in branches.iter().enumerate() {
            if source[i] != DynamicsSource::Default {
                continue;
            }
            let level = medians
                .keys()
                .copied()
                .min_by_key(|&l| (l.abs_diff(b.order), l));
            if let Some(l) = level {
                dynamics[i] = medians[&l];
                source[i] = DynamicsSource::Level(l);
            }
        }
        Ok(Assignment { dynamics, source })
    }
}
