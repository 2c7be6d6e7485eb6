//! The release test: pull a branch, let go in still air, compare with eq. (7).

use beam_anim::{
    AnimConfig, BeamTree, Dynamics, Integrator, PAPER_DYNAMICS, Simulation, free_response,
};
use space_colonize::Skeleton;
use space_colonize::synthetic::SyntheticConfig;

pub fn skeleton() -> Skeleton {
    SyntheticConfig {
        points: 2_000,
        ..Default::default()
    }
    .generate()
    .unwrap()
    .skeleton
}

fn release(integrator: Integrator, fps: f64, frames: usize) -> (Vec<f64>, f64, Dynamics) {
    let sk = skeleton();
    let config = AnimConfig {
        integrator,
        ..AnimConfig::default()
    };
    let tree = BeamTree::new(&sk, &config).unwrap();
    let d = Dynamics {
        frequency_hz: 1.46,
        damping_ratio: 0.086,
    };
    let mut dynamics = vec![PAPER_DYNAMICS; tree.branches().len()];
    let target = tree.branches().len() / 2;
    dynamics[target] = d;
    let id = tree.branches()[target].id;
    let mut sim = Simulation::new(tree, &dynamics, config, 1.0 / fps).unwrap();
    let a0 = 10f64.to_radians();
    sim.pull(id, a0).unwrap();
    assert!((sim.pose().angle_rad[target] - a0).abs() < 1e-12);
    let mut series = Vec::with_capacity(frames);
    for _ in 0..frames {
        sim.step_free();
        series.push(sim.pose().angle_rad[target]);
    }
    (series, a0, d)
}

#[test]
fn exact_release_follows_the_transfer_function_at_display_rates() {
    for fps in [24.0, 30.0, 60.0] {
        let (series, a0, d) = release(Integrator::ExactZoh, fps, (10.0 * fps) as usize);
        for (k, a) in series.iter().enumerate() {
            let t = (k + 1) as f64 / fps;
            let want = free_response(&d, a0, 0.0, t);
            assert!(
                (a - want).abs() < 1e-9,
                "{fps} fps, frame {k}: {a} vs {want}"
            );
        }
    }
}

#[test]
fn euler_release_is_stable_and_close() {
    for integ in [Integrator::ExplicitEuler, Integrator::SemiImplicitEuler] {
        let (series, a0, _) = release(integ, 30.0, 300);
        assert!(
            series.iter().all(|a| a.is_finite() && a.abs() <= 1.2 * a0),
            "{integ:?}"
        );
        // Decayed by e^{−ξω·10 s} ≈ 4e-4 of the pull, give or take the tolerance.
        let tail = series[270..].iter().fold(0.0_f64, |m, a| m.max(a.abs()));
        assert!(tail < 0.01 * a0, "{integ:?} {tail}");
    }
}
