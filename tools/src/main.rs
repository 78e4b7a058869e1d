//! The `echofield` command-line program.

mod cmd;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Scan-based pose-graph SLAM for underwater vehicles with a mechanically
/// scanned imaging sonar (MSIS), DVL and heading.
#[derive(Debug, Parser)]
#[command(name = "echofield", version, about, long_about = None)]
struct Cli {
    /// More log output (-v info, -vv debug); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Optimise a 2D pose graph (g2o or TORO) with sparse Gauss-Newton / LM.
    Optimize(cmd::optimize::Args),
    /// Convert a log (St Pere, Ping360, MiniKing) into an echofield MCAP mission.
    #[command(subcommand)]
    Convert(cmd::convert::Args),
    /// Simulate an MSIS/DVL/heading mission with ground truth into MCAP.
    Simulate(cmd::simulate::Args),
    /// Run the SLAM pipeline over a mission (MCAP or St Pere folder).
    Run(cmd::run::Args),
    /// Match the scan of one rotation against the acoustic image of another.
    Match(cmd::matching::Args),
    /// Success rate of the matcher against ground truth, beside ICP.
    BenchMatcher(cmd::bench_matcher::Args),
    /// Distortion of rotations and drift of dead reckoning against ground truth.
    BenchDeadReckoning(cmd::bench_dead_reckoning::Args),
    /// ATE and RPE of an estimated trajectory against a reference (TUM files).
    Eval(cmd::eval::Args),
    /// Precision-recall of the loop-closure gate from a run's loops.csv.
    EvalLoops(cmd::eval_loops::Args),
    /// Simulate the built-in marina mission and run the whole pipeline on it.
    Demo(cmd::demo::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    init_logging(cli.verbose);
    let result = match cli.command {
        Command::Optimize(args) => cmd::optimize::run(args),
        Command::Convert(args) => cmd::convert::run(args),
        Command::Simulate(args) => cmd::simulate::run(args),
        Command::Run(args) => cmd::run::run(args),
        Command::Match(args) => cmd::matching::run(args),
        Command::BenchMatcher(args) => cmd::bench_matcher::run(args),
        Command::BenchDeadReckoning(args) => cmd::bench_dead_reckoning::run(args),
        Command::Eval(args) => cmd::eval::run(args),
        Command::EvalLoops(args) => cmd::eval_loops::run(args),
        Command::Demo(args) => cmd::demo::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}

fn init_logging(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .init();
}
