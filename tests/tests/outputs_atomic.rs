//! A failure while writing the outputs leaves the files written before it
//! complete, the files after it untouched, and no temporary file behind.

use echofield::slam::outputs::demo::simulated_run;
use echofield::slam::outputs::write_outputs;
use echofield::slam::{SlamConfig, SlamOutput};
use echofield_frontend::sensors::Mission;
use echofield_graph::io::read_tum;
use std::path::Path;

/// The outputs written before `mosaic.png` and after it (module doc of
/// `slam::outputs`).
const BEFORE: [&str; 9] = [
    "config.toml",
    "trajectory_tum.txt",
    "dead_reckoning_tum.txt",
    "ground_truth_tum.txt",
    "poses.csv",
    "graph.g2o",
    "loops.csv",
    "trajectory.png",
    "loops.png",
];
const AFTER: [&str; 3] = ["mosaic.pgw", "mission.mcap", "report.json"];

fn run() -> (Mission, SlamOutput) {
    simulated_run("tank", 2, &SlamConfig::default()).unwrap()
}

fn temporary_files(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.starts_with(".echofield-") || name.ends_with(".tmp"))
        .collect()
}

#[test]
fn failure_midway_keeps_earlier_files_and_leaves_no_temporary_file() {
    let (mission, output) = run();
    let dir = tempfile::tempdir().unwrap();

    // A first complete run.
    write_outputs(dir.path(), &output, &mission).unwrap();
    let old_report = std::fs::read(dir.path().join("report.json")).unwrap();
    let old_mcap = std::fs::read(dir.path().join("mission.mcap")).unwrap();

    // Second run with a different config and report; `mosaic.png` cannot
    // be replaced because a folder now sits at its path.
    let mut changed = output.clone();
    changed.config.loops.min_separation_nodes += 3;
    changed.report.mission = "second run".into();
    std::fs::remove_file(dir.path().join("mosaic.png")).unwrap();
    std::fs::create_dir(dir.path().join("mosaic.png")).unwrap();
    std::fs::write(dir.path().join("mosaic.png").join("keep"), b"x").unwrap();
    let err = write_outputs(dir.path(), &changed, &mission).unwrap_err();
    assert!(format!("{err:#}").contains("mosaic.png"), "{err:#}");

    // Files before the failure are the new, complete ones.
    let config = std::fs::read_to_string(dir.path().join("config.toml")).unwrap();
    assert_eq!(SlamConfig::from_toml_str(&config).unwrap(), changed.config);
    for name in BEFORE {
        assert!(dir.path().join(name).is_file(), "{name} missing");
    }
    let tum = read_tum(&dir.path().join("trajectory_tum.txt")).unwrap();
    assert_eq!(tum.len(), output.nodes.len());
    image::open(dir.path().join("loops.png")).unwrap();
    // Files after it are the first run's, byte for byte.
    for name in AFTER {
        assert!(dir.path().join(name).is_file(), "{name} missing");
    }
    assert_eq!(
        std::fs::read(dir.path().join("report.json")).unwrap(),
        old_report
    );
    assert_eq!(
        std::fs::read(dir.path().join("mission.mcap")).unwrap(),
        old_mcap
    );
    assert!(
        temporary_files(dir.path()).is_empty(),
        "{:?}",
        temporary_files(dir.path())
    );
}

#[test]
fn failure_in_a_fresh_folder_writes_nothing_after_it() {
    let (mission, output) = run();
    let dir = tempfile::tempdir().unwrap();
    // The MCAP writer cannot rename onto a non-empty folder.
    std::fs::create_dir(dir.path().join("mission.mcap")).unwrap();
    std::fs::write(dir.path().join("mission.mcap").join("keep"), b"x").unwrap();
    let err = write_outputs(dir.path(), &output, &mission).unwrap_err();
    assert!(format!("{err:#}").contains("mission.mcap"), "{err:#}");
    for name in BEFORE.iter().chain(&["mosaic.png", "mosaic.pgw"]) {
        assert!(dir.path().join(name).is_file(), "{name} missing");
    }
    assert!(!dir.path().join("report.json").exists());
    assert!(
        temporary_files(dir.path()).is_empty(),
        "{:?}",
        temporary_files(dir.path())
    );
}

#[test]
fn the_outputs_do_not_depend_on_the_threads_that_write_them() {
    // `mission.mcap` is encoded beside the other files, its images in
    // parallel: one thread and three must give the same bytes.
    let (mission, output) = run();
    let write = |threads: usize| {
        let dir = tempfile::tempdir().unwrap();
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| write_outputs(dir.path(), &output, &mission))
            .unwrap();
        dir
    };
    let (one, three) = (write(1), write(3));
    for name in BEFORE.iter().chain(&AFTER).chain(&["mosaic.png"]) {
        let (a, b) = (one.path().join(name), three.path().join(name));
        if *name == "report.json" {
            // Only the writing time differs.
            let read = |p: &Path| -> serde_json::Value {
                let mut v: serde_json::Value =
                    serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap();
                v["timings"]["writing_s"] = serde_json::Value::Null;
                v
            };
            assert_eq!(read(&a), read(&b));
        } else {
            assert!(
                std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap(),
                "{name} differs"
            );
        }
    }
    assert!(temporary_files(three.path()).is_empty());
}
