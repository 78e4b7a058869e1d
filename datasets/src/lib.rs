//! # echofield-datasets
//!
//! Mission logs in and out of echofield: MCAP missions, the Girona St Pere
//! marina text logs, Ping360 and MiniKing sonar recordings, and a simulator of
//! MSIS/DVL/MRU missions with ground truth.

pub mod error;
pub mod mcap;
pub mod miniking;
pub mod ping360;
pub mod ros;
pub mod sim;
pub mod sonar_recording;
pub mod stpere;

pub use error::DatasetError;
