//! A fuzzing harness for every input parser, on the stable toolchain.
//!
//! Each [`Target`] names one reader (g2o, TORO, TUM, MCAP mission, St Pere
//! logs, St Pere keyframes, Ping360, MiniKing bag, config TOML) and knows
//! how to make inputs for it: structured random files built from the
//! format's own grammar, and mutations of the committed fixtures (byte
//! flips, truncation, splices, numbers replaced by 0, -1, 1e308, NaN or
//! huge integers, duplicated and removed lines; [`mutate`]). An input is a
//! set of named files; the harness writes them into a scratch folder and
//! calls the reader on it.
//!
//! Contract checked for every input: the reader returns (`Ok` or `Err`)
//! within the time limit and does not panic. Each input runs in a worker
//! thread under `catch_unwind`; the main thread waits at most
//! [`FuzzOptions::timeout`] and counts a hang when the worker does not
//! answer in time (the stuck worker is abandoned and a new one started,
//! and the target stops after [`MAX_HANGS`] hangs so that stuck threads do
//! not eat the machine). Panicking and hanging inputs are saved under
//! `findings/<target>/<kind>-<n>/`. An input that aborts the whole process
//! (an allocation failure) is left in `findings/<target>/current/`; the
//! next run finds the marker the dead run left, moves that input to
//! `findings/<target>/abort-<n>/` and reports it.
//!
//! Everything is seeded: the same seed and number of inputs give the same
//! inputs. Runs bounded by time (`--seconds`) differ only in how many
//! inputs they reach.
//!
//! Why not cargo-fuzz: it needs a nightly toolchain and libFuzzer; this
//! harness runs wherever the workspace builds, including the CI test
//! (`tests/tests/fuzz_smoke.rs`) and the `echofield-fuzz` binary
//! (README, "Fuzzing").

pub mod generate;
pub mod mutate;
pub mod targets;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub use targets::{Target, all_targets, target};

/// The target stops after this many hangs (each leaves a thread spinning).
pub const MAX_HANGS: usize = 2;

/// One fuzz input: files by name, written into one folder before parsing.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Input {
    pub files: Vec<(String, Vec<u8>)>,
}

impl Input {
    /// An input of one file.
    pub fn single(name: &str, bytes: Vec<u8>) -> Self {
        Self {
            files: vec![(name.to_string(), bytes)],
        }
    }

    /// Writes every file into `dir` (which must exist).
    pub fn write_to(&self, dir: &Path) -> std::io::Result<()> {
        for (name, bytes) in &self.files {
            std::fs::write(dir.join(name), bytes)?;
        }
        Ok(())
    }

    /// Total size in bytes.
    pub fn len(&self) -> usize {
        self.files.iter().map(|(_, b)| b.len()).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// How long and how hard to fuzz one target.
#[derive(Clone, Debug)]
pub struct FuzzOptions {
    /// Seed of every random choice.
    pub seed: u64,
    /// Stop after this many inputs (`None`: only the time limit).
    pub max_inputs: Option<u64>,
    /// Stop after this long (`None`: only the input limit).
    pub duration: Option<Duration>,
    /// Time one input may take before it counts as a hang.
    pub timeout: Duration,
    /// Where failing inputs are saved (`None`: not saved).
    pub findings_dir: Option<PathBuf>,
    /// Share of inputs generated from the grammar rather than mutated from
    /// a fixture, in [0, 1].
    pub generated_share: f64,
}

impl Default for FuzzOptions {
    fn default() -> Self {
        Self {
            seed: 1,
            max_inputs: Some(1000),
            duration: None,
            timeout: Duration::from_secs(10),
            findings_dir: None,
            generated_share: 0.3,
        }
    }
}

/// A failing input: what happened, and where it was saved.
#[derive(Clone, Debug)]
pub struct Finding {
    /// `"panic"` or `"hang"`.
    pub kind: &'static str,
    /// The panic message and location, or the time limit.
    pub message: String,
    /// Index of the input in the run (0-based).
    pub input_index: u64,
    pub saved_to: Option<PathBuf>,
    pub input: Input,
}

/// What one run of a target did.
#[derive(Clone, Debug, Default)]
pub struct FuzzReport {
    pub target: String,
    pub inputs: u64,
    /// Inputs the reader accepted.
    pub accepted: u64,
    /// Inputs the reader rejected with an error.
    pub errors: u64,
    pub panics: u64,
    pub hangs: u64,
    pub seconds: f64,
    pub findings: Vec<Finding>,
    /// Up to a few distinct error messages, to eyeball their quality.
    pub sample_errors: Vec<String>,
    /// The input an earlier run died on (it aborted the process), kept
    /// from `current/` when this run started.
    pub aborted_previous_run: Option<PathBuf>,
}

impl FuzzReport {
    /// One line: `target: N inputs (a ok, e errors), p panics, h hangs in s`.
    pub fn summary(&self) -> String {
        format!(
            "{}: {} inputs ({} accepted, {} errors), {} panics, {} hangs in {:.1} s",
            self.target,
            self.inputs,
            self.accepted,
            self.errors,
            self.panics,
            self.hangs,
            self.seconds
        )
    }
}

/// The result of parsing one input.
enum Outcome {
    Accepted,
    Rejected(String),
    Panicked(String),
}

/// The worker thread that runs the parser, and its channels.
struct Worker {
    to_worker: Sender<Input>,
    from_worker: Receiver<Outcome>,
}

impl Worker {
    /// A worker parsing inputs written into `scratch` (created if needed).
    fn spawn(target: &Arc<Target>, scratch: PathBuf) -> Self {
        let (to_worker, inputs) = channel::<Input>();
        let (outcomes, from_worker) = channel();
        let target = Arc::clone(target);
        std::thread::spawn(move || {
            for input in inputs {
                let outcome = run_one(&target, &scratch, &input);
                if outcomes.send(outcome).is_err() {
                    break;
                }
            }
        });
        Self {
            to_worker,
            from_worker,
        }
    }
}

/// The message of the last panic on each thread, recorded by the hook that
/// [`fuzz_target`] installs (the default hook would print every panic).
static LAST_PANIC: Mutex<Vec<(std::thread::ThreadId, String)>> = Mutex::new(Vec::new());

fn install_quiet_panic_hook() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        std::panic::set_hook(Box::new(|info| {
            let payload = info.payload();
            let text = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "(non-string panic payload)".into());
            let location = info
                .location()
                .map(|l| format!(" at {}:{}", l.file(), l.line()))
                .unwrap_or_default();
            if let Ok(mut last) = LAST_PANIC.lock() {
                let id = std::thread::current().id();
                last.retain(|(t, _)| *t != id);
                last.push((id, format!("{text}{location}")));
            }
        }));
    });
}

