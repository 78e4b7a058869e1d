//! A plain DVL + heading integrator, used to check the reader's frames and to
//! measure the heading offset of a mission against its ground truth.
//!
//! This is not the SLAM's dead reckoning (the EKF lives in `frontend`): it
//! holds each DVL velocity until the next sample (an invalid sample repeats
//! the last valid velocity), rotates it into the world with the attitude yaw
//! (linearly interpolated, unwrapped) plus a constant offset and the yaw of
//! `vehicle_from_dvl`, and integrates in 2D. The lever arm of the DVL is
//! ignored.

use echofield_frontend::sensors::{Attitude, Mission};
use nalgebra::{Rotation2, Vector2};

/// Dead reckoning against ground truth, at every ground-truth stamp inside the
/// DVL time span.
#[derive(Clone, Debug, PartialEq)]
pub struct DeadReckoningError {
    /// Mean horizontal distance to ground truth, metres.
    pub mean_m: f64,
    /// Largest horizontal distance to ground truth, metres.
    pub max_m: f64,
    /// Distance at the last compared stamp, metres.
    pub final_m: f64,
    /// Ground-truth stamps compared.
    pub compared: usize,
}

/// Yaw of the attitude stream at any time, unwrapped so that interpolation
/// across ±π is correct; clamped to the first/last sample outside the span.
struct YawSeries {
    stamps_s: Vec<f64>,
    unwrapped_rad: Vec<f64>,
}

impl YawSeries {
    fn new(attitude: &[Attitude]) -> Self {
        let mut unwrapped_rad = Vec::with_capacity(attitude.len());
        for (k, a) in attitude.iter().enumerate() {
            let value = match k {
                0 => a.yaw_rad,
                _ => {
                    let prev = unwrapped_rad[k - 1];
                    prev + echofield_graph::wrap_angle(a.yaw_rad - prev)
                }
            };
            unwrapped_rad.push(value);
        }
        Self {
            stamps_s: attitude.iter().map(|a| a.stamp_s).collect(),
            unwrapped_rad,
        }
    }

    fn at(&self, stamp_s: f64) -> f64 {
        let k = self.stamps_s.partition_point(|&t| t < stamp_s);
        if k == 0 {
            return self.unwrapped_rad[0];
        }
        if k == self.stamps_s.len() {
            return self.unwrapped_rad[k - 1];
        }
        let (t0, t1) = (self.stamps_s[k - 1], self.stamps_s[k]);
        let f = (stamp_s - t0) / (t1 - t0);
        self.unwrapped_rad[k - 1] + f * (self.unwrapped_rad[k] - self.unwrapped_rad[k - 1])
    }
}

/// The DVL samples prepared once: stamp, held velocity in the vehicle frame,
/// and the attitude yaw at that stamp.
struct Prepared {
    stamps_s: Vec<f64>,
    velocity_mps: Vec<Vector2<f64>>,
    yaw_rad: Vec<f64>,
}

fn prepare(mission: &Mission) -> Option<Prepared> {
    if mission.attitude.is_empty() || mission.dvl.is_empty() {
        return None;
    }
    let yaw = YawSeries::new(&mission.attitude);
    let vehicle_from_dvl = Rotation2::new(mission.mounting.vehicle_from_dvl.theta());
    let mut held = Vector2::zeros();
    let mut out = Prepared {
        stamps_s: Vec::with_capacity(mission.dvl.len()),
        velocity_mps: Vec::with_capacity(mission.dvl.len()),
        yaw_rad: Vec::with_capacity(mission.dvl.len()),
    };
    for sample in &mission.dvl {
        if sample.valid {
            held = vehicle_from_dvl * sample.velocity_mps.xy();
        }
        out.stamps_s.push(sample.stamp_s);
        out.velocity_mps.push(held);
        out.yaw_rad.push(yaw.at(sample.stamp_s));
    }
    Some(out)
}

