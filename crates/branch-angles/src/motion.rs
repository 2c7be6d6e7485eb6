//! What a marker's lifted positions need before they are angles or swings: isolated jumps
//! taken out (a lift that landed on another surface for a frame), and the child's swing as
//! one coordinate, its displacement from its parent's marker along the direction it moves
//! most.

use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};

use crate::trajectory::Trajectories;

/// A lifted position further than this from the median of its neighbours (two frames each
/// side) is a lift that landed on another surface: a branch marker moves about a
/// centimetre per frame at 30 fps (3 cm at 2.5 Hz peaks at 0.5 m/s), and the neighbours'
/// median follows its swing to about 1 cm. Metres.
pub const DEFAULT_JUMP_M: f64 = 0.04;

/// A marker is still inside a window when the variance of its positions there is at most
/// this many times half the mean square of its frame-to-frame steps. For white lift noise
/// both are the noise's variance (ratio 1, within about ±0.2 for a hundred frames); a swing
/// slower than a sixth of the frame rate adds its variance to the first and under a tenth of
/// it to the second, so the ratio reaches 2 when the motion's RMS equals the noise's. Below
/// it, subtracting the marker frame by frame adds more noise than the motion it removes. (On
/// the twin, parents in their children's tests give 0.8–1.2, the swinging children 22–56.)
pub const STILL_PARENT_RATIO: f64 = 2.0;

/// Fewest frame-to-frame steps inside the window that can call a marker still.
const MIN_STILL_STEPS: usize = 10;

/// Iteration limit of the eigen-decomposition of the swing's 3x3 covariance (it converges in
/// a handful; the limit only bounds a corrupt input).
const MAX_EIGEN_ITERATIONS: usize = 1000;

/// `positions` with the isolated jumps taken out (as gaps, filled later like any other): a
/// position further than `max_jump_m` from the per-coordinate median of its known
/// neighbours (two frames each side; kept when fewer than two are known).
pub fn drop_jumps(positions: &[Option<Point3<f64>>], max_jump_m: f64) -> Vec<Option<Point3<f64>>> {
    let n = positions.len();
    (0..n)
        .map(|i| {
            let p = positions[i]?;
            let around: Vec<Point3<f64>> = (i.saturating_sub(2)..(i + 3).min(n))
                .filter(|&j| j != i)
                .filter_map(|j| positions[j])
                .collect();
            if around.len() < 2 {
                return Some(p);
            }
            let median = |f: fn(&Point3<f64>) -> f64| {
                let mut v: Vec<f64> = around.iter().map(f).collect();
                v.sort_by(f64::total_cmp);
                0.5 * (v[(v.len() - 1) / 2] + v[v.len() / 2])
            };
            let m = Point3::new(median(|p| p.x), median(|p| p.y), median(|p| p.z));
            ((p - m).norm() <= max_jump_m).then_some(p)
        })
        .collect()
}

/// The child's position relative to its parent's marker, projected on the direction it moves
/// most inside `window_s` (the first principal axis of the relative positions there), metres:
/// one coordinate of the swing whichever way it goes, across or along the chord. The relative
/// angle of eq. (1) sees only the part of a swing across the chord; for a small swing the
/// angle is that part over the chord's length, so both carry the same frequency and damping,
/// but a twig swinging toward or away from its parent's marker leaves the angle a small,
/// distorted copy of its motion.
///
/// A parent that is still inside the window (its spread there no larger than
/// [`STILL_PARENT_RATIO`] times what its frame-to-frame differences give white noise: the
/// parent of a branch in its own pull-and-release test) is taken at its mean position inside
/// the window: subtracting it frame by frame would add its lift noise to the child's swing
/// and remove no motion (on the twin's JPEG recording this halves the twig's frequency
/// error). A parent that moves, sways with the wind or shakes with the camera is subtracted
/// frame by frame as before; outside the window it always is.
///
/// `None` when either marker is unknown or fewer than 3 frames inside the window have both.
pub fn relative_swing(
    trajectories: &Trajectories,
    parent: &str,
    child: &str,
    window_s: (f64, f64),
) -> Option<Vec<Option<f64>>> {
    let (p, c) = (trajectories.marker(parent)?, trajectories.marker(child)?);
    let inside_window = |t: &f64| (window_s.0..=window_s.1).contains(t);
    let still_at = still_position(&p.positions_m, trajectories.times_s(), window_s);
    let rel: Vec<Option<Vector3<f64>>> = p
        .positions_m
        .iter()
        .zip(&c.positions_m)
        .zip(trajectories.times_s())
        .map(|((a, b), t)| match still_at {
            Some(mean) if inside_window(t) => Some(b.as_ref()?.coords - mean),
            _ => Some(b.as_ref()? - a.as_ref()?),
        })
        .collect();
    let inside: Vec<Vector3<f64>> = rel
        .iter()
        .zip(trajectories.times_s())
        .filter(|(_, t)| inside_window(t))
        .filter_map(|(r, _)| *r)
        .collect();
    if inside.len() < 3 {
        return None;
    }
    let mean = inside.iter().sum::<Vector3<f64>>() / inside.len() as f64;
    let cov = inside
        .iter()
        .map(|r| (r - mean) * (r - mean).transpose())
        .sum::<Matrix3<f64>>();
    let eig = SymmetricEigen::try_new(cov, f64::EPSILON, MAX_EIGEN_ITERATIONS)?;
    let k = eig.eigenvalues.imax();
    let axis: Vector3<f64> = eig.eigenvectors.column(k).into();
    Some(
        rel.iter()
            .map(|r| r.map(|r| (r - mean).dot(&axis)))
            .collect(),
    )
}

