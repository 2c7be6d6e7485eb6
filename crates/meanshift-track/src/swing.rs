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
//! the prediction stays constant-velocity. A history that holds a release (and the smooth
//! pull before it) is motion the oscillator does not explain, so where the whole history
//! fails the fit is tried over its latest runs ([`RECENT_RUNS`]) with a stricter share
//! ([`MIN_EXPLAINED_RECENT`]): the swing is predicted through its turns from about 17 frames
//! after the release instead of 30.
//!
//! The same history gives the marker's swing line (the principal axis of its recent
//! positions, when they spread along one direction at least three times more than across
//! it). Two markers of one look that cross each other's paths are told apart where the paths
//! are apart by their offsets from their own lines, in spreads across the line (at least
//! 3 px, or 0.35 of the spread along it: a swing that runs in an ellipse beside the line of
//! its pull is still near it). On the tuning seeds it took the crossing condition from 91.9 %
//! to 95.1 % within 3 px and occlusion from 97.4 % to 99.9 %.

use std::collections::VecDeque;

use nalgebra::{Matrix3, Point2, Vector2, Vector3};

/// Frames of track the fit looks back over (a swing of 1 Hz at 30 fps in full).
const HISTORY_FRAMES: u64 = 30;
/// Least number of three-frame runs for a fit.
const MIN_RUNS: usize = 12;
/// Latest runs the fit is tried on, longest first, when it does not hold over the whole
/// history: a release (or the smooth pull before it) in the history is motion the
/// oscillator does not explain, and the swing after it is. Not fewer than 17: over 12,
/// a few measurements of a marker half behind another of its look fit a swing toward
/// that one (`docs/validation.md`).
const RECENT_RUNS: [usize; 2] = [22, 17];
/// Least share of the acceleration's variance the fit must explain on an axis.
const MIN_EXPLAINED: f64 = 0.7;
/// The same for a fit over the history's latest part only (fewer runs, where a few
/// measurements pulled by a neighbour fit a swing that is not there).
const MIN_EXPLAINED_RECENT: f64 = 0.85;
/// Largest `ω` per frame trusted (a swing of a period shorter than about 4 frames is
/// under-sampled: the differences no longer follow it).
const MAX_OMEGA_PER_FRAME: f64 = 1.5;
/// Least acceleration spread (pixels per frame²) worth modelling: below it the marker barely
/// swings and constant velocity does as well.
const MIN_ACCELERATION_PX: f64 = 0.5;

/// Positions a constant acceleration is fitted to for [`Swing::extrapolate`].
const EXTRAPOLATE_POINTS: usize = 5;
/// Most frames [`Swing::extrapolate`] looks ahead of the last position.
const EXTRAPOLATE_MAX_AHEAD: u64 = 3;
/// Loosest fit [`Swing::extrapolate`] trusts: root-mean-square residual, pixels.
const EXTRAPOLATE_MAX_RMS_PX: f64 = 0.75;
/// Least number of positions for a swing line.
const LINE_MIN_POINTS: usize = 12;
/// Least ratio of the spreads along and across the swing for a line (a branch that swings
/// in an ellipse has no line).
const LINE_MIN_ANISOTROPY: f64 = 3.0;
/// Least spread along the swing for a line, pixels (a marker at rest has none).
const LINE_MIN_SPREAD_PX: f64 = 3.0;
/// Least spread across the line a candidate's offset is measured in, pixels, and as a share
/// of the spread along it (an ellipse a quarter as wide as it is long is still a swing).
const LINE_SIGMA_MIN_PX: f64 = 3.0;
const LINE_SIGMA_SHARE: f64 = 0.35;

/// The line a marker swings along: its recent positions' mean, the unit normal of their
/// principal axis, and the spread across it (pixels).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SwingLine {
    pub centre: Point2<f64>,
    pub normal: Vector2<f64>,
    pub sigma_px: f64,
    /// Half the length of the stretch the track covered along the line, pixels.
    pub half_length_px: f64,
}

/// The swing line is a segment: it reaches this many spreads along it beyond the stretch
/// the track covered (a swing reaches about 1.4 spreads, a release further than its pull).
const LINE_REACH: f64 = 1.0;

