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
