//! `echofield run`: the SLAM pipeline over a whole mission, outputs into a
//! folder. The pipeline itself is `echofield::slam::run_mission`; this
//! command reads the mission and the config, drives a progress bar and
//! writes the outputs.

use anyhow::{Context, Result};
use echofield::output::folder::OutputFolder;
use echofield::slam::online::run_online_taking_beams;
use echofield::slam::outputs::{FOLDER_FILES, write_output_files};
use echofield::slam::result::Report;
use echofield::slam::{
    ProgressSink, RunInfo, SlamConfig, load_mission_choosing, load_mission_with_keyframes,
    run_mission_taking_beams,
};
use echofield_datasets::mcap::{ChannelUse, TopicChoice};
use echofield_frontend::sensors::Mission;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

const EXAMPLES: &str = "\
Examples:
  # A mission recorded or simulated into MCAP, default configuration
  echofield run marina.mcap --output out/marina

  # With a configuration file (TOML; every key optional, unknown keys are errors)
  echofield run marina.mcap --config tools/configs/marina.toml --output out/marina

  # A St Pere log folder that holds the raw beams (_IS.log)
  echofield run path/to/stpere-logs --output out/stpere

  # St Pere navigation with the sonar's thresholded point sets, and the
  # mounting that `echofield calibrate` estimated
  echofield run datasets/stpere-marina --keyframes datasets/stpere-marina-sonar \
    --config cal.toml --output out/stpere-real

  # A ROS 2 recording (rosbag2 folder, MCAP storage) with two odometry
  # topics: the one to evaluate against is chosen; the run lists every topic
  # it used or skipped, and why
  echofield run my_bag --topic ground_truth=/gps/odom --output out/bag

  # A ROS 1 bag with two sonar and two Imu topics, the filtered odometry's
  # twist as velocity (a topic chosen for one role feeds no other)
  echofield run mission.bag --topic sonar=/sonar_micron_ros \
    --topic heading=/imu/data --topic dvl=/odometry/filtered --output out/bag

  # Online: the mission fed record by record through the causal engine; each
  # node's estimate as emitted goes to online_tum.txt, the latency per
  # rotation and the ATE of the emitted estimates to report.json → online
  echofield run marina.mcap --online --output out/marina-online

  # Two missions of one harbour merged into one map: each is run, the
  # second placed on the first's map from its scans, then one graph is solved
  echofield run survey1.mcap survey2.mcap --output out/harbour

  # Make a mission to try it on
  echofield simulate --scenario marina --seed 1 --output marina.mcap

Exit status: 0 for an ok run; 3 when the run wrote every output but judged
its own result suspect (report.json → health: the sonar and the navigation
disagree, as with a wrong sonar mounting; the summary names the likely cause
and the remedy), unless --allow-suspect is given; 1 for any error.

OUTPUT is checked before any work and written whole: the outputs go into a
fresh folder beside it that replaces it at the end, so OUTPUT is always the
previous complete output or the new one. Only an empty folder or an output
of an earlier run is replaced; report.json → run names the run that wrote it.

The config sections are [mounting], [dead_reckoning], [rotation], [segmentation],
[image], [matcher], [sequential], [loops], [backend] and [evaluation]; see
tools/configs/default.toml for every key with its default and unit. The
effective config is written to OUTPUT/config.toml, the measured numbers to
OUTPUT/report.json (ATE, RPE and loop precision/recall when the mission has
ground truth).";

