//! The real St Pere sonar (issue 34, item 6): rotations 1-115 of the
//! MiniKing point sets with the real navigation, the mounting taken from
//! `echofield calibrate` (not set by hand), the default configuration
//! otherwise. Against DGPS: the ATE, and the sharpness of the map of all
//! scans placed at the optimised node poses against the map placed at the
//! dead-reckoning poses and at the DGPS track's. The figures and the
//! command that reproduces them are in README.md, section "Real data".

use echofield::calibration::{CalibrateSettings, calibrate_mission};
use echofield::slam::health::Verdict;
use echofield::slam::online::run_online;
use echofield::slam::{NoProgress, SlamConfig, SlamOutput, run_mission};
use echofield_frontend::sensors::{Mission, SweepTiming};
use echofield_frontend::sharpness::{Sharpness, sharpness};
use echofield_graph::Se2;
use echofield_tests::stpere_point_set_mission;
use nalgebra::Vector2;
use std::sync::OnceLock;

/// The mission and its calibrated configuration, computed once for the
/// tests of this file.
fn calibrated() -> &'static (Mission, SlamConfig) {
    static CALIBRATED: OnceLock<(Mission, SlamConfig)> = OnceLock::new();
    CALIBRATED.get_or_init(|| {
        // Rebuilt under the converter's default assumption (angle
        // increasing); calibrate decides the sweep with the rest.
        let mission = stpere_point_set_mission(Some(SweepTiming::AngleIncreasing));
        let calibration = calibrate_mission(&mission, &CalibrateSettings::default()).unwrap();
        let config = SlamConfig {
            mounting: calibration.mounting_config(),
            ..SlamConfig::default()
        };
        (mission, config)
    })
}

/// The calibrated run, computed once for the tests of this file.
fn calibrated_run() -> &'static SlamOutput {
    static RUN: OnceLock<SlamOutput> = OnceLock::new();
    RUN.get_or_init(|| {
        let (mission, config) = calibrated();
        run_mission(mission, config, &NoProgress).unwrap()
    })
}

/// Every node's scan placed at `pose(node)`; `None` nodes are left out.
fn map(out: &SlamOutput, pose: impl Fn(usize) -> Option<Se2>) -> Sharpness {
    let points: Vec<Vector2<f64>> = out
        .scans
        .iter()
        .enumerate()
        .filter_map(|(i, scan)| Some((pose(i)?, scan)))
        .flat_map(|(pose, scan)| {
            scan.points.iter().map(move |p| {
                let (x, y) = pose.transform_xy(p.x, p.y);
                Vector2::new(x, y)
            })
        })
        .collect();
    sharpness(&points, 0.5).unwrap()
}

#[test]
fn calibrated_real_st_pere_beats_dead_reckoning_against_dgps_and_is_healthy() {
    let out = calibrated_run();
    let report = &out.report;
    let (ate, dr) = (
        report.ate_rmse_m.unwrap(),
        report.ate_rmse_dead_reckoning_m.unwrap(),
    );
    eprintln!(
        "ATE {ate:.3} m, dead reckoning {dr:.3} m, {} nodes",
        report.nodes
    );
    // Rotations 13-115 are navigated; the default node spacing drops the
    // few where the vehicle hardly moved or turned.
    assert!(
        report.nodes >= 95 && report.thinned_rotations <= 5,
        "{} nodes, {} rotations thinned",
        report.nodes,
        report.thinned_rotations
    );
    assert!(ate < 0.8 * dr, "ATE {ate} m, dead reckoning {dr} m");
    assert!(ate <= 1.0, "ATE {ate} m");
    assert_eq!(report.health.verdict, Verdict::Ok, "{:?}", report.health);
}

#[test]
fn the_optimised_map_is_sharper_than_the_dead_reckoning_and_dgps_maps() {
    let out = calibrated_run();
    let optimised = map(out, |i| Some(out.nodes[i].optimised));
    let dead_reckoning = map(out, |i| Some(out.nodes[i].dead_reckoning));
    // Only the nodes the DGPS covers, in every map compared with it.
    let covered = |i: usize| out.nodes[i].ground_truth.is_some();
    let dgps = map(out, |i| out.nodes[i].ground_truth);
    let optimised_covered = map(out, |i| covered(i).then(|| out.nodes[i].optimised));
    eprintln!(
        "entropy (bits) / occupied 0.5 m cells: optimised {:.3} / {}, dead reckoning {:.3} / {}; \
         on the DGPS-covered nodes: optimised {:.3} / {}, DGPS {:.3} / {}",
        optimised.entropy_bits,
        optimised.occupied_cells,
        dead_reckoning.entropy_bits,
        dead_reckoning.occupied_cells,
        optimised_covered.entropy_bits,
        optimised_covered.occupied_cells,
        dgps.entropy_bits,
        dgps.occupied_cells
    );
    assert!(optimised.entropy_bits < dead_reckoning.entropy_bits);
    assert!(optimised.occupied_cells < dead_reckoning.occupied_cells);
    assert!(optimised_covered.entropy_bits < dgps.entropy_bits);
    assert!(optimised_covered.occupied_cells < dgps.occupied_cells);
}

/// The same mission fed through the causal engine as on the vehicle
/// (issue 36 item 1, on real data): the estimates as emitted, each with
/// only the data and the loops up to its rotation, beat the causal dead
/// reckoning by a wide margin, and `finish` ends where the batch run's
/// steps from the same causal navigation lead (README.md § Online has
/// the figures).
#[test]
fn the_real_mission_online_emits_estimates_well_ahead_of_dead_reckoning() {
    let (mission, config) = calibrated();
    let online = run_online(mission, config, &NoProgress).unwrap();
    let report = &online.report;
    let emitted = report.online.as_ref().unwrap().ate_rmse_m.unwrap();
    let (finished, dr) = (
        report.ate_rmse_m.unwrap(),
        report.ate_rmse_dead_reckoning_m.unwrap(),
    );
    eprintln!(
        "online: emitted {emitted:.3} m, after finish {finished:.3} m, causal dead reckoning {dr:.3} m"
    );
    assert_eq!(online.emitted.as_ref().unwrap().len(), report.nodes);
    // Each emitted estimate is the graph solved with its own node's edges;
    // composed from the last solve by the odometry they drift as the dead
    // reckoning does between loops (about 0.7 of it here).
    assert!(
        emitted < 0.65 * dr,
        "emitted {emitted} m, dead reckoning {dr} m"
    );
    assert!(
        finished < emitted && finished <= 1.0,
        "after finish {finished} m"
    );
}
