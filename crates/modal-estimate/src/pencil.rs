//! Matrix pencil on the signal subspace of a Hankel matrix (Hua & Sarkar 1990, in its
//! total-least-squares form): the poles that start the nonlinear fit.

use nalgebra::{DMatrix, SymmetricEigen, linalg::Schur};

use crate::error::{ModalError, Result};
use crate::fit::ModeGuess;

/// Largest pencil parameter L: the Hankel matrix has L + 1 columns. Above about 24 the
/// eigendecomposition costs more than the whole fit, and the fit refines the poles anyway
/// (the data are decimated to about 8 samples per period first, so 24 spans 3 periods).
const MAX_PENCIL: usize = 24;

/// Continuous-time oscillatory poles of uniformly sampled data (values at `interval_s`),
/// from a model of `order` exponentials (2 per mode, 1 per real pole such as an offset or
/// a drift). The data are first averaged over blocks of `decimation` samples, which keeps
/// every pole (an FIR filter does not move poles) and cuts the noise and the cost.
///
/// Returns the poles with a positive frequency as (decay rate, damped angular frequency).
pub(crate) fn pencil_poles(
    values: &[f64],
    interval_s: f64,
    order: usize,
    decimation: usize,
) -> Result<Vec<ModeGuess>> {
    let d = decimation.max(1);
    let x: Vec<f64> = values
        .chunks_exact(d)
        .map(|c| c.iter().sum::<f64>() / d as f64)
        .collect();
    let dt = interval_s * d as f64;
    let n = x.len();
    if n < 2 * order + 2 {
        return Err(ModalError::TooFewSamples {
            what: "the matrix pencil",
            present: n,
            needed: 2 * order + 2,
        });
    }
    let l = (n / 3)
        .clamp(order + 1, MAX_PENCIL.max(order + 1))
        .min(n - order - 1);
    let rows = n - l;
    let hankel = DMatrix::from_fn(rows, l + 1, |i, j| x[i + j]);
    let gram = hankel.tr_mul(&hankel);
    let eig = SymmetricEigen::try_new(gram, 1e-14, 500).ok_or(ModalError::Numerical {
        what: "the matrix pencil's eigendecomposition",
    })?;
    let mut idx: Vec<usize> = (0..=l).collect();
    idx.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let m = order.min(l);
    let v = DMatrix::from_fn(l + 1, m, |i, j| eig.eigenvectors[(i, idx[j])]);
    let v1 = v.rows(0, l).into_owned();
    let v2 = v.rows(1, l).into_owned();
    let numerical = || ModalError::Numerical {
        what: "the matrix pencil's pseudo-inverse",
    };
    let pinv = nalgebra::linalg::SVD::try_new(
        v1,
        true,
        true,
        f64::EPSILON,
        crate::fit::MAX_SVD_ITERATIONS,
    )
    .ok_or_else(numerical)?
    .pseudo_inverse(1e-12)
    .map_err(|_| numerical())?;
    let z = pinv * v2;
    if z.iter().any(|v| !v.is_finite()) {
        return Err(ModalError::Numerical {
            what: "the matrix pencil",
        });
    }
    let schur = Schur::try_new(z, 1e-14, 500).ok_or(ModalError::Numerical {
        what: "the matrix pencil's eigenvalues",
    })?;
    let mut poles = Vec::new();
    for zc in schur.complex_eigenvalues().iter() {
        let (r, arg) = (zc.norm(), zc.im.atan2(zc.re));
        if !(r > 0.0 && r.is_finite()) || arg <= 1e-4 {
            continue;
        }
        poles.push(ModeGuess {
            sigma: -r.ln() / dt,
            omega: arg / dt,
        });
    }
    Ok(poles)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_two_damped_modes_and_ignores_a_trend() {
        let dt = 1.0 / 30.0;
        let modes: [(f64, f64); 2] = [(0.3, 9.0), (0.8, 21.0)];
        let x: Vec<f64> = (0..400)
            .map(|i| {
                let t = f64::from(i) * dt;
                0.4 + 0.02 * t
                    + modes
                        .iter()
                        .enumerate()
                        .map(|(k, (s, w))| (1.0 - 0.6 * k as f64) * (-s * t).exp() * (w * t).cos())
                        .sum::<f64>()
            })
            .collect();
        for decimation in [1, 3] {
            let mut poles = pencil_poles(&x, dt, 6, decimation).unwrap();
            poles.sort_by(|a, b| a.omega.total_cmp(&b.omega));
            assert_eq!(poles.len(), 2, "{poles:?}");
            for (p, (s, w)) in poles.iter().zip(modes) {
                assert!((p.sigma - s).abs() < 1e-6, "{p:?}");
                assert!((p.omega - w).abs() < 1e-6, "{p:?}");
            }
        }
    }
}
