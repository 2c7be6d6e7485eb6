//! Tables across branches (the paper's Table 1 and Fig. 15): per branch and test, f and xi
//! with uncertainties; the frequency most branches share; damping statistics by branch
//! level to fill branches that were not measured.

use std::fmt::Write as _;

use serde::Serialize;

use crate::estimate::Estimate;
use crate::fit::Mode;

/// One branch in one test.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BranchRow {
    /// Branch name (the paper's A..J).
    pub branch: String,
    /// Branch level (1 for a child of the root, as in the paper).
    pub level: usize,
    /// Test name (e.g. "small force").
    pub test: String,
    /// Modes found, largest amplitude first (empty when nothing could be measured).
    pub modes: Vec<Mode>,
}

impl BranchRow {
    /// The dominant mode.
    #[must_use]
    pub fn dominant(&self) -> Option<&Mode> {
        self.modes.first()
    }
}

/// A frequency shared by several branches.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SharedFrequency {
    /// Inverse-variance weighted mean of the member modes, hertz.
    pub frequency_hz: f64,
    /// Its standard error: the larger of the weighted-mean error and the members' spread
    /// over sqrt(n), hertz.
    pub frequency_std_hz: f64,
    /// Rows (branch, test) with a mode at this frequency.
    pub members: Vec<(String, String)>,
    /// Members over rows with any mode.
    pub share: f64,
}

/// Damping statistics of one branch level (dominant modes).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LevelDamping {
    /// Branch level.
    pub level: usize,
    /// Rows measured.
    pub count: usize,
    /// Mean damping ratio.
    pub mean: f64,
    /// Median damping ratio.
    pub median: f64,
    /// Sample standard deviation (0 for one row).
    pub std: f64,
    /// Smallest.
    pub min: f64,
    /// Largest.
    pub max: f64,
}

/// A damping ratio for a branch that was not measured.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DampingFill {
    /// The value: the median of the nearest measured level.
    pub damping_ratio: f64,
    /// The level it comes from.
    pub from_level: usize,
    /// Rows behind it.
    pub count: usize,
}

/// Rows of branches and tests.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ModalTable {
    /// The rows in insertion order.
    pub rows: Vec<BranchRow>,
}

impl ModalTable {
    /// An empty table.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Add a branch's estimate for a test.
    pub fn push(&mut self, branch: &str, level: usize, test: &str, estimate: &Estimate) {
        self.rows.push(BranchRow {
            branch: branch.to_owned(),
            level,
            test: test.to_owned(),
            modes: estimate.modes.clone(),
        });
    }

    /// The frequency shared by the most rows: each row's modes are candidates, a row joins a
    /// candidate when one of its modes lies within `relative_tolerance` of it or within two
    /// combined standard errors; ties go to the candidate with the smaller spread. `None`
    /// when no row has a mode.
    #[must_use]
    pub fn dominant_frequency(&self, relative_tolerance: f64) -> Option<SharedFrequency> {
        let measured: Vec<&BranchRow> = self.rows.iter().filter(|r| !r.modes.is_empty()).collect();
        let mut best: Option<(usize, f64, SharedFrequency)> = None;
        for cand in measured.iter().flat_map(|r| r.modes.iter()) {
            let mut members = Vec::new();
            let mut picked = Vec::new();
            for row in &measured {
                let near = row
                    .modes
                    .iter()
                    .filter(|m| {
                        let s = cand
                            .frequency_std_hz
                            .unwrap_or(0.0)
                            .hypot(m.frequency_std_hz.unwrap_or(0.0));
                        (m.frequency_hz - cand.frequency_hz).abs()
                            <= (relative_tolerance * cand.frequency_hz).max(2.0 * s)
                    })
                    .min_by(|a, b| {
                        (a.frequency_hz - cand.frequency_hz)
                            .abs()
                            .total_cmp(&(b.frequency_hz - cand.frequency_hz).abs())
                    });
                if let Some(m) = near {
                    members.push((row.branch.clone(), row.test.clone()));
                    picked.push(*m);
                }
            }
            let weights: Vec<f64> = picked
                .iter()
                .map(|m| {
                    let s = m.frequency_std_hz.unwrap_or(0.0).max(1e-6 * m.frequency_hz);
                    1.0 / (s * s)
                })
                .collect();
            let wsum: f64 = weights.iter().sum();
            let mean = picked
                .iter()
                .zip(&weights)
                .map(|(m, w)| m.frequency_hz * w)
                .sum::<f64>()
                / wsum;
            let n = picked.len() as f64;
            let spread = if picked.len() > 1 {
                (picked
                    .iter()
                    .map(|m| (m.frequency_hz - mean).powi(2))
                    .sum::<f64>()
                    / (n - 1.0))
                    .sqrt()
            } else {
                0.0
            };
            let std = (1.0 / wsum.sqrt()).max(spread / n.sqrt());
            let shared = SharedFrequency {
                frequency_hz: mean,
                frequency_std_hz: std,
                share: n / measured.len() as f64,
                members,
            };
            let better = best
                .as_ref()
                .is_none_or(|(c, sp, _)| picked.len() > *c || (picked.len() == *c && spread < *sp));
            if better {
                best = Some((picked.len(), spread, shared));
            }
        }
        best.map(|(_, _, s)| s)
    }

