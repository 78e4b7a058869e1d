//! `echofield bench-dead-reckoning`: how much dead reckoning distorts the
//! rotations and how far its trajectory drifts, against ground truth.

use anyhow::{Context, Result};
use echofield::matching::MissionRotations;
use echofield::matching::navigation_eval::{
    Distortion, distortion, ground_truth_navigation, trajectory_errors, wall_fractions,
};
use echofield::slam::SlamConfig;
use echofield_datasets::sim::{Scenario, simulate_mission};
use echofield_datasets::stpere::read_stpere_dir;
use echofield_frontend::dead_reckoning::{self, Navigation};
use echofield_frontend::sensors::Mission;
use std::path::PathBuf;

const EXAMPLES: &str = "\
Examples:
  # The simulated marina and tank (seed 1), and the St Pere replay
  echofield bench-dead-reckoning --scenario marina --seed 1
  echofield bench-dead-reckoning --scenario stpere

  # The real St Pere marina logs against DGPS (trajectory only)
  echofield bench-dead-reckoning --stpere datasets/stpere-marina

  # A mission file with ground truth (e.g. from `echofield simulate`), and
  # the distortion left along the trajectory of a SLAM run
  echofield bench-dead-reckoning --mission stpere-sim.mcap --slam

  # Other noise parameters: a TOML file with a [dead_reckoning] section
  echofield bench-dead-reckoning --scenario marina --config dr.toml

For simulated missions and mission files with beams and ground truth it
prints the distortion of the rotations: the distance between the
dead-reckoning and the exact motion compensation of the point 5 m along
every beam, and the error of the motion over each rotation, with the three
rotations where it is largest, by index and start after the first beam (a
start, a stop or a turn that slows the vehicle, which a motion model can
follow badly, shows there and not in the median). Rotations outside the
dead reckoning's span, such as those of the St Pere replay before its
first DVL sample, are left out. For built-in scenarios the
fraction of scan points within 0.1 / 0.3 / 1 m of the environment's walls
(dead reckoning, and exact compensation for reference); and for every
mission the trajectory error at the ground-truth stamps (ATE RMSE after
SE(2) alignment; mean and max after moving the start onto the ground
truth). --slam adds the distortion left when the motion is compensated
along the trajectory of a SLAM run (the dead reckoning bent through its
optimised node poses).";

#[derive(Debug, clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// Built-in scenario to simulate.
    #[arg(long, conflicts_with_all = ["stpere", "mission"],
          value_parser = clap::builder::PossibleValuesParser::new(Scenario::NAMES))]
    pub scenario: Option<String>,
    /// Seed of the simulation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// A folder of real St Pere marina logs (DGPS as ground truth).
    #[arg(long, conflicts_with = "mission")]
    pub stpere: Option<PathBuf>,
    /// A mission file with ground truth (MCAP), instead of --scenario.
    #[arg(long)]
    pub mission: Option<PathBuf>,
    /// Configuration (TOML, as for `echofield match`; its
    /// [dead_reckoning] and [rotation] sections are used, and with --slam
    /// also [segmentation] and [image], for the SLAM run).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Also the distortion left when the motion is compensated along the
    /// trajectory of a SLAM run (default pipeline configuration).
    #[arg(long, conflicts_with = "stpere")]
    pub slam: bool,
}

