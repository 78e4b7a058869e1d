//! `echofield simulate`: simulate a mission with ground truth into MCAP.

use anyhow::{Context, Result};
use echofield::output::write_bytes_atomic;
use echofield_datasets::mcap::write_mission;
use echofield_datasets::sim::{Scenario, SimConfig, simulate_mission};
use std::path::{Path, PathBuf};

const EXAMPLES: &str = "\
Examples:
  # The built-in marina demo mission (40 min, ~36k beams) with seed 7
  echofield simulate --scenario marina --seed 7 --output marina.mcap

  # A quick tank mission (2 min) with a config file overriding some defaults
  echofield simulate --scenario tank --seed 1 --output tank.mcap --config sim.toml

  # The same with the beams thresholded as the published St Pere point sets
  echofield simulate --scenario marina --seed 7 --point-sets --output marina-points.mcap

  # The St Pere replay: real DVL, MTi and beam times, simulated beams
  echofield simulate --scenario stpere --data datasets/stpere-marina --output stpere-sim.mcap

Scenarios: marina (120 m x 240 m marina, loops and a lawnmower, ~40 min),
tank (20 m x 14 m, ~2 min), canyon (rock walls, out and back, ~18 min),
stpere (the real St Pere navigation with a marina drawn around its track).
The same scenario, seed and config always give a byte-identical file.

  # Two marina surveys with noisy GPS fixes at the surface (a fix every 10 s
  # for the first and last 300 s, 2 m per axis), then merged with the fixes
  # as the placement prior:
  printf '[gps]\nperiod_s = 10.0\nnoise_std_m = 2.0\n' > gps.toml
  echofield simulate --scenario marina --seed 1 --config gps.toml --output a.mcap
  echofield simulate --scenario marina --seed 2 --config gps.toml --output b.mcap
  echofield run a.mcap b.mcap --output merged

The config file is TOML with the sections [vehicle], [sonar], [dvl],
[heading], [replay], [mounting], [gps] and the top-level keys start_stamp_s and
ground_truth_rate_hz; every key is optional, unknown keys are errors (see
echofield_datasets::sim::SimConfig for units and defaults). The effective
config is written beside the output as <OUTPUT stem>.sim.toml.";

#[derive(Debug, clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// Built-in scenario.
    #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(Scenario::NAMES))]
    pub scenario: String,
    /// Seed of every random draw (sensor noise, speckle, blobs, dropouts).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Where to write the mission (MCAP).
    #[arg(long, short)]
    pub output: PathBuf,
    /// Simulator configuration (TOML); defaults for missing keys.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Keep only what a thresholded point-set log keeps (the recipe of the
    /// published St Pere point sets, `echofield_datasets::sim::point_sets`):
    /// binary intensities, walls as bands.
    #[arg(long)]
    pub point_sets: bool,
    /// Folder of the St Pere logs (--scenario stpere only); default: the
    /// workspace's datasets/stpere-marina.
    #[arg(long)]
    pub data: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<()> {
    let config_path = effective_config_path(&args.output);
    super::prepare_output_files([Some(&args.output), Some(&config_path)])?;
    let config = match &args.config {
        Some(path) => read_config(path)?,
        None => SimConfig::default(),
    };
    if args.data.is_some() && args.scenario != "stpere" {
        anyhow::bail!("--data is only used by --scenario stpere");
    }
    let scenario = Scenario::build(&args.scenario, config, args.data.as_deref())
        .with_context(|| format!("cannot set up scenario `{}`", args.scenario))?;
    let mut mission = simulate_mission(&scenario, args.seed).context("simulation failed")?;
    if args.point_sets {
        echofield_datasets::sim::point_sets::to_point_sets(&mut mission.beams);
    }
    if let Some(dir) = args.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create folder {}", dir.display()))?;
    }
    write_mission(&args.output, &mission)?;
    let effective =
        toml::to_string_pretty(scenario.config()).context("cannot serialise the config")?;
    write_bytes_atomic(&config_path, effective.as_bytes())?;
    let truth = scenario.ground_truth();
    println!(
        "wrote {}: {} beams, {} DVL, {} attitude, {} ground-truth records over {:.0} s ({:.0} m); config in {}",
        args.output.display(),
        mission.beams.len(),
        mission.dvl.len(),
        mission.attitude.len(),
        mission.ground_truth.len(),
        truth.duration_s(),
        truth.distance_travelled_m(),
        config_path.display()
    );
    Ok(())
}

fn read_config(path: &Path) -> Result<SimConfig> {
    let text = echofield::config_file::read_config_text(path)?;
    echofield::config_file::from_toml_over(&text, &SimConfig::default())
        .with_context(|| format!("invalid simulator config {}", path.display()))
}

