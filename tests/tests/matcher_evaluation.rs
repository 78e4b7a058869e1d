//! The matcher against ground truth beside point-to-point ICP (the
//! evaluation `echofield bench-matcher` prints, on a small scale), with
//! scans and images motion-compensated by dead reckoning as the pipeline
//! builds them, initial errors up to 5 m and 20°; success is a final error
//! < 0.3 m and < 2°.
//!
//! - Simulated tank, all 45 overlapping pairs: at least 95% success
//!   (95.6% measured) and more often than ICP (91.1%).
//! - Simulated canyon (rock walls on both sides), 20 pairs of each kind:
//!   at least 95% success and more often than ICP.
//! - Simulated marina (quays: many pairs see walls of one direction only,
//!   along which eq. (5) is nearly flat), 40 pairs: at least 85% success on
//!   the pairs whose overlap is constrained in every direction (90%
//!   measured), at least 80% overall (87.5%) and at least twice ICP's
//!   rate (29%).

use echofield::matching::MissionRotations;
use echofield::matching::evaluation::{Evaluation, Method, Trial, TrialConfig, evaluate};
use echofield::slam::SlamConfig;
use echofield_datasets::sim::{Scenario, simulate_mission};

fn evaluation(scenario: &str, pairs: usize, trials: usize, seed: u64) -> Evaluation {
    let mission = simulate_mission(&Scenario::named(scenario).unwrap(), 1).unwrap();
    let config = SlamConfig::default();
    let rotations = MissionRotations::new(mission, &config).unwrap();
    let eval = TrialConfig {
        trials_per_pair: trials,
        max_pairs_per_kind: pairs,
        seed,
        ..TrialConfig::default()
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
    // Measured 0.956 (ICP 0.911): the target is 0.95. It was 0.993
    // before the images dropped their off-axis echoes (`image.off_axis`);
    // the six non-consecutive failures since then are ambiguities of the
    // score (the estimate scores higher than the truth), four of them on
    // one pair. The suppression is kept for what it does to the bias of
    // the matches and to the trajectories (see `echofield_frontend::off_axis`).
    assert!(matcher >= 0.95, "matcher {matcher:.3}\n{table}");
    assert!(matcher > icp, "matcher {matcher:.3}, ICP {icp:.3}\n{table}");
}

#[test]
fn matcher_beats_icp_on_the_simulated_canyon() {
    let result = evaluation("canyon", 20, 2, 7);
    let matcher = result.success_rate(Method::AcousticImage);
    let icp = result.success_rate(Method::Icp);
    let table = result.table();
    assert!(result.trials.len() >= 2 * 2 * 2 * 20, "{table}");
    // `echofield bench-matcher --scenario canyon` (60 pairs of each kind,
    // 5 trials) measures 100% on both kinds, ICP 82.7% and 74.3%.
    assert!(matcher >= 0.95, "matcher {matcher:.3}\n{table}");
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

#[test]
fn rotations_before_the_navigation_starts_are_not_drawn() {
    // As on the St Pere logs, whose beams start ~183 s before the first
    // DVL sample: the tank mission's DVL and heading start 30 s late, so
    // dead reckoning does not cover its first rotations (which the ground
    // truth, used to choose the pairs, does).
    let mut mission = simulate_mission(&Scenario::named("tank").unwrap(), 1).unwrap();
    let start_s = mission.beams[0].stamp_s + 30.0;
    mission.dvl.retain(|d| d.stamp_s >= start_s);
    mission.attitude.retain(|a| a.stamp_s >= start_s);
    let config = SlamConfig::default();
    let rotations = MissionRotations::new(mission, &config).unwrap();
    let uncovered: Vec<usize> = (0..rotations.rotations.len())
        .filter(|&k| rotations.scan(k, &config).is_err())
        .collect();
    assert!(
        uncovered.len() >= 2 && uncovered.iter().enumerate().all(|(i, &k)| i == k),
        "uncovered rotations {uncovered:?}"
    );
    let last = rotations.rotations.len() - 1;
    assert_eq!(rotations.covered_rotations(), Some((uncovered.len(), last)));
    // The error says which rotations can be used.
    let message = format!("{:#}", rotations.scan(0, &config).unwrap_err());
    let covered = format!("the navigation covers rotations {}-{last}", uncovered.len());
    assert!(message.contains(&covered), "{message}");
    let eval = TrialConfig {
        trials_per_pair: 1,
        max_pairs_per_kind: 60,
        ..TrialConfig::default()
    };
    let result = evaluate(&rotations, &config, &eval).unwrap();
    let table = result.table();
    assert_eq!(result.rotations_without_scan, uncovered.len(), "{table}");
    // Every overlapping pair of covered rotations is drawn (fewer than 60
    // of each kind) and matched; none involves an uncovered rotation.
    assert!(!result.chosen_pairs.is_empty());
    assert!(
        result
            .chosen_pairs
            .iter()
            .all(|p| !uncovered.contains(&p.scan) && !uncovered.contains(&p.image))
    );
    assert_eq!(
        result.trials.len(),
        2 * result.chosen_pairs.len(),
        "{table}"
    );
    let drawn: usize = result.pairs.values().sum();
    let overlapping: usize = result.overlapping_pairs.values().sum();
    assert_eq!(drawn, overlapping, "{table}");
}

#[test]
fn the_slam_trajectory_compensates_the_motion_better_than_dead_reckoning() {
    // The pipeline's refining second pass in the evaluation: the motion
    // over each rotation, from its first beam to its last, comes closer to
    // the ground truth's (median error 0.22 -> 0.16 m measured on this
    // tank; 0.49 -> 0.19 m on the St Pere replay with `echofield
    // bench-dead-reckoning --slam`), and the matcher still succeeds.
    use echofield::matching::navigation_eval::{distortion, ground_truth_navigation};
    let mission = simulate_mission(&Scenario::named("tank").unwrap(), 1).unwrap();
    let config = SlamConfig::default();
    let mut rotations = MissionRotations::new(mission, &config).unwrap();
    let truth = ground_truth_navigation(&rotations.mission).unwrap();
    let of =
        |r: &MissionRotations| distortion(&r.mission, &r.rotations, &r.navigation, &truth).unwrap();
    let before = of(&rotations);
    let report = rotations.use_slam_navigation(&config).unwrap();
    assert!(report.ate_rmse_m.unwrap() < 0.3);
    let after = of(&rotations);
    assert_eq!(before.rotations, after.rotations);
    assert!(
        after.rotation_motion_m.median < 0.85 * before.rotation_motion_m.median,
        "{before:?}\n{after:?}"
    );
    assert!(
        after.point_5m_m.median < before.point_5m_m.median,
        "{before:?}\n{after:?}"
    );
    let eval = TrialConfig {
        trials_per_pair: 2,
        ..TrialConfig::default()
    };
    let result = evaluate(&rotations, &config, &eval).unwrap();
    assert!(
        result.success_rate(Method::AcousticImage) >= 0.98,
        "{}",
        result.table()
    );
}
