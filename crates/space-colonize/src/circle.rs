//! Circle fits in a plane: the algebraic fit of Kåsa (1976), with one robust refit.

/// A circle fitted to 2D points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Circle {
    /// Centre, metres.
    pub centre: [f64; 2],
    /// Radius, metres.
    pub radius_m: f64,
    /// Root-mean-square of |distance to centre − radius| over the points used, metres.
    pub rms_m: f64,
    /// Points used.
    pub points: usize,
    /// Share of 16 angular sectors around the centre that hold a point (1 = full circle).
    pub coverage: f64,
}

/// Rounds of outlier rejection.
const ROBUST_ROUNDS: usize = 3;
/// Sectors used for [`Circle::coverage`].
const SECTORS: usize = 16;

/// Kåsa's fit (minimises the algebraic distance x² + y² + Dx + Ey + F), then a refit
/// without points farther than three median absolute deviations from the first circle (a
/// side branch or noise in the slice). `None` when fewer than 5 points or degenerate.
pub(crate) fn fit_circle(pts: &[[f64; 2]]) -> Option<Circle> {
    let first = kasa(pts.iter())?;
    let all: Vec<&[f64; 2]> = pts.iter().collect();
    let (mut centre, mut radius_m) = geometric(&all, first);
    let mut used = all.clone();
    // Reject points beyond three median absolute deviations and refit, until the set holds.
    for _ in 0..ROBUST_ROUNDS {
        let mut dev: Vec<f64> = pts
            .iter()
            .map(|p| (dist(p, centre) - radius_m).abs())
            .collect();
        dev.sort_by(f64::total_cmp);
        let limit = (3.0 * 1.4826 * dev[dev.len() / 2]).max(1e-12 * radius_m);
        let kept: Vec<&[f64; 2]> = pts
            .iter()
            .filter(|p| (dist(p, centre) - radius_m).abs() <= limit)
            .collect();
        if kept.len() < 5 || kept.len() == used.len() {
            break;
        }
        let start = kasa(kept.iter().copied())?;
        (centre, radius_m) = geometric(&kept, start);
        used = kept;
    }
    let rms_m = (used
        .iter()
        .map(|p| (dist(p, centre) - radius_m).powi(2))
        .sum::<f64>()
        / used.len() as f64)
        .sqrt();
    let mut sectors = [false; SECTORS];
    for p in &used {
        let a = (p[1] - centre[1]).atan2(p[0] - centre[0]);
        let s = (((a + std::f64::consts::PI) / std::f64::consts::TAU) * SECTORS as f64) as usize;
        sectors[s.min(SECTORS - 1)] = true;
    }
    let coverage = sectors.iter().filter(|&&s| s).count() as f64 / SECTORS as f64;
    Some(Circle {
        centre,
        radius_m,
        rms_m,
        points: used.len(),
        coverage,
    })
}

fn dist(p: &[f64; 2], c: [f64; 2]) -> f64 {
    (p[0] - c[0]).hypot(p[1] - c[1])
}

/// Gauss–Newton iterations of the geometric fit.
const GEOMETRIC_ITERATIONS: usize = 10;

/// The geometric fit, min Σ (|p − c| − r)², by Gauss–Newton from `start`: unlike the
/// algebraic fit it does not shrink circles fitted to a noisy partial arc. Keeps `start`
/// when an iteration fails or would run off (more than 2 radii).
fn geometric(pts: &[&[f64; 2]], start: ([f64; 2], f64)) -> ([f64; 2], f64) {
    let (mut c, mut r) = start;
    for _ in 0..GEOMETRIC_ITERATIONS {
        let mut jtj = nalgebra::Matrix3::<f64>::zeros();
        let mut jtr = nalgebra::Vector3::<f64>::zeros();
        for p in pts {
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            let d = dx.hypot(dy);
            if d < 1e-12 {
                continue;
            }
            // residual d − r; derivatives w.r.t. (cx, cy, r)
            let j = nalgebra::Vector3::new(-dx / d, -dy / d, -1.0);
            jtj += j * j.transpose();
            jtr += j * (d - r);
        }
        let Some(step) = jtj.lu().solve(&(-jtr)) else {
            break;
        };
        let next = ([c[0] + step[0], c[1] + step[1]], r + step[2]);
        if !(next.1 > 0.0 && next.1.is_finite())
            || dist(&next.0, start.0) > 2.0 * start.1
            || next.1 > 3.0 * start.1
        {
            return start;
        }
        let done = step.norm() < 1e-9 * r.max(1e-12);
        (c, r) = next;
        if done {
            break;
        }
    }
    (c, r)
}

/// The algebraic fit on points shifted to their mean (for conditioning).
fn kasa<'a>(pts: impl Iterator<Item = &'a [f64; 2]> + Clone) -> Option<([f64; 2], f64)> {
    let mut n = 0.0;
    let (mut mx, mut my) = (0.0, 0.0);
    for p in pts.clone() {
        n += 1.0;
        mx += p[0];
        my += p[1];
    }
    if n < 5.0 {
        return None;
    }
    mx /= n;
    my /= n;
    // Normal equations of [x y 1] [D E F]' = -(x² + y²).
    let mut a = nalgebra::Matrix3::<f64>::zeros();
    let mut b = nalgebra::Vector3::<f64>::zeros();
    for p in pts {
        let (x, y) = (p[0] - mx, p[1] - my);
        let row = nalgebra::Vector3::new(x, y, 1.0);
        a += row * row.transpose();
        b -= row * (x * x + y * y);
    }
    let sol = a.lu().solve(&b)?;
    let (cx, cy) = (-sol[0] / 2.0, -sol[1] / 2.0);
    let r2 = cx * cx + cy * cy - sol[2];
    if r2.is_nan() || r2 <= 0.0 || !r2.is_finite() {
        return None;
    }
    Some(([cx + mx, cy + my], r2.sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_half_circle_with_an_outlier() {
        let mut pts: Vec<[f64; 2]> = (0..40)
            .map(|i| {
                let a = std::f64::consts::PI * f64::from(i) / 39.0;
                [1.0 + 0.05 * a.cos(), -2.0 + 0.05 * a.sin()]
            })
            .collect();
        pts.push([1.0, -1.9]);
        let c = fit_circle(&pts).unwrap();
        assert!((c.centre[0] - 1.0).abs() < 1e-9 && (c.centre[1] + 2.0).abs() < 1e-9);
        assert!((c.radius_m - 0.05).abs() < 1e-9);
        assert!(c.coverage > 0.4 && c.coverage < 0.6, "{}", c.coverage);
    }

    #[test]
    fn collinear_points_fit_nothing() {
        let pts: Vec<[f64; 2]> = (0..10)
            .map(|i| [f64::from(i), 2.0 * f64::from(i)])
            .collect();
        assert!(fit_circle(&pts).is_none());
    }
}
