//! The SLAM pipeline: frontend and backend joined over a whole mission.
//!
//! [`run_mission`] is what `echofield demo` and the end-to-end tests call
//! (`echofield run` and `bench-long` call [`run_mission_taking_beams`],
//! the same run with the beams moved into the nodes, not copied); it replays the mission, record by record in
//! time order, through the [`SlamEngine`] ([`engine`]), which is also
//! what an online user pushes samples into ([`run_mission_online`];
//! `echofield run M.mcap --online --output DIR` calls
//! [`run_mission_online_taking_beams`]). Per completed rotation:
//!
//! 1. **Dead reckoning** (EKF over DVL and heading, [`dead_reckoning`](echofield_frontend::dead_reckoning)):
//!    the causal filter online, the navigation computed beforehand over
//!    the whole mission (smoothed) in batch.
//! 2. **Nodes** ([`nodes`](echofield_frontend::nodes)): the beams are cut
//!    into rotations; each rotation the navigation covers becomes a node at
//!    its central pose, with `S_k` and `I_k` motion-compensated into that
//!    pose (eq. 3-4), built once.
//! 3. **Chain edges** ([`sequential`]): the dead-reckoning odometry edge
//!    `k-1 -> k` with the EKF's relative covariance, and the sequential
//!    match `S_k` vs `I_{k-1}` (eq. 5-6) as a `Sequential` edge when it
//!    passes its checks.
//! 4. **Loop closures** ([`loops`]), node by node: candidates gated by
//!    predicted overlap and relative uncertainty, `S_k` vs `I_j` and the
//!    symmetric `S_j` vs `I_k`, individual checks, and the maximum clique of
//!    mutually consistent loops; an incremental solve ([`estimate`]) each
//!    time the accepted set changes, so later candidates get corrected
//!    priors and small windows.
//! 5. **Final optimisation** ([`SlamEngine::finish`]), after loop
//!    densification, with false loops switched off
//!    ([`echofield_backend::optimize_robust`]: the graph grown in node order
//!    with the loop kernel, loops that disagree switched off, least squares
//!    over the rest, loops that fit switched back on); switched-off loops
//!    are rejected as `robust_kernel` and leave the graph.
//! 6. **Evaluation** ([`evaluation`]) when the mission has ground truth,
//!    strictly after the estimation.
//!
//! Bad input: a mission without beams, without valid DVL samples or without
//! heading is a [`SlamError::MissingSensor`]; rotations outside the
//! navigation's span are skipped and reported; gaps in the DVL or between
//! rotations are bridged by dead reckoning and reported
//! ([`result::TimeGap`]); a mission without any loop closure gives the
//! dead-reckoning-plus-sequential trajectory.
//!
//! Determinism: rotations are processed one at a time in the order they
//! complete; parallel work inside a stage (rayon) collects its results in
//! order, so a mission and a config always give the same output.
//!
//! ```no_run
//! use echofield::slam::{NoProgress, SlamConfig, load_mission, run_mission};
//! let mission = load_mission(std::path::Path::new("marina.mcap"))?;
//! let output = run_mission(&mission, &SlamConfig::default(), &NoProgress)?;
//! println!("{} nodes, {} loops", output.nodes.len(), output.report.loops_accepted);
//! # Ok::<(), anyhow::Error>(())
//! ```

pub mod config;
pub mod engine;
pub mod error;
pub mod error_budget;
pub mod estimate;
pub mod evaluation;
pub mod health;
mod input_checks;
pub mod loops;
pub mod multi;
pub mod navigation_rate;
pub mod node_record;
pub mod odometry_scale;
pub mod online;
pub mod outputs;
pub mod refine;
pub mod result;
pub mod sequential;

pub(crate) mod pipeline;

pub use config::{BackendConfig, EvaluationConfig, SequentialConfig, SlamConfig};
pub use engine::{NodeEvent, SlamEngine};
pub use error::SlamError;
pub use node_record::NodeRecord;
pub use pipeline::{
    replay, run_mission, run_mission_online, run_mission_online_taking_beams,
    run_mission_taking_beams,
};
pub use result::{
    IntensityReport, OnlineReport, RecallBin, RecallBudget, Report, RunInfo, SlamOutput,
    StageTimings,
};

use anyhow::{Context, Result, bail};
use echofield_datasets::{mcap, stpere};
use echofield_frontend::sensors::{Mission, SweepTiming};
use std::path::Path;

