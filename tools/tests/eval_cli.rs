//! `echofield eval` rejects option values that cannot mean anything
//! (issue 35: `--rpe-distances=-10,0` and `--max-time-diff NaN` were
//! accepted, and the latter associated nothing).

use std::process::Command;

/// A two-pose TUM trajectory in `dir`.
fn trajectory(dir: &std::path::Path) -> std::path::PathBuf {
    let path = dir.join("t.txt");
    std::fs::write(&path, "0.0 0 0 0 0 0 0 1\n1.0 1 0 0 0 0 0 1\n").unwrap();
    path
}

fn eval(extra: &[&str]) -> (bool, String) {
    let dir = tempfile::tempdir().unwrap();
    let t = trajectory(dir.path());
    let out = Command::new(env!("CARGO_BIN_EXE_echofield"))
        .arg("eval")
        .arg("--estimate")
        .arg(&t)
        .arg("--reference")
        .arg(&t)
        .args(extra)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn meaningless_option_values_are_rejected_naming_the_option() {
    for (args, option) in [
        (&["--rpe-distances=-10,0"][..], "--rpe-distances"),
        (&["--rpe-distances", "10,0"][..], "--rpe-distances"),
        (&["--rpe-distances", "inf"][..], "--rpe-distances"),
        (&["--max-time-diff", "NaN"][..], "--max-time-diff"),
        (&["--max-time-diff=-1"][..], "--max-time-diff"),
    ] {
        let (ok, stderr) = eval(args);
        assert!(!ok, "{args:?} was accepted");
        assert!(stderr.contains(option), "{args:?}: {stderr}");
    }
    let (ok, stderr) = eval(&["--rpe-distances", "0.5", "--max-time-diff", "0.001"]);
    assert!(ok, "{stderr}");
}
