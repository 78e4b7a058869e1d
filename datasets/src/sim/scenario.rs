//! A scenario: the world, the ground-truth motion through it and the
//! configuration of every sensor; [`super::simulate_mission`] turns it into
//! a mission for any seed.

use super::stpere::{ReplayData, prepare_replay};
use super::{Environment, SimConfig, SimError, Trajectory, follow_route, scenes};
use crate::stpere::read_stpere_dir;
use std::path::{Path, PathBuf};

/// Where the ground truth and the navigation records come from.
#[derive(Clone, Debug)]
pub(super) enum Source {
    /// Everything simulated from a planned route.
    Synthetic,
    /// Real navigation and beam times (St Pere), simulated beams.
    Replay(Box<ReplayData>),
}

/// A world, a ground-truth trajectory and the sensor configuration.
#[derive(Clone, Debug)]
pub struct Scenario {
    name: String,
    config: SimConfig,
    environment: Environment,
    ground_truth: Trajectory,
    pub(super) source: Source,
}

impl Scenario {
    /// The built-in scenarios.
    pub const NAMES: [&'static str; 4] = ["marina", "tank", "canyon", "stpere"];

    /// A built-in scenario with the default config (`stpere` reads the logs
    /// from [`Scenario::default_stpere_dir`]).
    pub fn named(name: &str) -> Result<Self, SimError> {
        Self::build(name, SimConfig::default(), None)
    }

    /// A built-in scenario with `config`; `stpere_dir` overrides the folder
    /// of the St Pere logs (ignored by the other scenarios).
    pub fn build(
        name: &str,
        config: SimConfig,
        stpere_dir: Option<&Path>,
    ) -> Result<Self, SimError> {
        config.validate()?;
        let scene = match name {
            "marina" => scenes::marina()?,
            "tank" => scenes::tank()?,
            "canyon" => scenes::canyon()?,
            "stpere" => {
                let dir = stpere_dir.map_or_else(Self::default_stpere_dir, Path::to_path_buf);
                return Self::stpere(&dir, config);
            }
            other => {
                return Err(SimError::UnknownScenario {
                    name: other.to_string(),
                    known: Self::NAMES.join(", "),
                });
            }
        };
        let ground_truth = follow_route(&scene.route, &config.vehicle, config.start_stamp_s)?;
        Self::custom(name, scene.environment, ground_truth, config)
    }

    /// The St Pere replay from the logs in `dir` (see [`super::stpere`]).
    /// The config it keeps is the effective one: the sonar head settings of
    /// the logs and the heading offset actually used, so that running it
    /// again reproduces the same mission.
    pub fn stpere(dir: &Path, mut config: SimConfig) -> Result<Self, SimError> {
        config.validate()?;
        let logs = read_stpere_dir(dir)?;
        let (data, ground_truth, environment) =
            prepare_replay(&logs, &config.replay, &config.sonar)?;
        config.sonar = data.sonar.clone();
        config.replay.heading_offset_rad = Some(data.heading_offset_rad);
        Ok(Self {
            name: "stpere".to_string(),
            config,
            environment,
            ground_truth,
            source: Source::Replay(Box::new(data)),
        })
    }

    /// Any environment and ground-truth trajectory with simulated sensors
    /// (for tests: a wall at a known distance, a vehicle holding still).
    pub fn custom(
        name: &str,
        environment: Environment,
        ground_truth: Trajectory,
        config: SimConfig,
    ) -> Result<Self, SimError> {
        config.validate()?;
        Ok(Self {
            name: name.to_string(),
            config,
            environment,
            ground_truth,
            source: Source::Synthetic,
        })
    }

    /// `datasets/stpere-marina` of this workspace.
    pub fn default_stpere_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("stpere-marina")
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// The effective configuration (for the replay: with the sonar head
    /// settings of the logs and the heading offset in use).
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    pub fn environment(&self) -> &Environment {
        &self.environment
    }

    /// The continuous ground truth the sensors are simulated from.
    pub fn ground_truth(&self) -> &Trajectory {
        &self.ground_truth
    }

    /// For the replay: the constant added to the MTi yaw to get the
    /// ground-truth heading, rad.
    pub fn heading_offset_rad(&self) -> Option<f64> {
        match &self.source {
            Source::Synthetic => None,
            Source::Replay(data) => Some(data.heading_offset_rad),
        }
    }

    /// For the replay: the DGPS fixes `(stamp_s, [east_m, north_m])`.
    pub fn dgps_fixes(&self) -> Vec<(f64, [f64; 2])> {
        match &self.source {
            Source::Synthetic => Vec::new(),
            Source::Replay(data) => data
                .fixes
                .iter()
                .map(|f| (f.stamp_s, [f.position_m.x, f.position_m.y]))
                .collect(),
        }
    }
}
