//! Whole output folders (issue 35, item 4), through the built `echofield`
//! binary on a short simulated mission: a run killed with SIGKILL at
//! several moments leaves its target either the previous complete output
//! or the new complete one, and the next run removes what it left; a full
//! disk (a file-size limit, and a small tmpfs where the machine allows
//! mounting one) keeps the previous output and leaves no temporary file;
//! unwritable and impossible output paths fail at once with an error that
//! names them; `report.json` → `run` says which run wrote the folder.

use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant, SystemTime};

const BIN: &str = env!("CARGO_BIN_EXE_echofield");

/// `echofield simulate` of the tank scenario (seed 1) into `dir/tank.mcap`.
fn simulated_tank(dir: &Path) -> PathBuf {
    let mission = dir.join("tank.mcap");
    let out = Command::new(BIN)
        .args(["simulate", "--scenario", "tank", "--seed", "1", "--output"])
        .arg(&mission)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    mission
}

fn run_command(mission: &Path, out: &Path) -> Command {
    let mut command = Command::new(BIN);
    command
        .arg("run")
        .arg(mission)
        .arg("--output")
        .arg(out)
        .arg("--allow-suspect")
        .env_remove("RUST_LOG");
    command
}

fn run(mission: &Path, out: &Path) -> Output {
    run_command(mission, out).output().unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Every file of `dir` by name (empty when `dir` does not exist).
fn snapshot(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return BTreeMap::new();
    };
    entries
        .map(|e| {
            let e = e.unwrap();
            assert!(e.file_type().unwrap().is_file(), "{:?}", e.path());
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect()
}

/// Entries of `dir` named like echofield's temporary files and folders.
fn temporaries(dir: &Path) -> Vec<String> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    entries
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(".echofield-"))
        .collect()
}

fn report(bytes: &[u8]) -> Value {
    serde_json::from_slice(bytes).unwrap()
}

/// `report.json` without what differs between two runs of the same input
/// and config: the `run` block and the wall times (`timings`, every
/// `time_s` and `..._time_s`; README, "Output folders").
fn comparable(mut report: Value) -> Value {
    fn strip_times(v: &mut Value) {
        match v {
            Value::Object(map) => {
                map.retain(|k, _| !(k == "time_s" || k.ends_with("_time_s") || k == "timings"));
                map.values_mut().for_each(strip_times);
            }
            Value::Array(items) => items.iter_mut().for_each(strip_times),
            _ => {}
        }
    }
    report.as_object_mut().unwrap().remove("run");
    strip_times(&mut report);
    report
}

fn run_id(snapshot: &BTreeMap<String, Vec<u8>>) -> Option<String> {
    let bytes = snapshot.get("report.json")?;
    report(bytes)["run"]["id"].as_str().map(str::to_string)
}

/// Whether `snap` is a complete output of the run that gave `reference`:
/// the same files, byte for byte but for the comparable `report.json`.
fn is_complete(snap: &BTreeMap<String, Vec<u8>>, reference: &BTreeMap<String, Vec<u8>>) -> bool {
    snap.keys().eq(reference.keys())
        && snap.iter().all(|(name, bytes)| {
            if name == "report.json" {
                comparable(report(bytes)) == comparable(report(&reference[name]))
            } else {
                *bytes == reference[name]
            }
        })
}

/// When to kill a run.
#[derive(Clone, Copy, Debug)]
enum Moment {
    /// This long after the start.
    After(Duration),
    /// When the fresh folder beside the target appears.
    FreshFolder,
    /// When an entry whose name ends with this appears in the fresh folder.
    FreshEntry(&'static str),
    /// When the target holds another run's report.
    Swapped,
}

/// The fresh folder of process `pid` beside `out`, if there is one.
fn fresh_folder(out: &Path, pid: u32) -> Option<PathBuf> {
    let prefix = format!(".echofield-{pid}-");
    let name = out.file_name().unwrap().to_str().unwrap();
    std::fs::read_dir(out.parent().unwrap())
        .ok()?
        .filter_map(|e| e.ok())
        .find(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            n.starts_with(&prefix) && n.ends_with(&format!(".new-{name}"))
        })
        .map(|e| e.path())
}

