//! Issue 35: what the CLI prints for bad text input, each case with its
//! minimal input. Every error names file, line and field, once, and the
//! exit status is non-zero; no NaN is printed as a result.

use std::path::Path;
use std::process::{Command, Output};

fn echofield(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_echofield"))
        .args(args)
        .output()
        .unwrap()
}

/// The standard error of a run that must fail.
fn failure(run: &Output) -> String {
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    assert!(!run.status.success(), "succeeded:\n{stderr}");
    stderr
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> String {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path.to_str().unwrap().to_string()
}

const TUM: &str = "1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 1\n3.0 2 0 0 0 0 0 1\n";

#[test]
fn a_graph_error_is_printed_once() {
    let dir = tempfile::tempdir().unwrap();
    let graph = write(
        dir.path(),
        "dup.g2o",
        b"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 0 1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n",
    );
    let out = dir.path().join("out.g2o");
    let stderr = failure(&echofield(&[
        "optimize",
        &graph,
        "--output",
        out.to_str().unwrap(),
    ]));
    assert_eq!(stderr.matches("duplicate node id 0").count(), 1, "{stderr}");
    assert!(stderr.contains("dup.g2o:2"), "{stderr}");
}

#[test]
fn invalid_utf8_and_a_bom_in_a_graph() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.g2o");
    let bad = write(
        dir.path(),
        "bad.g2o",
        b"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 \xff 0 0\n",
    );
    let stderr = failure(&echofield(&[
        "optimize",
        &bad,
        "--output",
        out.to_str().unwrap(),
    ]));
    assert!(
        stderr.contains("bad.g2o:2") && stderr.contains("byte 32"),
        "{stderr}"
    );
    assert!(
        !stderr.contains("stream did not contain valid UTF-8"),
        "{stderr}"
    );
    let bom = write(
        dir.path(),
        "bom.g2o",
        b"\xEF\xBB\xBFVERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\nFIX 0\n",
    );
    let run = echofield(&["optimize", &bom, "--output", out.to_str().unwrap()]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
}

#[test]
fn a_huge_tum_value_is_an_error_not_a_nan_ate() {
    let dir = tempfile::tempdir().unwrap();
    let estimate = write(dir.path(), "est.txt", TUM.as_bytes());
    let reference = write(
        dir.path(),
        "ref.txt",
        TUM.replace("2.0 1 0", "2.0 1e308 0").as_bytes(),
    );
    let run = echofield(&["eval", "--estimate", &estimate, "--reference", &reference]);
    let stderr = failure(&run);
    assert!(
        stderr.contains("ref.txt:2") && stderr.contains("`x`"),
        "{stderr}"
    );
    assert!(!String::from_utf8_lossy(&run.stdout).contains("NaN"));
}

#[test]
fn eval_refuses_distances_and_time_differences_that_are_not_positive() {
    let dir = tempfile::tempdir().unwrap();
    let estimate = write(dir.path(), "est.txt", TUM.as_bytes());
    let base = ["eval", "--estimate", &estimate, "--reference", &estimate];
    let mut args = base.to_vec();
    args.push("--rpe-distances=-10,0");
    let stderr = failure(&echofield(&args));
    assert!(stderr.contains("--rpe-distances"), "{stderr}");
    let mut args = base.to_vec();
    args.extend(["--max-time-diff", "NaN"]);
    let stderr = failure(&echofield(&args));
    assert!(stderr.contains("--max-time-diff"), "{stderr}");
    // The same files with sound options evaluate to 0.
    let run = echofield(&base);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(String::from_utf8_lossy(&run.stdout).contains("rmse 0.000000"));
}

/// The pipeline's errors that wrap another (a frontend stage's, the pose
/// graph's, the solver's) print its text once in a `{:#}` chain.
#[test]
fn slam_errors_print_the_inner_message_once() {
    use echofield::slam::SlamError;
    let frontend = SlamError::frontend(
        "dead reckoning",
        echofield_frontend::FrontendError::InvalidInput {
            record: "DVL sample 3".into(),
            field: "velocity".into(),
            message: "not finite".into(),
        },
    );
    let graph = SlamError::from(echofield_graph::GraphError::DuplicateNode { id: 7 });
    for (err, inner) in [(frontend, "DVL sample 3"), (graph, "duplicate node id 7")] {
        let chain = format!("{:#}", anyhow::Error::new(err));
        assert_eq!(chain.matches(inner).count(), 1, "{chain}");
    }
}
