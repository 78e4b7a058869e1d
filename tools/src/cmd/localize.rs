//! `echofield localize`: Monte Carlo localisation of a mission on the
//! acoustic map of an earlier run (`echofield::localize`).

use anyhow::{Context, Result};
use echofield::localize::outputs::{FOLDER_FILES, write_files};
use echofield::localize::{LocalizeConfig, LocalizeReport, build_report, load_prior_map, localize};
use echofield::output::folder::OutputFolder;
use echofield::slam::{RunInfo, load_mission_with_keyframes};
use std::path::{Path, PathBuf};
use std::time::Instant;

const EXAMPLES: &str = "\
Examples:
  # A map from one mission, a second mission localised on it from an
  # unknown start
  echofield simulate --scenario marina --seed 1 --output marina1.mcap
  echofield simulate --scenario marina --seed 2 --output marina2.mcap
  echofield run marina1.mcap --output out/map
  echofield localize marina2.mcap --map out/map --output out/loc

  # With a [localize] section (tools/configs/localize.toml lists every key)
  echofield localize marina2.mcap --map out/map --config loc.toml --output out/loc

The map is rebuilt from RUN_DIR: its report.json names the mission it read,
its config.toml how the scans and images were built (the localised mission's
scans are built the same way), its trajectory_tum.txt the optimised node
poses. The map's mission must still be where the run read it.

OUTPUT gets trajectory_tum.txt (the estimate per rotation, map frame, as
the filter gave it online), trajectory_smoothed_tum.txt (offline: the
filter's fixes and the dead reckoning between rotations smoothed over the
whole mission), localization.csv (per rotation: state, spread, particles, fit, coverage),
localization.png, localization.mcap (the particle cloud for Foxglove) and
report.json: the verdict (localised or not_localised), time to converge,
recoveries after kidnappings, ATE against ground truth when the mission has
it (through the map run's own fit onto its ground truth), particles and time
per rotation. OUTPUT is written whole, like `run`'s.";

#[derive(Debug, clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// The mission to localise: an MCAP file, a rosbag2 folder or a St Pere
    /// log folder.
    pub mission: PathBuf,
    /// The output folder of an `echofield run` whose map to localise on.
    #[arg(long, value_name = "RUN_DIR")]
    pub map: PathBuf,
    /// With a St Pere navigation folder as the mission: the thresholded
    /// point sets to rebuild the beams from (as `run --keyframes`).
    #[arg(long, value_name = "KF_DIR")]
    pub keyframes: Option<PathBuf>,
    /// A TOML file with a [localize] section; defaults for missing keys.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Output folder (created if needed), replaced whole at the end.
    #[arg(long, short)]
    pub output: PathBuf,
    /// Worker threads for rebuilding the map (default: one per core); the
    /// filter itself runs on one, and the results do not depend on it.
    #[arg(long, value_name = "N")]
    pub threads: Option<std::num::NonZeroUsize>,
}

pub fn run(args: Args) -> Result<()> {
    let mut inputs = vec![args.mission.as_path(), args.map.as_path()];
    inputs.extend(args.keyframes.as_deref());
    let run_info = RunInfo::start("localize", &inputs, args.config.as_deref(), &args.output);
    super::set_threads(args.threads)?;
    let config = LocalizeConfig::from_optional_toml_file(args.config.as_deref())?;
    let folder = OutputFolder::prepare(&args.output, FOLDER_FILES)?;
    let start = Instant::now();
    let map = load_prior_map(&args.map, &config.localize)
        .with_context(|| format!("reading the map of {}", args.map.display()))?;
    let map_s = start.elapsed().as_secs_f64();
    let mission = load_mission_with_keyframes(
        &args.mission,
        args.keyframes.as_deref(),
        map.config.mounting.sweep,
    )?;
    let localized = localize(&mission, &map, &config.localize)?;
    let report = build_report(
        &localized,
        &map,
        &args.map.display().to_string(),
        &config.localize,
        Some(run_info),
    );
    write_files(
        folder.path(),
        &localized,
        &map,
        &report,
        &config.to_toml_string()?,
    )
    .and_then(|()| folder.commit())
    .with_context(|| format!("cannot write the outputs into {}", args.output.display()))?;
    print_summary(&report, map_s, &args.output);
    Ok(())
}

/// The report's headline figures on stdout; `map_s` the time the map took
/// to rebuild, s.
fn print_summary(report: &LocalizeReport, map_s: f64, output: &Path) {
    println!(
        "{}: {} rotations on a map of {} nodes ({:.0} m² covered, built in {:.1} s): {}{}",
        report.mission,
        report.rotations,
        report.map_nodes,
        report.map_covered_area_m2,
        map_s,
        report.verdict,
        report.converged_rotation.map_or(String::new(), |k| format!(
            ", converged at rotation {k} ({:.0} s)",
            report.time_to_converge_s.unwrap_or(0.0)
        ))
    );
    if let Some(ate) = report.ate_rmse_m {
        println!(
            "ATE RMSE after convergence {ate:.3} m (fitted {}, dead reckoning fitted {})",
            report
                .ate_rmse_aligned_m
                .map_or("-".to_string(), |a| format!("{a:.3} m")),
            report
                .ate_rmse_dead_reckoning_m
                .map_or("-".to_string(), |a| format!("{a:.3} m"))
        );
        if let Some(smoothed) = report.ate_rmse_smoothed_m {
            println!(
                "smoothed offline: ATE RMSE {smoothed:.3} m (fitted {})",
                report
                    .ate_rmse_smoothed_aligned_m
                    .map_or("-".to_string(), |a| format!("{a:.3} m"))
            );
        }
    }
    println!(
        "particles p50 {:.0} (max {:.0}); filter {:.1} ms per rotation p50 ({:.1} p95), with scan building {:.1} ms p50; {} recoveries; outputs in {}",
        report.particles.p50,
        report.particles.max,
        report.filter_time_ms.p50,
        report.filter_time_ms.p95,
        report.rotation_time_ms.p50,
        report.recoveries.len(),
        output.display()
    );
}
