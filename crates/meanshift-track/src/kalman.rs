//! A constant-velocity Kalman filter for a marker's image position, in pixels and frames.
//!
//! State: position and velocity (pixels, pixels per frame). Noise is isotropic, so both image
//! axes share one 2x2 covariance over (position, velocity) — the filter is two identical
//! one-dimensional filters. Process noise is white acceleration with standard deviation
//! `sigma_a` (pixels per frame²), discretised for one frame (Bar-Shalom, Li, Kirubarajan 2001,
//! "Estimation with Applications to Tracking and Navigation", section 6.3.2: `Q = sigma_a² *
//! [[1/4, 1/2], [1/2, 1]]`). A release, the sudden start of a swing, is a manoeuvre the model
//! does not expect; [`Kalman::manoeuvre`] opens the covariance for it (a velocity jump that has
//! already moved the marker), so that the gate widens instead of the track ending.

use nalgebra::{Point2, Vector2};

/// Position–velocity covariance of one axis: `[pp, pv, vv]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Covariance {
    pub(crate) pp: f64,
    pub(crate) pv: f64,
    pub(crate) vv: f64,
}

/// The filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Kalman {
    pub(crate) position: Point2<f64>,
    pub(crate) velocity: Vector2<f64>,
    pub(crate) cov: Covariance,
}

impl Kalman {
    /// At rest at `position`, with standard deviations `position_px` and `velocity_px`.
    pub(crate) fn new(position: Point2<f64>, position_px: f64, velocity_px: f64) -> Self {
        Self {
            position,
            velocity: Vector2::zeros(),
            cov: Covariance {
                pp: position_px * position_px,
                pv: 0.0,
                vv: velocity_px * velocity_px,
            },
        }
    }

    /// One frame ahead with acceleration noise `sigma_a` (pixels per frame²).
    pub(crate) fn predict(&mut self, sigma_a: f64) {
        let q = sigma_a * sigma_a;
        let Covariance { pp, pv, vv } = self.cov;
        self.position += self.velocity;
        self.cov = Covariance {
            pp: pp + 2.0 * pv + vv + 0.25 * q,
            pv: pv + vv + 0.5 * q,
            vv: vv + q,
        };
    }

    /// Variance of the innovation for a measurement of standard deviation `sigma_z`: the
    /// squared gate scale (pixels²) per axis.
    pub(crate) fn innovation_var(&self, sigma_z: f64) -> f64 {
        self.cov.pp + sigma_z * sigma_z
    }

    /// Squared Mahalanobis distance of `z` from the prediction (2 degrees of freedom).
    #[cfg(test)]
    fn distance2(&self, z: Point2<f64>, sigma_z: f64) -> f64 {
        (z - self.position).norm_squared() / self.innovation_var(sigma_z)
    }

    /// Correct with a measured position `z` of standard deviation `sigma_z`.
    pub(crate) fn update(&mut self, z: Point2<f64>, sigma_z: f64) {
        let s = self.innovation_var(sigma_z);
        let Covariance { pp, pv, vv } = self.cov;
        let (k0, k1) = (pp / s, pv / s);
        let r = z - self.position;
        self.position += r * k0;
        self.velocity += r * k1;
        self.cov = Covariance {
            pp: (1.0 - k0) * pp,
            pv: (1.0 - k0) * pv,
            vv: vv - k1 * pv,
        };
    }

    /// An unexpected change of velocity of standard deviation `sigma_px` (pixels per frame)
    /// that has already moved the marker by as much: both variances and their covariance
    /// grow by `sigma_px²`, so a measurement far off is believed in position and velocity.
    pub(crate) fn manoeuvre(&mut self, sigma_px: f64) {
        let q = sigma_px * sigma_px;
        self.cov.pp += q;
        self.cov.pv += q;
        self.cov.vv += q;
    }

    /// Forget the velocity (a marker set by hand, or the paper's static model).
    pub(crate) fn stop(&mut self, velocity_px: f64) {
        self.velocity = Vector2::zeros();
        self.cov.pv = 0.0;
        self.cov.vv = velocity_px * velocity_px;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn follows_a_constant_velocity_and_its_gate_shrinks() {
        let mut k = Kalman::new(Point2::new(10.0, 20.0), 2.0, 5.0);
        let mut gates = Vec::new();
        for f in 1..=30 {
            k.predict(0.5);
            gates.push(k.innovation_var(0.5));
            let z = Point2::new(10.0 + 3.0 * f64::from(f), 20.0 - 1.0 * f64::from(f));
            k.update(z, 0.5);
        }
        assert!(
            (k.velocity - Vector2::new(3.0, -1.0)).norm() < 0.05,
            "{k:?}"
        );
        assert!(gates[29] < gates[0] / 4.0, "{gates:?}");
        // The covariance stays symmetric positive definite.
        let c = k.cov;
        assert!(c.pp > 0.0 && c.vv > 0.0 && c.pp * c.vv > c.pv * c.pv);
    }

    #[test]
    fn a_manoeuvre_lets_one_measurement_set_the_new_velocity() {
        let mut k = Kalman::new(Point2::new(0.0, 0.0), 1.0, 1.0);
        for _ in 0..20 {
            k.predict(0.3);
            k.update(Point2::new(0.0, 0.0), 0.5);
        }
        // A release: 40 px in one frame.
        k.predict(0.3);
        assert!(k.distance2(Point2::new(40.0, 0.0), 0.5) > 100.0);
        k.manoeuvre(40.0);
        assert!(k.distance2(Point2::new(40.0, 0.0), 0.5) < 2.0);
        k.update(Point2::new(40.0, 0.0), 0.5);
        assert!((k.velocity.x - 40.0).abs() < 2.0, "{k:?}");
        k.predict(0.3);
        assert!((k.position.x - 80.0).abs() < 3.0, "{k:?}");
    }
}
