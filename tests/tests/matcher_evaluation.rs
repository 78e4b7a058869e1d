//! The matcher against ground truth beside point-to-point ICP (the
//! evaluation `echofield bench-matcher` prints, on a small scale): on the
//! simulated tank with exact motion compensation, initial errors up to 5 m
//! and 20°, success (final error < 0.3 m and < 2°) for at least 95% of the
//! trials and more often than ICP.

use echofield::matching::evaluation::{EvaluationConfig, Method, evaluate};
use echofield::matching::{MatchingConfig, MissionRotations};
use echofield_datasets::sim::{Scenario, simulate_mission};

#[test]
fn matcher_beats_icp_on_the_simulated_tank() {
    let mission = simulate_mission(&Scenario::named("tank").unwrap(), 1).unwrap();
    let config = MatchingConfig::default();
    let mut rotations = MissionRotations::new(mission, &config).unwrap();
    rotations.use_ground_truth_navigation().unwrap();
    let eval = EvaluationConfig {
        trials_per_pair: 3,
        max_pairs_per_kind: 12,
        seed: 5,
        ..EvaluationConfig::default()
    };
    let result = evaluate(&rotations, &config, &eval).unwrap();
    let matcher = result.success_rate(Method::AcousticImage);
    let icp = result.success_rate(Method::Icp);
    let table = result.table();
    assert!(result.trials.len() >= 2 * 3 * 12, "{table}");
    assert!(matcher >= 0.95, "matcher {matcher:.3}\n{table}");
    assert!(matcher > icp, "matcher {matcher:.3}, ICP {icp:.3}\n{table}");
    // Every trial drew its initial error within the bounds.
    assert!(
        result
            .trials
            .iter()
            .all(|t| t.initial_error_m <= 5.0 && t.initial_error_rad <= 20.0_f64.to_radians())
    );
}