/// The mean position inside `window_s` of a marker that is still there (see
/// [`STILL_PARENT_RATIO`]), or `None` when it moves or too few frames tell.
fn still_position(
    positions: &[Option<Point3<f64>>],
    times_s: &[f64],
    window_s: (f64, f64),
) -> Option<Vector3<f64>> {
    let inside: Vec<Option<Vector3<f64>>> = positions
        .iter()
        .zip(times_s)
        .filter(|(_, t)| (window_s.0..=window_s.1).contains(*t))
        .map(|(p, _)| p.map(|p| p.coords))
        .collect();
    let steps: Vec<f64> = inside
        .windows(2)
        .filter_map(|w| Some((w[1]? - w[0]?).norm_squared()))
        .collect();
    if steps.len() < MIN_STILL_STEPS {
        return None;
    }
    let known: Vec<Vector3<f64>> = inside.iter().flatten().copied().collect();
    let n = known.len() as f64;
    let mean = known.iter().sum::<Vector3<f64>>() / n;
    let variance = known.iter().map(|p| (p - mean).norm_squared()).sum::<f64>() / n;
    let step_variance = 0.5 * steps.iter().sum::<f64>() / steps.len() as f64;
    (variance <= STILL_PARENT_RATIO * step_variance).then_some(mean)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trajectory::MarkerTrack;

    #[test]
    fn an_isolated_jump_goes_a_swing_stays() {
        let mut p: Vec<Option<Point3<f64>>> = (0..20)
            .map(|i| Some(Point3::new(0.01 * f64::from(i), 0.0, 1.0)))
            .collect();
        p[7] = Some(Point3::new(0.07, 0.3, 1.0));
        p[12] = None;
        let kept = drop_jumps(&p, DEFAULT_JUMP_M);
        assert!(kept[7].is_none());
        assert!(kept[12].is_none());
        assert_eq!(kept.iter().flatten().count(), 18);
        // Too few neighbours known: kept.
        let lone = [
            Some(Point3::origin()),
            None,
            None,
            Some(Point3::new(1.0, 0.0, 0.0)),
        ];
        assert_eq!(drop_jumps(&lone, DEFAULT_JUMP_M), lone.to_vec());
    }

    #[test]
    fn the_swing_is_the_displacement_along_the_main_axis() {
        let times: Vec<f64> = (0..100).map(|i| f64::from(i) * 0.05).collect();
        let parent = MarkerTrack {
            id: "A".into(),
            positions_m: times
                .iter()
                .map(|t| Some(Point3::new(0.0, 0.0, 0.01 * t)))
                .collect(),
        };
        // The child swings along (1, 1, 0)/sqrt 2 by 5 cm around (0.3, 0, 1) relative to A.
        let dir = Vector3::new(1.0, 1.0, 0.0).normalize();
        let child = MarkerTrack {
            id: "B".into(),
            positions_m: times
                .iter()
                .map(|t| {
                    let s = 0.05 * (2.0 * std::f64::consts::PI * t).sin();
                    Some(Point3::new(0.3, 0.0, 1.0 + 0.01 * t) + dir * s)
                })
                .collect(),
        };
        let tr = Trajectories::new(times.clone(), vec![parent, child]).unwrap();
        let swing = relative_swing(&tr, "A", "B", (0.0, 10.0)).unwrap();
        for (t, v) in times.iter().zip(&swing) {
            let s = 0.05 * (2.0 * std::f64::consts::PI * t).sin();
            // The axis's sign is arbitrary.
            assert!((v.unwrap().abs() - s.abs()).abs() < 1e-9, "{t}");
        }
        assert!(relative_swing(&tr, "A", "Z", (0.0, 10.0)).is_none());
        assert!(relative_swing(&tr, "A", "B", (20.0, 30.0)).is_none());
    }

    /// Deterministic white-ish noise in [-1, 1] (a hash of the frame and axis).
    fn noise(k: usize, axis: usize) -> f64 {
        let x = (k * 3 + axis) as f64;
        2.0 * ((x * 12.9898).sin() * 43_758.545_3).fract().abs() - 1.0
    }

    /// A noise-free child swinging 3 cm along x relative to a parent at (0, 0, 1), and the
    /// parent's track: `parent_swing_m` of swing along y plus `noise_m` of lift noise.
    fn parent_and_child(parent_swing_m: f64, noise_m: f64) -> (Trajectories, Vec<f64>) {
        let times: Vec<f64> = (0..120).map(|i| f64::from(i) / 30.0).collect();
        let truth: Vec<f64> = times
            .iter()
            .map(|t| 0.03 * (2.0 * std::f64::consts::PI * 2.0 * t).sin())
            .collect();
        let parent_at = |k: usize, t: f64| {
            let sway = parent_swing_m * (2.0 * std::f64::consts::PI * 0.7 * t).sin();
            Point3::new(0.0, sway, 1.0)
                + Vector3::new(noise(k, 0), noise(k, 1), noise(k, 2)) * noise_m
        };
        let parent = MarkerTrack {
            id: "P".into(),
            positions_m: times
                .iter()
                .enumerate()
                .map(|(k, t)| Some(parent_at(k, *t)))
                .collect(),
        };
        let child = MarkerTrack {
            id: "C".into(),
            positions_m: times
                .iter()
                .zip(&truth)
                .map(|(t, s)| {
                    let sway = parent_swing_m * (2.0 * std::f64::consts::PI * 0.7 * t).sin();
                    Some(Point3::new(0.3 + s, sway, 1.0))
                })
                .collect(),
        };
        (
            Trajectories::new(times, vec![parent, child]).unwrap(),
            truth,
        )
    }

    /// Largest difference between the swing and the truth, up to the axis's sign and the
    /// swing's mean.
    fn worst_error(swing: &[Option<f64>], truth: &[f64]) -> f64 {
        let v: Vec<f64> = swing.iter().map(|v| v.unwrap()).collect();
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let sign = if v.iter().zip(truth).map(|(a, b)| a * b).sum::<f64>() < 0.0 {
            -1.0
        } else {
            1.0
        };
        v.iter()
            .zip(truth)
            .map(|(a, b)| (sign * (a - mean) - b).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_still_parent_lends_its_mean_not_its_noise() {
        // A still parent with 3 mm of lift noise: the swing is the child's own, noise-free.
        let (tr, truth) = parent_and_child(0.0, 0.003);
        let swing = relative_swing(&tr, "P", "C", (0.0, 10.0)).unwrap();
        assert!(
            worst_error(&swing, &truth) < 1e-4,
            "{}",
            worst_error(&swing, &truth)
        );
        // Outside the window the parent is subtracted frame by frame: its noise shows.
        let outside = relative_swing(&tr, "P", "C", (0.0, 2.0)).unwrap();
        assert!(worst_error(&outside[61..], &truth[61..]) > 1e-3);
        // A parent that sways 1 cm (three times its noise) is subtracted frame by frame: the
        // child's swing holds no trace of the parent's sway, only the parent's noise.
        let (tr, truth) = parent_and_child(0.01, 0.003);
        let swing = relative_swing(&tr, "P", "C", (0.0, 10.0)).unwrap();
        let e = worst_error(&swing, &truth);
        assert!(e > 1e-3 && e < 0.006, "{e}");
    }
}