impl SwingLine {
    /// Distance of `p` from the swing's segment (the line, within the stretch the track
    /// covered and [`LINE_REACH`] beyond), in spreads across the line.
    pub(crate) fn offset(&self, p: Point2<f64>) -> f64 {
        let d = p - self.centre;
        let across = d.dot(&self.normal);
        let along = d.perp(&self.normal);
        let beyond = (along.abs() - self.half_length_px * (1.0 + LINE_REACH)).max(0.0);
        across.hypot(beyond) / self.sigma_px
    }
}

/// The recent track and the per-axis fit.
#[derive(Debug, Clone, Default)]
pub(crate) struct Swing {
    history: VecDeque<(u64, Point2<f64>)>,
    /// Per axis `[α, β, γ]`, when the fit holds.
    fit: [Option<Vector3<f64>>; 2],
    /// The swing line of the history, when it has one (kept up to date by `record`).
    line: Option<SwingLine>,
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
        self.line = None;
    }

    /// The line the recent track swings along, when it has one: enough positions, spread
    /// along one direction at least [`LINE_MIN_ANISOTROPY`] times more than across it.
    pub(crate) fn line(&self) -> Option<SwingLine> {
        self.line
    }

    fn fit_line(&self) -> Option<SwingLine> {
        let n = self.history.len();
        if n < LINE_MIN_POINTS {
            return None;
        }
        let mean = self
            .history
            .iter()
            .fold(Vector2::zeros(), |a, (_, p)| a + p.coords)
            / n as f64;
        let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
        for (_, p) in &self.history {
            let d = p.coords - mean;
            sxx += d.x * d.x;
            sxy += d.x * d.y;
            syy += d.y * d.y;
        }
        let (sxx, sxy, syy) = (sxx / n as f64, sxy / n as f64, syy / n as f64);
        // Eigenvalues of the 2x2 covariance in closed form.
        let half_trace = 0.5 * (sxx + syy);
        let root = (0.25 * (sxx - syy).powi(2) + sxy * sxy).sqrt();
        let (along, across) = (half_trace + root, (half_trace - root).max(0.0));
        let spread = along.sqrt();
        if !(spread >= LINE_MIN_SPREAD_PX && spread >= LINE_MIN_ANISOTROPY * across.sqrt()) {
            return None;
        }
        // Major axis direction; the normal is perpendicular to it.
        let axis = if sxy.abs() > 1e-12 {
            Vector2::new(along - syy, sxy)
        } else if sxx >= syy {
            Vector2::new(1.0, 0.0)
        } else {
            Vector2::new(0.0, 1.0)
        };
        let axis = axis.try_normalize(1e-12)?;
        let half_length_px = self
            .history
            .iter()
            .map(|(_, p)| (p.coords - mean).dot(&axis).abs())
            .fold(0.0, f64::max);
        Some(SwingLine {
            centre: Point2::from(mean),
            normal: Vector2::new(-axis.y, axis.x),
            half_length_px,
            sigma_px: across
                .sqrt()
                .max(LINE_SIGMA_MIN_PX)
                .max(LINE_SIGMA_SHARE * spread),
        })
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

    /// Where the last [`EXTRAPOLATE_POINTS`] positions (consecutive frames) put the marker on
    /// `frame`, and its velocity there, by a constant acceleration fitted to them: a marker
    /// speeding up in a pull, hidden behind another of its look for a frame or two, is
    /// still speeding up (a constant velocity falls behind by half the acceleration times
    /// the frames squared). `None` beyond [`EXTRAPOLATE_MAX_AHEAD`] frames after the last
    /// position, when the fit is loose (root-mean-square residual over
    /// [`EXTRAPOLATE_MAX_RMS_PX`]) or the acceleration too small to matter
    /// ([`MIN_ACCELERATION_PX`]).
    pub(crate) fn extrapolate(&self, frame: u64) -> Option<(Point2<f64>, Vector2<f64>)> {
        let n = self.history.len();
        let (last, _) = *self.history.back()?;
        if n < EXTRAPOLATE_POINTS || frame <= last || frame - last > EXTRAPOLATE_MAX_AHEAD {
            return None;
        }
        let mut recent = [(0.0, Point2::origin()); EXTRAPOLATE_POINTS];
        for (slot, (k, &(f, p))) in recent
            .iter_mut()
            .zip(self.history.range(n - EXTRAPOLATE_POINTS..).enumerate())
        {
            // Consecutive frames, ending at the last.
            if f + (EXTRAPOLATE_POINTS - 1 - k) as u64 != last {
                return None;
            }
            *slot = (f as f64 - last as f64, p);
        }
        let fit = ConstantAcceleration::fit(&recent)?;
        if fit.residual > EXTRAPOLATE_MAX_RMS_PX.powi(2) * EXTRAPOLATE_POINTS as f64
            || fit.acceleration().norm() < MIN_ACCELERATION_PX
        {
            return None;
        }
        let t = (frame - last) as f64;
        let (p, v) = (fit.at(t), fit.velocity(t));
        (p.x.is_finite() && p.y.is_finite() && v.x.is_finite() && v.y.is_finite()).then_some((p, v))
    }

    fn refit(&mut self) {
        self.line = self.fit_line();
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
            // The whole history first, then its latest parts (`RECENT_RUNS`).
            let axis = |recent: &[[Vector2<f64>; 3]], least: f64| {
                fit_axis(recent.iter().map(|r| (r[0][k], r[1][k], r[2][k])), least)
            };
            *fit = axis(&runs, MIN_EXPLAINED).or_else(|| {
                RECENT_RUNS
                    .iter()
                    .filter(|&&w| w < runs.len())
                    .find_map(|&w| axis(&runs[runs.len() - w..], MIN_EXPLAINED_RECENT))
            });
        }
    }
}

