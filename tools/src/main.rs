//! The `echofield` command-line program.

mod cmd;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// The program's allocator. With glibc's malloc the memory that the worker
/// threads free stays in their arenas, so the resident memory of a long run
/// grows well beyond what it holds (EXPERIMENTS.md § Long missions, "The
/// allocator"); mimalloc gives freed pages back to the system.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Scan-based pose-graph SLAM for underwater vehicles with a mechanically
/// scanned imaging sonar (MSIS), DVL and heading.
#[derive(Debug, Parser)]
#[command(name = "echofield", version, about, long_about = None)]
struct Cli {
    /// More log output (-v info, -vv debug); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    /// Errors only on stderr: no warnings, no progress bar (the results
    /// printed on stdout and written to files are unchanged).
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    quiet: bool,
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
    /// Localise a mission on the acoustic map of an earlier run (particle filter).
    Localize(cmd::localize::Args),
    /// Estimate the sonar head's mounting from the mission's own data.
    Calibrate(cmd::calibrate::Args),
    /// Print the default configuration with each key's documentation.
    Config(cmd::config::Args),
    /// Match the scan of one rotation against the acoustic image of another.
    Match(cmd::matching::Args),
    /// Success rate of the matcher against ground truth, beside ICP.
    BenchMatcher(cmd::bench_matcher::Args),
    /// The backend against false loop closures (vertigo-style benchmark).
    BenchRobust(cmd::bench_robust::Args),
    /// Distortion of rotations and drift of dead reckoning against ground truth.
    BenchDeadReckoning(cmd::bench_dead_reckoning::Args),
    /// Time, memory and accuracy against the number of rotations (long missions).
    BenchLong(cmd::bench_long::Args),
    /// ATE and RPE of an estimated trajectory against a reference (TUM files).
    Eval(cmd::eval::Args),
    /// Precision-recall of the loop-closure gate from a run's loops.csv.
    EvalLoops(cmd::eval_loops::Args),
    /// Errors of a run's edges against ground truth, and what each kind costs.
    ErrorBudget(cmd::error_budget::Args),
    /// Simulate the built-in marina mission and run the whole pipeline on it.
    Demo(cmd::demo::Args),
    /// Print a shell completion script for echofield.
    #[command(after_help = COMPLETIONS_EXAMPLES)]
    Completions {
        /// The shell to complete in.
        shell: clap_complete::Shell,
    },
}

const COMPLETIONS_EXAMPLES: &str = "Examples:
  # Bash, for the current user (bash-completion picks it up at the next login)
  echofield completions bash > ~/.local/share/bash-completion/completions/echofield

  # Zsh: a folder of your $fpath
  echofield completions zsh > ~/.zfunc/_echofield";