fn take_panic_message() -> String {
    let id = std::thread::current().id();
    LAST_PANIC
        .lock()
        .ok()
        .and_then(|mut last| {
            let k = last.iter().position(|(t, _)| *t == id)?;
            Some(last.swap_remove(k).1)
        })
        .unwrap_or_else(|| "panic (message not recorded)".into())
}

fn run_one(target: &Target, scratch: &Path, input: &Input) -> Outcome {
    // A fresh folder per input: files of the previous input must not leak
    // into this one.
    let _ = std::fs::remove_dir_all(scratch);
    if let Err(e) = std::fs::create_dir_all(scratch).and_then(|()| input.write_to(scratch)) {
        return Outcome::Rejected(format!("(harness) cannot write the input: {e}"));
    }
    match catch_unwind(AssertUnwindSafe(|| (target.parse)(scratch))) {
        Ok(Ok(())) => Outcome::Accepted,
        Ok(Err(message)) => Outcome::Rejected(message),
        Err(_) => Outcome::Panicked(take_panic_message()),
    }
}

/// Fuzzes `target` under `options` (see the module doc). Errors when the
/// seeds cannot be read, the scratch folder cannot be made or a finding
/// cannot be saved, or when the worker thread stops.
pub fn fuzz_target(target: Target, options: &FuzzOptions) -> anyhow::Result<FuzzReport> {
    install_quiet_panic_hook();
    let target = Arc::new(target);
    let seeds = (target.seeds)()?;
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let (temporary, scratch_root) = scratch_root(target.name, options)?;
    let aborted_previous_run = match &options.findings_dir {
        Some(_) => keep_input_of_aborted_run(&scratch_root)?,
        None => None,
    };
    let marker = scratch_root.join(RUNNING_MARKER);
    std::fs::write(&marker, b"an echofield-fuzz run is using this folder\n")?;
    let mut scratch = ScratchFolders::new(scratch_root);
    let mut worker = Worker::spawn(&target, scratch.next());
    let mut report = FuzzReport {
        target: target.name.to_string(),
        aborted_previous_run,
        ..FuzzReport::default()
    };
    let start = Instant::now();
    while !report.done(options, start) {
        let input = next_input(&target, &seeds, &mut rng, options.generated_share);
        let index = report.inputs;
        report.inputs += 1;
        let stopped = || anyhow::anyhow!("the fuzz worker of {} stopped", target.name);
        worker
            .to_worker
            .send(input.clone())
            .map_err(|_| stopped())?;
        let finding = match worker.from_worker.recv_timeout(options.timeout) {
            Ok(outcome) => report.count(outcome),
            Err(RecvTimeoutError::Timeout) => {
                report.hangs += 1;
                worker = Worker::spawn(&target, scratch.next());
                Some((
                    "hang",
                    format!("no answer within {:.1} s", options.timeout.as_secs_f64()),
                ))
            }
            Err(RecvTimeoutError::Disconnected) => return Err(stopped()),
        };
        if let Some((kind, message)) = finding {
            let finding = Finding {
                kind,
                message,
                input_index: index,
                saved_to: None,
                input,
            };
            report.findings.push(saved(finding, target.name, options)?);
        }
    }
    report.seconds = start.elapsed().as_secs_f64();
    drop(worker);
    let _ = std::fs::remove_file(&marker);
    drop(temporary);
    Ok(report)
}

