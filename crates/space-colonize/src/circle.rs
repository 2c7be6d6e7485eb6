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

/// Gauss–Newton iterations of [`centre_with_radius`].
const CENTRE_ITERATIONS: usize = 8;

/// Centre of a circle of known radius through 2D points: minimises Σ (|p − c| − r)² from
/// `c = 0`, without the points beyond three median absolute deviations of the start. With
/// the radius known, an arc of a one-sided view fixes the centre well where a free fit
/// (which must also find the curvature) does not. The centre moves at most `r` from the
/// origin. `None` with fewer than 3 points or a singular system.
pub(crate) fn centre_with_radius(pts: &[[f64; 2]], r: f64) -> Option<[f64; 2]> {
    if pts.len() < 3 || !(r.is_finite() && r > 0.0) {
        return None;
    }
    let mut dev: Vec<f64> = pts
        .iter()
        .map(|p| (dist(p, [0.0, 0.0]) - r).abs())
        .collect();
    dev.sort_by(f64::total_cmp);
    let limit = (3.0 * 1.4826 * dev[dev.len() / 2]).max(0.5 * r);
    let used: Vec<&[f64; 2]> = pts
        .iter()
        .filter(|p| (dist(p, [0.0, 0.0]) - r).abs() <= limit)
        .collect();
    if used.len() < 3 {
        return None;
    }
    let mut c = [0.0, 0.0];
    for _ in 0..CENTRE_ITERATIONS {
        let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for p in &used {
            let d = dist(p, c);
            if d < 1e-12 {
                continue;
            }
            // Residual e = d − r; de/dc = −(p − c)/d.
            let (jx, jy) = (-(p[0] - c[0]) / d, -(p[1] - c[1]) / d);
            let e = d - r;
            a11 += jx * jx;
            a12 += jx * jy;
            a22 += jy * jy;
            b1 -= jx * e;
            b2 -= jy * e;
        }
        let det = a11 * a22 - a12 * a12;
        if det.abs() < 1e-12 * (a11 + a22).powi(2) || det == 0.0 {
            return None;
        }
        let dx = (a22 * b1 - a12 * b2) / det;
        let dy = (a11 * b2 - a12 * b1) / det;
        c = [c[0] + dx, c[1] + dy];
        if dx.hypot(dy) < 1e-9 * r {
            break;
        }
    }
    let moved = c[0].hypot(c[1]);
    (moved.is_finite()).then(|| {
        if moved > r {
            [c[0] * r / moved, c[1] * r / moved]
        } else {
            c
        }
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
    fn known_radius_centres_a_quarter_arc() {
        // A quarter of a 1 cm circle around (3 mm, −2 mm), 2 % noise: a free fit of so short
        // an arc is poor, the known radius pins the centre.
        let pts: Vec<[f64; 2]> = (0..12)
            .map(|k| {
                let a = 0.2 + 1.4 * k as f64 / 11.0;
                let r = 0.01 * (1.0 + 0.02 * if k % 2 == 0 { 1.0 } else { -1.0 });
                [0.003 + r * a.cos(), -0.002 + r * a.sin()]
            })
            .collect();
        let c = centre_with_radius(&pts, 0.01).expect("fits");
        assert!(
            (c[0] - 0.003).abs() < 5e-4 && (c[1] + 0.002).abs() < 5e-4,
            "{c:?}"
        );
        assert!(centre_with_radius(&pts[..2], 0.01).is_none());
        assert!(centre_with_radius(&pts, 0.0).is_none());
    }

    #[test]
    fn collinear_points_fit_nothing() {
        let pts: Vec<[f64; 2]> = (0..10)
            .map(|i| [f64::from(i), 2.0 * f64::from(i)])
            .collect();
        assert!(fit_circle(&pts).is_none());
    }
}
