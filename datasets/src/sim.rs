//! A simulator of MSIS / DVL / heading missions with ground truth.
//!
//! A [`Scenario`] holds a 2D world ([`Environment`]: segments with
//! reflectivity and roughness, ray cast through a grid index), the
//! ground-truth motion of the vehicle ([`Trajectory`]) and a [`SimConfig`];
//! [`simulate_mission`] turns it into a [`Mission`] for a seed:
//!
//! - sonar beams ([`sonar`]): every beam cast from the ground-truth pose at
//!   its own time through the sonar mounting, so the vehicle moves during
//!   each rotation; beam pattern sampled by sub-rays, backscatter against
//!   incidence, transmission loss, speckle, blind zone, multipath ghosts,
//!   fish blobs, noise, 0-255 quantisation, timing jitter;
//! - DVL and attitude ([`navigation`]): noise, scale error, dropouts and
//!   gaps; a constant heading bias;
//! - ground truth at `ground_truth_rate_hz`;
//! - position fixes at the surface ([`gps`]), only when `[gps] period_s`
//!   is set.
//!
//! Built-in scenarios ([`Scenario::named`]): `marina` (the demo: 120 m x
//! 240 m, ~40 min with revisits), `tank` (20 m x 14 m, ~2.5 min, for tests),
//! `canyon` (natural rock walls, ~18 min, out and back) and `stpere` (the
//! real St Pere navigation and beam times with simulated beams; see
//! [`stpere`]).
//!
//! Frames follow [`echofield_frontend::sensors`]: world x east, y north;
//! vehicle x forward, y port; angles counter-clockwise. The transducer angle
//! of beam `k` is `k · 2π / steps_per_rotation`, wrapped to (-π, π].
//!
//! ```
//! use echofield_datasets::sim::{Scenario, simulate_mission};
//! let scenario = Scenario::named("tank")?;
//! let mission = simulate_mission(&scenario, 7)?;
//! assert_eq!(mission, simulate_mission(&scenario, 7)?);
//! println!("{} beams, {} DVL samples", mission.beams.len(), mission.dvl.len());
//! # Ok::<(), echofield_datasets::sim::SimError>(())
//! ```

mod config;
mod error;
pub mod geometry;
pub mod gps;
mod mission;
pub mod navigation;
pub mod point_sets;
mod scenario;
pub mod scenes;
pub mod sonar;
pub mod stpere;
mod trajectory;
mod vehicle;

pub use config::SimConfig;
pub use error::SimError;
pub use geometry::{Environment, EnvironmentBuilder, Material, RayHit, Segment};
pub use gps::GpsSimConfig;
pub use mission::{simulate_mission, stream_rng};
pub use navigation::{DvlSimConfig, HeadingSimConfig};
pub use scenario::Scenario;
pub use sonar::{SonarModel, SonarSimConfig};
pub use stpere::ReplayConfig;
pub use trajectory::Trajectory;
pub use vehicle::{VehicleConfig, follow_route};

pub use echofield_frontend::sensors::Mission;