#[derive(Debug, clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// The mission: an MCAP file (echofield's or a ROS 2 recording), a
    /// rosbag2 folder (MCAP or sqlite3 storage), a ROS 1 bag, or a St Pere
    /// log folder. ROS recordings: standard messages (the help of
    /// convert ros lists them), the sonar mounting from /tf_static.
    pub mission: PathBuf,
    /// More missions of the same place (same kinds of input as MISSION):
    /// each is run on its own, placed on the map of the missions before it
    /// by a global search of its scans (no shared start pose is assumed),
    /// and merged with them into one pose graph (see "Several missions"
    /// in the README). The outputs are then those of `slam::multi`.
    #[arg(value_name = "MORE_MISSIONS")]
    pub more_missions: Vec<PathBuf>,
    /// ROS input: the topic that feeds a stream, as ROLE=/name (roles:
    /// sonar, dvl, heading, ground_truth, position_fix); repeat for several. A stream
    /// with one topic of a type echofield reads needs none; a topic chosen
    /// for one role feeds no other.
    #[arg(long = "topic", value_name = "ROLE=/NAME", value_parser = TopicChoice::parse_assignment)]
    pub topics: Vec<(usize, String)>,
    /// Pipeline configuration (TOML); defaults for missing keys.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// With a St Pere navigation folder as the mission: a folder of
    /// thresholded point sets (`keyFrameTimeStamps.csv`,
    /// `pclKeyFrameK.pcd`) to rebuild the beams from, under the sweep of
    /// the config's `[mounting] sweep` (default `angle_increasing`).
    #[arg(long, value_name = "KF_DIR")]
    pub keyframes: Option<PathBuf>,
    /// Output folder (created if needed). Checked before any work and
    /// replaced whole at the end; only an empty folder or an earlier
    /// echofield output is replaced.
    #[arg(long, short)]
    pub output: PathBuf,
    /// Worker threads (default: one per core, or RAYON_NUM_THREADS); the
    /// results do not depend on it.
    #[arg(long, value_name = "N")]
    pub threads: Option<std::num::NonZeroUsize>,
    /// Exit with status 0 even when the run judges its result suspect
    /// (report.json → health); without it such a run exits with status 3,
    /// after writing every output.
    #[arg(long)]
    pub allow_suspect: bool,
    /// Run causally, as on the vehicle: the mission is fed record by record
    /// in time order through the SLAM engine with the forward dead-reckoning
    /// filter (no smoother, no look-ahead); each node's estimate as it was
    /// when its rotation completed is written to OUTPUT/online_tum.txt, the
    /// latency per rotation (p50, p95, max) and the ATE of those estimates
    /// to report.json → online. The final outputs are those of the
    /// engine's end-of-mission solve.
    #[arg(long)]
    pub online: bool,
}

/// What became of each channel of a ROS recording, one line each.
pub(crate) fn print_channels(channels: &[ChannelUse]) {
    // echofield's own files have one known channel per stream: nothing to say.
    if channels.iter().all(|c| c.schema.starts_with("echofield.")) {
        return;
    }
    for c in channels {
        let role = c
            .role
            .map_or("skipped".to_string(), |r| format!("used as {r}"));
        println!(
            "topic {} ({}, {} messages): {role}: {}",
            c.topic,
            if c.schema.is_empty() {
                "no schema"
            } else {
                &c.schema
            },
            c.messages,
            c.reason
        );
    }
}

pub fn run(args: Args) -> Result<()> {
    if !args.more_missions.is_empty() {
        return super::run_multi::run(args);
    }
    let mut inputs = vec![args.mission.as_path()];
    inputs.extend(args.keyframes.as_deref());
    let run_info = RunInfo::start("run", &inputs, args.config.as_deref(), &args.output);
    super::set_threads(args.threads)?;
    let config = SlamConfig::from_optional_toml_file(args.config.as_deref())?;
    // Before any work: a folder that cannot be written fails now.
    let folder = OutputFolder::prepare(&args.output, FOLDER_FILES)?;
    let start = Instant::now();
    let mut mission = load(&args, &config)?;
    let reading_s = start.elapsed().as_secs_f64();
    let progress = BarProgress::new();
    let failed = || format!("SLAM on {} failed", args.mission.display());
    let mut output = if args.online {
        run_online_taking_beams(&mut mission, &config, &progress).with_context(failed)?
    } else {
        run_mission_taking_beams(&mut mission, &config, &progress).with_context(failed)?
    };
    output.report.timings.reading_s = Some(reading_s);
    output.report.run = Some(run_info);
    write_output_files(folder.path(), &output, &mission)
        .and_then(|()| folder.commit())
        .with_context(|| format!("cannot write the outputs into {}", args.output.display()))?;
    let report = &output.report;
    print_summary(report, start.elapsed().as_secs_f64(), &args.output);
    // The remedy names the mission as it was read.
    let mut mission = args.mission.display().to_string();
    if let Some(keyframes) = &args.keyframes {
        mission += &format!(" --keyframes {}", keyframes.display());
    }
    super::check_health(&report.health, &mission, args.allow_suspect)
}

/// The mission of `args`: with its keyframe folder when given, else with
/// the `--topic` choices (printing what became of every channel).
fn load(args: &Args, config: &SlamConfig) -> Result<Mission> {
    if args.keyframes.is_some() {
        return load_mission_with_keyframes(
            &args.mission,
            args.keyframes.as_deref(),
            config.mounting.sweep,
        );
    }
    let mut choice = TopicChoice::default();
    for (role, topic) in &args.topics {
        choice.topics[*role] = Some(topic.clone());
    }
    let (mission, channels) = load_mission_choosing(&args.mission, &choice)?;
    print_channels(&channels);
    Ok(mission)
}

