//! The St Pere replay: the real navigation of the Ictineu AUV in the St Pere
//! Pescador marina (2004) with simulated sonar beams.
//!
//! - Ground truth: the DGPS track, smoothed and interpolated, with the MTi
//!   heading plus a constant offset ([`track`] explains the choice).
//! - Navigation: the real DVL and MTi records, unchanged (the attitude keeps
//!   the MTi's own heading: a consumer applies the offset it believes in).
//! - Sonar: one beam at every real `_IS_timestamps.log` stamp, with the bin
//!   count, bin size and step of `_SETUP.log`, simulated against a marina
//!   drawn around the real track ([`map`]).

pub mod map;
pub mod track;

use super::{Environment, SimError, SonarSimConfig, Trajectory};
use crate::stpere::{SonarSetup, StPereLogs, best_yaw_offset};
use echofield_frontend::sensors::{Attitude, DvlVelocity};
use echofield_graph::Se2;
use map::MapShape;
use nalgebra::Vector2;
use serde::{Deserialize, Serialize};
use track::Fix;

/// Settings of the St Pere replay.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReplayConfig {
    /// Constant added to the MTi yaw to get the ground-truth heading, rad.
    /// `None` (the default): the reader's best fit against DGPS
    /// (`stpere::best_yaw_offset`, about +19.4 deg on the marina mission).
    pub heading_offset_rad: Option<f64>,
    /// Standard deviation of the Gaussian kernel that smooths the 1 Hz DGPS
    /// fixes, s.
    pub dgps_smoothing_s: f64,
    /// Mean distance from the track to the walls of the drawn marina, m.
    pub wall_distance_m: f64,
    /// The wall distance varies over the area by up to ± this, m.
    pub wall_distance_variation_m: f64,
    /// Mooring blocks and moored boats scattered near the track.
    pub clutter_objects: usize,
}

impl Default for ReplayConfig {
    fn default() -> Self {
        Self {
            heading_offset_rad: None,
            dgps_smoothing_s: 4.0,
            wall_distance_m: 13.0,
            wall_distance_variation_m: 5.0,
            clutter_objects: 30,
        }
    }
}

impl ReplayConfig {
    pub fn validate(&self) -> Result<(), SimError> {
        use std::f64::consts::PI;
        if let Some(offset) = self.heading_offset_rad {
            super::config::check_ranges(&[("replay.heading_offset_rad", offset, -PI, PI)])?;
        }
        super::config::check_ranges(&[
            ("replay.dgps_smoothing_s", self.dgps_smoothing_s, 0.0, 600.0),
            (
                "replay.wall_distance_m",
                self.wall_distance_m,
                map::MIN_CLEARANCE_M + 1.0,
                45.0,
            ),
            (
                "replay.wall_distance_variation_m",
                self.wall_distance_variation_m,
                0.0,
                self.wall_distance_m - map::MIN_CLEARANCE_M - 1.0,
            ),
        ])?;
        if self.clutter_objects > 10_000 {
            return Err(SimError::config(
                "replay.clutter_objects",
                "must be at most 10000",
            ));
        }
        Ok(())
    }
}

/// What the replay takes from the real logs.
#[derive(Clone, Debug)]
pub struct ReplayData {
    pub dvl: Vec<DvlVelocity>,
    pub attitude: Vec<Attitude>,
    pub vehicle_from_dvl: Se2,
    /// Real beam times, s.
    pub beam_stamps_s: Vec<f64>,
    /// The sonar model with the head settings of `_SETUP.log` (bins, bin
    /// size, step) and the median beam period of the time stamps.
    pub sonar: SonarSimConfig,
    /// The DGPS fixes in the local frame (x east, y north).
    pub fixes: Vec<Fix>,
    /// The heading offset the ground truth uses, rad.
    pub heading_offset_rad: f64,
}

/// Ground truth rate of the replay's internal trajectory, Hz.
const TRACK_RATE_HZ: f64 = 10.0;