/// `finding` saved under the findings folder's target folder, when there
/// is a findings folder (`saved_to` says where).
fn saved(
    mut finding: Finding,
    target_name: &str,
    options: &FuzzOptions,
) -> anyhow::Result<Finding> {
    if let Some(dir) = &options.findings_dir {
        finding.saved_to = Some(save_finding(
            &dir.join(target_name),
            finding.kind,
            finding.input_index,
            &finding.message,
            &finding.input,
        )?);
    }
    Ok(finding)
}

/// The folder the workers' scratch folders go in, created: the target's
/// folder under the findings folder, or without one a temporary folder of
/// this run only (returned too, so that it lives until the run ends).
fn scratch_root(
    target_name: &str,
    options: &FuzzOptions,
) -> anyhow::Result<(Option<tempfile::TempDir>, PathBuf)> {
    let temporary = match &options.findings_dir {
        Some(_) => None,
        None => Some(
            tempfile::Builder::new()
                .prefix(&format!("echofield-fuzz-{target_name}-"))
                .tempdir()?,
        ),
    };
    let root = match (&options.findings_dir, &temporary) {
        (Some(dir), _) => dir.join(target_name),
        (None, Some(t)) => t.path().to_path_buf(),
        (None, None) => std::env::temp_dir(),
    };
    std::fs::create_dir_all(&root)?;
    Ok((temporary, root))
}

/// One scratch folder per worker: `current`, then `current-2`, ... for the
/// workers started after a hang.
struct ScratchFolders {
    root: PathBuf,
    started: usize,
}

impl ScratchFolders {
    fn new(root: PathBuf) -> Self {
        Self { root, started: 0 }
    }

    fn next(&mut self) -> PathBuf {
        self.started += 1;
        if self.started == 1 {
            self.root.join("current")
        } else {
            self.root.join(format!("current-{}", self.started))
        }
    }
}

impl FuzzReport {
    /// Whether the run ends: the input budget or the time (since `start`)
    /// is spent, or too many inputs hung.
    fn done(&self, options: &FuzzOptions, start: Instant) -> bool {
        options.max_inputs.is_some_and(|n| self.inputs >= n)
            || options.duration.is_some_and(|d| start.elapsed() >= d)
            || self.hangs as usize >= MAX_HANGS
    }

    /// Counts one parse outcome (keeping a few distinct error messages);
    /// a panic is a finding, returned as (kind, message).
    fn count(&mut self, outcome: Outcome) -> Option<(&'static str, String)> {
        match outcome {
            Outcome::Accepted => {
                self.accepted += 1;
                None
            }
            Outcome::Rejected(message) => {
                self.errors += 1;
                if self.sample_errors.len() < 8
                    && !self.sample_errors.iter().any(|m| same_kind(m, &message))
                {
                    self.sample_errors.push(message);
                }
                None
            }
            Outcome::Panicked(message) => {
                self.panics += 1;
                Some(("panic", message))
            }
        }
    }
}

/// Left in a target's folder while a run uses it: found at the start of
/// the next run, it means the last one died (an allocation failure aborts
/// the process, past any `catch_unwind`).
const RUNNING_MARKER: &str = "RUNNING";

/// When the last run in `scratch_root` died, moves the input it was
/// parsing (`current/`) to `abort-<n>/` and returns that folder.
fn keep_input_of_aborted_run(scratch_root: &Path) -> anyhow::Result<Option<PathBuf>> {
    let current = scratch_root.join("current");
    if !(scratch_root.join(RUNNING_MARKER).exists() && current.is_dir()) {
        return Ok(None);
    }
    let mut n = 0;
    let kept = loop {
        let candidate = scratch_root.join(format!("abort-{n}"));
        if !candidate.exists() {
            break candidate;
        }
        n += 1;
    };
    std::fs::rename(&current, &kept)?;
    std::fs::write(
        kept.join("FINDING.txt"),
        "abort: the fuzz run died while parsing this input (allocation failure or other abort)\n",
    )?;
    Ok(Some(kept))
}

