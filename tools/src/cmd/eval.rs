//! `echofield eval`: ATE and RPE between two TUM trajectories.

use anyhow::{Context, Result};
use echofield::eval::{Alignment, AteStats, RpeStats, ate, rpe};
use echofield::output::write_atomic;
use echofield_graph::io::read_tum;
use serde::Serialize;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
#[command(after_help = "\
Examples:
  # ATE after the best rigid alignment of the plane, and RPE over 10 m and 50 m
  echofield eval --estimate out/trajectory_tum.txt --reference out/ground_truth_tum.txt

  # No alignment (both trajectories already in the same world frame), JSON out
  echofield eval --estimate a.txt --reference b.txt --align none --json ate.json

The ATE RMSE equals `evo_ape tum REFERENCE ESTIMATE [-a]` (tools/check_evo.sh
checks it against the evo package).")]
pub struct Args {
    /// Estimated trajectory, TUM format (stamp x y z qx qy qz qw).
    #[arg(long)]
    estimate: PathBuf,
    /// Reference (ground-truth) trajectory, TUM format.
    #[arg(long)]
    reference: PathBuf,
    /// Alignment applied to the estimate before measuring ATE.
    #[arg(long, value_enum, default_value_t = Alignment::Se2)]
    align: Alignment,
    /// Largest stamp difference for two poses to be associated, seconds.
    #[arg(long, default_value_t = 0.01)]
    max_time_diff: f64,
    /// Travelled distances for the RPE, metres, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "10,50")]
    rpe_distances: Vec<f64>,
    /// Also write the results as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(Serialize)]
struct Report {
    alignment: Alignment,
    ate: AteStats,
    rpe: Vec<RpeStats>,
}

pub fn run(args: Args) -> Result<()> {
    if !(args.max_time_diff.is_finite() && args.max_time_diff > 0.0) {
        anyhow::bail!(
            "--max-time-diff must be a positive number of seconds, got {}",
            args.max_time_diff
        );
    }
    if let Some(d) = args
        .rpe_distances
        .iter()
        .find(|d| !(d.is_finite() && **d > 0.0))
    {
        anyhow::bail!("--rpe-distances must be positive distances in metres, got {d}");
    }
    let estimate = read_tum(&args.estimate).context("reading the estimate")?;
    let reference = read_tum(&args.reference).context("reading the reference")?;
    let ate = ate(&estimate, &reference, args.align, args.max_time_diff)?;
    let rpe = rpe(
        &estimate,
        &reference,
        &args.rpe_distances,
        args.max_time_diff,
    );
    println!(
        "ATE ({:?} alignment, {} pairs): rmse {:.6} m  mean {:.6} m  median {:.6} m  max {:.6} m",
        args.align, ate.pairs, ate.rmse_m, ate.mean_m, ate.median_m, ate.max_m
    );
    for r in &rpe {
        println!(
            "RPE over {:>6.1} m ({} pairs): translation {:.4} m ({:.3} %)  rotation {:.4} deg",
            r.distance_m,
            r.pairs,
            r.translation_rmse_m,
            r.translation_rmse_percent,
            r.rotation_rmse_deg
        );
    }
    if let Some(path) = &args.json {
        let report = Report {
            alignment: args.align,
            ate,
            rpe,
        };
        write_atomic(path, |w| Ok(serde_json::to_writer_pretty(w, &report)?))?;
    }
    Ok(())
}
