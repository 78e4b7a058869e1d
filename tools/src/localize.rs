//! `echofield localize`: Monte Carlo localisation of a mission on the
//! acoustic map of an earlier run (issue 38).
//!
//! 1. [`run_folder`] and [`map`]: the prior map rebuilt from the run's
//!    output folder (its mission, config and optimised poses) as one
//!    likelihood field.
//! 2. [`replay`]: the mission replayed causally; per rotation the particle
//!    filter ([`echofield_frontend::localization`]) moves by the forward
//!    dead reckoning and weighs the rotation's scan on the field (eq. 5).
//! 3. [`smooth`]: offline, the filter's fixes and the dead reckoning
//!    between rotations in one pose graph over the mission, solved by the
//!    backend: the smoothed trajectory beside the causal one.
//! 4. [`report`] and [`outputs`]: the verdict, convergence, accuracy,
//!    particles and time per rotation; TUM, CSV, PNG, MCAP.
//!
//! ```no_run
//! use echofield::localize::{LocalizeConfig, load_prior_map, localize};
//! use echofield::slam::load_mission;
//! let config = LocalizeConfig::default();
//! let map = load_prior_map(std::path::Path::new("out/marina1"), &config.localize)?;
//! let mission = load_mission(std::path::Path::new("marina2.mcap"))?;
//! let localized = localize(&mission, &map, &config.localize)?;
//! println!("{:?}", localized.rotations.last().map(|r| r.step.state));
//! # Ok::<(), anyhow::Error>(())
//! ```

pub mod map;
pub mod odometry;
pub mod outputs;
pub mod replay;
pub mod report;
pub mod run_folder;
pub mod smooth;

pub use map::{PriorMap, build_prior_map};
pub use replay::{Localized, localize_mission};
pub use report::{LocalizeReport, build_report};
pub use run_folder::load_prior_map;

use anyhow::{Context, Result};
use echofield_frontend::localization::{LocalizationConfig, MonteCarloLocalizer};
use echofield_frontend::sensors::Mission;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// `tools/configs/localize.toml`: the `[localize]` defaults, documented.
pub const DOCUMENTED_DEFAULTS: &str = include_str!("../configs/localize.toml");

/// What `echofield localize --config FILE` reads: the `[localize]` section
/// (every key optional; an unknown key is an error naming it). The scans
/// are built with the map run's own config (its `config.toml`), so that
/// they match the map's images.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LocalizeConfig {
    pub localize: LocalizationConfig,
}

impl LocalizeConfig {
    /// Parses TOML laid over the defaults; errors name the key's path.
    pub fn from_toml_str(text: &str) -> Result<Self> {
        let config: Self = crate::config_file::from_toml_over(text, &Self::default())
            .map_err(|e| anyhow::anyhow!("config key `{}`: {}", e.path, e.message))?;
        config
            .localize
            .validate()
            .map_err(|e| anyhow::anyhow!("[localize] {e}"))?;
        Ok(config)
    }

    /// The file's config when given, else the defaults.
    pub fn from_optional_toml_file(path: Option<&Path>) -> Result<Self> {
        let Some(path) = path else {
            return Ok(Self::default());
        };
        let text = crate::config_file::read_config_text(path)?;
        Self::from_toml_str(&text).with_context(|| format!("in config {}", path.display()))
    }

    /// The effective config as TOML.
    pub fn to_toml_string(&self) -> Result<String> {
        Ok(toml::to_string_pretty(self)?)
    }
}

/// Localises `mission` on `map` (see the module doc).
pub fn localize(
    mission: &Mission,
    map: &PriorMap,
    config: &LocalizationConfig,
) -> Result<Localized> {
    let mut filter = MonteCarloLocalizer::new(config, map.field.clone())
        .map_err(|e| anyhow::anyhow!("[localize] {e}"))?;
    let mut localized = localize_mission(mission, &map.config, &mut filter)
        .with_context(|| format!("localising {}", mission.name))?;
    let rotations = smooth::smoothing_rotations(&localized.rotations, config);
    match smooth::smooth_trajectory(&rotations) {
        Ok(poses) => localized.smoothed = Some(poses),
        Err(e) => tracing::warn!(
            "{}: no smoothed trajectory (the filtered one stands): {e:#}",
            mission.name
        ),
    }
    Ok(localized)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_documented_defaults_are_exactly_the_built_in_defaults() {
        let parsed: LocalizeConfig = toml::from_str(DOCUMENTED_DEFAULTS).unwrap();
        assert_eq!(parsed, LocalizeConfig::default());
        // And every key is there (a key left out would take its default
        // above and hide a missing line).
        let table: toml::Table = toml::from_str(DOCUMENTED_DEFAULTS).unwrap();
        let documented = table["localize"].as_table().unwrap().len();
        let built_in = toml::Table::try_from(LocalizationConfig::default())
            .unwrap()
            .len();
        assert_eq!(documented, built_in);
    }

    #[test]
    fn every_key_is_documented() {
        let mut previous = "";
        for line in DOCUMENTED_DEFAULTS.lines() {
            let is_key = line.contains(" = ") && !line.starts_with('#');
            if is_key || line.starts_with('[') {
                assert!(previous.starts_with('#'), "undocumented: {line}");
            }
            previous = line;
        }
    }

    #[test]
    fn an_unknown_key_is_named() {
        let err = LocalizeConfig::from_toml_str("[localize]\nmax_particle = 5\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("max_particle"), "{err}");
        let err = LocalizeConfig::from_toml_str("[localize]\nmin_fit = 2.0\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("min_fit"), "{err}");
    }
}
