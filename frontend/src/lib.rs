//! # echofield-frontend
//!
//! From sonar beams to matched scans: sensor types, dead reckoning, rotation
//! assembly, beam segmentation, scans `S_k`, acoustic images `I_k` and the
//! acoustic-image measurement model of the seed paper.

pub mod calibration;
pub mod config_check;
pub mod dead_reckoning;
pub mod error;
pub mod icp;
pub mod image;
pub mod intensity;
pub mod localization;
pub mod loops;
pub mod matcher;
pub mod motion;
pub mod mounting;
pub mod nodes;
pub mod off_axis;
pub mod replay;
pub mod rotation;
pub mod scan;
pub mod screening;
pub mod segmentation;
pub mod sensors;
pub mod sharpness;
pub mod sweep_lag;
pub mod uncertainty;
pub mod warnings;

pub use error::{FrontendError, StageError};

pub use sensors::{
    Attitude, DvlVelocity, GroundTruthPose, Mission, PositionFix, SensorMounting, SonarBeam,
};
