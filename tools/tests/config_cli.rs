//! `echofield config`: the printed defaults are a config file that
//! `echofield run --config` accepts, and a bad `--section` is one clear
//! error line.

use echofield::slam::SlamConfig;
use std::path::PathBuf;
use std::process::Command;

fn echofield(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_echofield"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn the_printed_defaults_are_a_config_that_run_accepts() {
    let printed = echofield(&["config"]);
    assert!(printed.status.success(), "{printed:?}");
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("my.toml");
    std::fs::write(&file, &printed.stdout).unwrap();
    assert_eq!(
        SlamConfig::from_toml_file(&file).unwrap(),
        SlamConfig::default()
    );

    let mission =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../datasets/samples/tank-seed1.mcap");
    let out = dir.path().join("run");
    let run = Command::new(env!("CARGO_BIN_EXE_echofield"))
        .arg("run")
        .arg(&mission)
        .arg("--config")
        .arg(&file)
        .arg("--output")
        .arg(&out)
        .arg("--allow-suspect")
        .output()
        .unwrap();
    assert!(run.status.success(), "{run:?}");
    let effective = SlamConfig::from_toml_file(&out.join("config.toml")).unwrap();
    assert_eq!(effective.loops, SlamConfig::default().loops);
    assert_eq!(effective.matcher, SlamConfig::default().matcher);
}

#[test]
fn one_section_and_its_keys() {
    let loops = echofield(&["config", "--section", "loops"]);
    assert!(loops.status.success(), "{loops:?}");
    let text = String::from_utf8(loops.stdout).unwrap();
    assert!(text.contains("\nmax_window = ["), "{text}");
    assert_eq!(
        SlamConfig::from_toml_str(&text).unwrap(),
        SlamConfig::default()
    );

    let keys = echofield(&["config", "--section", "loops.gate", "--list-keys"]);
    assert!(keys.status.success(), "{keys:?}");
    assert_eq!(
        String::from_utf8(keys.stdout).unwrap(),
        "loops.gate.max_window\nloops.gate.min_mean_intensity\nloops.gate.min_sigma\n\
         loops.gate.min_window\nloops.gate.n_sigma\nloops.gate.reverse_max_translation_m\n"
    );
}

#[test]
fn an_unknown_section_is_one_error_line_naming_it() {
    let bad = echofield(&["config", "--section", "loop"]);
    assert!(!bad.status.success());
    let stderr = String::from_utf8(bad.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("no config section `loop`"), "{stderr}");
    assert!(stderr.contains("loops"), "{stderr}");
    assert!(bad.stdout.is_empty());
}
