//! A swinging marker's motion learnt from its own recent track, so that its prediction turns
//! where the swing turns.
//!
//! A branch released from a pull swings as a damped oscillator about its rest point: per
//! image axis, the acceleration is close to a linear function of position and velocity,
//! `a = α + β p + γ v` with `β = -ω²` (per frame²) and `γ = -2 ζ ω`. A constant-velocity
//! prediction overshoots at every turn by about `|a|`, up to a marker width at the ends of a
//! fast swing, which is where two markers of one look are confused. The fit uses the last
//! [`HISTORY_FRAMES`] frames the marker was found in (central differences over runs of three
//! consecutive frames) and is used only while it explains most of the acceleration; otherwise
//! the prediction stays constant-velocity.

use std::collections::VecDeque;

use nalgebra::{Matrix3, Point2, Vector2, Vector3};

/// Frames of track the fit looks back over (a swing of 1 Hz at 30 fps in full).
const HISTORY_FRAMES: u64 = 30;
/// Least number of three-frame runs for a fit.
const MIN_RUNS: usize = 12;
/// Least share of the acceleration's variance the fit must explain on an axis.
const MIN_EXPLAINED: f64 = 0.7;
/// Largest `ω` per frame trusted (a swing of a period shorter than about 4 frames is
/// under-sampled: the differences no longer follow it).
const MAX_OMEGA_PER_FRAME: f64 = 1.5;
/// Least acceleration spread (pixels per frame²) worth modelling: below it the marker barely
/// swings and constant velocity does as well.
const MIN_ACCELERATION_PX: f64 = 0.5;

/// The recent track and the per-axis fit.
#[derive(Debug, Clone, Default)]
pub(crate) struct Swing {
    history: VecDeque<(u64, Point2<f64>)>,
    /// Per axis `[α, β, γ]`, when the fit holds.
    fit: [Option<Vector3<f64>>; 2],
}

impl Swing {
    /// Record where the marker was found in `frame` (frames increasing) and refit.
    pub(crate) fn record(&mut self, frame: u64, at: Point2<f64>) {
        if !(at.x.is_finite() && at.y.is_finite()) {
            return;
        }
        if self.history.back().is_some_and(|&(f, _)| f >= frame) {
            self.history.clear();
        }
        self.history.push_back((frame, at));
        while self
            .history
            .front()
            .is_some_and(|&(f, _)| f + HISTORY_FRAMES < frame)
        {
            self.history.pop_front();
        }
        self.refit();
    }

    /// Forget the track (the marker was set by hand).
    pub(crate) fn clear(&mut self) {
        self.history.clear();
        self.fit = [None, None];
    }

    /// The acceleration (pixels per frame²) the fit expects at position `p` with velocity
    /// `v` (pixels per frame); zero on an axis without a fit.
    pub(crate) fn acceleration(&self, p: Point2<f64>, v: Vector2<f64>) -> Option<Vector2<f64>> {
        if self.fit.iter().all(Option::is_none) {
            return None;
        }
        let axis =
            |k: usize, p: f64, v: f64| self.fit[k].map_or(0.0, |c| c[0] + c[1] * p + c[2] * v);
        let a = Vector2::new(axis(0, p.x, v.x), axis(1, p.y, v.y));
        (a.x.is_finite() && a.y.is_finite()).then_some(a)
    }

    fn refit(&mut self) {
        let h = &self.history;
        // Runs of three consecutive frames: position, central velocity and acceleration.
        let mut runs: Vec<[Vector2<f64>; 3]> = Vec::new();
        for k in 1..h.len().saturating_sub(1) {
            let (f0, p0) = h[k - 1];
            let (f1, p1) = h[k];
            let (f2, p2) = h[k + 1];
            if f1 == f0 + 1 && f2 == f1 + 1 {
                runs.push([p1.coords, 0.5 * (p2 - p0), p2 - 2.0 * p1 + p0.coords]);
            }
        }
        if runs.len() < MIN_RUNS {
            self.fit = [None, None];
            return;
        }
        for (k, fit) in self.fit.iter_mut().enumerate() {
            *fit = fit_axis(runs.iter().map(|r| (r[0][k], r[1][k], r[2][k])));
        }
    }
}

