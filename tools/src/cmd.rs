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
