//! The benchmark commands on a mission file (`--mission`): they read it,
//! report on it, and refuse one without ground truth.

use std::path::PathBuf;
use std::process::{Command, Output};

fn echofield(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_echofield"))
        .args(args)
        .output()
        .unwrap()
}

fn stdout_of(run: &Output) -> String {
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    String::from_utf8_lossy(&run.stdout).into_owned()
}

/// The standard output of benchmark `command` on the committed tank
/// sample (`--mission`) with `extra` arguments; it must succeed.
fn on_sample(command: &str, extra: &[&str]) -> String {
    let sample =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../datasets/samples/tank-seed1.mcap");
    let mut args = vec![command, "--mission", sample.to_str().unwrap()];
    args.extend_from_slice(extra);
    stdout_of(&echofield(&args))
}

/// The number after `key` in `text`.
fn number_after(text: &str, key: &str) -> f64 {
    let rest = &text[text.find(key).unwrap_or_else(|| panic!("{key} in {text}")) + key.len()..];
    let token: String = rest
        .trim_start()
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.')
        .collect();
    token.parse().unwrap_or_else(|_| panic!("{key} in {text}"))
}

#[test]
fn bench_dead_reckoning_reports_on_a_mission_file() {
    let out = on_sample("bench-dead-reckoning", &[]);
    // The sample is the 2-minute tank mission: 10 rotations, every one
    // inside the dead reckoning's span.
    assert!(out.contains(": 10 rotations"), "{out}");
    assert!(out.contains("distortion over 10 rotations"), "{out}");
    let ate = number_after(&out, "ATE RMSE (SE(2)-aligned)");
    assert!(ate > 0.0 && ate < 2.0, "{out}");
    // No map of the walls for a mission file.
    assert!(!out.contains("near walls"), "{out}");
    // The three worst rotations, the first of them the largest motion
    // error of the distortion line.
    let worst = out
        .lines()
        .find(|l| l.starts_with("worst rotations (motion over the rotation): "))
        .unwrap_or_else(|| panic!("{out}"));
    assert_eq!(worst.matches("rotation ").count(), 3, "{worst}");
    let largest = number_after(worst, " s ");
    let distortion = out
        .lines()
        .find(|l| l.starts_with("distortion over"))
        .unwrap_or_else(|| panic!("{out}"));
    // The line's last "max" is the motion's.
    let last_max = distortion
        .rfind("max ")
        .unwrap_or_else(|| panic!("{distortion}"));
    let max_motion = number_after(&distortion[last_max..], "max ");
    assert_eq!(largest, max_motion, "{worst} / {distortion}");

    // With --slam, also the distortion along a SLAM run's trajectory.
    let out = on_sample("bench-dead-reckoning", &["--slam"]);
    let key = "motion over a rotation median";
    let dead_reckoning = number_after(&out, key);
    let slam_line = out
        .lines()
        .find(|l| l.starts_with("distortion along the SLAM trajectory, ATE"))
        .unwrap_or_else(|| panic!("{out}"));
    assert!(number_after(slam_line, key) < dead_reckoning, "{out}");
}

#[test]
fn bench_matcher_reports_on_a_mission_file() {
    let few = ["--trials", "1", "--max-pairs", "5"];
    let out = on_sample("bench-matcher", &few);
    assert!(out.contains("evaluated"), "{out}");
    assert!(out.contains("| Consecutive | AcousticImage |"), "{out}");
    assert!(out.contains("| NonConsecutive | Icp |"), "{out}");

    let out = on_sample(
        "bench-matcher",
        &[&few[..], &["--navigation", "slam"]].concat(),
    );
    assert!(
        out.contains("SLAM run for the motion compensation: ATE RMSE"),
        "{out}"
    );
    assert!(out.contains("motion compensation by Slam"), "{out}");
}

