//! Motion compensation of beams (paper eq. 3-4).
//!
//! Every beam `z_t` of a rotation is acquired from a different vehicle pose.
//! Eq. (4) brings the bin endpoints of eq. (3) into the vehicle frame at the
//! reference time `j` (the rotation's central time) by compounding the
//! relative motions `x_{j+1}^j ⊕ … ⊕ x_t^{t-1}` stored in the
//! transformations history. The chain of relative motions between two
//! filter steps composes to `⊖ world_from_vehicle(t_j) ⊕
//! world_from_vehicle(t)`, so one pose lookup per beam is enough:
//!
//! ```text
//! reference_from_beam = ⊖ world_from_vehicle(t_ref) ⊕ world_from_vehicle(t_beam)
//!                       ⊕ vehicle_from_sonar ⊕ Rot(±angle_rad)
//! ```
//!
//! `reference_from_beam` is the paper's `x_t^R` moved to the reference
//! frame: its origin is the transducer, its x axis points along the beam.
//! Bin `i`'s endpoint (eq. 3) in the reference vehicle frame is
//! `reference_from_beam.transform_xy(beam.bin_end_range_m(i), 0.0)`.

use crate::dead_reckoning::Navigation;
use crate::error::FrontendError;
use crate::sensors::{SensorMounting, SonarBeam};
use echofield_graph::Se2;

/// For each beam, `reference_from_beam`: the pose of the beam frame (origin
/// at the transducer, x along the beam at the beam's transducer angle) in the
/// vehicle frame at `reference_stamp_s` (eq. 4).
///
/// Errors: a beam with a non-finite stamp or angle (named by its index in
/// `beams`), or a time the navigation cannot give a pose for
/// ([`FrontendError::OutsideNavigation`]).
pub fn reference_from_beams(
    beams: &[SonarBeam],
    nav: &Navigation,
    mounting: &SensorMounting,
    reference_stamp_s: f64,
) -> Result<Vec<Se2>, FrontendError> {
    let reference_from_world = nav.pose_at(reference_stamp_s)?.inverse();
    beams
        .iter()
        .enumerate()
        .map(|(i, beam)| {
            if !beam.stamp_s.is_finite() {
                return Err(FrontendError::input(
                    format!("beam {i}"),
                    "stamp_s",
                    "not finite",
                ));
            }
            if !beam.angle_rad.is_finite() {
                return Err(FrontendError::input(
                    format!("beam {i}"),
                    "angle_rad",
                    "not finite",
                ));
            }
            let world_from_vehicle = nav.pose_at(beam.stamp_s)?;
            // Eq. (4): compose the motion from the reference time to the beam time.
            Ok(reference_from_world
                .compose(&world_from_vehicle)
                .compose(&mounting.vehicle_from_beam(beam.angle_rad)))
        })
        .collect()
}

/// `vehicle_from_sonar ⊕ Rot(±angle_rad)` for every beam (the sign from
/// [`SensorMounting::sonar_angle`]): the beam frames
/// without motion compensation (a vehicle that does not move, or the
/// uncompensated baseline the paper's Fig. 4 improves on).
pub fn uncompensated_reference_from_beams(
    beams: &[SonarBeam],
    mounting: &SensorMounting,
) -> Vec<Se2> {
    beams
        .iter()
        .map(|beam| mounting.vehicle_from_beam(beam.angle_rad))
        .collect()
}

#[cfg(test)]
mod tests;