/// `dir/mission.mcap` -> `dir/mission.sim.toml`.
fn effective_config_path(output: &Path) -> PathBuf {
    let stem = output
        .file_stem()
        .map_or_else(|| "mission".into(), |s| s.to_string_lossy());
    output.with_file_name(format!("{stem}.sim.toml"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(dir: &Path, name: &str, seed: u64, config: Option<PathBuf>) -> Args {
        Args {
            scenario: "tank".into(),
            seed,
            output: dir.join(name),
            config,
            point_sets: false,
            data: None,
        }
    }

    #[test]
    fn same_seed_writes_identical_bytes_and_another_seed_does_not() {
        let dir = tempfile::tempdir().unwrap();
        run(args(dir.path(), "a.mcap", 5, None)).unwrap();
        run(args(dir.path(), "b.mcap", 5, None)).unwrap();
        run(args(dir.path(), "c.mcap", 6, None)).unwrap();
        let read = |n: &str| std::fs::read(dir.path().join(n)).unwrap();
        assert!(
            read("a.mcap") == read("b.mcap"),
            "same seed, different bytes"
        );
        assert!(read("a.mcap") != read("c.mcap"));
        // The effective config is written beside the output and reads back.
        let text = std::fs::read_to_string(dir.path().join("a.sim.toml")).unwrap();
        let config: SimConfig = toml::from_str(&text).unwrap();
        assert_eq!(config, SimConfig::default());
    }

    #[test]
    fn config_file_is_applied_and_unknown_keys_are_rejected() {
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("good.toml");
        std::fs::write(&good, "[sonar]\nbins = 120\n").unwrap();
        run(args(dir.path(), "m.mcap", 1, Some(good))).unwrap();
        let mission = echofield_datasets::mcap::read_mission(&dir.path().join("m.mcap")).unwrap();
        assert!(mission.beams.iter().all(|b| b.intensities.len() == 120));
        let bad = dir.path().join("bad.toml");
        std::fs::write(&bad, "[sonar]\nbinz = 120\n").unwrap();
        let err = format!(
            "{:#}",
            run(args(dir.path(), "x.mcap", 1, Some(bad))).unwrap_err()
        );
        assert!(err.contains("binz") && err.contains("bad.toml"), "{err}");
        let invalid = dir.path().join("invalid.toml");
        std::fs::write(&invalid, "[dvl]\nrate_hz = -3.0\n").unwrap();
        let err = format!(
            "{:#}",
            run(args(dir.path(), "y.mcap", 1, Some(invalid))).unwrap_err()
        );
        assert!(err.contains("dvl.rate_hz"), "{err}");
        assert!(!dir.path().join("x.mcap").exists() && !dir.path().join("y.mcap").exists());
    }

    /// The shipped simulator configs of the README's known limits change
    /// exactly what their comments say, and nothing else.
    #[test]
    fn shipped_sim_configs_change_only_what_they_say() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/sim");
        let mut exact = SimConfig::default();
        exact.dvl.time_jitter_s = 0.0;
        exact.dvl.noise_std_mps = 0.0;
        exact.dvl.vertical_noise_std_mps = 0.0;
        exact.dvl.scale_error = 0.0;
        exact.dvl.invalid_probability = 0.0;
        exact.dvl.gap_rate_per_hour = 0.0;
        exact.heading.yaw_noise_std_rad = 0.0;
        exact.heading.yaw_bias_rad = 0.0;
        exact.heading.yaw_drift_std_rad = 0.0;
        exact.heading.yaw_rate_noise_std_radps = 0.0;
        let mut narrow = exact.clone();
        narrow.sonar.beam_width_rad = 0.01;
        let mut flat = SimConfig::default();
        flat.sonar.spreading_loss_db_per_decade = 0.0;
        flat.sonar.absorption_db_per_m = 0.0;
        flat.sonar.backscatter_falls_with_incidence = false;
        flat.sonar.footprint_lowers_peak = false;
        for (file, want) in [
            ("exact_navigation.toml", exact),
            ("exact_navigation_narrow_beam.toml", narrow),
            ("flat_echo.toml", flat),
        ] {
            let got = read_config(&dir.join(file)).unwrap();
            got.validate().unwrap();
            assert_eq!(got, want, "{file}");
        }
    }

    #[test]
    fn data_folder_only_goes_with_the_replay() {
        let dir = tempfile::tempdir().unwrap();
        let mut a = args(dir.path(), "m.mcap", 1, None);
        a.data = Some(dir.path().to_path_buf());
        assert!(run(a).is_err());
    }
}
