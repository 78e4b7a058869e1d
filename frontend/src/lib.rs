//! # echofield-frontend
//!
//! From sonar beams to matched scans: sensor types, dead reckoning, rotation
//! assembly, beam segmentation, scans `S_k`, acoustic images `I_k` and the
//! acoustic-image measurement model of the seed paper.

pub mod error;
pub mod sensors;

pub use error::FrontendError;

pub use sensors::{Attitude, DvlVelocity, GroundTruthPose, Mission, SensorMounting, SonarBeam};
