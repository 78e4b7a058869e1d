//! # echofield (library part of the command-line tool)
//!
//! Holds what the `echofield` binary and the end-to-end tests share: atomic
//! output files and, in later stages, the SLAM pipeline that joins the
//! frontend and the backend.

pub mod calibration;
pub mod config_doc;
pub mod config_file;
pub mod eval;
pub mod fuzz;
pub mod localize;
pub mod matching;
pub mod output;
pub mod plots;
pub mod slam;
