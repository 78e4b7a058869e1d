//! The whole SLAM pipeline on the simulated marina mission (seed 1, 40.6 min,
//! about 950 m, revisits in both directions): accuracy against ground
//! truth, loop-closure quality, and the structure of the result.
//!
//! The ATE is recomputed here from the node poses and the mission's ground
//! truth (interpolated by this test, aligned with `echofield::eval`'s SE(2)
//! fit), not read from the pipeline's report.

use echofield::eval::{Alignment, ate};
use echofield::matching::ground_truth_at;
use echofield::slam::{NoProgress, SlamConfig, SlamOutput, run_mission};
use echofield_datasets::sim::{Scenario, simulate_mission};
use echofield_frontend::GroundTruthPose;
use echofield_graph::io::TrajectoryPose;
use echofield_graph::{EdgeKind, Se2};
use echofield_tests::ground_truth_odometry_scale;

/// ATE RMSE of `pose(node)` against the ground truth, and the ground-truth
/// path length over the nodes' span.
fn ate_and_distance(
    output: &SlamOutput,
    truth: &[GroundTruthPose],
    pose: impl Fn(usize) -> Se2,
) -> (f64, f64) {
    let (mut estimate, mut reference) = (Vec::new(), Vec::new());
    for (i, node) in output.nodes.iter().enumerate() {
        if let Some(g) = ground_truth_at(truth, node.stamp_s) {
            estimate.push(TrajectoryPose {
                stamp_s: node.stamp_s,
                pose: pose(i),
            });
            reference.push(TrajectoryPose {
                stamp_s: node.stamp_s,
                pose: g,
            });
        }
    }
    let (t0, t1) = (reference[0].stamp_s, reference[reference.len() - 1].stamp_s);
    let path: Vec<&GroundTruthPose> = truth
        .iter()
        .filter(|g| g.stamp_s >= t0 && g.stamp_s <= t1)
        .collect();
    let distance: f64 = path
        .windows(2)
        .map(|w| {
            (w[1].world_from_vehicle.translation() - w[0].world_from_vehicle.translation()).norm()
        })
        .sum();
    let stats = ate(&estimate, &reference, Alignment::Se2, 1e-6).unwrap();
    (stats.rmse_m, distance)
}