fn main() -> ExitCode {
    let cli = Cli::parse();
    init_logging(cli.verbose, cli.quiet);
    cmd::set_quiet(cli.quiet);
    let result = match cli.command {
        Command::Optimize(args) => cmd::optimize::run(args),
        Command::Convert(args) => cmd::convert::run(args),
        Command::Simulate(args) => cmd::simulate::run(args),
        Command::Run(args) => cmd::run::run(args),
        Command::Localize(args) => cmd::localize::run(args),
        Command::Calibrate(args) => cmd::calibrate::run(args),
        Command::Config(args) => cmd::config::run(args),
        Command::Match(args) => cmd::matching::run(args),
        Command::BenchMatcher(args) => cmd::bench_matcher::run(args),
        Command::BenchRobust(args) => cmd::bench_robust::run(args),
        Command::BenchDeadReckoning(args) => cmd::bench_dead_reckoning::run(args),
        Command::BenchLong(args) => cmd::bench_long::run(args),
        Command::ErrorBudget(args) => cmd::error_budget::run(args),
        Command::Eval(args) => cmd::eval::run(args),
        Command::EvalLoops(args) => cmd::eval_loops::run(args),
        Command::Demo(args) => cmd::demo::run(args),
        Command::Completions { shell } => {
            use clap::CommandFactory as _;
            clap_complete::generate(
                shell,
                &mut Cli::command(),
                "echofield",
                &mut std::io::stdout(),
            );
            Ok(())
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) if err.is::<cmd::SuspectRun>() => {
            eprintln!("{err}");
            ExitCode::from(echofield::slam::health::SUSPECT_EXIT_STATUS)
        }
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}

fn init_logging(verbose: u8, quiet: bool) {
    let default = match (quiet, verbose) {
        (true, _) => "error",
        (false, 0) => "warn",
        (false, 1) => "info",
        (false, _) => "debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    // Colours only on a terminal: a log redirected to a file or a pipe
    // stays plain text.
    use std::io::IsTerminal as _;
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(|| cmd::run::StderrAboveBar)
        .with_ansi(std::io::stderr().is_terminal())
        .init();
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    /// The `echofield ...` command lines of `text`: whole lines (joined
    /// across trailing backslashes; in Markdown only inside code fences)
    /// and backquoted spans that are not just a command's name, with the
    /// README's `cargo run --release -p echofield --` spelled `echofield`.
    fn command_lines(text: &str, markdown: bool) -> Vec<String> {
        let text = text
            .replace("cargo run --release -p echofield --", "echofield")
            .replace("\\\n", " ");
        let mut found = Vec::new();
        let mut fenced = false;
        for line in text.lines() {
            let line = line.trim();
            if line.starts_with("```") {
                fenced = !fenced;
                continue;
            }
            if (fenced || !markdown) && line.starts_with("echofield ") {
                found.push(line.to_string());
                continue;
            }
            for (i, span) in line.split('`').enumerate() {
                if i % 2 == 1 && span.starts_with("echofield ") && !names_a_command(span) {
                    found.push(span.to_string());
                }
            }
        }
        found
    }

    /// `echofield run` or `echofield convert stpere`: a command's name,
    /// not an example of its use.
    fn names_a_command(span: &str) -> bool {
        let mut command = Cli::command();
        for word in span.split_whitespace().skip(1) {
            match command.find_subcommand(word) {
                Some(sub) => command = sub.clone(),
                None => return false,
            }
        }
        true
    }

    /// Parses each line as echofield's arguments, up to a shell
    /// redirection or pipe (`echofield completions bash > FILE`).
    fn parse_all(source: &str, lines: &[String]) {
        for line in lines {
            let words = line
                .split_whitespace()
                .take_while(|w| !matches!(*w, ">" | ">>" | "|" | "2>"));
            if let Err(e) = Cli::try_parse_from(words) {
                panic!("{source}: `{line}` does not parse:\n{e}");
            }
        }
    }

    fn help_examples(command: &clap::Command, found: &mut Vec<String>) {
        for help in [command.get_after_help(), command.get_after_long_help()]
            .into_iter()
            .flatten()
        {
            found.extend(command_lines(&help.to_string(), false));
        }
        for sub in command.get_subcommands() {
            help_examples(sub, found);
        }
    }

    #[test]
    fn every_example_in_the_help_parses() {
        let mut found = Vec::new();
        help_examples(&Cli::command(), &mut found);
        assert!(found.len() >= 30, "{found:#?}");
        parse_all("--help", &found);
    }

    #[test]
    fn every_command_in_the_documentation_parses() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let mut files = vec![
            root.join("README.md"),
            root.join("ARCHITECTURE.md"),
            root.join("tools/peers/README.md"),
            root.join("datasets/README.md"),
        ];
        for entry in std::fs::read_dir(root.join("datasets")).unwrap() {
            let readme = entry.unwrap().path().join("README.md");
            if readme.is_file() {
                files.push(readme);
            }
        }
        let mut total = 0;
        for file in &files {
            let text = std::fs::read_to_string(file).unwrap();
            let found: Vec<String> = command_lines(&text, true)
                .into_iter()
                // Placeholders such as `echofield run DIR` are syntax, not
                // examples.
                .filter(|l| {
                    !l.split_whitespace()
                        .any(|w| w.chars().all(|c| c.is_ascii_uppercase()))
                })
                .collect();
            total += found.len();
            parse_all(&file.display().to_string(), &found);
        }
        assert!(total >= 10, "{total} commands in {files:?}");
    }
}
