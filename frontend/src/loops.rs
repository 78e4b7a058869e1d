//! Loop-closure machinery that needs no solver: the records of every
//! match, the configuration of `[loops]`, the match of one candidate and
//! its own checks ([`checks`]), the mutual consistency of accepted loops
//! ([`consistency`]) and the cover rule that sparsifies them ([`cover`]).
//!
//! The loop closer that drives these against the running estimate (which
//! the backend keeps) joins frontend and backend in the `echofield` tools
//! crate (`slam::loops`).

pub mod checks;
pub mod config;
pub mod consistency;
pub mod cover;
pub mod records;

pub use config::LoopConfig;
pub use records::{LoopRecord, RejectReason, ReverseCheck, SequentialRecord};
