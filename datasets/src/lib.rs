//! # echofield-datasets
//!
//! Mission logs in and out of echofield: MCAP missions, the Girona St Pere
//! marina text logs, Ping360 and MiniKing sonar recordings, and a simulator of
//! MSIS/DVL/MRU missions with ground truth.

pub mod error;

pub use error::DatasetError;
