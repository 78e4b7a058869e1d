//! `echofield run` on input it cannot process: a one-line error and no
//! output.

use std::path::{Path, PathBuf};
use std::process::Command;

#[test]
fn stpere_folder_without_beams_names_the_replay_command_and_writes_nothing() {
    let logs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../datasets/stpere-marina");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let run = Command::new(env!("CARGO_BIN_EXE_echofield"))
        .arg("run")
        .arg(&logs)
        .arg("--output")
        .arg(&out)
        .output()
        .unwrap();
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("hold no sonar beams"), "{stderr}");
    // The command it suggests uses the simulator's flags (`simulate
    // stpere`, as it read before, is not a valid invocation).
    let suggested = format!(
        "echofield simulate --scenario stpere --data {}",
        logs.display()
    );
    assert!(stderr.contains(&suggested), "{stderr}");
    assert!(!out.exists() || out.read_dir().unwrap().next().is_none());
}

/// `echofield simulate` of the tank scenario with `seed` into `dir`.
fn simulated_tank(dir: &Path, seed: &str) -> PathBuf {
    let mission = dir.join("tank.mcap");
    let simulate = Command::new(env!("CARGO_BIN_EXE_echofield"))
        .args(["simulate", "--scenario", "tank", "--seed", seed, "--output"])
        .arg(&mission)
        .output()
        .unwrap();
    assert!(simulate.status.success(), "{simulate:?}");
    mission
}

/// The log goes to stderr in colour only on a terminal: captured through a
/// pipe (a file, CI, `2>&1 | tee`), its lines carry no escape codes.
#[test]
fn log_lines_written_to_a_pipe_are_plain_text() {
    let dir = tempfile::tempdir().unwrap();
    let mission = simulated_tank(dir.path(), "1");
    let run = Command::new(env!("CARGO_BIN_EXE_echofield"))
        .arg("run")
        .arg(&mission)
        .arg("--output")
        .arg(dir.path().join("run"))
        .arg("-vv")
        .env_remove("RUST_LOG")
        .output()
        .unwrap();
    assert!(run.status.success(), "{run:?}");
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("DEBUG"), "no log lines: {stderr}");
    assert!(!stderr.contains('\u{1b}'), "escape codes in: {stderr:?}");
}

/// `--threads` sets the worker threads; the trajectory is the same byte
/// for byte with one thread and with three.
#[test]
fn the_thread_count_does_not_change_the_trajectory() {
    let dir = tempfile::tempdir().unwrap();
    let mission = simulated_tank(dir.path(), "2");
    let trajectory = |threads: &str| {
        let out = dir.path().join(format!("run{threads}"));
        let run = Command::new(env!("CARGO_BIN_EXE_echofield"))
            .arg("run")
            .arg(&mission)
            .arg("--output")
            .arg(&out)
            .args(["--threads", threads])
            .output()
            .unwrap();
        assert!(run.status.success(), "{run:?}");
        std::fs::read(out.join("trajectory_tum.txt")).unwrap()
    };
    assert_eq!(trajectory("1"), trajectory("3"));
    let zero = Command::new(env!("CARGO_BIN_EXE_echofield"))
        .arg("run")
        .arg(&mission)
        .args(["--output", "unused", "--threads", "0"])
        .output()
        .unwrap();
    assert!(!zero.status.success());
    assert!(
        String::from_utf8_lossy(&zero.stderr).contains("--threads"),
        "{zero:?}"
    );
}

/// The real St Pere point sets (`datasets/stpere-marina-sonar`) expanded
/// into a keyframe folder in `dir`.
fn st_pere_keyframes(dir: &Path) -> PathBuf {
    echofield_datasets::stpere::point_bands::committed_keyframes(dir).unwrap()
}

