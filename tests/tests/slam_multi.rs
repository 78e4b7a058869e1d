//! Several missions, one map (issue 38, item 3): missions run on their
//! own, placed on one another's map from their scans alone, merged into
//! one graph.
//!
//! - Two simulated marina missions with different routes and starts (seed
//!   1's route from the southern basin; a second route from the northern
//!   basin, south along the east side and round the mole) merge, and the
//!   merged nodes of both, fitted once onto the common ground truth, are
//!   within the 0.3 m.
//! - A canyon mission is not merged with the marina: no placement, an
//!   honest report, each mission's own result written.
//! - The real St Pere halves (rotations 1-60 and 61-115, cut in time, so
//!   that the second half's dead reckoning starts from nothing at its
//!   first record) merge; their merged ATE against DGPS is printed.
//!
//! The errors are recomputed here from the poses and the missions' own
//! ground truth, not read from the report.

use echofield::calibration::{CalibrateSettings, calibrate_mission};
use echofield::eval::{align_se2, aligned_position_rmse};
use echofield::slam::multi::{MultiOutput, combine, outputs::write_files};
use echofield::slam::{NoProgress, SlamConfig, SlamOutput, run_mission};
use echofield_datasets::sim::scenes::marina;
use echofield_datasets::sim::{Scenario, SimConfig, follow_route, simulate_mission};
use echofield_frontend::sensors::{Mission, SweepTiming};
use echofield_graph::Se2;
use echofield_tests::{split_mission_at, stpere_point_set_mission};
use std::sync::OnceLock;

/// The run of marina seed 1 (the first mission, the map frame).
fn marina_seed_1() -> &'static SlamOutput {
    static RUN: OnceLock<SlamOutput> = OnceLock::new();
    RUN.get_or_init(|| {
        let mission = simulate_mission(&Scenario::named("marina").unwrap(), 1).unwrap();
        run_mission(&mission, &SlamConfig::default(), &NoProgress).unwrap()
    })
}

/// The marina surveyed along another route (about 400 m): from the
/// northern basin's west side east along it, south along the east side,
/// round the mole counter-clockwise; seed 2's sensor noise.
fn marina_other_route() -> Mission {
    let scene = marina().unwrap();
    let route = [
        [40.0, 222.0],
        [84.0, 222.0],
        [84.0, 200.0],
        [84.0, 140.0],
        [92.0, 120.0],
        [88.0, 90.0],
        [26.0, 90.0],
        [26.0, 14.0],
        [88.0, 14.0],
        [88.0, 40.0],
    ];
    let config = SimConfig::default();
    let truth = follow_route(&route, &config.vehicle, config.start_stamp_s).unwrap();
    let scenario = Scenario::custom("marina-north", scene.environment, truth, config).unwrap();
    simulate_mission(&scenario, 2).unwrap()
}

/// Every mission's merged poses with ground truth, and the truth.
fn merged_with_truth(out: &MultiOutput, missions: &[usize]) -> (Vec<Se2>, Vec<Se2>) {
    let mut pairs = Vec::new();
    for &m in missions {
        let poses = out.poses(m);
        for (n, p) in out.runs[m].nodes.iter().zip(poses) {
            if let Some(g) = n.ground_truth {
                pairs.push((p, g));
            }
        }
    }
    pairs.into_iter().unzip()
}

/// `map_from_mission` of mission `m` as the ground truth tells it: each
/// run's own nodes fitted onto their ground truth (`truth_from_own`),
/// then `first_from_m = truth_from_first⁻¹ ⊕ truth_from_m`.
fn true_placement(out: &MultiOutput, m: usize) -> Se2 {
    let truth_from_own = |run: &SlamOutput| {
        let (p, q): (Vec<_>, Vec<_>) = run
            .nodes
            .iter()
            .filter_map(|n| {
                n.ground_truth
                    .map(|g| (n.optimised.translation(), g.translation()))
            })
            .unzip();
        align_se2(&p, &q)
    };
    truth_from_own(&out.runs[0])
        .inverse()
        .compose(&truth_from_own(&out.runs[m]))
}

/// Distance (m) and heading difference (deg) between the found and the
/// true placement at mission `m`'s nodes (mean over them).
fn placement_error(out: &MultiOutput, m: usize) -> (f64, f64) {
    let found = out.placements[m]
        .as_ref()
        .unwrap()
        .map_from_mission
        .unwrap();
    let truth = true_placement(out, m);
    let nodes = &out.runs[m].nodes;
    let d: f64 = nodes
        .iter()
        .map(|n| {
            let (a, b) = (found.compose(&n.optimised), truth.compose(&n.optimised));
            (a.translation() - b.translation()).norm()
        })
        .sum::<f64>()
        / nodes.len() as f64;
    let dtheta = echofield_graph::se2::wrap_angle(found.theta() - truth.theta()).to_degrees();
    (d, dtheta)
}

