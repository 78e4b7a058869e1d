//! The SLAM pipeline on missing or damaged input, on the small simulated
//! `tank` mission: missing sensor streams are clear errors, gaps are
//! bridged and reported, navigation that starts late skips rotations, a
//! mission without loop closures still gives the dead-reckoning-plus-
//! sequential trajectory, and a run is deterministic.

use echofield::slam::{NoProgress, SlamConfig, SlamError, run_mission};
use echofield_datasets::sim::{Scenario, simulate_mission};
use echofield_frontend::Mission;
use echofield_frontend::loops::RejectReason;
use echofield_graph::EdgeKind;
use std::sync::OnceLock;

fn tank() -> &'static Mission {
    static MISSION: OnceLock<Mission> = OnceLock::new();
    MISSION.get_or_init(|| simulate_mission(&Scenario::named("tank").unwrap(), 3).unwrap())
}

fn error_of(mission: &Mission) -> String {
    match run_mission(mission, &SlamConfig::default(), &NoProgress) {
        Ok(_) => panic!("a run on bad input succeeded"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn missing_streams_are_errors_naming_them() {
    let mut no_beams = tank().clone();
    no_beams.beams.clear();
    let message = error_of(&no_beams);
    assert!(message.contains("no sonar beams"), "{message}");

    let mut no_dvl = tank().clone();
    no_dvl.dvl.iter_mut().for_each(|d| d.valid = false);
    let message = error_of(&no_dvl);
    assert!(message.contains("no valid DVL"), "{message}");
    no_dvl.dvl.clear();
    assert!(error_of(&no_dvl).contains("DVL"));

    let mut no_heading = tank().clone();
    no_heading.attitude.clear();
    let message = error_of(&no_heading);
    assert!(message.contains("no heading"), "{message}");
    assert!(matches!(
        run_mission(&no_heading, &SlamConfig::default(), &NoProgress),
        Err(SlamError::MissingSensor { .. })
    ));
}

#[test]
fn damaged_records_are_errors_not_panics() {
    let mut mission = tank().clone();
    let k = mission.beams.len() / 2;
    mission.beams[k].angle_rad = f64::NAN;
    let message = error_of(&mission);
    assert!(
        message.contains(&format!("beam {k}")) && message.contains("angle_rad"),
        "{message}"
    );

    let mut mission = tank().clone();
    mission.dvl[10].stamp_s = f64::INFINITY;
    let message = error_of(&mission);
    assert!(message.contains("DVL sample 10"), "{message}");
}

#[test]
fn navigation_that_starts_late_skips_the_first_rotations() {
    let mut mission = tank().clone();
    let late_s = mission.beams[0].stamp_s + 30.0;
    mission.dvl.retain(|d| d.stamp_s >= late_s);
    mission.attitude.retain(|a| a.stamp_s >= late_s);
    let output = run_mission(&mission, &SlamConfig::default(), &NoProgress).unwrap();
    let report = &output.report;
    assert!(!report.skipped_rotations.is_empty());
    assert!(report.skipped_rotations.iter().all(|s| s.start_s < late_s));
    assert_eq!(
        report.nodes + report.skipped_rotations.len(),
        report.rotations
    );
    assert!(output.nodes.iter().all(|n| n.stamp_s > late_s));
    assert!(report.warnings.iter().any(|w| w.contains("skipped")));

    // Navigation that covers no rotation at all is an error, not a panic.
    let mut mission = tank().clone();
    let end_s = mission.beams[mission.beams.len() - 1].stamp_s;
    mission.dvl.iter_mut().for_each(|d| d.stamp_s += end_s);
    mission.attitude.iter_mut().for_each(|a| a.stamp_s += end_s);
    assert!(matches!(
        run_mission(&mission, &SlamConfig::default(), &NoProgress),
        Err(SlamError::NoNodes { .. })
    ));
}

#[test]
fn gaps_are_bridged_and_reported() {
    let mut mission = tank().clone();
    let t0 = mission.beams[0].stamp_s;
    // 40 s without sonar and 12 s without DVL.
    let (sonar_gap, dvl_gap) = ((t0 + 50.0, t0 + 90.0), (t0 + 100.0, t0 + 112.0));
    mission
        .beams
        .retain(|b| b.stamp_s < sonar_gap.0 || b.stamp_s > sonar_gap.1);
    mission
        .dvl
        .retain(|d| d.stamp_s < dvl_gap.0 || d.stamp_s > dvl_gap.1);
    let output = run_mission(&mission, &SlamConfig::default(), &NoProgress).unwrap();
    let gaps = &output.report.time_gaps;
    let sonar = gaps
        .iter()
        .find(|g| g.kind == "sonar")
        .expect("a sonar gap");
    assert!(
        sonar.start_s <= sonar_gap.0 && sonar.end_s >= sonar_gap.1,
        "{gaps:?}"
    );
    let dvl = gaps.iter().find(|g| g.kind == "dvl").expect("a DVL gap");
    assert!(dvl.end_s - dvl.start_s >= 12.0, "{gaps:?}");
    // The chain of odometry edges bridges both: one component.
    assert!(output.graph.is_connected());
    let odometry = output
        .graph
        .edges()
        .filter(|e| e.kind == EdgeKind::Odometry)
        .count();
    assert_eq!(odometry, output.nodes.len() - 1);
    // Rotations that span the DVL gap are not matched.
    let in_gap: Vec<u64> = output
        .nodes
        .iter()
        .filter(|n| n.in_dvl_gap)
        .map(|n| n.id)
        .collect();
    assert!(!in_gap.is_empty());
    for record in output.sequential.iter().filter(|s| in_gap.contains(&s.to)) {
        assert_eq!(record.rejected_by, Some(RejectReason::DvlGap));
    }
}

#[test]
fn without_loop_closures_the_trajectory_is_dead_reckoning_plus_sequential() {
    let config = SlamConfig::from_toml_str("[loops]\nenabled = false\n").unwrap();
    let output = run_mission(tank(), &config, &NoProgress).unwrap();
    let report = &output.report;
    assert_eq!(report.loop_candidates, 0);
    assert_eq!(report.loops_accepted, 0);
    assert!(output.graph.edges().all(|e| e.kind != EdgeKind::Loop));
    let sequential = output
        .graph
        .edges()
        .filter(|e| e.kind == EdgeKind::Sequential)
        .count();
    assert!(
        sequential >= output.nodes.len() - 2,
        "{sequential} sequential edges"
    );
    assert!(report.solver.summary.termination.is_converged());
    // Better than dead reckoning alone on this short mission, and sane.
    let (ate, dead_reckoning) = (
        report.ate_rmse_m.unwrap(),
        report.ate_rmse_dead_reckoning_m.unwrap(),
    );
    assert!(
        ate < 0.5 && ate <= dead_reckoning + 0.05,
        "{ate} vs {dead_reckoning}"
    );
    // With ground truth the report still holds a precision: no loop was
    // accepted, so none is wrong (documented convention), and the counts
    // behind it are zero.
    assert_eq!(report.loop_precision, Some(1.0));
    let evaluation = report.loop_evaluation.as_ref().unwrap();
    assert_eq!(
        (evaluation.true_positives, evaluation.false_positives),
        (0, 0)
    );
    let json = serde_json::to_value(report).unwrap();
    assert_eq!(json["loop_precision"], serde_json::json!(1.0));
    assert!(json["definitions"]["loop_precision"].is_string());
}

#[test]
fn the_same_mission_and_config_give_the_same_output() {
    let a = run_mission(tank(), &SlamConfig::default(), &NoProgress).unwrap();
    let b = run_mission(tank(), &SlamConfig::default(), &NoProgress).unwrap();
    assert_eq!(a.nodes, b.nodes);
    assert_eq!(a.loops, b.loops);
    assert_eq!(a.sequential, b.sequential);
    assert_eq!(a.graph.poses(), b.graph.poses());
    assert_eq!(a.dead_reckoning, b.dead_reckoning);
}