/// A constant acceleration `p(t) = c0 + c1 t + c2 t²` fitted per axis, by least squares, to
/// timed points, and its summed squared residual (pixels²).
#[derive(Debug, Clone, Copy)]
pub(crate) struct ConstantAcceleration {
    x: Vector3<f64>,
    y: Vector3<f64>,
    pub residual: f64,
}

impl ConstantAcceleration {
    /// The fit to `points` (time, position); `None` with fewer than 4 points or times that do
    /// not determine it.
    pub(crate) fn fit(points: &[(f64, Point2<f64>)]) -> Option<Self> {
        if points.len() < 4 {
            return None;
        }
        let row = |t: f64| Vector3::new(1.0, t, t * t);
        let mut ata = Matrix3::zeros();
        let (mut atx, mut aty) = (Vector3::zeros(), Vector3::zeros());
        for &(t, p) in points {
            let r = row(t);
            ata += r * r.transpose();
            atx += r * p.x;
            aty += r * p.y;
        }
        let chol = ata.cholesky()?;
        let (x, y) = (chol.solve(&atx), chol.solve(&aty));
        let residual = points
            .iter()
            .map(|&(t, p)| (p.x - row(t).dot(&x)).powi(2) + (p.y - row(t).dot(&y)).powi(2))
            .sum();
        Some(Self { x, y, residual })
    }

    /// Position at time `t`.
    pub(crate) fn at(&self, t: f64) -> Point2<f64> {
        let row = Vector3::new(1.0, t, t * t);
        Point2::new(row.dot(&self.x), row.dot(&self.y))
    }

    /// Velocity at time `t` (pixels per unit of time).
    pub(crate) fn velocity(&self, t: f64) -> Vector2<f64> {
        Vector2::new(
            self.x[1] + 2.0 * self.x[2] * t,
            self.y[1] + 2.0 * self.y[2] * t,
        )
    }

    /// The acceleration (pixels per unit of time²).
    pub(crate) fn acceleration(&self) -> Vector2<f64> {
        2.0 * Vector2::new(self.x[2], self.y[2])
    }
}