#[test]
fn two_marina_missions_with_different_routes_and_starts_merge_within_0_3_m() {
    let a = marina_seed_1().clone();
    let b = run_mission(&marina_other_route(), &SlamConfig::default(), &NoProgress).unwrap();
    // The two start far apart: no shared start pose to lean on.
    let (start_a, start_b) = (
        a.nodes[0].ground_truth.unwrap(),
        b.nodes[0].ground_truth.unwrap(),
    );
    assert!((start_a.translation() - start_b.translation()).norm() > 100.0);
    let out = combine(vec![a, b], &SlamConfig::default()).unwrap();
    let report = &out.report;
    eprintln!("{}", serde_json::to_string_pretty(report).unwrap());
    assert!(report.merged);
    assert!(report.missions[1].merged);
    let placement = out.placements[1].as_ref().unwrap();
    assert!(placement.agreeing >= 3, "{placement:?}");
    assert!(
        report.cross_loops_accepted >= 10,
        "{} cross-mission loops",
        report.cross_loops_accepted
    );
    let (estimate, truth) = merged_with_truth(&out, &[0, 1]);
    let ate = aligned_position_rmse(&estimate, &truth);
    let (estimate_b, truth_b) = merged_with_truth(&out, &[1]);
    let ate_b = aligned_position_rmse(&estimate_b, &truth_b);
    eprintln!("merged ATE {ate:.3} m (mission 2 alone in the merged graph {ate_b:.3} m)");
    assert!(ate <= 0.3, "merged ATE {ate} m");
    let (d, dtheta) = placement_error(&out, 1);
    eprintln!("placement off the truth by {d:.3} m, {dtheta:.2}° (mean over mission 2's nodes)");
    assert!(d <= 1.0 && dtheta.abs() <= 1.0, "{d} m, {dtheta}°");
    // The report's figure is the same computation.
    assert!((report.merged_ate_rmse_m.unwrap() - ate).abs() < 1e-9);

    // The outputs: a mission column in the nodes and loops tables, both
    // missions in the cross-mission loops, one TUM file per mission.
    let dir = tempfile::tempdir().unwrap();
    write_files(dir.path(), &out).unwrap();
    let poses = std::fs::read_to_string(dir.path().join("poses.csv")).unwrap();
    assert!(poses.starts_with("mission,node,"));
    let rows_of = |m: &str| poses.lines().filter(|l| l.starts_with(m)).count();
    assert_eq!(rows_of("1,"), out.runs[0].nodes.len());
    assert_eq!(rows_of("2,"), out.runs[1].nodes.len());
    let loops = std::fs::read_to_string(dir.path().join("loops.csv")).unwrap();
    let cross_accepted = loops
        .lines()
        .filter(|l| l.starts_with("1,") && l.contains(",2,") && l.contains(",true,true,"))
        .count();
    assert_eq!(cross_accepted, report.cross_loops_accepted);
    for f in [
        "trajectory_1_tum.txt",
        "trajectory_2_tum.txt",
        "trajectory.png",
        "report.json",
    ] {
        assert!(dir.path().join(f).is_file(), "{f}");
    }
}

#[test]
fn a_canyon_mission_is_not_merged_with_the_marina() {
    let a = marina_seed_1().clone();
    let canyon = simulate_mission(&Scenario::named("canyon").unwrap(), 1).unwrap();
    let b = run_mission(&canyon, &SlamConfig::default(), &NoProgress).unwrap();
    let own_b: Vec<Se2> = b.nodes.iter().map(|n| n.optimised).collect();
    let out = combine(vec![a, b], &SlamConfig::default()).unwrap();
    let report = &out.report;
    eprintln!("{}", serde_json::to_string_pretty(report).unwrap());
    assert!(!report.merged);
    assert!(!report.missions[1].merged);
    assert!(out.merged.is_none());
    let placement = out.placements[1].as_ref().unwrap();
    assert!(placement.map_from_mission.is_none());
    assert!(placement.agreeing < 3);
    assert_eq!(report.warnings.len(), 1, "{:?}", report.warnings);
    assert!(report.warnings[0].contains("could not be placed"));
    // Its own result, in its own frame.
    assert_eq!(out.poses(1), own_b);
    let dir = tempfile::tempdir().unwrap();
    write_files(dir.path(), &out).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
            .unwrap();
    assert_eq!(json["merged"], false);
    assert_eq!(
        json["missions"][1]["placement"]["map_from_mission"],
        serde_json::Value::Null
    );
}

#[test]
fn the_real_st_pere_halves_merge() {
    let mission = stpere_point_set_mission(Some(SweepTiming::AngleIncreasing));
    let calibration = calibrate_mission(&mission, &CalibrateSettings::default()).unwrap();
    let config = SlamConfig {
        mounting: calibration.mounting_config(),
        ..SlamConfig::default()
    };
    // 200 beams per rotation (README, "Real data"): rotation 61 starts at
    // beam 12 000.
    let cut_s = mission.beams[60 * 200].stamp_s;
    let (mut first, mut second) = split_mission_at(&mission, cut_s);
    first.name += " 1-60";
    second.name += " 61-115";
    let a = run_mission(&first, &config, &NoProgress).unwrap();
    let b = run_mission(&second, &config, &NoProgress).unwrap();
    let out = combine(vec![a, b], &config).unwrap();
    let report = &out.report;
    eprintln!("{}", serde_json::to_string_pretty(report).unwrap());
    assert!(report.merged, "{:?}", report.warnings);
    let (estimate, truth) = merged_with_truth(&out, &[0, 1]);
    let ate = aligned_position_rmse(&estimate, &truth);
    eprintln!(
        "real St Pere halves merged: ATE against DGPS {ate:.3} m over {} nodes, {} cross-mission loops",
        estimate.len(),
        report.cross_loops_accepted
    );
    let (d, dtheta) = placement_error(&out, 1);
    eprintln!(
        "placement off the truth by {d:.3} m, {dtheta:.2}° (mean over the second half's nodes)"
    );
    assert!(report.cross_loops_accepted >= 5);
    assert!(ate <= 1.2, "merged ATE {ate} m");
}