    /// Damping statistics per level over the rows' dominant modes, levels ascending.
    #[must_use]
    pub fn damping_by_level(&self) -> Vec<LevelDamping> {
        let mut levels: Vec<usize> = self.rows.iter().map(|r| r.level).collect();
        levels.sort_unstable();
        levels.dedup();
        levels
            .into_iter()
            .filter_map(|level| {
                let mut xi: Vec<f64> = self
                    .rows
                    .iter()
                    .filter(|r| r.level == level)
                    .filter_map(|r| r.dominant().map(|m| m.damping_ratio))
                    .collect();
                if xi.is_empty() {
                    return None;
                }
                xi.sort_by(f64::total_cmp);
                let n = xi.len() as f64;
                let mean = xi.iter().sum::<f64>() / n;
                let median = if xi.len() % 2 == 1 {
                    xi[xi.len() / 2]
                } else {
                    0.5 * (xi[xi.len() / 2 - 1] + xi[xi.len() / 2])
                };
                let std = if xi.len() > 1 {
                    (xi.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
                } else {
                    0.0
                };
                Some(LevelDamping {
                    level,
                    count: xi.len(),
                    mean,
                    median,
                    std,
                    min: xi[0],
                    max: xi[xi.len() - 1],
                })
            })
            .collect()
    }

    /// A damping ratio for an unmeasured branch at `level`: the median of that level, else
    /// of the nearest measured level (the lower one on a tie). `None` when nothing was
    /// measured.
    #[must_use]
    pub fn fill_damping(&self, level: usize) -> Option<DampingFill> {
        self.damping_by_level()
            .into_iter()
            .min_by_key(|l| (l.level.abs_diff(level), l.level))
            .map(|l| DampingFill {
                damping_ratio: l.median,
                from_level: l.level,
                count: l.count,
            })
    }

    /// The table as Markdown, one row per branch, one column pair (f, xi) per test, with
    /// standard errors where known: the layout of the paper's Table 1.
    #[must_use]
    pub fn to_markdown(&self) -> String {
        let mut tests: Vec<&str> = Vec::new();
        let mut branches: Vec<(&str, usize)> = Vec::new();
        for r in &self.rows {
            if !tests.contains(&r.test.as_str()) {
                tests.push(&r.test);
            }
            if !branches.iter().any(|(b, _)| *b == r.branch) {
                branches.push((&r.branch, r.level));
            }
        }
        let mut out = String::from("| branch | level |");
        for t in &tests {
            let _ = write!(out, " f (Hz), {t} | xi, {t} |");
        }
        out.push_str("\n|---|---|");
        out.push_str(&"---|---|".repeat(tests.len()));
        out.push('\n');
        let pm = |v: f64, s: Option<f64>, digits: usize| match s {
            Some(s) => format!("{v:.digits$} ± {s:.digits$}"),
            None => format!("{v:.digits$}"),
        };
        for (b, level) in branches {
            let _ = write!(out, "| {b} | {level} |");
            for t in &tests {
                let row = self.rows.iter().find(|r| r.branch == b && r.test == *t);
                match row.and_then(BranchRow::dominant) {
                    Some(m) => {
                        let _ = write!(
                            out,
                            " {} | {} |",
                            pm(m.frequency_hz, m.frequency_std_hz, 3),
                            pm(m.damping_ratio, m.damping_std, 3)
                        );
                    }
                    None => out.push_str(" – | – |"),
                }
            }
            out.push('\n');
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mode(f: f64, xi: f64) -> Mode {
        Mode {
            frequency_hz: f,
            frequency_std_hz: Some(0.002),
            damping_ratio: xi,
            damping_std: Some(0.004),
            damped_frequency_hz: f,
            decay_rate_per_s: 0.0,
            amplitude: 1.0,
            amplitude_std: None,
            phase_rad: 0.0,
            reference_time_s: 0.0,
        }
    }

    fn row(b: &str, level: usize, modes: Vec<Mode>) -> BranchRow {
        BranchRow {
            branch: b.into(),
            level,
            test: "small".into(),
            modes,
        }
    }

    #[test]
    fn shared_frequency_counts_secondary_modes_and_fill_uses_nearest_level() {
        let table = ModalTable {
            rows: vec![
                row("A", 1, vec![mode(1.460, 0.10)]),
                row("C", 2, vec![mode(1.462, 0.08)]),
                row("D", 2, vec![mode(2.400, 0.12), mode(1.458, 0.07)]),
                row("F", 3, vec![mode(1.390, 0.09)]),
                row("G", 3, vec![]),
            ],
        };
        let shared = table.dominant_frequency(0.01).unwrap();
        assert_eq!(shared.members.len(), 3);
        assert!((shared.frequency_hz - 1.46).abs() < 0.002);
        assert!((shared.share - 0.75).abs() < 1e-12);
        let levels = table.damping_by_level();
        assert_eq!(levels.len(), 3);
        assert!((levels[1].median - 0.10).abs() < 1e-12);
        let fill = table.fill_damping(4).unwrap();
        assert_eq!(fill.from_level, 3);
        assert!((fill.damping_ratio - 0.09).abs() < 1e-12);
        assert!(
            table
                .to_markdown()
                .contains("| D | 2 | 2.400 ± 0.002 | 0.120 ± 0.004 |")
        );
    }
}
