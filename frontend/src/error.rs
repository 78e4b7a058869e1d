//! The frontend's error type. Variants carry enough context (which beam,
//! rotation or config field) for a user to find the cause.

use thiserror::Error;

#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum FrontendError {
    /// A configuration value is out of its documented range.
    #[error("invalid config `{field}`: {message}")]
    InvalidConfig { field: String, message: String },
    /// An input record cannot be used (NaN, out-of-order time, empty beam).
    #[error("{record}: field `{field}`: {message}")]
    InvalidInput {
        /// Which record: "beam 1234", "DVL sample 17", "rotation 5".
        record: String,
        field: String,
        message: String,
    },
    /// Not enough data for the requested operation (too few ranges, no DVL
    /// sample before a beam, an empty image).
    #[error("{what}: {message}")]
    InsufficientData { what: String, message: String },
    /// A scan has fewer valid ranges than `SegmentationConfig::min_scan_points`:
    /// the rotation gives no scan to match (callers treat it as "no scan").
    #[error(
        "scan at t = {reference_stamp_s:.3} s: {found} valid ranges, at least {required} required"
    )]
    TooFewRanges {
        reference_stamp_s: f64,
        found: usize,
        required: usize,
    },
    /// A stamp lies outside the time span the navigation covers (beyond the
    /// allowed extrapolation).
    #[error(
        "t = {stamp_s:.3} s is outside the navigation span [{start_s:.3}, {end_s:.3}] s (+/- {max_extrapolation_s} s allowed)"
    )]
    OutsideNavigation {
        stamp_s: f64,
        start_s: f64,
        end_s: f64,
        max_extrapolation_s: f64,
    },
}

impl FrontendError {
    pub fn config(field: impl Into<String>, message: impl Into<String>) -> Self {
        FrontendError::InvalidConfig {
            field: field.into(),
            message: message.into(),
        }
    }

    pub fn input(
        record: impl Into<String>,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        FrontendError::InvalidInput {
            record: record.into(),
            field: field.into(),
            message: message.into(),
        }
    }

    pub fn insufficient(what: impl Into<String>, message: impl Into<String>) -> Self {
        FrontendError::InsufficientData {
            what: what.into(),
            message: message.into(),
        }
    }
}

/// A frontend failure at a named stage of a run (`"rotation 5"`,
/// `"loop 3 -> 17"`): what callers that run many stages report.
#[derive(Debug, Error, Clone, PartialEq)]
#[error("{stage}: {error}")]
pub struct StageError {
    pub stage: String,
    pub error: FrontendError,
}

impl StageError {
    pub fn new(stage: impl Into<String>, error: FrontendError) -> Self {
        Self {
            stage: stage.into(),
            error,
        }
    }
}
