//! Why a SLAM run failed. Data that merely cannot be matched (a silent
//! rotation, a loop candidate without overlap) is not an error: it is
//! recorded in the output and the run goes on.

use echofield_backend::SolveError;
use echofield_frontend::{FrontendError, StageError};
use echofield_graph::GraphError;
use thiserror::Error;

/// A failed [`run_mission`](super::run_mission).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum SlamError {
    /// A configuration value is out of range; `field` is its TOML path
    /// (`loops.min_separation_nodes`).
    #[error("invalid config `{field}`: {message}")]
    Config { field: String, message: String },
    /// The mission lacks a sensor stream the pipeline needs.
    #[error("mission `{mission}`: {what}")]
    MissingSensor { mission: String, what: String },
    /// A frontend stage failed on the mission's data (bad records, no
    /// complete rotation).
    // The inner errors of this and the variants below are part of the
    // message and deliberately not `source`s: an error chain (`{:#}` in the
    // CLI) would print their text twice.
    #[error("{stage}: {error}")]
    Frontend { stage: String, error: FrontendError },
    /// No rotation of the mission became a node (e.g. every beam lies
    /// outside the span of the navigation).
    #[error("mission `{mission}`: no rotation could become a node: {reason}")]
    NoNodes { mission: String, reason: String },
    #[error("pose graph: {0}")]
    Graph(GraphError),
    #[error("optimisation: {0}")]
    Solve(SolveError),
    /// An evaluation against ground truth that cannot be computed.
    #[error("evaluation: {0}")]
    Evaluation(String),
}

impl SlamError {
    pub fn config(field: impl Into<String>, message: impl Into<String>) -> Self {
        SlamError::Config {
            field: field.into(),
            message: message.into(),
        }
    }

    pub fn frontend(stage: impl Into<String>, error: FrontendError) -> Self {
        SlamError::Frontend {
            stage: stage.into(),
            error,
        }
    }
}

impl SlamError {
    /// A config section's [`FrontendError::InvalidConfig`] (its `field`
    /// the full TOML path) as [`SlamError::Config`]; any other frontend
    /// error as a config error without a field.
    pub fn from_config(error: FrontendError) -> Self {
        match error {
            FrontendError::InvalidConfig { field, message } => SlamError::Config { field, message },
            other => SlamError::config("config", other.to_string()),
        }
    }
}

impl From<StageError> for SlamError {
    fn from(error: StageError) -> Self {
        SlamError::Frontend {
            stage: error.stage,
            error: error.error,
        }
    }
}

impl From<GraphError> for SlamError {
    fn from(error: GraphError) -> Self {
        SlamError::Graph(error)
    }
}

impl From<SolveError> for SlamError {
    fn from(error: SolveError) -> Self {
        SlamError::Solve(error)
    }
}
