//! The matcher against ground truth beside point-to-point ICP (the
//! evaluation `echofield bench-matcher` prints, on a small scale), with
//! scans and images motion-compensated by dead reckoning as the pipeline
//! builds them, initial errors up to 5 m and 20°; success is a final error
//! < 0.3 m and < 2°.
//!
//! - Simulated tank, all 45 overlapping pairs: at least 98% success
//!   (100% measured) and more often than ICP (89.6%).
//! - Simulated marina (quays: many pairs see walls of one direction only,
//!   along which eq. (5) is nearly flat), 40 pairs: at least 85% success on
//!   the pairs whose overlap is constrained in every direction (90%
//!   measured), at least 80% overall (87.5%) and at least twice ICP's
//!   rate (29%).

use echofield::matching::evaluation::{Evaluation, EvaluationConfig, Method, Trial, evaluate};
use echofield::matching::{MatchingConfig, MissionRotations};
use echofield_datasets::sim::{Scenario, simulate_mission};

fn evaluation(scenario: &str, pairs: usize, trials: usize, seed: u64) -> Evaluation {
    let mission = simulate_mission(&Scenario::named(scenario).unwrap(), 1).unwrap();
    let config = MatchingConfig::default();
    let rotations = MissionRotations::new(mission, &config).unwrap();
    let eval = EvaluationConfig {
        trials_per_pair: trials,
        max_pairs_per_kind: pairs,
        seed,
        ..EvaluationConfig::default()
    };
    let result = evaluate(&rotations, &config, &eval).unwrap();
    // Every trial drew its initial error within the bounds.
    assert!(
        result
            .trials
            .iter()
            .all(|t| t.initial_error_m <= 5.0 && t.initial_error_rad <= 20.0_f64.to_radians())
    );
    result
}

#[test]
fn matcher_beats_icp_on_the_simulated_tank() {
    // Every overlapping pair of the tank (45).
    let result = evaluation("tank", 60, 3, 5);
    let matcher = result.success_rate(Method::AcousticImage);
    let icp = result.success_rate(Method::Icp);
    let table = result.table();
    assert!(result.trials.len() >= 2 * 3 * 40, "{table}");
    assert!(matcher >= 0.98, "matcher {matcher:.3}\n{table}");
    assert!(matcher > icp, "matcher {matcher:.3}, ICP {icp:.3}\n{table}");
}

#[test]
fn matcher_beats_icp_on_the_simulated_marina() {
    let result = evaluation("marina", 20, 2, 3);
    let table = result.table();
    let min_constraint = result.config.min_constraint;
    let constrained = |t: &Trial| t.constraint >= min_constraint;
    let n_constrained = result
        .trials
        .iter()
        .filter(|t| t.method == Method::AcousticImage && constrained(t))
        .count();
    assert!(
        n_constrained >= 15,
        "{n_constrained} constrained trials\n{table}"
    );
    let on_constrained = result.success_rate_where(Method::AcousticImage, constrained);
    assert!(
        on_constrained >= 0.85,
        "constrained {on_constrained:.3}\n{table}"
    );
    let matcher = result.success_rate(Method::AcousticImage);
    let icp = result.success_rate(Method::Icp);
    assert!(matcher >= 0.8, "matcher {matcher:.3}\n{table}");
    assert!(
        matcher >= 2.0 * icp,
        "matcher {matcher:.3}, ICP {icp:.3}\n{table}"
    );
}