#[test]
fn marina_mission_is_five_times_better_than_dead_reckoning() {
    let mission = simulate_mission(&Scenario::named("marina").unwrap(), 1).unwrap();
    let output = run_mission(&mission, &SlamConfig::default(), &NoProgress).unwrap();
    let truth = &mission.ground_truth;

    // Structure: every rotation is a node, the chain is complete.
    let report = &output.report;
    // The demo's mission judges its own result ok (`report.json` →
    // `health`; the suspect cases are in `slam_health`).
    assert_eq!(
        report.health.verdict,
        echofield::slam::health::Verdict::Ok,
        "{:#?}",
        report.health
    );
    assert_eq!(
        report.nodes, report.rotations,
        "{:?}",
        report.skipped_rotations
    );
    assert!(
        (170..=190).contains(&report.nodes),
        "{} nodes",
        report.nodes
    );
    let count = |kind| output.graph.edges().filter(|e| e.kind == kind).count();
    assert_eq!(count(EdgeKind::Odometry), report.nodes - 1);
    assert!(count(EdgeKind::Sequential) >= report.nodes * 9 / 10);
    assert_eq!(count(EdgeKind::Loop), report.loops_accepted);
    assert!(output.graph.is_connected());
    // The simulated gyro (0.2°/s noise) agrees with the compass as well as
    // configured: the yaw-rate check leaves the configured noise.
    let config = SlamConfig::default();
    let check = report.dead_reckoning.yaw_rate_check.unwrap();
    assert!(
        check.yaw_rate_noise_radps < config.dead_reckoning.yaw_rate_noise_radps,
        "{check:?}"
    );
    assert_eq!(
        report.dead_reckoning.yaw_rate_noise_radps,
        config.dead_reckoning.yaw_rate_noise_radps
    );
    // The simulated DVL reads 1.5% long: the odometry edges are about that
    // much longer than the true motion, and the optimised motion finds it
    // (measured 0.9858 against 0.9843 from the ground truth).
    let truths: Vec<Option<Se2>> = output
        .nodes
        .iter()
        .map(|n| ground_truth_at(truth, n.stamp_s))
        .collect();
    let true_scale = ground_truth_odometry_scale(&output.graph, &truths);
    assert!((0.975..0.99).contains(&true_scale), "{true_scale}");
    let scale = report.dead_reckoning.odometry_scale.unwrap();
    assert_eq!(scale.edges, report.nodes - 1);
    assert!(
        (scale.scale - true_scale).abs() < 0.005,
        "{scale:?} against {true_scale}"
    );
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains("DVL may read long"))
    );

    // Accuracy: at most 0.2% of the distance, and at least 5x better than
    // dead reckoning at the same stamps.
    let (slam, distance) = ate_and_distance(&output, truth, |i| output.nodes[i].optimised);
    let (dead_reckoning, _) = ate_and_distance(&output, truth, |i| output.nodes[i].dead_reckoning);
    assert!(distance > 900.0, "{distance} m");
    assert!(
        slam <= 0.002 * distance,
        "ATE {slam:.3} m over {distance:.0} m"
    );
    assert!(
        5.0 * slam <= dead_reckoning,
        "ATE {slam:.3} m, dead reckoning {dead_reckoning:.3} m"
    );
    // The report agrees with the recomputation.
    assert!((report.ate_rmse_m.unwrap() - slam).abs() < 1e-6);

    // Loops: many, nearly all within the true-positive tolerances (0.5 m,
    // 3 deg), at most one in a hundred more than 1 m off and none more than
    // 1.5 m. Measured on seed 1: ATE 0.229 m (dead reckoning 2.816 m,
    // 12.3x; 0.295 m before the matcher's pose fit read its own raster,
    // `image.pose_fit`, 0.488 m before the off-axis suppression and the
    // derived heading priors), precision 0.997 (two loops 0.50 and 0.73 m
    // off, both densified between nodes 42-43 and 66-67; 0.991 before the
    // pose fit), recall 0.787 of the overlapping node pairs (0.741 before
    // densification retried the pairs the mission rejected for their window
    // or covariance) and 0.968 of the revisits. 246 of the 752 loops are
    // partial (`densify_partial`): they see one quay along its length, and
    // all are right across the quay (within 0.5 m) and in heading; without
    // them recall was 0.512 (with `reverse_max_translation_m` 0.5).
    assert!(
        report.loops_accepted >= 150,
        "{} loops",
        report.loops_accepted
    );
    let (mut wrong, mut gross) = (0, 0);
    let (mut partial, mut partial_right) = (0, 0);
    for l in output.loops.iter().filter(|l| l.accepted) {
        let (a, b) = (
            output.nodes[l.from as usize].stamp_s,
            output.nodes[l.to as usize].stamp_s,
        );
        let truth_rel = ground_truth_at(truth, a)
            .unwrap()
            .between(&ground_truth_at(truth, b).unwrap());
        let measurement = l.measurement.unwrap();
        let error = truth_rel.between(&measurement);
        let (dt, dr) = (error.translation().norm(), error.theta().abs().to_degrees());
        assert!(
            dt < 1.5 && dr < 3.0,
            "loop {} -> {}: {dt:.2} m, {dr:.2} deg",
            l.from,
            l.to
        );
        wrong += usize::from(dt > 0.5);
        gross += usize::from(dt > 1.0);
        if let Some([ux, uy]) = l.unconstrained_direction {
            // A partial loop: the components it constrains are right.
            partial += 1;
            assert!(l.densified);
            let across = (measurement.translation() - truth_rel.translation())
                .dot(&nalgebra::Vector2::new(-uy, ux));
            assert!(
                across.abs() < 1.0,
                "partial loop {} -> {}: {across:.2} m across",
                l.from,
                l.to
            );
            partial_right += usize::from(across.abs() <= 0.5 && dr <= 3.0);
        }
    }
    let counts = report.loop_evaluation.as_ref().unwrap();
    assert!(partial >= 100, "{partial} partial loops");
    assert_eq!(counts.partial_loops, partial);
    assert_eq!(counts.partial_constrained_correct, partial_right);
    // Seeds 1-6: 1 201 of 1 203 partial loops right across the quay.
    assert!(
        partial_right as f64 >= 0.97 * partial as f64,
        "{partial_right} of {partial} partial loops right"
    );
    assert!(
        100 * gross <= report.loops_accepted,
        "{gross} loops more than 1 m off"
    );
    let precision = 1.0 - wrong as f64 / report.loops_accepted as f64;
    assert!(precision >= 0.98, "precision {precision:.3}");
    assert!((report.loop_precision.unwrap() - precision).abs() < 1e-9);
    let revisits = report.loop_recall_revisits.unwrap();
    assert!(revisits >= 0.88, "revisit recall {revisits:.3}");
    let recall = report.loop_recall.unwrap();
    // Measured 0.787; 0.741 before densification retried the pairs the
    // mission rejected for their window or covariance, which this bound
    // guards (issue 5 asks for 0.9; seeds 1-10 measure 0.735-0.787).
    assert!(recall >= 0.76 && recall < revisits, "recall {recall:.3}");
    assert!(
        counts.recall_pairs > 800,
        "{} recall pairs",
        counts.recall_pairs
    );
    let ratio = counts.recalled_pairs as f64 / counts.recall_pairs as f64;
    assert!((ratio - recall).abs() < 1e-12);
    // The bins by overlap split the same pairs; the pairs that share the
    // most are recalled the most (measured: 0.46 of the 176 pairs of
    // overlap 0.4-0.5, 0.93-1.0 from 0.7 up).
    let bins = &counts.recall_by_overlap;
    assert_eq!(
        bins.iter().map(|b| b.pairs).sum::<usize>(),
        counts.recall_pairs
    );
    assert_eq!(
        bins.iter().map(|b| b.recalled).sum::<usize>(),
        counts.recalled_pairs
    );
    let rate = |b: &echofield::slam::RecallBin| b.recalled as f64 / b.pairs as f64;
    let (first, last) = (&bins[0], &bins[bins.len() - 1]);
    assert!(first.pairs > 0 && last.pairs > 0, "{bins:?}");
    assert!(rate(last) > rate(first), "{bins:?}");

    // The recall budget splits the same pairs once each. Seed 1: 698
    // recalled, 119 matched right but rejected (quality 59, covariance 41,
    // reverse mismatch 19), 43 matched only wrong, 27 never matched: checks
    // that accepted every right match would reach 0.921.
    let budget = &counts.recall_budget;
    assert_eq!(budget.recalled, counts.recalled_pairs);
    assert_eq!(
        budget.recalled + budget.right_match_rejected + budget.matched_wrong + budget.not_matched,
        counts.recall_pairs
    );
    assert!(budget.right_match_rejected_by.values().sum::<usize>() <= budget.right_match_rejected);
    // Recounted from the candidates and the ground truth: the recall pairs
    // with a right match and none accepted right.
    let min_overlap = config.evaluation.recall_min_overlap;
    let mut right_pairs = std::collections::BTreeMap::new();
    for l in &output.loops {
        let (Some(overlap), Some(measurement)) = (l.gt_overlap, l.measurement) else {
            continue;
        };
        if overlap < min_overlap {
            continue;
        }
        let (a, b) = (
            output.nodes[l.from as usize].stamp_s,
            output.nodes[l.to as usize].stamp_s,
        );
        let error = ground_truth_at(truth, a)
            .unwrap()
            .between(&ground_truth_at(truth, b).unwrap())
            .between(&measurement);
        if error.translation().norm() <= config.evaluation.true_positive_translation_m
            && error.theta().abs().to_degrees() <= config.evaluation.true_positive_rotation_deg
        {
            *right_pairs.entry((l.from, l.to)).or_insert(false) |= l.accepted;
        }
    }
    let rejected_right = right_pairs.values().filter(|&&accepted| !accepted).count();
    assert_eq!(budget.right_match_rejected, rejected_right);
    let ceiling = budget.gate_ceiling.unwrap();
    assert!(
        (ceiling - (budget.recalled + rejected_right) as f64 / counts.recall_pairs as f64).abs()
            < 1e-12
    );
    assert!(
        ceiling > recall && ceiling >= 0.88,
        "gate ceiling {ceiling:.3}"
    );
}