fn reached(
    moment: Moment,
    out: &Path,
    pid: u32,
    start: Instant,
    previous: &Option<String>,
) -> bool {
    match moment {
        Moment::After(d) => start.elapsed() >= d,
        Moment::FreshFolder => fresh_folder(out, pid).is_some(),
        Moment::FreshEntry(suffix) => fresh_folder(out, pid)
            .and_then(|f| std::fs::read_dir(f).ok())
            .is_some_and(|mut entries| {
                entries.any(|e| e.is_ok_and(|e| e.file_name().to_string_lossy().ends_with(suffix)))
            }),
        Moment::Swapped => {
            let id = std::fs::read(out.join("report.json"))
                .ok()
                .and_then(|b| serde_json::from_slice::<Value>(&b).ok())
                .and_then(|v| v["run"]["id"].as_str().map(str::to_string));
            id.is_some() && id != *previous
        }
    }
}

/// Runs into `out` and kills the run with SIGKILL at `moment`; whether the
/// run had finished before.
fn kill_at(mission: &Path, out: &Path, moment: Moment) -> bool {
    let previous = run_id(&snapshot(out));
    let mut child = run_command(mission, out)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            return true;
        }
        if reached(moment, out, child.id(), start, &previous) {
            child.kill().unwrap();
            child.wait().unwrap();
            return false;
        }
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "{moment:?} never came"
        );
        std::thread::sleep(Duration::from_micros(500));
    }
}

#[test]
fn a_run_killed_at_any_moment_leaves_the_previous_or_the_new_output_whole() {
    let dir = tempfile::tempdir().unwrap();
    let mission = simulated_tank(dir.path());
    let work = dir.path().join("work");
    std::fs::create_dir(&work).unwrap();
    let out = work.join("out");

    // The reference: a complete output, and how long a run takes.
    let t = Instant::now();
    let first = run(&mission, &out);
    let full = t.elapsed();
    assert!(first.status.success(), "{}", stderr(&first));
    let reference = snapshot(&out);
    assert!(reference.len() >= 12, "{:?}", reference.keys());
    assert!(temporaries(&work).is_empty());

    let moments = [
        Moment::After(Duration::ZERO),
        Moment::FreshFolder,
        Moment::FreshEntry("config.toml"),
        Moment::FreshEntry(".mcap.tmp"),
        Moment::FreshEntry("mosaic.png"),
        Moment::FreshEntry("report.json"),
        Moment::Swapped,
        Moment::After(full.mul_f64(0.3)),
        Moment::After(full.mul_f64(0.7)),
        Moment::After(full.mul_f64(0.95)),
    ];
    let mut left_temporaries = 0;
    for moment in moments {
        let previous = snapshot(&out);
        let finished = kill_at(&mission, &out, moment);
        let after = snapshot(&out);
        let state = if after == previous {
            "previous"
        } else {
            assert!(
                is_complete(&after, &reference) && run_id(&after) != run_id(&previous),
                "{moment:?}: the target is neither the previous output nor a new complete one: {:?}",
                after.keys()
            );
            "new"
        };
        let stale = temporaries(&work);
        println!(
            "killed at {moment:?}: target {state}, {} temporary entries left{}",
            stale.len(),
            if finished {
                " (the run had finished)"
            } else {
                ""
            }
        );
        left_temporaries += stale.len();

        // The next run succeeds, says what it removed and leaves nothing.
        let next = run(&mission, &out);
        assert!(next.status.success(), "{}", stderr(&next));
        if !stale.is_empty() {
            assert!(
                stderr(&next).contains("left by an interrupted echofield run"),
                "{moment:?}: {}",
                stderr(&next)
            );
        }
        assert!(temporaries(&work).is_empty(), "{:?}", temporaries(&work));
        assert!(temporaries(&out).is_empty());
        assert!(is_complete(&snapshot(&out), &reference));
        let entries: Vec<_> = std::fs::read_dir(&work).unwrap().collect();
        assert_eq!(entries.len(), 1, "only the output folder in {work:?}");
    }
    // Kills while the fresh folder existed left it behind (kill -9 cannot
    // clean up), and the runs after them removed it.
    assert!(left_temporaries >= 1);
}

