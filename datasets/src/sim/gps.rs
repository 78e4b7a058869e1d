//! Position fixes from the ground truth: a GPS receiver at the vehicle
//! origin that has a fix while the vehicle is at the surface (the first
//! and the last `surface_s` of the mission: before it dives and after it
//! comes up), one fix every `period_s`, each with independent Gaussian
//! noise on both axes. Off by default (`period_s = 0`), so that missions
//! simulated without a `[gps]` section are unchanged.
//!
//! The fixes are in the simulated world frame, which every mission of one
//! scene shares: the plane a merge of those missions needs
//! ([`echofield_frontend::sensors::PositionFix`]).

use super::{SimError, Trajectory};
use echofield_frontend::sensors::PositionFix;
use rand::Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

/// The simulated GPS.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GpsSimConfig {
    /// Time between two fixes, s; 0 (the default) writes no fixes.
    pub period_s: f64,
    /// Standard deviation of the noise on each axis, m; also each fix's
    /// `std_m`.
    pub noise_std_m: f64,
    /// Fixes are written only within this long of the start and of the
    /// end of the mission (the vehicle at the surface), s; at least half
    /// the mission's length gives fixes throughout.
    pub surface_s: f64,
}

impl Default for GpsSimConfig {
    fn default() -> Self {
        Self {
            period_s: 0.0,
            noise_std_m: 2.0,
            surface_s: 300.0,
        }
    }
}

impl GpsSimConfig {
    pub fn validate(&self) -> Result<(), SimError> {
        super::config::check_ranges(&[
            ("gps.period_s", self.period_s, 0.0, 3600.0),
            ("gps.noise_std_m", self.noise_std_m, 0.001, 1000.0),
            ("gps.surface_s", self.surface_s, 0.0, 1e7),
        ])
    }

    /// Whether the simulated mission gets fixes.
    pub fn enabled(&self) -> bool {
        self.period_s > 0.0
    }
}

/// The fixes along `truth` (none when `config` is off), stamped every
/// `period_s` from the start of the ground truth, each drawn from `rng`
/// (two standard normal draws per fix, in stamp order).
pub fn simulate_fixes<R: Rng>(
    truth: &Trajectory,
    config: &GpsSimConfig,
    rng: &mut R,
) -> Vec<PositionFix> {
    if !config.enabled() {
        return Vec::new();
    }
    let (start_s, end_s) = (truth.start_s(), truth.end_s());
    let count = ((end_s - start_s) / config.period_s).floor() as usize + 1;
    (0..count)
        .map(|k| start_s + k as f64 * config.period_s)
        .filter(|t| t - start_s <= config.surface_s || end_s - t <= config.surface_s)
        .map(|stamp_s| {
            let p = truth.pose_at(stamp_s);
            let (ex, ey): (f64, f64) = (rng.sample(StandardNormal), rng.sample(StandardNormal));
            PositionFix {
                stamp_s,
                x_m: p.x() + config.noise_std_m * ex,
                y_m: p.y() + config.noise_std_m * ey,
                std_m: config.noise_std_m,
            }
        })
        .collect()
}
