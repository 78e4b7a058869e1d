//! `echofield demo` end to end on a short mission (the tank scenario; the
//! CLI's default is the 40-minute marina).

use echofield::slam::outputs::demo::{SIMULATED_MISSION, run_demo};
use echofield::slam::{NoProgress, SlamConfig};
use echofield_datasets::mcap::read_mission;
use echofield_datasets::sim::{Scenario, simulate_mission};

#[test]
fn demo_simulates_runs_and_writes_every_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let scenario = Scenario::named("tank").unwrap();
    let config = SlamConfig::from_toml_str("[loops]\nmin_separation_nodes = 4\n").unwrap();
    let summary = run_demo(&out, &scenario, 3, &config, None, &NoProgress).unwrap();

    // The simulated input is kept and is the seed's mission.
    let kept = read_mission(&out.join(SIMULATED_MISSION)).unwrap();
    let expected = simulate_mission(&scenario, 3).unwrap();
    assert_eq!(kept.beams.len(), expected.beams.len());
    assert_eq!(kept.beams[10], expected.beams[10]);
    assert_eq!(summary.beams, expected.beams.len());

    for name in [
        "config.toml",
        "trajectory_tum.txt",
        "dead_reckoning_tum.txt",
        "trajectory_nav_tum.txt",
        "trajectory_nav_kitti.txt",
        "trajectory_nav_times.txt",
        "ground_truth_tum.txt",
        "poses.csv",
        "graph.g2o",
        "loops.csv",
        "trajectory.png",
        "loops.png",
        "mosaic.png",
        "mosaic.pgw",
        "mission.mcap",
        "report.json",
    ] {
        let path = out.join(name);
        assert!(
            path.is_file() && std::fs::metadata(&path).unwrap().len() > 0,
            "{name}"
        );
    }
    let report = &summary.output.report;
    assert_eq!(report.nodes, summary.output.nodes.len());
    // The run's judgement of itself is in report.json, and it is ok.
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(
        written["health"]["verdict"], "ok",
        "{:#}",
        written["health"]
    );
    assert!(report.nodes >= 5, "{} nodes", report.nodes);
    // The summary states the accuracy against ground truth and where to look.
    let text = summary.text();
    let ate = report.ate_rmse_m.unwrap();
    assert!(text.contains(&format!("ATE RMSE: {ate:.2} m")), "{text}");
    assert!(
        text.contains("trajectory.png") && text.contains("mission.mcap"),
        "{text}"
    );
    // The loops' precision and recall, and the recall budget's ceiling.
    let loops = report.loop_summary().unwrap();
    let ceiling = report
        .loop_evaluation
        .as_ref()
        .unwrap()
        .recall_budget
        .gate_ceiling
        .unwrap();
    assert!(text.contains(&loops), "{text}");
    for number in [
        report.loop_precision.unwrap(),
        report.loop_recall.unwrap(),
        ceiling,
    ] {
        assert!(
            loops.contains(&format!("{number:.3}")),
            "{number} in {loops}"
        );
    }
    // With the tolerances and the accepted loops' median error against
    // the ground truth, taken here from loops.csv.
    let csv = std::fs::read_to_string(out.join("loops.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (accepted, error) = (column("accepted"), column("gt_error_m"));
    let mut errors: Vec<f64> = lines
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|f| f[accepted] == "true" && !f[error].is_empty())
        .map(|f| f[error].parse().unwrap())
        .collect();
    assert!(!errors.is_empty());
    errors.sort_by(f64::total_cmp);
    let n = errors.len();
    let median = 0.5 * (errors[(n - 1) / 2] + errors[n / 2]);
    assert!(
        loops.contains("within 0.5 m and 3°")
            && loops.contains(&format!("median error {median:.2} m")),
        "{median} in {loops}"
    );
    // And the DVL scale check, as the inverse of the report's scale.
    let scale = report.dead_reckoning.odometry_scale.unwrap().scale;
    let excess = 1.0 / scale - 1.0;
    let words = format!("distances are {:.1} ± ", 100.0 * excess.abs());
    let side = if excess >= 0.0 { "longer" } else { "shorter" };
    assert!(
        text.contains(&words) && text.contains(side),
        "{words}, {side} in {text}"
    );
}