/// Two runs into one target at the same time: neither removes the other's
/// fresh folder (its process is alive), both succeed, and the target is
/// one complete output.
#[test]
fn two_runs_into_one_target_at_once_leave_one_complete_output() {
    let dir = tempfile::tempdir().unwrap();
    let mission = simulated_tank(dir.path());
    let reference_dir = dir.path().join("reference");
    assert!(run(&mission, &reference_dir).status.success());
    let reference = snapshot(&reference_dir);
    let work = dir.path().join("work");
    let out = work.join("out");
    let children: Vec<_> = (0..2)
        .map(|_| {
            run_command(&mission, &out)
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for child in children {
        let done = child.wait_with_output().unwrap();
        assert!(done.status.success(), "{}", stderr(&done));
    }
    assert!(is_complete(&snapshot(&out), &reference));
    assert!(temporaries(&work).is_empty(), "{:?}", temporaries(&work));
}

/// A command `echofield ARGS` under bash with the file-size limit `kib`
/// KiB, SIGXFSZ ignored so that a write past the limit fails with EFBIG
/// (as on a full disk) rather than killing the process.
fn limited(kib: u64, args: &[std::ffi::OsString]) -> Command {
    let mut command = Command::new("bash");
    command
        .arg("-c")
        .arg(format!("trap '' XFSZ; ulimit -f {kib}; exec \"$0\" \"$@\""))
        .arg(BIN)
        .args(args)
        .env_remove("RUST_LOG");
    command
}

#[test]
fn writes_that_fail_midway_keep_the_previous_output_and_leave_no_temporary_file() {
    if Command::new("bash").arg("-c").arg("true").status().is_err() {
        println!("skipped: no bash");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mission = simulated_tank(dir.path());
    let work = dir.path().join("work");
    let out = work.join("out");
    let first = run(&mission, &out);
    assert!(first.status.success(), "{}", stderr(&first));
    let previous = snapshot(&out);
    // A limit that the tables written first fit under and the plots and
    // the MCAP do not: writing fails midway.
    let kib = 64;
    let too_large: Vec<&String> = previous
        .iter()
        .filter(|(_, b)| b.len() > 1024 * kib as usize)
        .map(|(n, _)| n)
        .collect();
    assert!(
        !too_large.is_empty() && previous.len() > too_large.len() + 5,
        "{too_large:?}"
    );
    let args = |out: &Path| -> Vec<std::ffi::OsString> {
        vec![
            "run".into(),
            mission.clone().into(),
            "--output".into(),
            out.into(),
            "--allow-suspect".into(),
        ]
    };
    let a = args(&out);
    let failed = limited(kib, &a).output().unwrap();
    assert!(!failed.status.success());
    let message = stderr(&failed);
    assert!(
        message.contains("File too large")
            && too_large.iter().any(|n| message.contains(n.as_str())),
        "{message}"
    );
    assert_eq!(message.matches("error:").count(), 1, "{message}");
    assert!(snapshot(&out) == previous, "the previous output changed");
    assert!(temporaries(&work).is_empty(), "{:?}", temporaries(&work));

    // Into a new folder under new parents: nothing is left at all.
    let fresh = dir.path().join("new/parents/out");
    let a = args(&fresh);
    let failed = limited(kib, &a).output().unwrap();
    assert!(!failed.status.success(), "{}", stderr(&failed));
    assert!(!dir.path().join("new").exists());
}

/// A tmpfs mounted for the test, unmounted when dropped.
struct Tmpfs(PathBuf);

impl Tmpfs {
    /// `None` where mounting is not allowed (not root, no CAP_SYS_ADMIN).
    fn mount(path: &Path, size_kib: u64) -> Option<Self> {
        std::fs::create_dir_all(path).unwrap();
        let ok = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size_kib}k"), "tmpfs"])
            .arg(path)
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        ok.then(|| Self(path.to_path_buf()))
    }

    fn read_only(&self) {
        let status = Command::new("mount")
            .args(["-o", "remount,ro"])
            .arg(&self.0)
            .status()
            .unwrap();
        assert!(status.success());
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.0).status();
    }
}

/// On a small tmpfs that holds one output but not two: the second run
/// fails with a full disk and the first output survives whole; remounted
/// read-only, a run fails at once, before reading its mission.
#[test]
fn a_full_and_a_read_only_file_system_keep_the_previous_output() {
    let dir = tempfile::tempdir().unwrap();
    let mission = simulated_tank(dir.path());
    let reference_dir = dir.path().join("reference");
    assert!(run(&mission, &reference_dir).status.success());
    let total: usize = snapshot(&reference_dir).values().map(Vec::len).sum();
    let size_kib = (total as u64 * 3 / 2) / 1024 + 64;
    let Some(disk) = Tmpfs::mount(&dir.path().join("disk"), size_kib) else {
        println!("skipped: cannot mount a tmpfs here");
        return;
    };
    let out = disk.0.join("out");
    let first = run(&mission, &out);
    assert!(first.status.success(), "{}", stderr(&first));
    let previous = snapshot(&out);
    assert!(is_complete(&previous, &snapshot(&reference_dir)));

    let full = run(&mission, &out);
    assert!(!full.status.success());
    let message = stderr(&full);
    assert!(message.contains("No space left on device"), "{message}");
    assert!(snapshot(&out) == previous);
    assert!(
        temporaries(&disk.0).is_empty(),
        "{:?}",
        temporaries(&disk.0)
    );

    disk.read_only();
    let missing = dir.path().join("missing.mcap");
    let read_only = run(&missing, &out);
    assert!(!read_only.status.success());
    let message = stderr(&read_only);
    assert!(
        message.contains(&out.display().to_string())
            && message.contains("Read-only file system")
            && !message.contains("missing.mcap"),
        "{message}"
    );
    assert!(snapshot(&out) == previous);
}

/// Whether permission bits stop this user (not for root).
fn permissions_bite(dir: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    let probe = dir.join("probe");
    std::fs::create_dir(&probe).unwrap();
    std::fs::set_permissions(&probe, std::fs::Permissions::from_mode(0o555)).unwrap();
    let bites = std::fs::write(probe.join("x"), b"x").is_err();
    std::fs::set_permissions(&probe, std::fs::Permissions::from_mode(0o755)).unwrap();
    std::fs::remove_dir_all(&probe).unwrap();
    bites
}

#[test]
fn a_read_only_folder_fails_at_once_naming_it() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    if !permissions_bite(dir.path()) {
        println!("skipped: permission bits do not stop this user (root)");
        return;
    }
    let parent = dir.path().join("ro");
    std::fs::create_dir(&parent).unwrap();
    std::fs::set_permissions(&parent, std::fs::Permissions::from_mode(0o555)).unwrap();
    // The mission does not exist: an error about it would mean that the
    // output was checked after reading it.
    let missing = dir.path().join("missing.mcap");
    let out = run(&missing, &parent.join("out"));
    std::fs::set_permissions(&parent, std::fs::Permissions::from_mode(0o755)).unwrap();
    assert!(!out.status.success());
    let message = stderr(&out);
    assert!(
        message.contains(&parent.join("out").display().to_string())
            && message.contains("Permission denied")
            && !message.contains("missing.mcap"),
        "{message}"
    );
}

