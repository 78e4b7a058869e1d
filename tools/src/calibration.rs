//! `echofield calibrate`: the sensor mounting of a mission estimated from
//! its own data ([`echofield_frontend::calibration`]), with the settings of
//! a pipeline config file, and written back as a config file that
//! `echofield run` accepts.
//!
//! The settings file is a pipeline config (every section of
//! [`SlamConfig`]) plus an optional `[calibration]` section
//! ([`CalibrationConfig`]). Its `[mounting]` is the starting point: the
//! values the data cannot determine are kept from it (or from the mission
//! where it sets none). The file written ([`output::config_toml`]) holds a
//! `[mounting]` with every key of the sonar head, each with its
//! uncertainty as a comment, followed by the settings file's other
//! pipeline sections, so that `run` builds its scans as the calibration
//! did.

pub mod output;

use crate::slam::{SlamConfig, SlamError, check_sensors};
use anyhow::{Context, Result};
use echofield_frontend::calibration::{Calibration, CalibrationConfig, calibrate};
use echofield_frontend::dead_reckoning;
use echofield_frontend::sensors::Mission;
use std::path::Path;

/// The name of the section of [`CalibrationConfig`] in a settings file.
pub const SECTION: &str = "calibration";

/// What `echofield calibrate` is told by its `--config` file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CalibrateSettings {
    /// The pipeline's sections: the mounting to start from, and the
    /// dead reckoning, rotation and segmentation the returns are built
    /// with.
    pub slam: SlamConfig,
    /// `[calibration]`.
    pub calibration: CalibrationConfig,
    /// The file's sections other than `[mounting]` and `[calibration]`, as
    /// written: they are copied into the output.
    pub other_sections: toml::Table,
}

impl CalibrateSettings {
    /// Parses a settings file's text (module doc). Errors name the key by
    /// its TOML path (`calibration.window_rotations`, `segmentation.x`).
    pub fn from_toml_str(text: &str) -> Result<Self, SlamError> {
        let mut table: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| SlamError::config("(document)", e.to_string()))?;
        let calibration = match table.remove(SECTION) {
            None => CalibrationConfig::default(),
            Some(value) => {
                let config: CalibrationConfig =
                    serde_path_to_error::deserialize(value).map_err(|e| {
                        SlamError::config(
                            format!("{SECTION}.{}", e.path()),
                            e.into_inner().to_string().trim_end().to_string(),
                        )
                    })?;
                config.validate().map_err(|e| match e {
                    echofield_frontend::FrontendError::InvalidConfig { field, message } => {
                        SlamError::config(format!("{SECTION}.{field}"), message)
                    }
                    other => SlamError::config(SECTION, other.to_string()),
                })?;
                config
            }
        };
        let rest =
            toml::to_string(&table).map_err(|e| SlamError::config("(document)", e.to_string()))?;
        let slam = SlamConfig::from_toml_str(&rest)?;
        table.remove("mounting");
        Ok(Self {
            slam,
            calibration,
            other_sections: table,
        })
    }

    /// Reads a settings file, or gives the defaults without one.
    pub fn from_optional_file(path: Option<&Path>) -> Result<Self> {
        let Some(path) = path else {
            return Ok(Self::default());
        };
        let text = crate::config_file::read_config_text(path)?;
        Self::from_toml_str(&text).with_context(|| format!("in config {}", path.display()))
    }
}

/// Calibrates `mission` under `settings`: its `[mounting]` laid over the
/// mission's, then the dead reckoning, then
/// [`echofield_frontend::calibration::calibrate`].
///
/// Errors: a mission without beams, valid DVL samples or heading; a
/// `[mounting]` the mission cannot take; a failed dead reckoning or
/// calibration (too few rotations, no echo).
pub fn calibrate_mission(mission: &Mission, settings: &CalibrateSettings) -> Result<Calibration> {
    let mission = settings.slam.mounting.apply(mission).map_err(|e| match e {
        echofield_frontend::FrontendError::InvalidConfig { field, message } => {
            anyhow::Error::new(SlamError::config(format!("mounting.{field}"), message))
        }
        other => anyhow::Error::new(other).context("[mounting] does not apply"),
    })?;
    check_sensors(&mission)?;
    let navigation =
        dead_reckoning::run(&mission, &settings.slam.dead_reckoning).context("dead reckoning")?;
    let result = calibrate(
        &mission,
        &navigation,
        &settings.slam.rotation,
        &settings.slam.segmentation,
        &settings.calibration,
    )?;
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_calibration_section_is_split_from_the_pipeline_sections() {
        let text = "[calibration]\nwindow_rotations = 4\n\n[mounting]\nsonar_yaw_deg = 90.0\n\n\
                    [segmentation]\nmin_intensity = 60.0\n";
        let settings = CalibrateSettings::from_toml_str(text).unwrap();
        assert_eq!(settings.calibration.window_rotations, 4);
        assert_eq!(settings.slam.mounting.sonar_yaw_deg, Some(90.0));
        assert_eq!(settings.slam.segmentation.min_intensity, 60.0);
        let kept: Vec<&String> = settings.other_sections.keys().collect();
        assert_eq!(kept, ["segmentation"]);
    }

    #[test]
    fn bad_keys_are_named_by_their_path() {
        for (text, path) in [
            ("[calibration]\nwindow_rotation = 4\n", "calibration"),
            (
                "[calibration]\nwindow_rotations = 1\n",
                "calibration.window_rotations",
            ),
            ("[segmentation]\nmin_intensityy = 1.0\n", "segmentation"),
            ("[calibration\n", "(document)"),
        ] {
            let err = CalibrateSettings::from_toml_str(text)
                .unwrap_err()
                .to_string();
            assert!(err.contains(path), "{text}: {err}");
        }
    }
}
