//! ROS recordings with standard messages: one mapping of each message
//! type's fields to echofield records ([`messages`]), read through either
//! serialisation ([`wire`]: CDR for ROS 2, the ROS 1 wire format for
//! bags), from any of the containers ROS users record to:
//!
//! - ROS 2: single MCAP files and rosbag2 folders with MCAP storage (read
//!   by [`crate::mcap`]), or with sqlite3 storage ([`sqlite`]);
//! - ROS 1: `.bag` files, format 2.0, with uncompressed, bz2 or lz4 chunks
//!   ([`bag`]).
//!
//! Topics are chosen and summarised in one place for all of them
//! ([`crate::mcap::read_mission_with`]); the sonar and DVL mountings come
//! from `/tf_static` ([`tf`]) unless an echofield MCAP records them.

pub mod bag;
pub(crate) mod messages;
pub mod sqlite;
pub(crate) mod tf;
pub(crate) mod wire;

pub use messages::MessageType;