#[test]
fn impossible_outputs_fail_at_once_naming_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    let missing = dir.path().join("missing.mcap");
    let user = dir.path().join("mine");
    std::fs::create_dir(&user).unwrap();
    std::fs::write(user.join("notes.txt"), "keep me").unwrap();
    let long = dir.path().join("x".repeat(300));
    let cases: Vec<(Vec<std::ffi::OsString>, PathBuf, &str)> = vec![
        (
            vec![
                "run".into(),
                missing.clone().into(),
                "--output".into(),
                file.join("out").into(),
            ],
            file.clone(),
            "is a file, not a folder",
        ),
        (
            vec![
                "run".into(),
                missing.clone().into(),
                "--output".into(),
                file.clone().into(),
            ],
            file.clone(),
            "exists and is not a folder",
        ),
        (
            vec![
                "run".into(),
                missing.clone().into(),
                "--output".into(),
                user.clone().into(),
            ],
            user.clone(),
            "notes.txt",
        ),
        (
            vec![
                "run".into(),
                missing.clone().into(),
                "--output".into(),
                long.clone().into(),
            ],
            long.clone(),
            "File name too long",
        ),
        (
            vec!["demo".into(), "--output".into(), file.join("demo").into()],
            file.clone(),
            "is a file, not a folder",
        ),
        (
            vec![
                "optimize".into(),
                missing.clone().into(),
                "--output".into(),
                file.join("x.g2o").into(),
            ],
            file.join("x.g2o"),
            "is a file, not a folder",
        ),
        (
            vec![
                "simulate".into(),
                "--scenario".into(),
                "marina".into(),
                "--output".into(),
                dir.path().into(),
            ],
            dir.path().to_path_buf(),
            "is a folder",
        ),
        (
            vec![
                "convert".into(),
                "ping360".into(),
                missing.clone().into(),
                "--output".into(),
                file.join("b.mcap").into(),
            ],
            file.join("b.mcap"),
            "is a file, not a folder",
        ),
        (
            vec![
                "calibrate".into(),
                missing.clone().into(),
                "--output".into(),
                file.join("cal.toml").into(),
            ],
            file.join("cal.toml"),
            "is a file, not a folder",
        ),
        (
            vec![
                "eval".into(),
                "--estimate".into(),
                missing.clone().into(),
                "--reference".into(),
                missing.clone().into(),
                "--json".into(),
                file.join("ate.json").into(),
            ],
            file.join("ate.json"),
            "is a file, not a folder",
        ),
    ];
    for (args, path, words) in cases {
        let t = Instant::now();
        let out = Command::new(BIN).args(&args).output().unwrap();
        let message = stderr(&out);
        println!("{args:?}: {:.2} s: {message}", t.elapsed().as_secs_f64());
        assert!(!out.status.success(), "{args:?}");
        assert!(
            message.contains(&path.display().to_string()) && message.contains(words),
            "{args:?}: {message}"
        );
        // Checked before the input was read.
        assert!(!message.contains("missing.mcap"), "{args:?}: {message}");
        assert_eq!(message.lines().count(), 1, "{args:?}: {message}");
    }
    assert_eq!(
        std::fs::read_to_string(user.join("notes.txt")).unwrap(),
        "keep me"
    );
    assert_eq!(std::fs::read_dir(&user).unwrap().count(), 1);
    assert!(temporaries(dir.path()).is_empty());
}

