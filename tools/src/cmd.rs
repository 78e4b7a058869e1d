//! One module per subcommand: its clap arguments and its `run`.

pub mod convert;
pub mod matching;
pub mod optimize;
pub mod simulate;
