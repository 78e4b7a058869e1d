//! One module per subcommand: its clap arguments and its `run`.

pub mod bench_dead_reckoning;
pub mod bench_long;
pub mod bench_matcher;
pub mod bench_robust;
pub mod calibrate;
pub mod config;
pub mod convert;
pub mod demo;
pub mod error_budget;
pub mod eval;
pub mod eval_loops;
pub mod localize;
pub mod matching;
pub mod optimize;
pub mod run;
pub mod run_multi;
pub mod simulate;

/// `-q`: no progress bar (set once by `main` before any command runs).
static QUIET: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Records the `-q` flag for the progress bars.
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, std::sync::atomic::Ordering::Relaxed);
}

/// Whether `-q` was given.
pub fn quiet() -> bool {
    QUIET.load(std::sync::atomic::Ordering::Relaxed)
}

/// Sets the number of rayon worker threads of a pipeline command
/// (`--threads`); `None` keeps rayon's default (one per core, or
/// `RAYON_NUM_THREADS`).
pub fn set_threads(threads: Option<std::num::NonZeroUsize>) -> anyhow::Result<()> {
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n.get())
            .build_global()
            .map_err(|e| anyhow::anyhow!("cannot start {n} worker threads: {e}"))?;
    }
    Ok(())
}

/// Checks before any work that each given output file can be written
/// ([`echofield::output::prepare_output_file`]).
pub fn prepare_output_files<'a>(
    paths: impl IntoIterator<Item = Option<&'a std::path::PathBuf>>,
) -> anyhow::Result<()> {
    for path in paths.into_iter().flatten() {
        echofield::output::prepare_output_file(path)?;
    }
    Ok(())
}

/// The error of a run that wrote every output but judged its result
/// suspect (`report.json` → `health`); `main` exits with
/// [`SUSPECT_EXIT_STATUS`](echofield::slam::health::SUSPECT_EXIT_STATUS).
#[derive(Debug)]
pub struct SuspectRun;

impl std::fmt::Display for SuspectRun {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "suspect result (report.json → health; every output was written): \
             exit status {}, or 0 with --allow-suspect",
            echofield::slam::health::SUSPECT_EXIT_STATUS
        )
    }
}

impl std::error::Error for SuspectRun {}

/// Prints the run's health for `mission` to stdout; a suspect run is a
/// [`SuspectRun`] error unless `allow_suspect`.
pub fn check_health(
    health: &echofield::slam::health::Health,
    mission: &str,
    allow_suspect: bool,
) -> anyhow::Result<()> {
    for line in health.summary_lines(mission) {
        println!("{line}");
    }
    if health.verdict == echofield::slam::health::Verdict::Suspect && !allow_suspect {
        return Err(SuspectRun.into());
    }
    Ok(())
}
