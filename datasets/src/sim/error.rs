//! Errors of the mission simulator.

use crate::DatasetError;
use thiserror::Error;

/// What can go wrong when building a scenario or simulating a mission.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum SimError {
    /// A configuration value is out of its documented range.
    #[error("invalid simulator config: field `{field}`: {message}")]
    InvalidConfig { field: String, message: String },
    /// A scenario name that [`super::Scenario::named`] does not know.
    #[error("unknown scenario `{name}` (known: {known})")]
    UnknownScenario { name: String, known: String },
    /// Environment geometry that cannot be ray cast (non-finite vertex,
    /// zero-length segment, material outside [0, 1]).
    #[error("invalid environment `{environment}`: segment {segment}: {message}")]
    InvalidEnvironment {
        environment: String,
        segment: usize,
        message: String,
    },
    /// A trajectory that cannot be simulated (too short, non-finite, not
    /// increasing in time).
    #[error("invalid trajectory: {message}")]
    InvalidTrajectory { message: String },
    /// Reading the real logs of a replay scenario failed.
    #[error(transparent)]
    Dataset(#[from] DatasetError),
}

impl SimError {
    /// Shorthand for [`SimError::InvalidConfig`].
    pub fn config(field: impl Into<String>, message: impl Into<String>) -> Self {
        SimError::InvalidConfig {
            field: field.into(),
            message: message.into(),
        }
    }
}