/// The lines a run prints on stdout (counts, ATE when there is ground
/// truth, online latencies, the loop summary) and its warnings as log
/// lines; `elapsed_s` is the whole run's time.
fn print_summary(report: &Report, elapsed_s: f64, output: &std::path::Path) {
    println!(
        "{}: {} nodes, {} of {} loop candidates accepted, {elapsed_s:.2} s; outputs in {}",
        report.mission,
        report.nodes,
        report.loops_accepted,
        report.loop_candidates,
        output.display()
    );
    if let (Some(ate), Some(dr)) = (report.ate_rmse_m, report.ate_rmse_dead_reckoning_m) {
        println!("ATE RMSE {ate:.3} m (dead reckoning {dr:.3} m)");
    }
    if let Some(online) = &report.online {
        println!(
            "online: {} nodes emitted, latency per rotation p50 {:.1} ms, p95 {:.1} ms, max {:.1} ms{}",
            online.nodes_emitted,
            online.latency_p50_ms,
            online.latency_p95_ms,
            online.latency_max_ms,
            online.ate_rmse_m.map_or(String::new(), |a| format!(
                ", ATE of the emitted estimates {a:.3} m"
            ))
        );
    }
    if let Some(line) = report.loop_summary() {
        println!("{line}");
    }
    for warning in &report.warnings {
        tracing::warn!("{warning}");
    }
}

/// The progress of a run on stderr: one line `[stage/stages] name`, with a
/// bar over the mission's beams during the node-by-node stage. Hidden when
/// stderr is not a terminal, and with `-q`. While it is drawn, log lines
/// go above it ([`StderrAboveBar`]).
pub struct BarProgress {
    bar: ProgressBar,
}

/// The bar being drawn, for [`StderrAboveBar`].
static ACTIVE_BAR: Mutex<Option<ProgressBar>> = Mutex::new(None);

fn bar_style(template: &str) -> ProgressStyle {
    ProgressStyle::with_template(template)
        .expect("a valid template")
        .progress_chars("=> ")
}

impl BarProgress {
    pub fn new() -> Self {
        let bar = if std::io::stderr().is_terminal() && !super::quiet() {
            ProgressBar::new(0)
        } else {
            ProgressBar::hidden()
        };
        bar.set_style(bar_style("{spinner} {prefix} {msg}"));
        if let Ok(mut active) = ACTIVE_BAR.lock() {
            *active = Some(bar.clone());
        }
        Self { bar }
    }
}

impl Default for BarProgress {
    fn default() -> Self {
        Self::new()
    }
}

impl ProgressSink for BarProgress {
    fn stage(&self, index: usize, total: usize, name: &str) {
        self.bar.set_style(bar_style("{spinner} {prefix} {msg}"));
        self.bar.set_prefix(format!("[{index}/{total}]"));
        self.bar.set_message(name.to_string());
        self.bar.tick();
    }

    fn beams(&self, done: usize, total: usize) {
        if self.bar.length() != Some(total as u64) {
            self.bar.set_style(bar_style(
                "{spinner} {prefix} {msg:36} [{bar:20}] {percent:>3}% of beams",
            ));
            self.bar.set_length(total as u64);
        }
        self.bar.set_position(done as u64);
    }

    fn node_done(&self, nodes: usize, loops: usize) {
        self.bar
            .set_message(format!("node by node: {nodes} nodes, {loops} loops"));
    }

    fn finish(&self) {
        self.bar.finish_and_clear();
        if let Ok(mut active) = ACTIVE_BAR.lock() {
            *active = None;
        }
    }
}

/// `tracing`'s writer for the CLI: stderr, with the active progress bar
/// hidden while a log line is written and redrawn below it (indicatif's
/// `suspend`), so that warnings never glue onto the bar. Written here
/// because `tracing-indicatif` ties bars to tracing spans, which this CLI
/// does not use; this is all it needs.
pub struct StderrAboveBar;

impl std::io::Write for StderrAboveBar {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let bar = ACTIVE_BAR.lock().ok().and_then(|b| b.clone());
        match bar {
            Some(bar) => bar.suspend(|| std::io::stderr().write(buf)),
            None => std::io::stderr().write(buf),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        std::io::stderr().flush()
    }
}
