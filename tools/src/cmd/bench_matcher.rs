//! `echofield bench-matcher`: success rate of the acoustic-image matcher
//! against ground truth, side by side with point-to-point ICP.

use anyhow::{Context, Result};
use echofield::matching::MissionRotations;
use echofield::matching::evaluation::{TrialConfig, evaluate};
use echofield::output::{write_atomic, write_bytes_atomic};
use echofield::slam::SlamConfig;
use echofield_datasets::sim::{Scenario, simulate_mission};
use std::path::PathBuf;

const EXAMPLES: &str = "\
Examples:
  # The simulated tank and marina missions (seed 1), 5 initial guesses per pair
  echofield bench-matcher --scenario tank --seed 1
  echofield bench-matcher --scenario marina --seed 1 --json marina-matcher.json

  # A mission file with ground truth instead of a built-in scenario
  echofield bench-matcher --mission stpere-sim.mcap --trials 3

  # The scans and images as the refining second pass of `run` builds them
  echofield bench-matcher --mission stpere-sim.mcap --navigation slam

  # Every scan point at the true pose: what pulls the matches along their
  # displacement (summarised by tools/peers/pull_at_truth.py)
  echofield bench-matcher --mission marina.mcap --navigation ground-truth \
      --trials 1 --max-pairs 400 --pull-at-truth pull.csv

For every pair of overlapping rotations (consecutive and non-consecutive,
at most --max-pairs of each, chosen with the seed among all pairs where at
least half of the points of S_K lie within 0.5 m of S_J at the true pose,
with scans built with the true motion so that the overlap does not depend
on --navigation or --config; both rotations must have a scan with the
navigation evaluated, which leaves out those it does not cover), initial guesses are drawn around the true
relative pose with a translation error up to
--max-error-m and a heading error up to --max-error-deg. The matcher
searches a window just wider than that; ICP (point-to-point, on the same
extracted ranges) starts from the same guess. A trial succeeds when the
final error is below 0.3 m and 2 degrees. The table gives the success rate
overall, over the constrained pairs (whose overlapping points lie on walls
of more than one direction, so that the match is determined along every
axis; see echofield::matching::evaluation), and by initial translation error, the median final error of the
successes, the mean time per match, the matcher's mean NEES over its
successes (about 3 when its covariance is calibrated), and the share of
matches whose covariance claims success-level precision (standard
deviations below 0.3 m and 2 degrees) with their success rate, and how
many of the matcher's failures put the scan where the mean score of eq. (5)
is at least as high as at the true pose (an ambiguity of the score, e.g.
along a quay, that no search can resolve; the rest are search failures).
The last column is the mean signed error of the successes with its
standard error: along the true displacement (negative: the matches are
short), in heading, and as a scale (the slope of the along-track error
over the distance). The pose graph averages random errors away but not
these; with --navigation ground-truth they are the matcher's own.

--navigation ground-truth compensates the vehicle's motion within each
rotation with the ground truth instead of dead reckoning: the scans and
images are then exact and the table measures the matcher alone.
--navigation slam first runs the SLAM pipeline (default configuration) and
compensates the motion along its trajectory; no ground truth is used
for it.";

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum NavigationSource {
    /// The mission's dead reckoning, as the pipeline's first pass.
    DeadReckoning,
    /// The ground truth: exact scans and images, the matcher alone.
    GroundTruth,
    /// The dead reckoning bent through the node poses of a SLAM run with
    /// the default pipeline configuration.
    Slam,
}

#[derive(Debug, clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// Built-in scenario to simulate.
    #[arg(long, conflicts_with = "mission",
          value_parser = clap::builder::PossibleValuesParser::new(Scenario::NAMES))]
    pub scenario: Option<String>,
    /// Seed of the simulation and of the pair and guess draws.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// A mission file with ground truth (MCAP) instead of --scenario.
    #[arg(long)]
    pub mission: Option<PathBuf>,
    /// Initial guesses per pair.
    #[arg(long, default_value_t = 5)]
    pub trials: usize,
    /// At most this many pairs of each kind.
    #[arg(long, default_value_t = 60)]
    pub max_pairs: usize,
    /// Largest initial translation error, metres.
    #[arg(long, default_value_t = 5.0)]
    pub max_error_m: f64,
    /// Largest initial heading error, degrees.
    #[arg(long, default_value_t = 20.0)]
    pub max_error_deg: f64,
    /// Motion compensation within rotations: dead reckoning (as the SLAM
    /// pipeline) or the mission's ground truth (the matcher alone).
    #[arg(long, value_enum, default_value_t = NavigationSource::DeadReckoning)]
    pub navigation: NavigationSource,
    /// Matching configuration (TOML, as for `echofield match`).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Also write every trial and the table as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Also write every scan point of every pair at the true pose as CSV:
    /// its margin to the image's rim and the slope of the image along the
    /// true displacement (what pulls the match; see
    /// `tools/peers/pull_at_truth.py`).
    #[arg(long)]
    pub pull_at_truth: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<()> {
    super::prepare_output_files([args.json.as_ref(), args.pull_at_truth.as_ref()])?;
    let config = match &args.config {
        Some(path) => SlamConfig::from_toml_file(path)?,
        None => SlamConfig::default(),
    };
    let mission = match (&args.scenario, &args.mission) {
        (Some(name), None) => {
            let scenario = Scenario::named(name)?;
            simulate_mission(&scenario, args.seed)
                .with_context(|| format!("simulating the {name} scenario"))?
        }
        (None, Some(path)) => echofield::matching::load_mission(path)?,
        _ => anyhow::bail!("give either --scenario or --mission"),
    };
    let name = mission.name.clone();
    let mut rotations = MissionRotations::new(mission, &config)?;
    match args.navigation {
        NavigationSource::DeadReckoning => {}
        NavigationSource::GroundTruth => rotations.use_ground_truth_navigation()?,
        NavigationSource::Slam => {
            let report = rotations.use_slam_navigation(&config)?;
            if let Some(ate) = report.ate_rmse_m {
                println!("SLAM run for the motion compensation: ATE RMSE {ate:.3} m");
            }
        }
    }
    let eval = TrialConfig {
        trials_per_pair: args.trials,
        max_pairs_per_kind: args.max_pairs,
        max_initial_error_m: args.max_error_m,
        max_initial_error_rad: args.max_error_deg.to_radians(),
        seed: args.seed,
        pull_at_truth: args.pull_at_truth.is_some(),
        ..TrialConfig::default()
    };
    let source = match &args.mission {
        Some(path) => path.display().to_string(),
        None => format!("the simulated {name} mission"),
    };
    let result = evaluate(&rotations, &config, &eval)
        .with_context(|| format!("evaluating the matcher on {source}"))?;
    let table = result.table();
    println!(
        "{name}, motion compensation by {:?}: {} rotations ({} without a scan), overlapping pairs {:?}, evaluated {:?}\n\n{table}",
        args.navigation,
        result.rotations,
        result.rotations_without_scan,
        result.overlapping_pairs,
        result.pairs
    );
    if let Some(path) = &args.json {
        let value = serde_json::json!({ "mission": name, "table": table, "evaluation": result });
        write_bytes_atomic(
            path,
            (serde_json::to_string_pretty(&value)? + "\n").as_bytes(),
        )?;
    }
    if let Some(path) = &args.pull_at_truth {
        write_atomic(path, |w| {
            let mut writer = csv::Writer::from_writer(w);
            for row in &result.pulls {
                writer.serialize(row)?;
            }
            Ok(writer.flush()?)
        })?;
    }
    Ok(())
}
