//! `echofield run` on input it cannot process: a one-line error and no
//! output.

use std::path::PathBuf;
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
