//! The single-mode oscillator of eq. (7), x'' + 4πξf x' + 4π²f² x = a(t), and its
//! integrators for a forcing held constant over each step.

use std::f64::consts::TAU;

use serde::{Deserialize, Serialize};

use crate::error::{AnimError, Result};

/// Natural frequency and damping ratio of a branch's first mode.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Dynamics {
    /// Natural frequency f, Hz.
    pub frequency_hz: f64,
    /// Damping ratio ξ, in [0, 1).
    pub damping_ratio: f64,
}

/// The paper's dominant mode (Table 1: 1.46 Hz for more than 85 % of the marked branches;
/// ξ = 0.086 is branch C under a small force).
pub const PAPER_DYNAMICS: Dynamics = Dynamics {
    frequency_hz: 1.46,
    damping_ratio: 0.086,
};

/// Highest branch frequency accepted, hertz: leaves flutter at tens of hertz, and nothing of
/// a tree sways at a kilohertz.
pub const MAX_FREQUENCY_HZ: f64 = 1000.0;

impl Dynamics {
    /// Check 0 < f ≤ [`MAX_FREQUENCY_HZ`] and ξ in [0, 1); `what` names the entry in the error.
    ///
    /// # Errors
    /// [`AnimError::InvalidFrequency`], [`AnimError::InvalidDamping`].
    pub fn validate(&self, what: &str) -> Result<()> {
        if !(self.frequency_hz.is_finite()
            && self.frequency_hz > 0.0
            && self.frequency_hz <= MAX_FREQUENCY_HZ)
        {
            return Err(AnimError::InvalidFrequency {
                what: what.to_owned(),
                frequency_hz: self.frequency_hz,
            });
        }
        if !(self.damping_ratio.is_finite() && (0.0..1.0).contains(&self.damping_ratio)) {
            return Err(AnimError::InvalidDamping {
                what: what.to_owned(),
                damping_ratio: self.damping_ratio,
            });
        }
        Ok(())
    }

    /// Angular natural frequency ω = 2πf, rad/s.
    pub fn omega_rad_s(&self) -> f64 {
        TAU * self.frequency_hz
    }
}

/// How eq. (7) is advanced over one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[non_exhaustive]
pub enum Integrator {
    /// The exact solution for a forcing held over the step (zero-order hold): stable and
    /// exact for any step, frequency and damping. The default.
    #[default]
    ExactZoh,
    /// Semi-implicit (symplectic) Euler, sub-stepped to [`EULER_TOLERANCE`].
    SemiImplicitEuler,
    /// The paper's explicit Euler, sub-stepped to [`EULER_TOLERANCE`] (without sub-steps it
    /// diverges below 2ξ/ω per step: about 53 fps for f = 1.46 Hz, ξ = 0.086).
    ExplicitEuler,
}

/// Largest relative error of the effective frequency and damping ratio the Euler integrators
/// are sub-stepped to.
pub const EULER_TOLERANCE: f64 = 0.05;
/// Most sub-steps per frame for the Euler integrators.
pub const MAX_SUBSTEPS: usize = 4096;

/// One step of x' = v, v' = a − 2ξω v − ω² x for a constant a: (x, v) ← Φ (x, v) + Γ a.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Step {
    pub phi: [[f64; 2]; 2],
    pub gamma: [f64; 2],
}

impl Step {
    #[inline]
    pub(crate) fn apply(&self, x: f64, v: f64, a: f64) -> (f64, f64) {
        (
            self.phi[0][0] * x + self.phi[0][1] * v + self.gamma[0] * a,
            self.phi[1][0] * x + self.phi[1][1] * v + self.gamma[1] * a,
        )
    }

    fn compose(&self, next: &Step) -> Step {
        // Apply self, then next: Φ = Φn Φs, Γ = Φn Γs + Γn.
        let (a, b) = (next.phi, self.phi);
        let phi = [
            [
                a[0][0] * b[0][0] + a[0][1] * b[1][0],
                a[0][0] * b[0][1] + a[0][1] * b[1][1],
            ],
            [
                a[1][0] * b[0][0] + a[1][1] * b[1][0],
                a[1][0] * b[0][1] + a[1][1] * b[1][1],
            ],
        ];
        let g = self.gamma;
        let gamma = [
            a[0][0] * g[0] + a[0][1] * g[1] + next.gamma[0],
            a[1][0] * g[0] + a[1][1] * g[1] + next.gamma[1],
        ];
        Step { phi, gamma }
    }

