//! `echofield demo`: simulate the built-in marina mission and run the whole
//! pipeline on it.

use super::run::BarProgress;
use anyhow::{Context, Result};
use echofield::slam::SlamConfig;
use echofield::slam::outputs::demo::run_demo;
use echofield_datasets::sim::Scenario;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
#[command(after_help = "\
Examples:
  # The marina demo: simulate ~40 min of mission, run SLAM, write everything
  echofield demo --output out/demo

  # Another seed, and a faster small tank mission
  echofield demo --output out/demo7 --seed 7
  echofield demo --output out/tank --scenario tank

  # The St Pere replay (real navigation, simulated beams; about 231 rotations)
  echofield demo --output out/stpere --scenario stpere

The folder gets the simulated input (simulated_mission.mcap) and every output
of `echofield run`: trajectory.png, loops.png, mosaic.png, mission.mcap (open
it in Foxglove), report.json, loops.csv, TUM/CSV/g2o trajectories and
config.toml.

Exit status: as for `echofield run`: 3 when the run judges its own result
suspect (report.json → health), unless --allow-suspect; 1 for any error.")]
pub struct Args {
    /// Output folder (created if needed). Replaced whole at the end; only
    /// an empty folder or an earlier echofield output is replaced.
    #[arg(long, short)]
    pub output: PathBuf,
    /// Seed of the simulation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated scenario.
    #[arg(long, default_value = "marina",
          value_parser = clap::builder::PossibleValuesParser::new(["marina", "tank", "canyon", "stpere"]))]
    pub scenario: String,
    /// Pipeline configuration (TOML), as for `echofield run`.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Worker threads (default: one per core, or RAYON_NUM_THREADS); the
    /// results do not depend on it.
    #[arg(long, value_name = "N")]
    pub threads: Option<std::num::NonZeroUsize>,
    /// Exit with status 0 even when the run judges its result suspect, as
    /// for `echofield run`.
    #[arg(long)]
    pub allow_suspect: bool,
}

pub fn run(args: Args) -> Result<()> {
    super::set_threads(args.threads)?;
    let config = SlamConfig::from_optional_toml_file(args.config.as_deref())?;
    let scenario = Scenario::named(&args.scenario)
        .with_context(|| format!("cannot set up scenario `{}`", args.scenario))?;
    let summary = run_demo(
        &args.output,
        &scenario,
        args.seed,
        &config,
        args.config.as_deref(),
        &BarProgress::new(),
    )
    .with_context(|| format!("demo into {}", args.output.display()))?;
    println!("{}", summary.text());
    let mission = summary.mission_path.display().to_string();
    super::check_health(&summary.output.report.health, &mission, args.allow_suspect)
}
