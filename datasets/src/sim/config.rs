//! The simulator's configuration: one struct per sensor or stage, all with
//! documented units and defaults, read from TOML by the CLI.

use super::{
    DvlSimConfig, GpsSimConfig, HeadingSimConfig, ReplayConfig, SimError, SonarSimConfig,
    VehicleConfig,
};
use echofield_frontend::sensors::SensorMounting;
use echofield_graph::Se2;
use serde::{Deserialize, Serialize};

/// Everything [`super::simulate_mission`] can be told. Unknown keys are
/// errors; missing keys take the defaults below.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimConfig {
    /// Absolute time of the start of a simulated mission, Unix seconds
    /// (default 2024-06-01 10:00:00 UTC). The St Pere replay keeps the real
    /// log times instead.
    pub start_stamp_s: f64,
    /// Rate of the ground-truth poses written into the mission, Hz.
    pub ground_truth_rate_hz: f64,
    /// Sensor placement on the vehicle. Default: the sonar head 0.33 m ahead
    /// of the vehicle origin and turned 180 deg in yaw, as on the Ictineu
    /// AUV of the St Pere data set (so that consumers exercise a non-trivial
    /// `vehicle_from_sonar`); the DVL at the origin, aligned.
    pub mounting: SensorMounting,
    pub vehicle: VehicleConfig,
    pub sonar: SonarSimConfig,
    pub dvl: DvlSimConfig,
    pub heading: HeadingSimConfig,
    /// Settings of the St Pere replay only.
    pub replay: ReplayConfig,
    /// Position fixes at the surface; off by default.
    pub gps: GpsSimConfig,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            start_stamp_s: 1_717_236_000.0,
            ground_truth_rate_hz: 10.0,
            mounting: SensorMounting {
                vehicle_from_sonar: Se2::new(0.33, 0.0, std::f64::consts::PI),
                vehicle_from_dvl: Se2::identity(),
                heading_offset_rad: 0.0,
                ..Default::default()
            },
            vehicle: VehicleConfig::default(),
            sonar: SonarSimConfig::default(),
            dvl: DvlSimConfig::default(),
            heading: HeadingSimConfig::default(),
            replay: ReplayConfig::default(),
            gps: GpsSimConfig::default(),
        }
    }
}

impl SimConfig {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), SimError> {
        check_ranges(&[
            ("start_stamp_s", self.start_stamp_s, -1e12, 1e12),
            (
                "ground_truth_rate_hz",
                self.ground_truth_rate_hz,
                0.01,
                1000.0,
            ),
        ])?;
        for (field, pose) in [
            (
                "mounting.vehicle_from_sonar",
                &self.mounting.vehicle_from_sonar,
            ),
            ("mounting.vehicle_from_dvl", &self.mounting.vehicle_from_dvl),
        ] {
            if !pose.is_finite() || pose.translation().norm() > 100.0 {
                return Err(SimError::config(
                    field,
                    "must be finite and within 100 m of the vehicle origin",
                ));
            }
        }
        self.vehicle.validate()?;
        self.sonar.validate()?;
        self.dvl.validate()?;
        self.heading.validate()?;
        self.replay.validate()?;
        self.gps.validate()
    }
}

/// Fails on the first `(field, value, min, max)` whose value is not finite
/// or lies outside `[min, max]`.
pub(crate) fn check_ranges(checks: &[(&str, f64, f64, f64)]) -> Result<(), SimError> {
    for &(field, value, min, max) in checks {
        if !value.is_finite() {
            return Err(SimError::config(
                field,
                format!("{value} is not a finite number"),
            ));
        }
        if value < min || value > max {
            return Err(SimError::config(
                field,
                format!("{value} is outside [{min}, {max}]"),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_config_is_valid_and_round_trips_through_json() {
        let config = SimConfig::default();
        config.validate().unwrap();
        let text = serde_json::to_string(&config).unwrap();
        let back: SimConfig = serde_json::from_str(&text).unwrap();
        assert_eq!(back, config);
    }

    #[test]
    fn missing_keys_take_defaults_and_unknown_keys_are_rejected() {
        let partial: SimConfig = serde_json::from_str(r#"{"sonar": {"bins": 250}}"#).unwrap();
        assert_eq!(partial.sonar.bins, 250);
        assert_eq!(
            partial.sonar.bin_size_m,
            SonarSimConfig::default().bin_size_m
        );
        let err = serde_json::from_str::<SimConfig>(r#"{"sonar": {"binz": 250}}"#).unwrap_err();
        assert!(err.to_string().contains("binz"), "{err}");
        let err = serde_json::from_str::<SimConfig>(r#"{"speed": 1.0}"#).unwrap_err();
        assert!(err.to_string().contains("speed"), "{err}");
    }

    #[test]
    fn validation_names_the_bad_field() {
        type Breaker = Box<dyn Fn(&mut SimConfig)>;
        let cases: Vec<(&str, Breaker)> = vec![
            ("sonar.bin_size_m", Box::new(|c| c.sonar.bin_size_m = 0.0)),
            ("sonar.bins", Box::new(|c| c.sonar.bins = 0)),
            (
                "sonar.beam_width_rad",
                Box::new(|c| c.sonar.beam_width_rad = f64::NAN),
            ),
            (
                "sonar.blind_zone_m",
                Box::new(|c| c.sonar.blind_zone_m = 60.0),
            ),
            (
                "sonar.beam_time_jitter_s",
                Box::new(|c| c.sonar.beam_time_jitter_s = 0.05),
            ),
            (
                "dvl.noise_std_mps",
                Box::new(|c| c.dvl.noise_std_mps = -0.1),
            ),
            (
                "dvl.invalid_probability",
                Box::new(|c| c.dvl.invalid_probability = 1.5),
            ),
            (
                "heading.rate_hz",
                Box::new(|c| c.heading.rate_hz = f64::INFINITY),
            ),
            (
                "vehicle.cruise_speed_mps",
                Box::new(|c| c.vehicle.cruise_speed_mps = 0.0),
            ),
            (
                "ground_truth_rate_hz",
                Box::new(|c| c.ground_truth_rate_hz = 0.0),
            ),
            ("gps.noise_std_m", Box::new(|c| c.gps.noise_std_m = 0.0)),
            ("gps.period_s", Box::new(|c| c.gps.period_s = f64::NAN)),
            (
                "replay.dgps_smoothing_s",
                Box::new(|c| c.replay.dgps_smoothing_s = -1.0),
            ),
            (
                "mounting.vehicle_from_sonar",
                Box::new(|c| c.mounting.vehicle_from_sonar = Se2::new(f64::NAN, 0.0, 0.0)),
            ),
        ];
        for (field, breaks) in cases {
            let mut config = SimConfig::default();
            breaks(&mut config);
            match config.validate() {
                Err(SimError::InvalidConfig { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: expected an InvalidConfig error, got {other:?}"),
            }
        }
    }
}
