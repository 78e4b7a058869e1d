//! `echofield calibrate`: estimates a mission's sonar mounting from its own
//! data and writes it as a config file for `echofield run`
//! ([`echofield::calibration`]).

use anyhow::{Context, Result};
use echofield::calibration::output::{config_toml, summary_lines};
use echofield::calibration::{CalibrateSettings, calibrate_mission};
use echofield::output::{write_atomic, write_bytes_atomic};
use echofield::slam::{SlamConfig, load_mission_with_keyframes};
use std::path::PathBuf;
use std::time::Instant;

const EXAMPLES: &str = "\
Examples:
  # A mission in MCAP: the head's angle convention and yaw (and its
  # position where the data can tell), written as a [mounting] section
  echofield simulate --scenario marina --seed 1 --output marina.mcap
  echofield calibrate marina.mcap --output cal.toml
  echofield run marina.mcap --config cal.toml --output out/marina

  # The real St Pere sonar: a folder of its point sets (keyFrameTimeStamps.csv
  # and pclKeyFrameK.pcd) beside the navigation logs; the sweep direction
  # (which the point sets do not record) is estimated too
  echofield calibrate datasets/stpere-marina --keyframes stpere-keyframes --output cal.toml
  echofield run datasets/stpere-marina --keyframes stpere-keyframes --config cal.toml \\
    --output out/stpere-real

  # The pipeline settings the returns are built with, calibration settings,
  # and the whole result as JSON
  echofield calibrate marina.mcap --config my.toml --output cal.toml --json cal.json

Nothing but the mission's sonar, DVL and heading is used (never its ground
truth). Each returned echo is placed in the world with the dead-reckoned
pose at its beam's time and a candidate mounting, and the mounting that
makes windows of a few consecutive rotations sharpest is kept. Every value
is printed with its uncertainty (a block jackknife over the windows), or
with the reason it cannot be determined from this mission; such values are
kept from the mission (or from --config). The heading calibration is never
determined: a constant heading offset turns the whole map rigidly, which no
sharpness can see; it needs an absolute reference such as GPS.

--config takes a pipeline config (the sections of tools/configs/default.toml;
its [mounting] is the starting point) and an optional [calibration] section:
  window_rotations     rotations per window (default 6)
  cell_size_m          grid cell, m (default: the beam spacing at the median
                       range of the returns, at least two bins)
  coarse_yaw_step_deg  step of the first search over the full circle (5)
  jackknife_blocks     blocks of windows for the uncertainties (10)
The file written holds [mounting] with every key of the sonar head and the
config's other pipeline sections, so `run --config` builds its scans the same
way. It is written atomically.";

#[derive(Debug, clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// The mission: an MCAP file, or a St Pere log folder.
    pub mission: PathBuf,
    /// With a St Pere navigation folder as the mission: a folder of
    /// thresholded point sets to rebuild the beams from, under the sweep of
    /// the config's `[mounting] sweep` (default `angle_increasing`; the
    /// calibration tries both).
    #[arg(long, value_name = "KF_DIR")]
    pub keyframes: Option<PathBuf>,
    /// Pipeline configuration (TOML) with an optional `[calibration]`
    /// section; defaults for missing keys.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// The config file to write (TOML with a `[mounting]` section).
    #[arg(long, short, value_name = "CAL.toml")]
    pub output: PathBuf,
    /// Also write the whole result as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

/// The JSON file of `--json`.
#[derive(serde::Serialize)]
struct JsonReport<'a> {
    mission: &'a str,
    calibration: &'a echofield_frontend::calibration::Calibration,
}

pub fn run(args: Args) -> Result<()> {
    super::prepare_output_files([Some(&args.output), args.json.as_ref()])?;
    let settings = CalibrateSettings::from_optional_file(args.config.as_deref())?;
    let start = Instant::now();
    let mission = load_mission_with_keyframes(
        &args.mission,
        args.keyframes.as_deref(),
        settings.slam.mounting.sweep,
    )?;
    let result = calibrate_mission(&mission, &settings)
        .with_context(|| format!("cannot calibrate {}", args.mission.display()))?;
    for line in summary_lines(&result, &mission.name) {
        println!("{line}");
    }
    let text = config_toml(&result, &mission.name, &settings.other_sections);
    // What is written must be a config `run` accepts.
    SlamConfig::from_toml_str(&text)
        .context("the calibrated config does not parse as a pipeline config")?;
    write_bytes_atomic(&args.output, text.as_bytes())
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    if let Some(path) = &args.json {
        let report = JsonReport {
            mission: &mission.name,
            calibration: &result,
        };
        write_atomic(path, |w| {
            serde_json::to_writer_pretty(&mut *w, &report)?;
            writeln!(w)?;
            Ok(())
        })
        .with_context(|| format!("cannot write {}", path.display()))?;
    }
    let keyframes = args
        .keyframes
        .as_ref()
        .map_or(String::new(), |k| format!(" --keyframes {}", k.display()));
    println!(
        "wrote {} ({:.1} s); use it with: echofield run {}{keyframes} --config {} --output DIR",
        args.output.display(),
        start.elapsed().as_secs_f64(),
        args.mission.display(),
        args.output.display()
    );
    Ok(())
}
