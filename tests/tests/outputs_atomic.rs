//! The output folder is written whole: a failure while writing leaves the
//! previous output as it was (or no folder at all) and no temporary file
//! or folder behind; what is written does not depend on the threads.

use echofield::output::folder::OutputFolder;
use echofield::slam::outputs::demo::simulated_run;
use echofield::slam::outputs::{FOLDER_FILES, write_output_files, write_outputs};
use echofield::slam::{SlamConfig, SlamOutput};
use echofield_frontend::sensors::Mission;
use std::collections::BTreeMap;
use std::path::Path;

/// The outputs written before `mosaic.png` and after it (module doc of
/// `slam::outputs`).
const BEFORE: [&str; 13] = [
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
    "trajectory_error.png",
    "loops.png",
];
const AFTER: [&str; 3] = ["mosaic.pgw", "mission.mcap", "report.json"];

fn run() -> (Mission, SlamOutput) {
    simulated_run("tank", 2, &SlamConfig::default()).unwrap()
}

/// Entries named like echofield's temporary files and folders.
fn temporary_files(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.starts_with(".echofield-") || name.ends_with(".tmp"))
        .collect()
}

/// Every file of `dir` by name.
fn snapshot(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect()
}

/// Writes `output` into a fresh folder for `target` in which `mosaic.png`
/// cannot be written (a folder sits at its path), so that writing fails
/// after the files before it.
fn write_failing_at_the_mosaic(target: &Path, output: &SlamOutput, mission: &Mission) -> String {
    let folder = OutputFolder::prepare(target, FOLDER_FILES).unwrap();
    std::fs::create_dir(folder.path().join("mosaic.png")).unwrap();
    std::fs::write(folder.path().join("mosaic.png").join("keep"), b"x").unwrap();
    let err = write_output_files(folder.path(), output, mission).unwrap_err();
    // Written up to the failure.
    for name in BEFORE {
        assert!(folder.path().join(name).is_file(), "{name} missing");
    }
    format!("{err:#}")
    // `folder` is dropped here, uncommitted.
}

#[test]
fn failure_midway_keeps_the_previous_output_whole_and_leaves_no_temporary_file() {
    let (mission, output) = run();
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("out");

    // A first complete run.
    write_outputs(&target, &output, &mission).unwrap();
    let previous = snapshot(&target);
    for name in BEFORE.iter().chain(&AFTER) {
        assert!(previous.contains_key(*name), "{name} missing");
    }

    // A second run with a different config and report fails midway.
    let mut changed = output.clone();
    changed.config.loops.min_separation_nodes += 3;
    changed.report.mission = "second run".into();
    let err = write_failing_at_the_mosaic(&target, &changed, &mission);
    assert!(err.contains("mosaic.png"), "{err}");

    // The target is the first run's output, byte for byte, and nothing else
    // is left beside it or in it.
    assert!(snapshot(&target) == previous, "the previous output changed");
    assert!(temporary_files(&target).is_empty());
    assert!(
        temporary_files(dir.path()).is_empty(),
        "{:?}",
        temporary_files(dir.path())
    );
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn failure_in_a_fresh_folder_leaves_no_folder() {
    let (mission, output) = run();
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("a/b/out");
    let err = write_failing_at_the_mosaic(&target, &output, &mission);
    assert!(err.contains("mosaic.png"), "{err}");
    // Neither the target nor the parents created for it are left.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
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