/// `[rotation] node_spacing_m` (keyframe selection) on the marina, with a
/// spacing a little above the vehicle's travel per rotation: it drops at
/// least a tenth and at most half of the rotations, each node is as far
/// from the last as the rule asks (or the rule's cap forced it), and the
/// thinned run keeps the accuracy bounds of the full one (ATE at most 0.2%
/// of the distance and a fifth of the dead reckoning's).
#[test]
fn a_node_spacing_thins_the_rotations_and_keeps_the_accuracy() {
    use echofield_frontend::nodes::spacing::MAX_THINNED_IN_A_ROW;
    let mission = simulate_mission(&Scenario::named("marina").unwrap(), 1).unwrap();
    let mut config = SlamConfig::default();
    let spacing_m = 6.0;
    config.rotation.node_spacing_m = spacing_m;
    let output = run_mission(&mission, &config, &NoProgress).unwrap();
    let report = &output.report;
    assert_eq!(
        report.nodes + report.skipped_rotations.len() + report.thinned_rotations,
        report.rotations
    );
    assert!(
        report.thinned_rotations >= report.rotations / 10 && report.nodes >= report.rotations / 2,
        "{} of {} rotations thinned",
        report.thinned_rotations,
        report.rotations
    );
    let reach_m = mission
        .beams
        .iter()
        .map(|b| b.max_range_m())
        .fold(0.0, f64::max);
    for w in output.nodes.windows(2) {
        let moved = w[0].dead_reckoning.between(&w[1].dead_reckoning);
        let scene_m = moved.translation().norm() + 0.5 * reach_m * moved.theta().abs();
        let forced = w[1].rotation_index - w[0].rotation_index == MAX_THINNED_IN_A_ROW + 1;
        assert!(
            scene_m >= spacing_m - 1e-6 || forced,
            "rotations {} and {}: {scene_m:.2} m apart",
            w[0].rotation_index,
            w[1].rotation_index
        );
        assert!(w[1].rotation_index - w[0].rotation_index <= MAX_THINNED_IN_A_ROW + 1);
    }
    let truth = &mission.ground_truth;
    let (slam, distance) = ate_and_distance(&output, truth, |i| output.nodes[i].optimised);
    let (dead_reckoning, _) = ate_and_distance(&output, truth, |i| output.nodes[i].dead_reckoning);
    assert!(
        slam <= 0.002 * distance && 5.0 * slam <= dead_reckoning,
        "ATE {slam:.3} m over {distance:.0} m, dead reckoning {dead_reckoning:.3} m"
    );
}
