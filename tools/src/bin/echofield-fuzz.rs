//! `echofield-fuzz`: runs the parser fuzz targets of `echofield::fuzz`.
//!
//! ```text
//! cargo run --release --bin echofield-fuzz -- all --seconds 600 --seed 1
//! cargo run --release --bin echofield-fuzz -- g2o tum --inputs 100000
//! cargo run --release --bin echofield-fuzz -- g2o --replay fuzz-findings/g2o/panic-17
//! ```
//! Exit status 0 when no input panicked or hung, 1 otherwise.

use clap::Parser;
use echofield::fuzz::targets::{TARGET_NAMES, Target};
use echofield::fuzz::{FuzzOptions, FuzzReport, fuzz_target};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

/// Fuzz echofield's input parsers (g2o, TORO, TUM, MCAP, St Pere logs and
/// keyframes, Ping360, MiniKing bags, config TOML) with seeded structured
/// and mutated inputs; report inputs, errors, panics and hangs.
#[derive(Debug, Parser)]
#[command(
    name = "echofield-fuzz",
    after_help = "\
Examples:
  # Every target for ten minutes each, one after the other
  echofield-fuzz all --seconds 600 --seed 1

  # Two targets for a fixed number of inputs (same inputs on every machine)
  echofield-fuzz g2o tum --inputs 100000 --seed 7

  # Parse a saved finding again (a folder under --findings)
  echofield-fuzz g2o --replay fuzz-findings/g2o/panic-17"
)]
struct Cli {
    /// Targets to run (`all` for every one): g2o, toro, tum, mcap, stpere,
    /// keyframes, ping360, miniking, config.
    #[arg(required = true)]
    targets: Vec<String>,
    /// Seconds to run each target.
    #[arg(long)]
    seconds: Option<f64>,
    /// Inputs to run each target (with --seconds: whichever comes first).
    #[arg(long)]
    inputs: Option<u64>,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Seconds one input may take before it counts as a hang.
    #[arg(long, default_value_t = 10.0)]
    timeout: f64,
    /// Folder where panicking and hanging inputs are saved.
    #[arg(long, default_value = "fuzz-findings")]
    findings: PathBuf,
    /// Parse the files of this folder with the (single) target and print
    /// the outcome, instead of fuzzing.
    #[arg(long)]
    replay: Option<PathBuf>,
    /// Print a few of the error messages each target produced.
    #[arg(short, long)]
    verbose: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(&cli) {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

/// Runs the targets of `cli` (or replays one input); true when no target
/// panicked, hung or found the input of an aborted earlier run.
fn run(cli: &Cli) -> anyhow::Result<bool> {
    let targets = chosen_targets(cli)?;
    if let Some(folder) = &cli.replay {
        anyhow::ensure!(targets.len() == 1, "--replay takes one target");
        let outcome = (targets[0].parse)(folder);
        match outcome {
            Ok(()) => println!("accepted"),
            Err(message) => println!("rejected: {message}"),
        }
        return Ok(true);
    }
    let options = options(cli)?;
    let mut clean = true;
    let mut rows = Vec::new();
    for target in targets {
        let report = fuzz_target(target, &options)?;
        clean &= print_report(&report, cli.verbose);
        rows.push(report);
    }
    println!("\n| target | seconds | inputs | accepted | errors | panics | hangs |");
    println!("|---|---|---|---|---|---|---|");
    for r in &rows {
        println!(
            "| {} | {:.0} | {} | {} | {} | {} | {} |",
            r.target, r.seconds, r.inputs, r.accepted, r.errors, r.panics, r.hangs
        );
    }
    Ok(clean)
}

/// The targets named on the command line (`all`: every one); errors on an
/// unknown name.
fn chosen_targets(cli: &Cli) -> anyhow::Result<Vec<Target>> {
    let names: Vec<&str> = if cli.targets.iter().any(|t| t == "all") {
        TARGET_NAMES.to_vec()
    } else {
        cli.targets.iter().map(String::as_str).collect()
    };
    names
        .iter()
        .map(|name| {
            echofield::fuzz::target(name).ok_or_else(|| {
                anyhow::anyhow!(
                    "unknown target `{name}` (known: {})",
                    TARGET_NAMES.join(", ")
                )
            })
        })
        .collect()
}

/// The fuzz options of the command line: 1000 inputs per target unless
/// `--inputs` or `--seconds` says otherwise. Errors on a timeout or a
/// duration that is not a positive number of seconds.
fn options(cli: &Cli) -> anyhow::Result<FuzzOptions> {
    anyhow::ensure!(
        cli.timeout.is_finite() && cli.timeout > 0.0,
        "--timeout must be a positive number of seconds, got {}",
        cli.timeout
    );
    let duration = match cli.seconds {
        Some(s) if s.is_finite() && s > 0.0 => Some(Duration::from_secs_f64(s)),
        Some(s) => anyhow::bail!("--seconds must be a positive number, got {s}"),
        None => None,
    };
    Ok(FuzzOptions {
        seed: cli.seed,
        max_inputs: cli
            .inputs
            .or(if duration.is_none() { Some(1000) } else { None }),
        duration,
        timeout: Duration::from_secs_f64(cli.timeout),
        findings_dir: Some(cli.findings.clone()),
        ..FuzzOptions::default()
    })
}

/// Prints one target's summary and findings (and, `verbose`, its sample
/// errors); false when the target panicked, hung or found the input of an
/// aborted earlier run.
fn print_report(report: &FuzzReport, verbose: bool) -> bool {
    let mut clean = true;
    if let Some(kept) = &report.aborted_previous_run {
        println!(
            "{}: the previous run died (abort) on the input now in {}",
            report.target,
            kept.display()
        );
        clean = false;
    }
    println!("{}", report.summary());
    for finding in &report.findings {
        println!(
            "  {} on input {}: {} (saved to {})",
            finding.kind,
            finding.input_index,
            finding.message,
            finding
                .saved_to
                .as_ref()
                .map_or_else(|| "-".into(), |p| p.display().to_string())
        );
    }
    if verbose {
        for e in &report.sample_errors {
            println!("  error: {e}");
        }
    }
    clean && report.panics == 0 && report.hangs == 0
}
