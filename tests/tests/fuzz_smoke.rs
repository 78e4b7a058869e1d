//! A short pass of every parser fuzz target (`echofield::fuzz`): a fixed
//! number of seeded inputs each, none of which may panic or hang. The long
//! runs use the `echofield-fuzz` binary (README, "Fuzzing").

use echofield::fuzz::{FuzzOptions, fuzz_target, target, targets::TARGET_NAMES};
use std::time::Duration;

/// Inputs per target: enough to reach every mutation and generator branch
/// a few times, few enough for a debug build to finish in seconds.
const INPUTS: u64 = 400;

fn short_pass(name: &str) {
    let options = FuzzOptions {
        seed: 20_240_825,
        max_inputs: Some(INPUTS),
        duration: None,
        timeout: Duration::from_secs(20),
        findings_dir: None,
        generated_share: 0.3,
    };
    let target = target(name).expect("known target");
    let report = fuzz_target(target, &options).expect("the fuzz harness runs");
    println!("{}", report.summary());
    assert_eq!(report.inputs, INPUTS, "{}", report.summary());
    // Both kinds of outcome must occur, or the inputs miss the parser: all
    // rejected means the generator or the seeds are broken, all accepted
    // means the mutations do not reach it.
    assert!(report.errors > 0, "no input rejected: {}", report.summary());
    assert!(
        report.accepted > 0,
        "no input accepted: {}",
        report.summary()
    );
    let findings: Vec<String> = report
        .findings
        .iter()
        .map(|f| format!("{} on input {}: {}", f.kind, f.input_index, f.message))
        .collect();
    assert!(
        findings.is_empty(),
        "{}\n{}",
        report.summary(),
        findings.join("\n")
    );
}

#[test]
fn every_target_is_listed() {
    for name in TARGET_NAMES {
        assert!(target(name).is_some(), "{name}");
    }
    assert!(target("nope").is_none());
}

#[test]
fn fuzz_g2o() {
    short_pass("g2o");
}

#[test]
fn fuzz_toro() {
    short_pass("toro");
}

#[test]
fn fuzz_tum() {
    short_pass("tum");
}

#[test]
fn fuzz_mcap() {
    short_pass("mcap");
}

#[test]
fn fuzz_stpere() {
    short_pass("stpere");
}

#[test]
fn fuzz_keyframes() {
    short_pass("keyframes");
}

#[test]
fn fuzz_ping360() {
    short_pass("ping360");
}

#[test]
fn fuzz_miniking() {
    short_pass("miniking");
}

#[test]
fn fuzz_config() {
    short_pass("config");
}

#[test]
fn the_same_seed_gives_the_same_counts() {
    let options = FuzzOptions {
        seed: 5,
        max_inputs: Some(60),
        ..FuzzOptions::default()
    };
    let run = || {
        let r = fuzz_target(target("tum").expect("tum"), &options).expect("runs");
        (r.inputs, r.accepted, r.errors, r.panics, r.hangs)
    };
    assert_eq!(run(), run());
}