/// Two error messages of the same kind: equal once digits are dropped.
fn same_kind(a: &str, b: &str) -> bool {
    let shape =
        |s: &str| -> String { s.chars().filter(|c| !c.is_ascii_digit()).take(80).collect() };
    shape(a) == shape(b)
}

fn next_input(target: &Target, seeds: &[Input], rng: &mut ChaCha8Rng, generated: f64) -> Input {
    if seeds.is_empty() || rng.random_bool(generated.clamp(0.0, 1.0)) {
        let mut input = (target.generate)(rng);
        if rng.random_bool(0.3) {
            mutate::mutate_input(&mut input, seeds, rng);
        }
        input
    } else {
        let mut input = seeds[rng.random_range(0..seeds.len())].clone();
        mutate::mutate_input(&mut input, seeds, rng);
        input
    }
}

fn save_finding(
    dir: &Path,
    kind: &str,
    index: u64,
    message: &str,
    input: &Input,
) -> anyhow::Result<PathBuf> {
    let folder = dir.join(format!("{kind}-{index}"));
    std::fs::create_dir_all(&folder)?;
    input.write_to(&folder)?;
    std::fs::write(folder.join("FINDING.txt"), format!("{kind}: {message}\n"))?;
    Ok(folder)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A target whose "parser" panics on inputs holding `!`, spins on
    /// inputs holding `~` and rejects those holding `?`: the harness must
    /// count and save each kind.
    fn planted_bugs() -> Target {
        Target {
            name: "planted",
            about: "test target with planted bugs",
            seeds: || Ok(vec![Input::single("x.txt", b"abc".to_vec())]),
            generate: |rng| {
                let byte = [b'a', b'!', b'~', b'?'][rng.random_range(0..4)];
                Input::single("x.txt", vec![byte])
            },
            parse: Arc::new(|dir: &Path| {
                let bytes = std::fs::read(dir.join("x.txt")).map_err(|e| e.to_string())?;
                if bytes.contains(&b'!') {
                    panic!("planted panic");
                }
                if bytes.contains(&b'~') {
                    std::thread::sleep(Duration::from_secs(5));
                }
                if bytes.contains(&b'?') {
                    return Err("planted error".into());
                }
                Ok(())
            }),
        }
    }

    #[test]
    fn the_input_of_an_aborted_run_is_kept_and_reported() {
        let findings = tempfile::tempdir().unwrap();
        let folder = findings.path().join("planted");
        std::fs::create_dir_all(folder.join("current")).unwrap();
        std::fs::write(folder.join("current/x.txt"), b"killer").unwrap();
        std::fs::write(folder.join(RUNNING_MARKER), b"").unwrap();
        let options = FuzzOptions {
            max_inputs: Some(1),
            findings_dir: Some(findings.path().to_path_buf()),
            ..FuzzOptions::default()
        };
        let report = fuzz_target(planted_bugs(), &options).unwrap();
        let kept = report.aborted_previous_run.unwrap();
        assert_eq!(std::fs::read(kept.join("x.txt")).unwrap(), b"killer");
        // A run that ends normally leaves no marker behind.
        assert!(!folder.join(RUNNING_MARKER).exists());
        let again = fuzz_target(planted_bugs(), &options).unwrap();
        assert!(again.aborted_previous_run.is_none());
    }

    #[test]
    fn panics_hangs_and_errors_are_counted_and_saved() {
        let findings = tempfile::tempdir().unwrap();
        let options = FuzzOptions {
            seed: 3,
            max_inputs: Some(40),
            duration: None,
            timeout: Duration::from_millis(200),
            findings_dir: Some(findings.path().to_path_buf()),
            generated_share: 1.0,
        };
        let report = fuzz_target(planted_bugs(), &options).unwrap();
        assert!(report.panics > 0, "{}", report.summary());
        assert!(report.errors > 0, "{}", report.summary());
        assert!(report.accepted > 0, "{}", report.summary());
        // The run stops at the hang limit, or runs its 40 inputs.
        assert!(
            report.hangs as usize == MAX_HANGS || report.inputs == 40,
            "{}",
            report.summary()
        );
        assert_eq!(
            report.inputs,
            report.accepted + report.errors + report.panics + report.hangs
        );
        let panic = report.findings.iter().find(|f| f.kind == "panic").unwrap();
        assert!(panic.message.contains("planted panic"), "{}", panic.message);
        let saved = panic.saved_to.as_ref().unwrap();
        assert_eq!(std::fs::read(saved.join("x.txt")).unwrap(), b"!");
        assert!(saved.join("FINDING.txt").is_file());
        if report.hangs > 0 {
            let hang = report.findings.iter().find(|f| f.kind == "hang").unwrap();
            assert_eq!(hang.input.files[0].1, b"~");
        }
    }
}