/// A run that judges its result suspect (the real St Pere sonar under the
/// head conventions as logged) writes every output, says why and what to
/// do, and exits with the documented status; `--allow-suspect` makes it 0.
#[test]
fn a_suspect_run_writes_its_outputs_and_exits_with_the_suspect_status() {
    let dir = tempfile::tempdir().unwrap();
    let keyframes = st_pere_keyframes(dir.path());
    let logs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../datasets/stpere-marina");
    let run = |out: &Path, extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_echofield"))
            .arg("run")
            .arg(&logs)
            .arg("--keyframes")
            .arg(&keyframes)
            .arg("--output")
            .arg(out)
            .args(extra)
            .output()
            .unwrap()
    };
    let out = dir.path().join("suspect");
    let suspect = run(&out, &[]);
    assert_eq!(
        suspect.status.code(),
        Some(i32::from(echofield::slam::health::SUSPECT_EXIT_STATUS)),
        "{suspect:?}"
    );
    let stdout = String::from_utf8_lossy(&suspect.stdout);
    assert!(stdout.contains("health: SUSPECT"), "{stdout}");
    assert!(stdout.contains("echofield calibrate"), "{stdout}");
    assert!(stdout.contains("--keyframes"), "{stdout}");
    let stderr = String::from_utf8_lossy(&suspect.stderr);
    assert!(stderr.contains("--allow-suspect"), "{stderr}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["health"]["verdict"], "suspect");
    assert_eq!(report["health"]["cause"], "mounting");
    assert!(out.join("trajectory_tum.txt").is_file() && out.join("mosaic.png").is_file());

    let allowed = run(&dir.path().join("allowed"), &["--allow-suspect"]);
    assert!(allowed.status.success(), "{allowed:?}");
    assert!(String::from_utf8_lossy(&allowed.stdout).contains("health: SUSPECT"));
    // Rotations 0-12 precede the navigation: a warning, which `-q` keeps
    // off stderr (the results on stdout stay).
    assert!(
        String::from_utf8_lossy(&allowed.stderr).contains("WARN"),
        "{allowed:?}"
    );
    let quiet = run(&dir.path().join("quiet"), &["--allow-suspect", "-q"]);
    assert!(quiet.status.success(), "{quiet:?}");
    assert_eq!(String::from_utf8_lossy(&quiet.stderr), "");
    assert!(String::from_utf8_lossy(&quiet.stdout).contains("health: SUSPECT"));
}

