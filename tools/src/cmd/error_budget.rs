//! `echofield error-budget`: runs the pipeline on a mission with ground
//! truth and prints how far each kind of edge is from the truth and how
//! much of the trajectory error it causes
//! ([`echofield::slam::error_budget`]).

use anyhow::{Context, Result, bail};
use echofield::output::write_atomic;
use echofield::slam::error_budget::{ErrorBudget, error_budget};
use echofield::slam::{NoProgress, SlamConfig, load_mission, run_mission};
use std::path::PathBuf;

const EXAMPLES: &str = "\
Examples:
  # The built-in marina mission (seed 1) with the default configuration
  echofield simulate --scenario marina --seed 1 --output marina.mcap
  echofield error-budget marina.mcap

  # Another configuration, and the numbers as JSON too
  echofield error-budget marina.mcap --config my.toml --json budget.json

The first table compares every odometry, sequential and loop edge of the
final graph with the ground-truth relative pose of its two nodes: mean
and RMS error (x, y in the first node's frame, heading), the RMS of the
error in units of the edge's own standard deviation (1 when the covariance
is right, below 1 when it is cautious), the mean NEES (3 when right), and
the bias along the true displacement with its scale. The second solves the
graph again with the measurements of some kinds replaced by their true
values (information unchanged) and gives the ATE of each solve: what the
errors of those kinds cost. With every kind replaced, what is left comes
from the heading priors. Its last row keeps every measurement but divides
the odometry's information by 100: the motion the sonar's edges make of
the mission on their own. The motion scale of a solve is how far it moves
against the truth (below 1: shorter). The mission needs ground truth.";

#[derive(Debug, clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// The mission with ground truth: an MCAP file or a St Pere log folder.
    pub mission: PathBuf,
    /// Pipeline configuration (TOML); defaults for missing keys.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Also write the budget as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<()> {
    super::prepare_output_files([args.json.as_ref()])?;
    let config = SlamConfig::from_optional_toml_file(args.config.as_deref())?;
    let mission = load_mission(&args.mission)?;
    let output = run_mission(&mission, &config, &NoProgress)
        .with_context(|| format!("SLAM on {} failed", args.mission.display()))?;
    let Some(budget) = error_budget(&output)? else {
        bail!(
            "{} has no ground truth: nothing to compare the edges with",
            args.mission.display()
        );
    };
    println!(
        "{}: {} nodes ({} with ground truth), run ATE {:.3} m\n",
        args.mission.display(),
        output.nodes.len(),
        budget.nodes_with_ground_truth,
        output.report.ate_rmse_m.unwrap_or(f64::NAN)
    );
    print!("{}", table(&budget));
    if let Some(path) = &args.json {
        write_atomic(path, |w| Ok(serde_json::to_writer_pretty(w, &budget)?))?;
        println!("\nwrote {}", path.display());
    }
    Ok(())
}

/// The two Markdown tables.
fn table(budget: &ErrorBudget) -> String {
    let mut s = String::from(
        "| edges | count | mean error x, y (m), θ (°) | RMS error x, y (m), θ (°) | RMS error / σ x, y, θ | mean NEES | along-track bias (m), scale |\n|---|---|---|---|---|---|---|\n",
    );
    for k in &budget.edges {
        let [mx, my, mt] = k.mean_error;
        let [rx, ry, rt] = k.rms_error;
        let [nx, ny, nt] = k.rms_normalised_error;
        s += &format!(
            "| {:?} | {} | {mx:+.3}, {my:+.3}, {mt:+.3} | {rx:.3}, {ry:.3}, {rt:.3} | {nx:.2}, {ny:.2}, {nt:.2} | {:.2} | {:+.3}, {:+.2}% |\n",
            k.kind,
            k.edges,
            k.mean_nees,
            k.along_track_bias_m,
            100.0 * k.scale_error
        );
    }
    s +=
        "\n| measurements set to the ground truth | ATE RMSE (m) | motion scale |\n|---|---|---|\n";
    for o in &budget.oracle_solves {
        let replaced = if o.odometry_information_factor != 1.0 {
            format!(
                "none, odometry information × {} (the sonar's own motion)",
                o.odometry_information_factor
            )
        } else if o.replaced.is_empty() {
            "none (the graph solved again)".to_string()
        } else {
            o.replaced
                .iter()
                .map(|k| format!("{k:?}").to_lowercase())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let scale = o
            .motion_scale
            .map_or("-".to_string(), |m| format!("{m:.4}"));
        s += &format!("| {replaced} | {:.3} | {scale} |\n", o.ate_rmse_m);
    }
    s
}
