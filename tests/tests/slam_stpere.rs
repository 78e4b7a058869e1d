//! The SLAM pipeline on the St Pere replay: the real DVL and MTi navigation
//! of the Ictineu AUV with simulated beams at the real beam times, against
//! the DGPS track.

use echofield::slam::{NoProgress, SlamConfig, run_mission};
use echofield_datasets::sim::{Mission, Scenario, simulate_mission};
use echofield_frontend::loops::config::DENSIFY_MIN_PREDICTED_OVERLAP;
use echofield_tests::ground_truth_odometry_scale;
use std::sync::OnceLock;

/// The St Pere replay with seed 1, simulated once for all the tests here.
fn st_pere_mission() -> &'static Mission {
    static MISSION: OnceLock<Mission> = OnceLock::new();
    MISSION.get_or_init(|| simulate_mission(&Scenario::named("stpere").unwrap(), 1).unwrap())
}

#[test]
fn st_pere_replay_is_within_a_metre_of_dgps() {
    let mission = st_pere_mission();
    let output = run_mission(mission, &SlamConfig::default(), &NoProgress).unwrap();
    let report = &output.report;
    // The beams of the first ~183 s precede the navigation: those
    // rotations are skipped and reported, the rest are nodes.
    assert!(report.rotations >= 225, "{} rotations", report.rotations);
    let skipped = &report.skipped_rotations;
    assert!((10..=16).contains(&skipped.len()), "{skipped:?}");
    // The navigation starts once both a valid DVL sample and a heading
    // exist; a rotation is skipped when it ends after that.
    let first_dvl = mission.dvl.iter().find(|d| d.valid).unwrap().stamp_s;
    let navigation_start_s = first_dvl.max(mission.attitude[0].stamp_s);
    assert!(
        skipped.iter().all(|s| s.start_s < navigation_start_s),
        "{skipped:?}"
    );
    // The default node spacing drops the odd rotation where the vehicle
    // hardly moved or turned.
    assert_eq!(
        report.nodes + skipped.len() + report.thinned_rotations,
        report.rotations
    );
    assert!(report.thinned_rotations <= report.rotations / 20);
    assert!(report.warnings.iter().any(|w| w.contains("skipped")));
    // The MTi's yaw rate reads 6% more than its heading changes and
    // 0.66°/s off: the yaw-rate check measures 0.040 rad/s where 0.01 is
    // configured, the filter uses that, and the run says so.
    let configured = SlamConfig::default().dead_reckoning.yaw_rate_noise_radps;
    let used = report.dead_reckoning.yaw_rate_noise_radps;
    assert!(used > 3.0 * configured, "{:?}", report.dead_reckoning);
    assert_eq!(
        Some(used),
        report
            .dead_reckoning
            .yaw_rate_check
            .map(|c| c.yaw_rate_noise_radps)
    );
    assert!(report.warnings.iter().any(|w| w.contains("yaw rates")));
    // The real DVL's distances are about 3% longer than the DGPS ones, and
    // the optimised motion finds that (measured 0.9722 against 0.9701 from
    // the DGPS track at the nodes).
    let truths: Vec<_> = output.nodes.iter().map(|n| n.ground_truth).collect();
    let true_scale = ground_truth_odometry_scale(&output.graph, &truths);
    assert!((0.96..0.98).contains(&true_scale), "{true_scale}");
    let scale = report.dead_reckoning.odometry_scale.unwrap();
    assert!(
        (scale.scale - true_scale).abs() < 0.005,
        "{scale:?} against {true_scale}"
    );

    let ate = report.ate.as_ref().unwrap();
    let dead_reckoning = report.ate_dead_reckoning.as_ref().unwrap();
    assert_eq!(ate.pairs, report.nodes);
    assert!(ate.rmse_m <= 1.0, "ATE {:.3} m against DGPS", ate.rmse_m);
    // Measured: 0.202 m against 3.09 m for dead reckoning (0.208 m before
    // the yaw-rate check raised the MTi's yaw-rate noise; 0.171 m with
    // densification down to a predicted overlap of 0.5 instead of 0.4,
    // 0.197 m before the off-axis suppression and the derived heading
    // priors, 0.203 m with the midpoint fusion of sequential matches).
    // With the densified loops taken as independent
    // (`densify_correlation = 0`) it was 0.246 m. Small changes move this
    // seed's ATE by a few centimetres (seeds 1-6: 0.179-0.209 m, 0.168-0.208
    // m before the yaw-rate check, 0.178-0.208 m before the matcher's pose
    // fit read its own raster), hence the margin.
    assert!(ate.rmse_m <= 0.25, "ATE {:.3} m against DGPS", ate.rmse_m);
    assert!(
        ate.rmse_m < 0.2 * dead_reckoning.rmse_m,
        "{:.3} vs {:.3}",
        ate.rmse_m,
        dead_reckoning.rmse_m
    );
    assert!(
        report.loops_accepted >= 1000,
        "{} loops",
        report.loops_accepted
    );
    // Loops: measured precision 0.993 (seeds 1-6: 0.988-0.993; 16 near
    // misses, 0.50-0.68 m off against the 0.5 m tolerance). Before the
    // yaw-rate check it was 0.981 (0.979-0.984): the MTi's biased,
    // mis-scaled yaw rate dragged the dead-reckoning heading up to 2° from
    // the headings at the end of fast turns, and every loop of such a
    // rotation (nodes 26 and 51) came out 0.5-1.2 m or 2-3.6° off.
    // Recall 0.921 of the overlapping node pairs (0.929 before the check;
    // 0.911 without the densification's retries of pairs the
    // mission rejected for their window or covariance, 0.896 with
    // `densify_min_predicted_overlap` 0.5 instead of 0.4, 0.836 without
    // partial loops) and 0.987 of the revisits.
    let precision = report.loop_precision.unwrap();
    assert!(precision >= 0.985, "precision {precision:.3}");
    let revisits = report.loop_recall_revisits.unwrap();
    assert!(revisits >= 0.85, "revisit recall {revisits:.3}");
    let recall = report.loop_recall.unwrap();
    // Issue 5 asks for 0.9 (seeds 1-6 measure 0.921-0.933).
    assert!(recall >= 0.9 && recall < revisits, "recall {recall:.3}");
    // Partial loops: 186 measured (188 before the yaw-rate check), all
    // right across their one wall and in heading (509 of 509 on seeds 1-3
    // with densification down to 0.5); by the whole-pose verdict 3 were
    // false (13 before the check), the estimate being off along the wall.
    let counts = report.loop_evaluation.as_ref().unwrap();
    assert!(counts.partial_loops >= 50, "{counts:?}");
    assert!(
        counts.partial_constrained_correct as f64 >= 0.97 * counts.partial_loops as f64,
        "{counts:?}"
    );
    assert!(
        output
            .loops
            .iter()
            .all(|l| l.unconstrained_direction.is_none() || l.densified)
    );

    // Densification (`loops.densify`, on by default): after the mission
    // every overlapping pair whose relative pose the estimate knows is
    // matched by a local climb.
    let dense: Vec<_> = output.loops.iter().filter(|l| l.densified).collect();
    assert_eq!(dense.len(), report.loop_densified_candidates);
    assert!(
        report.loops_densified >= 1000,
        "{} densified loops",
        report.loops_densified
    );
    // Densified pairs come after the mission and keep the minimum
    // separation; a pair the mission examined comes back only when the
    // mission rejected it for how it was searched (window, covariance).
    let config = SlamConfig::default();
    let last = (report.nodes - 1) as u64;
    let mut pairs = std::collections::HashMap::new();
    let mut retried = 0;
    for l in &output.loops {
        if let Some(earlier) = pairs.insert((l.from, l.to), l) {
            assert!(
                l.densified
                    && !earlier.densified
                    && earlier
                        .rejected_by
                        .is_some_and(|r| r.densification_retries()),
                "{} -> {} twice",
                l.from,
                l.to
            );
            retried += 1;
        }
        if l.densified {
            assert_eq!(l.examined_at, last);
            assert!(l.predicted_overlap >= DENSIFY_MIN_PREDICTED_OVERLAP);
            assert!(l.to - l.from >= config.loops.min_separation_nodes as u64);
        }
    }
    assert!(retried > 0);
    // Densification reaches below the mission's own overlap gate.
    assert!(
        dense
            .iter()
            .any(|l| l.accepted && l.predicted_overlap < config.loops.min_predicted_overlap)
    );
    let accepted_edges = output
        .graph
        .edges()
        .filter(|e| e.kind == echofield_graph::EdgeKind::Loop)
        .count();
    assert_eq!(accepted_edges, report.loops_accepted);
}

/// Without densification each node is matched against at most
/// `max_candidates_per_node` older ones while the mission runs. Measured
/// on seed 1: recall over node pairs 0.195 (0.911 with it), precision
/// 0.987 (0.983), ATE 0.168 m (0.208 m).
#[test]
fn without_densification_recall_stays_at_the_candidates_per_node() {
    let mission = st_pere_mission();
    let mut config = SlamConfig::default();
    config.loops.densify = false;
    let output = run_mission(mission, &config, &NoProgress).unwrap();
    let report = &output.report;
    let ate = report.ate.as_ref().unwrap();
    assert!(ate.rmse_m <= 0.22, "ATE {:.3} m against DGPS", ate.rmse_m);
    assert_eq!(report.loop_densified_candidates, 0);
    assert_eq!(report.loops_densified, 0);
    assert!(output.loops.iter().all(|l| !l.densified));
    assert!(
        report.loops_accepted >= 200,
        "{} loops",
        report.loops_accepted
    );
    let precision = report.loop_precision.unwrap();
    assert!(precision >= 0.97, "precision {precision:.3}");
    let recall = report.loop_recall.unwrap();
    assert!((0.15..0.3).contains(&recall), "recall {recall:.3}");
}