    /// The exact zero-order-hold step of length `dt_s` (0 ≤ ξ < 1).
    pub(crate) fn exact(d: &Dynamics, dt_s: f64) -> Step {
        let w = d.omega_rad_s();
        let z = d.damping_ratio;
        let wd = w * (1.0 - z * z).sqrt();
        let e = (-z * w * dt_s).exp();
        let (s, c) = (wd * dt_s).sin_cos();
        let phi = [
            [e * (c + z * w / wd * s), e * s / wd],
            [-e * w * w / wd * s, e * (c - z * w / wd * s)],
        ];
        // Γ = A⁻¹ (Φ − I) B with B = (0, 1): the response to a unit step held over dt.
        let gamma = [(1.0 - phi[0][0]) / (w * w), -phi[1][0] / (w * w)];
        Step { phi, gamma }
    }

    fn euler(d: &Dynamics, h: f64, implicit_velocity: bool) -> Step {
        let w = d.omega_rad_s();
        let k = w * w;
        let c = 2.0 * d.damping_ratio * w;
        if implicit_velocity {
            // v ← v + h(a − c v − k x); x ← x + h v_new.
            let v_row = [-h * k, 1.0 - h * c];
            Step {
                phi: [[1.0 + h * v_row[0], h * v_row[1]], v_row],
                gamma: [h * h, h],
            }
        } else {
            Step {
                phi: [[1.0, h], [-h * k, 1.0 - h * c]],
                gamma: [0.0, h],
            }
        }
    }

    /// The step's eigenvalues as the frequency and damping ratio of the continuous
    /// oscillator they sample (`None` if they are real or outside the unit circle's log).
    pub(crate) fn effective(&self, dt_s: f64) -> Option<Dynamics> {
        let tr = self.phi[0][0] + self.phi[1][1];
        let det = self.phi[0][0] * self.phi[1][1] - self.phi[0][1] * self.phi[1][0];
        let disc = tr * tr / 4.0 - det;
        if disc >= 0.0 || det <= 0.0 {
            return None;
        }
        // λ = r e^{±iθ}; s = ln λ / dt.
        let r = det.sqrt();
        let theta = (-disc).sqrt().atan2(tr / 2.0);
        let re = r.ln() / dt_s;
        let im = theta / dt_s;
        let w = re.hypot(im);
        Some(Dynamics {
            frequency_hz: w / TAU,
            damping_ratio: -re / w,
        })
    }
}

/// The step of `integrator` over `dt_s`, and the sub-steps used (1 for the exact one);
/// `Err(substeps tried)` when an Euler integrator stays unstable at [`MAX_SUBSTEPS`].
pub(crate) fn step_for(
    d: &Dynamics,
    integrator: Integrator,
    dt_s: f64,
) -> std::result::Result<(Step, usize), usize> {
    let implicit = match integrator {
        Integrator::ExactZoh => return Ok((Step::exact(d, dt_s), 1)),
        Integrator::SemiImplicitEuler => true,
        Integrator::ExplicitEuler => false,
    };
    let mut n = 1;
    loop {
        let h = dt_s / n as f64;
        let sub = Step::euler(d, h, implicit);
        let good = sub.effective(h).is_some_and(|e| {
            (e.frequency_hz / d.frequency_hz - 1.0).abs() <= EULER_TOLERANCE
                && (d.damping_ratio == 0.0 && e.damping_ratio.abs() <= 1e-3
                    || (e.damping_ratio / d.damping_ratio - 1.0).abs() <= EULER_TOLERANCE)
        });
        if good || n >= MAX_SUBSTEPS {
            let stable = sub.effective(h).is_some_and(|e| e.damping_ratio >= 0.0);
            if !stable {
                return Err(n);
            }
            let mut total = sub;
            for _ in 1..n {
                total = total.compose(&sub);
            }
            return Ok((total, n));
        }
        n = (n * 2).min(MAX_SUBSTEPS);
    }
}

