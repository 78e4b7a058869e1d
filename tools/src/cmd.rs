//! One module per subcommand: its clap arguments and its `run`.

pub mod bench_dead_reckoning;
pub mod bench_matcher;
pub mod convert;
pub mod demo;
pub mod error_budget;
pub mod eval;
pub mod eval_loops;
pub mod matching;
pub mod optimize;
pub mod run;
pub mod simulate;

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