pub fn run(args: Args) -> Result<()> {
    let config = match &args.config {
        Some(path) => SlamConfig::from_toml_file(path)?,
        None => SlamConfig::default(),
    };
    let (mission, scenario) = match (&args.scenario, &args.stpere, &args.mission) {
        (Some(name), None, None) => {
            let scenario = Scenario::named(name)?;
            let mission = simulate_mission(&scenario, args.seed)
                .with_context(|| format!("simulating the {name} scenario"))?;
            (mission, Some(scenario))
        }
        (None, Some(dir), None) => {
            // Real logs: navigation only (the St Pere folder holds no beams).
            let logs = read_stpere_dir(dir)
                .with_context(|| format!("reading the St Pere logs in {}", dir.display()))?;
            let nav = dead_reckoning::run(&logs.mission, &config.dead_reckoning)
                .context("dead reckoning")?;
            return print_trajectory(&logs.mission, &nav);
        }
        (None, None, Some(path)) => {
            let mission = echofield::matching::load_mission(path)?;
            if mission.ground_truth.len() < 2 {
                anyhow::bail!("{} has no ground truth to compare with", path.display());
            }
            (mission, None)
        }
        _ => anyhow::bail!("give one of --scenario, --stpere or --mission"),
    };
    let name = mission.name.clone();
    let mut rotations = MissionRotations::new(mission, &config)?;
    let (mission, nav) = (&rotations.mission, &rotations.navigation);
    println!("{name}: {} rotations", rotations.rotations.len());
    print_trajectory(mission, nav)?;
    let truth = ground_truth_navigation(mission)?;
    print_distortion("", &distortion(mission, &rotations.rotations, nav, &truth)?);
    if let Some(scenario) = &scenario {
        for (label, navigation) in [("dead reckoning", nav), ("exact", &truth)] {
            print_wall_fractions(label, &rotations, navigation, scenario)?;
        }
    }
    if args.slam {
        let report = rotations.use_slam_navigation(&config)?;
        let d = distortion(
            &rotations.mission,
            &rotations.rotations,
            &rotations.navigation,
            &truth,
        )?;
        let ate = report
            .ate_rmse_m
            .map_or(String::new(), |a| format!(", ATE {a:.3} m"));
        print_distortion(&format!(" along the SLAM trajectory{ate}"), &d);
    }
    Ok(())
}

/// How close the scan points built with `navigation` lie to the
/// scenario's walls (one line on stdout).
fn print_wall_fractions(
    label: &str,
    rotations: &MissionRotations,
    navigation: &Navigation,
    scenario: &Scenario,
) -> Result<()> {
    let w = wall_fractions(
        &rotations.mission,
        &rotations.rotations,
        navigation,
        scenario.environment(),
    )?;
    println!(
        "scan points near walls ({label}): {:.1}% within 0.1 m, {:.1}% within 0.3 m, {:.1}% within 1 m ({} points)",
        100.0 * w.within_0_1_m,
        100.0 * w.within_0_3_m,
        100.0 * w.within_1_m,
        w.points
    );
    Ok(())
}

fn print_distortion(label: &str, d: &Distortion) {
    println!(
        "distortion{label} over {} rotations: point at 5 m median {:.3} m, p90 {:.3} m, max {:.3} m; motion over a rotation median {:.3} m / {:.2}°, p90 {:.3} m / {:.2}°, max {:.3} m / {:.2}°",
        d.rotations,
        d.point_5m_m.median,
        d.point_5m_m.p90,
        d.point_5m_m.max,
        d.rotation_motion_m.median,
        d.rotation_motion_deg.median,
        d.rotation_motion_m.p90,
        d.rotation_motion_deg.p90,
        d.rotation_motion_m.max,
        d.rotation_motion_deg.max
    );
    let worst: Vec<String> = d
        .worst
        .iter()
        .map(|w| {
            format!(
                "rotation {} at {:.1} s {:.3} m / {:.2}°",
                w.index, w.start_s, w.translation_m, w.heading_deg
            )
        })
        .collect();
    println!(
        "worst rotations{label} (motion over the rotation): {}",
        worst.join("; ")
    );
}

fn print_trajectory(mission: &Mission, nav: &Navigation) -> Result<()> {
    let t = trajectory_errors(mission, nav)?;
    println!(
        "trajectory at {} ground-truth stamps: ATE RMSE (SE(2)-aligned) {:.2} m; from the start: mean {:.2} m, max {:.2} m",
        t.compared, t.ate_rmse_se2_m, t.origin_mean_m, t.origin_max_m
    );
    Ok(())
}