/// Turns the logs into replay data, the ground-truth trajectory and the
/// drawn marina. `sonar` provides the echo model; its head settings are
/// replaced by the logged ones.
pub fn prepare_replay(
    logs: &StPereLogs,
    config: &ReplayConfig,
    sonar: &SonarSimConfig,
) -> Result<(ReplayData, Trajectory, Environment), SimError> {
    let missing = |what: &str| SimError::InvalidTrajectory {
        message: format!("the St Pere logs hold no {what}"),
    };
    let setup = logs
        .sonar_setup
        .as_ref()
        .ok_or_else(|| missing("_SETUP.log"))?;
    if logs.beam_stamps.is_empty() {
        return Err(missing("beam time stamps (_IS_timestamps.log)"));
    }
    let fixes: Vec<Fix> = logs
        .dgps
        .iter()
        .map(|f| Fix {
            stamp_s: f.stamp_s,
            position_m: Vector2::new(f.east_m, f.north_m),
        })
        .collect();
    let heading_offset_rad = match config.heading_offset_rad {
        Some(offset) => offset,
        None => best_yaw_offset(&logs.mission)
            .map(|(offset, _)| offset)
            .ok_or_else(|| {
                missing("overlap of DVL, attitude and DGPS to fit the heading offset")
            })?,
    };
    let beam_stamps_s: Vec<f64> = logs.beam_stamps.iter().map(|b| b.stamp_s).collect();
    let first = beam_stamps_s[0].min(fixes.first().map_or(f64::INFINITY, |f| f.stamp_s));
    let last = beam_stamps_s[beam_stamps_s.len() - 1]
        .max(fixes.last().map_or(f64::NEG_INFINITY, |f| f.stamp_s));
    let ground_truth = track::ground_truth(
        &fixes,
        &logs.mission.attitude,
        heading_offset_rad,
        config.dgps_smoothing_s,
        (first, last),
        1.0 / TRACK_RATE_HZ,
    )?;
    let environment = map::marina_around_track(&ground_truth, &config.map_shape())?;
    let sonar = logged_head(sonar, setup, &beam_stamps_s)?;
    let data = ReplayData {
        dvl: logs.mission.dvl.clone(),
        attitude: logs.mission.attitude.clone(),
        vehicle_from_dvl: logs.mission.mounting.vehicle_from_dvl,
        beam_stamps_s,
        sonar,
        fixes,
        heading_offset_rad,
    };
    Ok((data, ground_truth, environment))
}

/// `sonar` with the head settings of the log: steps per turn and bins
/// from the setup, the beam period from the median interval of the stamps
/// (`sonar`'s when there is none), no jitter. Errors when those settings
/// are not a valid simulator head.
fn logged_head(
    sonar: &SonarSimConfig,
    setup: &SonarSetup,
    beam_stamps_s: &[f64],
) -> Result<SonarSimConfig, SimError> {
    let sonar = SonarSimConfig {
        steps_per_rotation: (2.0 * std::f64::consts::PI / setup.step_rad).round() as u32,
        beam_period_s: median_interval(beam_stamps_s).unwrap_or(sonar.beam_period_s),
        beam_time_jitter_s: 0.0,
        bins: setup.bins(),
        bin_size_m: setup.bin_size_m,
        ..sonar.clone()
    };
    sonar
        .validate()
        .map_err(|e| SimError::config("St Pere _SETUP.log", e.to_string()))?;
    Ok(sonar)
}

impl ReplayConfig {
    /// The shape of the marina drawn around the track.
    fn map_shape(&self) -> MapShape {
        MapShape {
            wall_distance_m: self.wall_distance_m,
            wall_distance_variation_m: self.wall_distance_variation_m,
            clutter_objects: self.clutter_objects,
        }
    }
}

fn median_interval(stamps: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = stamps
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    if d.is_empty() {
        return None;
    }
    d.sort_by(f64::total_cmp);
    Some(d[d.len() / 2])
}