/// The free response of eq. (7) from (x0, v0): the exact transfer function's impulse form,
/// x(t) = e^{−ξωt} (x0 cos ω_d t + (v0 + ξω x0)/ω_d sin ω_d t).
pub fn free_response(d: &Dynamics, x0: f64, v0: f64, t_s: f64) -> f64 {
    let w = d.omega_rad_s();
    let z = d.damping_ratio;
    let wd = w * (1.0 - z * z).sqrt();
    let (s, c) = (wd * t_s).sin_cos();
    (-z * w * t_s).exp() * (x0 * c + (v0 + z * w * x0) / wd * s)
}

/// Steady-state amplitude of eq. (7) per unit forcing amplitude at `forcing_hz`:
/// |H(iΩ)| = 1 / |ω² − Ω² + 2iξωΩ|.
pub fn gain(d: &Dynamics, forcing_hz: f64) -> f64 {
    let w = d.omega_rad_s();
    let o = TAU * forcing_hz;
    1.0 / ((w * w - o * o).powi(2) + (2.0 * d.damping_ratio * w * o).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    const PAPER: Dynamics = PAPER_DYNAMICS;

    #[test]
    fn exact_step_samples_the_free_response() {
        for fps in [24.0, 30.0, 60.0, 7.0] {
            let dt = 1.0 / fps;
            let st = Step::exact(&PAPER, dt);
            let (mut x, mut v) = (0.1, 0.0);
            for k in 1..=200 {
                (x, v) = st.apply(x, v, 0.0);
                let t = k as f64 * dt;
                assert!(
                    (x - free_response(&PAPER, 0.1, 0.0, t)).abs() < 1e-12,
                    "{fps} {k}"
                );
            }
        }
    }

    #[test]
    fn exact_step_holds_a_constant_force_to_its_static_deflection() {
        let st = Step::exact(&PAPER, 1.0 / 30.0);
        let (mut x, mut v) = (0.0, 0.0);
        for _ in 0..3000 {
            (x, v) = st.apply(x, v, 2.0);
        }
        let w = PAPER.omega_rad_s();
        assert!((x - 2.0 / (w * w)).abs() < 1e-12 && v.abs() < 1e-12);
    }

    #[test]
    fn explicit_euler_alone_diverges_where_the_issue_says() {
        // 2ξ/ω = 0.01875 s: unstable at 30 fps, stable but under-damped at 60 fps.
        let e30 = Step::euler(&PAPER, 1.0 / 30.0, false)
            .effective(1.0 / 30.0)
            .unwrap();
        assert!(e30.damping_ratio < 0.0);
        let e60 = Step::euler(&PAPER, 1.0 / 60.0, false)
            .effective(1.0 / 60.0)
            .unwrap();
        assert!(e60.damping_ratio > 0.0 && e60.damping_ratio < PAPER.damping_ratio / 5.0);
        // Growth per second at 30 fps: |λ|^30 ≈ 1.8.
        let s = Step::euler(&PAPER, 1.0 / 30.0, false);
        let det = s.phi[0][0] * s.phi[1][1] - s.phi[0][1] * s.phi[1][0];
        let growth = det.sqrt().powi(30);
        assert!((growth - 1.8).abs() < 0.1, "{growth}");
    }

    #[test]
    fn substepped_eulers_reach_the_tolerance() {
        for integ in [Integrator::ExplicitEuler, Integrator::SemiImplicitEuler] {
            let (st, n) = step_for(&PAPER, integ, 1.0 / 30.0).unwrap();
            let e = st.effective(1.0 / 30.0).unwrap();
            assert!((e.damping_ratio / PAPER.damping_ratio - 1.0).abs() <= EULER_TOLERANCE);
            assert!((e.frequency_hz / PAPER.frequency_hz - 1.0).abs() <= EULER_TOLERANCE);
            assert!(n >= 1);
        }
        let undamped = Dynamics {
            frequency_hz: 1.0,
            damping_ratio: 0.0,
        };
        assert!(step_for(&undamped, Integrator::ExplicitEuler, 1.0 / 30.0).is_err());
    }

    #[test]
    fn validation_names_the_entry() {
        let bad = Dynamics {
            frequency_hz: 0.0,
            damping_ratio: 0.1,
        };
        assert!(matches!(
            bad.validate("x"),
            Err(AnimError::InvalidFrequency { .. })
        ));
        let bad = Dynamics {
            frequency_hz: 1.0,
            damping_ratio: 1.0,
        };
        assert!(matches!(
            bad.validate("x"),
            Err(AnimError::InvalidDamping { .. })
        ));
    }
}