/// The status is documented where a user looks for it.
#[test]
fn the_suspect_status_is_documented() {
    let help = Command::new(env!("CARGO_BIN_EXE_echofield"))
        .args(["run", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    let status = echofield::slam::health::SUSPECT_EXIT_STATUS;
    assert!(help.contains("--allow-suspect"), "{help}");
    assert!(
        help.contains(&format!("Exit status: 0 for an ok run; {status} when")),
        "{help}"
    );
    let readme =
        std::fs::read_to_string(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../README.md"))
            .unwrap();
    assert!(
        readme.contains(&format!("exits with status {status}")),
        "README"
    );
}

/// `echofield completions SHELL` prints a completion script that knows
/// the subcommands; `-q` and `-v` together are refused.
#[test]
fn completions_and_quiet_flag() {
    let echofield = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_echofield"))
            .args(args)
            .output()
            .unwrap()
    };
    let bash = echofield(&["completions", "bash"]);
    assert!(bash.status.success(), "{bash:?}");
    let script = String::from_utf8_lossy(&bash.stdout);
    assert!(
        script.contains("_echofield()") && script.contains("calibrate"),
        "{script}"
    );
    let zsh = echofield(&["completions", "zsh"]);
    assert!(String::from_utf8_lossy(&zsh.stdout).starts_with("#compdef echofield"));
    let both = echofield(&["-q", "-v", "completions", "bash"]);
    assert!(!both.status.success());
    assert!(
        String::from_utf8_lossy(&both.stderr).contains("cannot be used with"),
        "{both:?}"
    );
}

/// A ROS 2 recording as a rosbag2 folder (MCAP storage): `run` reads it,
/// lists what it did with each topic, and takes `--topic` choices.
#[test]
fn a_rosbag2_folder_runs_and_its_topics_are_listed() {
    use echofield_datasets::mcap::{Ros2GroundTruth, read_mission, write_mission_ros2};
    let dir = tempfile::tempdir().unwrap();
    let mission = read_mission(&simulated_tank(dir.path(), "3")).unwrap();
    let bag = dir.path().join("tank_bag");
    std::fs::create_dir(&bag).unwrap();
    write_mission_ros2(
        &bag.join("tank_bag_0.mcap"),
        &mission,
        Ros2GroundTruth::Odometry,
    )
    .unwrap();
    std::fs::write(
        bag.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  storage_identifier: mcap\n  relative_file_paths:\n  - tank_bag_0.mcap\n",
    )
    .unwrap();
    let run = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_echofield"))
            .arg("run")
            .arg(&bag)
            .arg("--output")
            .arg(dir.path().join("out"))
            .args(extra)
            .output()
            .unwrap()
    };
    let plain = run(&["--allow-suspect"]);
    assert!(plain.status.success(), "{plain:?}");
    let stdout = String::from_utf8_lossy(&plain.stdout);
    assert!(
        stdout.contains("topic /sonar/beam (echofield_msgs/msg/SonarBeam,")
            && stdout.contains("used as sonar: the only topic of its type"),
        "{stdout}"
    );
    assert!(stdout.contains("ATE RMSE"), "{stdout}");
    let chosen = run(&[
        "--allow-suspect",
        "--topic",
        "ground_truth=/ground_truth/odom",
    ]);
    assert!(String::from_utf8_lossy(&chosen.stdout).contains("chosen with --topic ground_truth"));
    let wrong = run(&["--topic", "dvl=/imu/data"]);
    assert!(!wrong.status.success());
    assert!(
        String::from_utf8_lossy(&wrong.stderr).contains("sensor_msgs/msg/Imu"),
        "{wrong:?}"
    );
}

/// `run --online`: the emitted estimates in `online_tum.txt`, one line per
/// node, and `report.json` → `online` with the latency per rotation and
/// the ATE of the emitted estimates (the tank has ground truth).
#[test]
fn online_run_writes_the_emitted_estimates_and_the_latency_report() {
    let dir = tempfile::tempdir().unwrap();
    let mission = simulated_tank(dir.path(), "4");
    let out = dir.path().join("online");
    let run = Command::new(env!("CARGO_BIN_EXE_echofield"))
        .arg("run")
        .arg(&mission)
        .args(["--online", "--allow-suspect", "--output"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(run.status.success(), "{run:?}");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains("nodes emitted"), "{stdout}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let online = &report["online"];
    let emitted = online["nodes_emitted"].as_u64().unwrap();
    assert_eq!(emitted, report["nodes"].as_u64().unwrap());
    let ms = |key: &str| {
        online[key]
            .as_f64()
            .unwrap_or_else(|| panic!("{key}: {online}"))
    };
    let (p50, p95, max) = (
        ms("latency_p50_ms"),
        ms("latency_p95_ms"),
        ms("latency_max_ms"),
    );
    assert!(0.0 < p50 && p50 <= p95 && p95 <= max, "{online}");
    let ate = ms("ate_rmse_m");
    assert!(ate.is_finite() && ate > 0.0, "{online}");
    let tum = std::fs::read_to_string(out.join("online_tum.txt")).unwrap();
    let lines: Vec<&str> = tum.lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(lines.len() as u64, emitted);
    for line in &lines {
        let fields: Vec<f64> = line
            .split_whitespace()
            .map(|f| f.parse().unwrap())
            .collect();
        assert_eq!(fields.len(), 8, "{line}");
    }
    // The batch run has no online section and no online_tum.txt.
    let batch = dir.path().join("batch");
    let run = Command::new(env!("CARGO_BIN_EXE_echofield"))
        .arg("run")
        .arg(&mission)
        .args(["--allow-suspect", "--output"])
        .arg(&batch)
        .output()
        .unwrap();
    assert!(run.status.success(), "{run:?}");
    assert!(!batch.join("online_tum.txt").exists());
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(batch.join("report.json")).unwrap()).unwrap();
    assert!(report.get("online").is_none());
}

/// `echofield run A B`: two missions give one output folder with a mission
/// column (whether or not the second is placed on the first, which the
/// library tests of `slam::multi` judge), and `--online` with two missions
/// is refused before anything is written.
#[test]
fn two_missions_write_one_folder_with_a_mission_column() {
    let dir = tempfile::tempdir().unwrap();
    let (da, db) = (dir.path().join("a"), dir.path().join("b"));
    std::fs::create_dir_all(&da).unwrap();
    std::fs::create_dir_all(&db).unwrap();
    let (a, b) = (simulated_tank(&da, "1"), simulated_tank(&db, "2"));

    let refused = dir.path().join("online");
    let online = Command::new(env!("CARGO_BIN_EXE_echofield"))
        .arg("run")
        .args([&a, &b])
        .arg("--online")
        .arg("--output")
        .arg(&refused)
        .output()
        .unwrap();
    assert!(!online.status.success());
    let stderr = String::from_utf8_lossy(&online.stderr);
    assert!(stderr.contains("--online runs one mission"), "{stderr}");
    assert!(!refused.exists() || refused.read_dir().unwrap().next().is_none());

    let out = dir.path().join("merged");
    let run = Command::new(env!("CARGO_BIN_EXE_echofield"))
        .arg("run")
        .args([&a, &b])
        .arg("--output")
        .arg(&out)
        .arg("--allow-suspect")
        .output()
        .unwrap();
    assert!(run.status.success(), "{run:?}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let missions = report["missions"].as_array().unwrap();
    assert_eq!(missions.len(), 2);
    let poses = std::fs::read_to_string(out.join("poses.csv")).unwrap();
    let mut lines = poses.lines();
    assert!(
        lines.next().unwrap().starts_with("mission,node,"),
        "{poses}"
    );
    for (k, mission) in missions.iter().enumerate() {
        let nodes = mission["nodes"].as_u64().unwrap() as usize;
        assert!(nodes > 0);
        let id = format!("{}", k + 1);
        let rows = poses
            .lines()
            .skip(1)
            .filter(|l| l.split(',').next() == Some(id.as_str()))
            .count();
        assert_eq!(rows, nodes, "mission {id}");
        let tum = std::fs::read_to_string(out.join(format!("trajectory_{id}_tum.txt"))).unwrap();
        assert_eq!(tum.lines().count(), nodes, "mission {id}");
    }
    // `run`'s mosaic and MCAP, for both missions (the library tests of
    // `slam::multi` check their content).
    let anchor = report["anchor"].as_u64().unwrap();
    assert!(anchor == 1 || anchor == 2, "{report}");
    assert!(image::open(out.join("mosaic.png")).is_ok());
    // An MCAP file: the magic at both ends.
    let bytes = std::fs::read(out.join("mission.mcap")).unwrap();
    let magic = b"\x89MCAP0\r\n";
    assert!(bytes.starts_with(magic) && bytes.ends_with(magic));
}

/// `echofield simulate` of `scenario` with `seed` and the simulator config
/// `config` (TOML) into `dir/NAME.mcap`.
fn simulated_with(dir: &Path, scenario: &str, seed: &str, config: &Path, name: &str) -> PathBuf {
    let mission = dir.join(format!("{name}.mcap"));
    let simulate = Command::new(env!("CARGO_BIN_EXE_echofield"))
        .args([
            "simulate",
            "--scenario",
            scenario,
            "--seed",
            seed,
            "--config",
        ])
        .arg(config)
        .arg("--output")
        .arg(&mission)
        .output()
        .unwrap();
    assert!(simulate.status.success(), "{simulate:?}");
    mission
}

/// `echofield run A B --output OUT`: its report and its standard output.
fn run_two(a: &Path, b: &Path, out: &Path) -> (serde_json::Value, String) {
    let run = Command::new(env!("CARGO_BIN_EXE_echofield"))
        .arg("run")
        .args([a, b])
        .arg("--output")
        .arg(out)
        .arg("--allow-suspect")
        .output()
        .unwrap();
    assert!(run.status.success(), "{run:?}");
    let report =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    (report, String::from_utf8_lossy(&run.stdout).into_owned())
}

/// `echofield run A B` takes the position fixes of the missions' MCAP
/// (`/position/fix`, written by the simulator's `[gps]`: noisy surface
/// fixes in the simulated world both missions share) as the placement
/// prior: with right fixes the prior is used and confirmed by the sonar;
/// with one mission's fixes shifted 30 m (far beyond their sigma) the
/// prior is rejected, said so in the summary, the report and a warning,
/// and the mission is still merged from its scans.
#[test]
fn position_fixes_in_the_missions_are_the_merge_prior_and_wrong_ones_are_reported() {
    use echofield_datasets::mcap::{read_mission, write_mission};
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("gps.toml");
    std::fs::write(
        &config,
        "[gps]\nperiod_s = 5.0\nnoise_std_m = 1.5\nsurface_s = 300.0\n",
    )
    .unwrap();
    let a = simulated_with(dir.path(), "marina", "1", &config, "a");
    let b = simulated_with(dir.path(), "marina", "2", &config, "b");
    let fixes_of = |path: &Path| read_mission(path).unwrap().position_fixes;
    assert!(fixes_of(&a).len() >= 100 && fixes_of(&b).len() >= 100);

    let (report, stdout) = run_two(&a, &b, &dir.path().join("right"));
    eprintln!("{stdout}");
    assert_eq!(report["merged"], true, "{report}");
    let anchor = report["anchor"].as_u64().unwrap() as usize;
    let other = 3 - anchor;
    let mission = |report: &serde_json::Value, m: usize| report["missions"][m - 1].clone();
    for m in [anchor, other] {
        assert_eq!(
            mission(&report, m)["position_fixes"].as_u64().unwrap() as usize,
            fixes_of(if m == 1 { &a } else { &b }).len()
        );
    }
    assert_eq!(mission(&report, anchor)["fix_prior"], "map");
    assert_eq!(
        mission(&report, other)["fix_prior"],
        "confirmed",
        "{report}"
    );
    let check = &mission(&report, other)["placement"]["prior"];
    assert_eq!(check["bounded"], true, "{check}");
    assert!(stdout.contains("confirmed by the sonar"), "{stdout}");
    assert_eq!(report["warnings"].as_array().unwrap().len(), 0, "{report}");

    // The other mission's fixes 30 m east of where it was.
    let other_path = if other == 1 { &a } else { &b };
    let mut shifted = read_mission(other_path).unwrap();
    for f in &mut shifted.position_fixes {
        f.x_m += 30.0;
    }
    let wrong = dir.path().join("wrong.mcap");
    write_mission(&wrong, &shifted).unwrap();
    let (first, second) = if other == 1 {
        (&wrong, &b)
    } else {
        (&a, &wrong)
    };
    let (report, stdout) = run_two(first, second, &dir.path().join("wrong"));
    eprintln!("{stdout}");
    assert_eq!(mission(&report, other)["fix_prior"], "rejected", "{report}");
    let check = &mission(&report, other)["placement"]["prior"];
    assert_eq!(check["consistent"], false, "{check}");
    assert!(check["offset_m"].as_f64().unwrap() > 20.0, "{check}");
    assert!(stdout.contains("REJECTED"), "{stdout}");
    let warnings = report["warnings"].as_array().unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.as_str().unwrap().contains("not trusted")),
        "{warnings:?}"
    );
    assert_eq!(report["merged"], true, "{report}");
    assert_eq!(mission(&report, other)["merged"], true, "{report}");
}
