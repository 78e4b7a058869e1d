//! Loop-closure machinery that needs no solver: the records of every
//! match, the configuration of `[loops]`, the match of one candidate and
//! its own checks ([`checks`]), the mutual consistency of accepted loops
//! ([`consistency`]), the cover rule that sparsifies them ([`cover`]), the
//! design effect of loops that share a place ([`places`]) and the order in
//! which a batch of matches reads the node images ([`schedule`]).
//!
//! The loop closer that drives these against the running estimate (which
//! the backend keeps) joins frontend and backend in the `echofield` tools
//! crate (`slam::loops`).

pub mod checks;
pub mod config;
pub mod consistency;
pub mod cover;
pub mod places;
pub mod records;
pub mod schedule;

pub use config::LoopConfig;
pub use records::{LoopRecord, RejectReason, ReverseCheck, SequentialRecord};
