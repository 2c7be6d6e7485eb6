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
/// `None` when either marker is unknown or fewer than 3 frames inside the window have both.
pub fn relative_swing(
    trajectories: &Trajectories,
    parent: &str,
    child: &str,
    window_s: (f64, f64),
) -> Option<Vec<Option<f64>>> {
    let (p, c) = (trajectories.marker(parent)?, trajectories.marker(child)?);
    let rel: Vec<Option<Vector3<f64>>> = p
        .positions_m
        .iter()
        .zip(&c.positions_m)
        .map(|(a, b)| Some(b.as_ref()? - a.as_ref()?))
        .collect();
    let inside: Vec<Vector3<f64>> = rel
        .iter()
        .zip(trajectories.times_s())
        .filter(|(_, t)| (window_s.0..=window_s.1).contains(*t))
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
}