/// Least squares `a = α + β p + γ v` over `(p, v, a)` samples, centred for conditioning;
/// `None` unless it explains [`MIN_EXPLAINED`] of the variance with a restoring, resolvable
/// `β`.
fn fit_axis(
    samples: impl Iterator<Item = (f64, f64, f64)> + Clone,
    least_explained: f64,
) -> Option<Vector3<f64>> {
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
    if !(explained >= least_explained
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

    /// Pulled smoothly 40 px left of (200, 100) over frames 0-25, then released: a damped
    /// swing of 12 frames' period about it.
    fn released_at(frame: u64) -> Point2<f64> {
        let t = frame as f64;
        let x = if t <= 25.0 {
            let s = t / 25.0;
            -40.0 * s * s * (3.0 - 2.0 * s)
        } else {
            let omega = std::f64::consts::TAU / 12.0;
            -40.0 * (-0.04 * omega * (t - 25.0)).exp() * (omega * (t - 25.0)).cos()
        };
        Point2::new(200.0 + x, 100.0 + 0.2 * (t * 1.7).sin())
    }

    #[test]
    fn a_swing_after_a_pull_is_learnt_on_the_frames_since_the_release() {
        let mut s = Swing::default();
        // 30 frames of history: 13 of the pull, the release, 17 of the swing, predicted
        // at its turn.
        for f in 0..=42 {
            s.record(f, released_at(f));
        }
        let (p, q) = (released_at(42), released_at(41));
        let v = p - q;
        let a = s.acceleration(p, v).expect("fitted on the swing");
        let truth = released_at(43);
        assert!((p + v + a - truth).norm() < 1.0, "{} vs {truth}", p + v + a);
        assert!((p + v - truth).norm() > 4.0);
        // Over the whole history the oscillator does not hold.
        let runs: Vec<_> = (13..42)
            .map(|f| {
                let (a, b, c) = (released_at(f - 1), released_at(f), released_at(f + 1));
                (b.x, 0.5 * (c.x - a.x), c.x - 2.0 * b.x + a.x)
            })
            .collect();
        assert!(fit_axis(runs.iter().copied(), MIN_EXPLAINED).is_none());
    }

    #[test]
    fn a_swing_has_a_line_and_a_circle_has_none() {
        let mut s = Swing::default();
        for f in 0..30 {
            let t = f as f64 * 0.3;
            s.record(f, Point2::new(100.0 + 30.0 * t.cos(), 50.0 + 0.5 * t.sin()));
        }
        let line = s.line().expect("a horizontal swing");
        assert!((line.normal.x).abs() < 0.05, "{line:?}");
        assert!(line.offset(Point2::new(120.0, 50.0)).abs() < 0.3);
        assert!(line.offset(Point2::new(100.0, 62.0)).abs() > 1.5);
        let mut c = Swing::default();
        for f in 0..30 {
            let t = f as f64 * 0.3;
            c.record(
                f,
                Point2::new(100.0 + 30.0 * t.cos(), 50.0 + 30.0 * t.sin()),
            );
        }
        assert!(c.line().is_none());
    }

    #[test]
    fn a_speeding_up_track_is_extrapolated_on_its_acceleration_for_a_few_frames() {
        let at = |f: u64| {
            let t = f as f64;
            Point2::new(100.0 + 0.5 * t + 0.3 * t * t, 40.0 - 0.25 * t * t)
        };
        let mut s = Swing::default();
        for f in 0..6 {
            s.record(f, at(f));
        }
        for ahead in 1..=EXTRAPOLATE_MAX_AHEAD {
            let (p, v) = s
                .extrapolate(5 + ahead)
                .expect("a clean constant acceleration");
            assert!(
                (p - at(5 + ahead)).norm() < 1e-9,
                "{p} vs {}",
                at(5 + ahead)
            );
            let t = (5 + ahead) as f64;
            assert!(
                (v - Vector2::new(0.5 + 0.6 * t, -0.5 * t)).norm() < 1e-9,
                "{v}"
            );
        }
        // Too far ahead, or for a frame already seen.
        assert!(s.extrapolate(6 + EXTRAPOLATE_MAX_AHEAD).is_none());
        assert!(s.extrapolate(5).is_none());
        // A steady velocity has no acceleration to add.
        let mut steady = Swing::default();
        for f in 0..6 {
            steady.record(f, Point2::new(3.0 * f as f64, 10.0));
        }
        assert!(steady.extrapolate(6).is_none());
        // A gap among the last positions, or a track that jitters, is not extrapolated.
        let mut gap = Swing::default();
        for f in [0, 1, 2, 4, 5] {
            gap.record(f, at(f));
        }
        assert!(gap.extrapolate(6).is_none());
        let mut jitter = Swing::default();
        for f in 0..6 {
            let d = if f % 2 == 0 { 2.0 } else { -2.0 };
            jitter.record(f, at(f) + Vector2::new(d, -d));
        }
        assert!(jitter.extrapolate(6).is_none());
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