/// Progress of a run, for a progress bar. Every method has an empty
/// default; [`NoProgress`] ignores everything.
pub trait ProgressSink: Sync {
    /// Stage `index` (1-based) of the run's `total` stages starts
    /// (`"dead reckoning"`, `"node by node"`, `"final optimisation"`).
    fn stage(&self, _index: usize, _total: usize, _name: &str) {}
    /// `done` of the mission's `total` sonar beams have been fed to the
    /// engine (the count of the node-by-node stage).
    fn beams(&self, _done: usize, _total: usize) {}
    /// `nodes` nodes have been emitted; `loops` loops are accepted so far.
    fn node_done(&self, _nodes: usize, _loops: usize) {}
    /// The run is over (successfully or not).
    fn finish(&self) {}
}

/// A [`ProgressSink`] that reports nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoProgress;

impl ProgressSink for NoProgress {}

/// Reads a mission: an echofield (or ROS 2) MCAP file, a rosbag2 folder
/// (`metadata.yaml`, MCAP or sqlite3 storage), a ROS 1 bag, or a St Pere
/// log folder (which must hold the raw beams, `_IS.log`).
pub fn load_mission(path: &Path) -> Result<Mission> {
    load_mission_choosing(path, &mcap::TopicChoice::default()).map(|(m, _)| m)
}

/// [`load_mission`] with the topics of a ROS recording chosen by
/// `topics` (`--topic ROLE=/name`); also returns what became of each
/// channel of a ROS or echofield MCAP input (empty for St Pere logs).
pub fn load_mission_choosing(
    path: &Path,
    topics: &mcap::TopicChoice,
) -> Result<(Mission, Vec<mcap::ChannelUse>)> {
    let ros = path.is_file() || mcap::rosbag2::is_rosbag2(path);
    if ros {
        // Its errors name the file already.
        return Ok(mcap::read_mission_with(path, topics)?);
    }
    if topics.topics.iter().any(Option::is_some) {
        bail!(
            "--topic applies to ROS recordings (an MCAP file, a rosbag2 folder or a ROS 1 bag), and {} is none of them",
            path.display()
        );
    }
    let mission = if path.is_dir() {
        let logs = stpere::read_stpere_dir(path)
            .with_context(|| format!("reading the St Pere logs in {}", path.display()))?;
        if logs.mission.beams.is_empty() {
            bail!(
                "the St Pere logs in {} hold no sonar beams (the raw `_IS.log` is not in the folder); \
                 `echofield simulate --scenario stpere --data {} --output stpere-sim.mcap` \
                 makes a replay with simulated beams",
                path.display(),
                path.display()
            );
        }
        logs.mission
    } else {
        bail!(
            "{} is neither an MCAP file, a ROS 1 bag, a rosbag2 folder nor a St Pere log folder",
            path.display()
        );
    };
    Ok((mission, Vec::new()))
}

/// The sweep a reader of point sets assumes when nothing says otherwise:
/// the head's angle increasing with time.
pub const DEFAULT_POINT_SET_SWEEP: SweepTiming = SweepTiming::AngleIncreasing;

/// Reads a mission like [`load_mission`], or, with `keyframes`, a St Pere
/// navigation folder (`path`) whose beams are rebuilt from the thresholded
/// point sets in `keyframes`
/// ([`echofield_datasets::stpere::keyframes`]) under the assumed `sweep`
/// (`None`: [`DEFAULT_POINT_SET_SWEEP`]).
pub fn load_mission_with_keyframes(
    path: &Path,
    keyframes: Option<&Path>,
    sweep: Option<SweepTiming>,
) -> Result<Mission> {
    let Some(keyframes) = keyframes else {
        return load_mission(path);
    };
    if !path.is_dir() {
        bail!(
            "--keyframes needs the St Pere navigation folder as the mission, and {} is not a folder",
            path.display()
        );
    }
    let sweep = match sweep {
        None | Some(SweepTiming::Logged) => DEFAULT_POINT_SET_SWEEP,
        Some(s) => s,
    };
    let (logs, _) =
        stpere::read_stpere_with_keyframes(path, keyframes, sweep).with_context(|| {
            format!(
                "reading the St Pere logs in {} with the point sets in {}",
                path.display(),
                keyframes.display()
            )
        })?;
    Ok(logs.mission)
}

/// Checks that the mission has the three streams the pipeline needs.
pub fn check_sensors(mission: &Mission) -> Result<(), SlamError> {
    let missing = |what: &str| SlamError::MissingSensor {
        mission: mission.name.clone(),
        what: what.to_string(),
    };
    if mission.beams.is_empty() {
        return Err(missing("no sonar beams: nothing to build scans from"));
    }
    if !mission.dvl.iter().any(|d| d.valid) {
        return Err(missing(&format!(
            "no valid DVL velocity ({} DVL samples, none valid): dead reckoning needs one",
            mission.dvl.len()
        )));
    }
    if mission.attitude.is_empty() {
        return Err(missing(
            "no heading: the mission has no attitude samples, dead reckoning needs them",
        ));
    }
    Ok(())
}