#[test]
fn bench_matcher_writes_every_scan_point_at_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("pull.csv");
    let json = dir.path().join("trials.json");
    on_sample(
        "bench-matcher",
        &[
            "--trials",
            "1",
            "--max-pairs",
            "3",
            "--pull-at-truth",
            csv.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ],
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some(
            "scan,image,kind,displacement_m,scan_x_m,scan_y_m,rim_margin_m,value,\
             slope_along_per_m,fine_slope_along_per_m"
        )
    );
    // One row per scan point of every pair the trials evaluated, each pair
    // with the displacement of its truth in the JSON.
    let trials: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let mut truth_of = std::collections::BTreeMap::new();
    for t in trials["evaluation"]["trials"].as_array().unwrap() {
        let key = (t["scan"].as_u64().unwrap(), t["image"].as_u64().unwrap());
        let xy = (
            t["truth"][0].as_f64().unwrap(),
            t["truth"][1].as_f64().unwrap(),
        );
        truth_of.insert(key, xy.0.hypot(xy.1));
    }
    let mut pairs = std::collections::BTreeSet::new();
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), 10, "{line}");
        let key = (f[0].parse::<u64>().unwrap(), f[1].parse::<u64>().unwrap());
        assert!(["consecutive", "non_consecutive"].contains(&f[2]), "{line}");
        let d: f64 = f[3].parse().unwrap();
        assert!((d - truth_of[&key]).abs() < 1e-9, "{line}");
        // The sample's images have a reach: every point has a margin.
        let margin: f64 = f[6].parse().unwrap();
        let value: f64 = f[7].parse().unwrap();
        assert!(margin.is_finite() && (0.0..=1.0).contains(&value), "{line}");
        pairs.insert(key);
    }
    assert_eq!(pairs.len(), truth_of.len(), "{text}");
}

#[test]
fn a_mission_without_ground_truth_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let mission = dir.path().join("ping360.mcap");
    let log = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../datasets/msis-real/ping360/Sensor_Log_01__inside_base.bin");
    let convert = echofield(&[
        "convert",
        "ping360",
        log.to_str().unwrap(),
        "--output",
        mission.to_str().unwrap(),
    ]);
    assert!(convert.status.success());
    for command in ["bench-dead-reckoning", "bench-matcher"] {
        let run = echofield(&[command, "--mission", mission.to_str().unwrap()]);
        assert!(!run.status.success(), "{command}");
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(stderr.contains("ping360.mcap"), "{command}: {stderr}");
        assert!(stderr.contains("ground truth"), "{command}: {stderr}");
    }
}

#[test]
fn error_budget_reports_on_a_mission_file() {
    let sample =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../datasets/samples/tank-seed1.mcap");
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("budget.json");
    let out = stdout_of(&echofield(&[
        "error-budget",
        sample.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]));
    // 10 rotations, 10 nodes: 9 odometry and sequential edges, no loop
    // (they need 10 rotations between their nodes).
    assert!(out.contains("10 nodes (10 with ground truth)"), "{out}");
    assert!(out.contains("| Odometry | 9 |"), "{out}");
    assert!(out.contains("| Sequential |"), "{out}");
    assert!(!out.contains("| Loop |"), "{out}");
    let budget: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let solves = budget["oracle_solves"].as_array().unwrap();
    let replaced: Vec<&serde_json::Value> = solves.iter().map(|s| &s["replaced"]).collect();
    assert_eq!(
        replaced,
        [
            &serde_json::json!([]),
            &serde_json::json!(["odometry"]),
            &serde_json::json!(["sequential"]),
            &serde_json::json!(["odometry", "sequential"]),
            &serde_json::json!([]),
        ]
    );
    // The last solve weakens the odometry and says so, in the JSON and in
    // the table; every solve has a motion scale near 1.
    assert_eq!(solves[4]["odometry_information_factor"], 0.01);
    assert!(out.contains("odometry information × 0.01"), "{out}");
    assert!(solves.iter().all(|s| {
        let scale = s["motion_scale"].as_f64().unwrap();
        (scale - 1.0).abs() < 0.2
    }));
    // The graph solved again is the run's solution: its ATE is the one
    // the first line reports.
    let run_ate = number_after(&out, "run ATE");
    let again = solves[0]["ate_rmse_m"].as_f64().unwrap();
    assert!((again - run_ate).abs() < 2e-3, "{again} vs {out}");
    assert!(
        solves
            .iter()
            .all(|s| s["ate_rmse_m"].as_f64().unwrap().is_finite())
    );
}

#[test]
fn error_budget_needs_ground_truth() {
    // The tank sample without its ground truth.
    let sample =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../datasets/samples/tank-seed1.mcap");
    let mut mission = echofield::slam::load_mission(&sample).unwrap();
    mission.ground_truth.clear();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("no-truth.mcap");
    echofield_datasets::mcap::write_mission(&path, &mission).unwrap();
    let run = echofield(&["error-budget", path.to_str().unwrap()]);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("has no ground truth"), "{stderr}");
}