/// Least squares `a = α + β p + γ v` over `(p, v, a)` samples, centred for conditioning;
/// `None` unless it explains [`MIN_EXPLAINED`] of the variance with a restoring, resolvable
/// `β`.
fn fit_axis(samples: impl Iterator<Item = (f64, f64, f64)> + Clone) -> Option<Vector3<f64>> {
    let n = samples.clone().count() as f64;
    let (mut mp, mut mv, mut ma) = (0.0, 0.0, 0.0);
    for (p, v, a) in samples.clone() {
        mp += p;
        mv += v;
        ma += a;
    }
    let (mp, mv, ma) = (mp / n, mv / n, ma / n);
    let mut normal = Matrix3::zeros();
    let mut rhs = Vector3::zeros();
    let mut total = 0.0;
    for (p, v, a) in samples.clone() {
        let x = Vector3::new(1.0, p - mp, v - mv);
        normal += x * x.transpose();
        rhs += x * (a - ma);
        total += (a - ma) * (a - ma);
    }
    if total / n < MIN_ACCELERATION_PX * MIN_ACCELERATION_PX {
        return None;
    }
    let c = normal.lu().solve(&rhs)?;
    let residual: f64 = samples
        .map(|(p, v, a)| {
            let e = (a - ma) - (c[0] + c[1] * (p - mp) + c[2] * (v - mv));
            e * e
        })
        .sum();
    let explained = 1.0 - residual / total;
    let omega2 = -c[1];
    if !(explained >= MIN_EXPLAINED
        && omega2 > 0.0
        && omega2 <= MAX_OMEGA_PER_FRAME * MAX_OMEGA_PER_FRAME
        && c[2] <= 0.0)
    {
        return None;
    }
    // Back to uncentred coordinates: a = α + β p + γ v.
    let alpha = ma + c[0] - c[1] * mp - c[2] * mv;
    Some(Vector3::new(alpha, c[1], c[2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A damped swing about (200, 100) sampled per frame.
    fn swing_at(frame: u64) -> Point2<f64> {
        let t = frame as f64;
        let omega = 2.0 * std::f64::consts::PI / 20.0;
        let decay = (-0.03 * omega * t).exp();
        Point2::new(
            200.0 + 40.0 * decay * (omega * t).cos(),
            100.0 + 15.0 * decay * (omega * t + 0.4).sin(),
        )
    }

    #[test]
    fn a_swing_is_predicted_through_its_turns() {
        let mut s = Swing::default();
        for f in 0..40 {
            s.record(f, swing_at(f));
        }
        // Predict frame 40 from 39 with the backward velocity, as the filter does.
        let (p, q) = (swing_at(39), swing_at(38));
        let v = p - q;
        let a = s.acceleration(p, v).expect("fitted");
        let predicted = p + v + a;
        let cv = p + v;
        let truth = swing_at(40);
        assert!((predicted - truth).norm() < 0.5, "{predicted} vs {truth}");
        assert!((cv - truth).norm() > 2.0 * (predicted - truth).norm());
    }

    #[test]
    fn straight_motion_and_short_tracks_give_no_fit() {
        let mut s = Swing::default();
        for f in 0..40 {
            s.record(f, Point2::new(3.0 * f as f64, 50.0));
        }
        assert!(
            s.acceleration(Point2::new(0.0, 0.0), Vector2::zeros())
                .is_none()
        );
        let mut short = Swing::default();
        for f in 0..8 {
            short.record(f, swing_at(f));
        }
        assert!(short.acceleration(swing_at(7), Vector2::zeros()).is_none());
        // Gaps break runs; frames going back start over.
        short.record(3, swing_at(3));
        assert_eq!(short.history.len(), 1);
    }
}