fn error_with(
    prepared: &Prepared,
    mission: &Mission,
    yaw_offset_rad: f64,
) -> Option<DeadReckoningError> {
    let truth = &mission.ground_truth;
    let first = truth
        .iter()
        .position(|g| g.stamp_s >= prepared.stamps_s[0])?;
    let last_dvl_s = *prepared.stamps_s.last()?;
    let mut position = truth[first].world_from_vehicle.translation();
    let mut clock_s = truth[first].stamp_s;
    // Index of the DVL sample whose velocity holds at `clock_s`.
    let mut k = prepared.stamps_s.partition_point(|&t| t <= clock_s) - 1;
    let (mut sum, mut max, mut final_m, mut compared) = (0.0, 0.0f64, 0.0, 0usize);
    for gt in &truth[first..] {
        if gt.stamp_s > last_dvl_s {
            break;
        }
        while clock_s < gt.stamp_s {
            let next_s = prepared
                .stamps_s
                .get(k + 1)
                .map_or(gt.stamp_s, |&t| t.min(gt.stamp_s));
            let world_from_vehicle = Rotation2::new(prepared.yaw_rad[k] + yaw_offset_rad);
            position += world_from_vehicle * prepared.velocity_mps[k] * (next_s - clock_s);
            clock_s = next_s;
            if k + 1 < prepared.stamps_s.len() && prepared.stamps_s[k + 1] <= clock_s {
                k += 1;
            }
        }
        let distance = (position - gt.world_from_vehicle.translation()).norm();
        sum += distance;
        max = max.max(distance);
        final_m = distance;
        compared += 1;
    }
    (compared > 0).then(|| DeadReckoningError {
        mean_m: sum / compared as f64,
        max_m: max,
        final_m,
        compared,
    })
}

/// Dead reckoning from the first ground-truth pose inside the DVL span, with
/// `yaw_offset_rad` added to every attitude yaw, compared with the ground
/// truth. `None` when the mission lacks DVL, attitude or overlapping truth.
pub fn dead_reckoning_error(mission: &Mission, yaw_offset_rad: f64) -> Option<DeadReckoningError> {
    error_with(&prepare(mission)?, mission, yaw_offset_rad)
}

/// The constant yaw offset (radians, added to the attitude yaw) that
/// minimises the mean dead-reckoning error: a 1° grid over the whole circle,
/// then a golden-section refinement to 0.01° around the best grid point.
pub fn best_yaw_offset(mission: &Mission) -> Option<(f64, DeadReckoningError)> {
    let prepared = prepare(mission)?;
    let cost =
        |offset: f64| error_with(&prepared, mission, offset).map_or(f64::INFINITY, |e| e.mean_m);
    let grid_rad = 1f64.to_radians();
    let best_grid = (-180..180)
        .map(|d| f64::from(d) * grid_rad)
        .min_by(|a, b| cost(*a).total_cmp(&cost(*b)))?;
    let (mut lo, mut hi) = (best_grid - grid_rad, best_grid + grid_rad);
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    while hi - lo > 0.01f64.to_radians() {
        let (a, b) = (hi - ratio * (hi - lo), lo + ratio * (hi - lo));
        if cost(a) < cost(b) {
            hi = b;
        } else {
            lo = a;
        }
    }
    let offset = echofield_graph::wrap_angle(0.5 * (lo + hi));
    Some((offset, error_with(&prepared, mission, offset)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use echofield_frontend::sensors::{DvlVelocity, GroundTruthPose};
    use echofield_graph::Se2;
    use nalgebra::Vector3;

    /// A vehicle driving at 0.5 m/s along a heading of 30° whose compass reads
    /// 10° too little: the offset must come out as +20°.
    fn straight_mission() -> Mission {
        let heading = 30f64.to_radians();
        let mut mission = Mission::default();
        for i in 0..=200 {
            let t = f64::from(i);
            mission.dvl.push(DvlVelocity {
                stamp_s: t,
                velocity_mps: Vector3::new(0.5, 0.0, 0.0),
                valid: i % 7 != 3,
                covariance: None,
            });
            mission.attitude.push(Attitude {
                stamp_s: t,
                roll_rad: 0.0,
                pitch_rad: 0.0,
                yaw_rad: heading - 20f64.to_radians(),
                yaw_rate_radps: None,
            });
            let d = 0.5 * t;
            mission.ground_truth.push(GroundTruthPose {
                stamp_s: t,
                world_from_vehicle: Se2::new(d * heading.cos(), d * heading.sin(), heading),
            });
        }
        mission
    }

    #[test]
    fn recovers_a_known_offset_and_scores_it_zero() {
        let mission = straight_mission();
        let (offset, error) = best_yaw_offset(&mission).unwrap();
        assert!(
            (offset.to_degrees() - 20.0).abs() < 0.02,
            "{}",
            offset.to_degrees()
        );
        assert!(error.max_m < 0.05, "{error:?}");
        let wrong = dead_reckoning_error(&mission, 0.0).unwrap();
        // 100 m at 20° off: chord 2·100·sin(10°) = 34.7 m at the end.
        assert!((wrong.final_m - 34.73).abs() < 0.05, "{wrong:?}");
    }
}