/// A pid that no process has: one above the kernel's maximum.
fn dead_pid() -> u32 {
    std::fs::read_to_string("/proc/sys/kernel/pid_max")
        .ok()
        .and_then(|s| s.trim().parse::<u32>().ok())
        .unwrap_or(4_194_304)
        + 1
}

#[test]
fn temporary_files_of_killed_runs_beside_single_file_outputs_are_removed() {
    let dir = tempfile::tempdir().unwrap();
    let dead = dead_pid();
    let stale = dir
        .path()
        .join(format!(".echofield-{dead}-Ab12Cd.mcap.tmp"));
    std::fs::write(&stale, b"half a file").unwrap();
    let mission = simulated_tank(dir.path());
    assert!(mission.is_file() && !stale.exists());
    // Nothing else of echofield's is left beside it.
    assert!(
        temporaries(dir.path()).is_empty(),
        "{:?}",
        temporaries(dir.path())
    );
}

#[test]
fn report_json_names_the_run_and_differs_only_there_and_in_wall_times() {
    let dir = tempfile::tempdir().unwrap();
    let mission = simulated_tank(dir.path());
    let config = dir.path().join("c.toml");
    std::fs::write(&config, "[loops]\nmin_separation_nodes = 4\n").unwrap();
    let before = SystemTime::now();
    let outputs: Vec<BTreeMap<String, Vec<u8>>> = ["a", "b"]
        .iter()
        .map(|name| {
            let out = dir.path().join(name);
            let done = run_command(&mission, &out)
                .arg("--config")
                .arg(&config)
                .output()
                .unwrap();
            assert!(done.status.success(), "{}", stderr(&done));
            snapshot(&out)
        })
        .collect();
    let after = SystemTime::now();
    let (a, b) = (
        report(&outputs[0]["report.json"]),
        report(&outputs[1]["report.json"]),
    );
    let run = &a["run"];
    let start = humantime::parse_rfc3339(run["start_time_utc"].as_str().unwrap()).unwrap();
    assert!(before <= start && start <= after, "{run:#}");
    assert!(run["start_time_utc"].as_str().unwrap().ends_with('Z'));
    assert_eq!(run["command"], "run");
    assert_eq!(
        run["inputs"],
        serde_json::json!([mission.display().to_string()])
    );
    assert_eq!(run["config"], config.display().to_string());
    assert_eq!(run["output"], dir.path().join("a").display().to_string());
    assert_eq!(run["echofield_version"], env!("CARGO_PKG_VERSION"));
    assert_ne!(run["id"], b["run"]["id"]);
    // Everything else is the same; every other file, byte for byte.
    assert_eq!(comparable(a), comparable(b));
    assert!(is_complete(&outputs[1], &outputs[0]));
}
