//! Sensor records of a mission and the sensor mounting.
//!
//! Frames: the *vehicle* frame is x forward, y to port (left), z up, so that
//! a positive yaw turns the vehicle counter-clockwise seen from above and all
//! 2D maths is right-handed. Readers of logs in other conventions (NED, x
//! forward / y starboard) convert on reading. The *world* frame is a local
//! metric frame (x east, y north unless stated by the reader). All stamps are
//! absolute seconds (Unix time for real logs); angles are in radians.

use crate::warnings::Warnings;
use echofield_graph::Se2;
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// One MSIS beam: an echo-intensity profile along one transducer angle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SonarBeam {
    /// Time the beam was received, in seconds.
    pub stamp_s: f64,
    /// Transducer angle in the sonar head frame, radians, counter-clockwise
    /// from the head's x axis. Not necessarily wrapped.
    pub angle_rad: f64,
    /// Range length of one bin, in metres.
    pub bin_size_m: f64,
    /// Range of the start of bin 0, in metres (0 for most heads). Bin `i`
    /// covers `[first_bin_range_m + i·bin_size_m, first_bin_range_m + (i+1)·bin_size_m)`.
    pub first_bin_range_m: f64,
    /// Echo intensities 0-255, one per bin, nearest first.
    pub intensities: Vec<u8>,
}

impl SonarBeam {
    /// Range of the far end of bin `i` (the paper's eq. 3 uses the endpoint).
    pub fn bin_end_range_m(&self, i: usize) -> f64 {
        self.first_bin_range_m + (i as f64 + 1.0) * self.bin_size_m
    }

    /// Range of the centre of bin `i`.
    pub fn bin_centre_range_m(&self, i: usize) -> f64 {
        self.first_bin_range_m + (i as f64 + 0.5) * self.bin_size_m
    }

    /// The far range of the last bin.
    pub fn max_range_m(&self) -> f64 {
        self.bin_end_range_m(self.intensities.len().saturating_sub(1))
    }
}

/// A DVL velocity over ground, in the DVL instrument frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DvlVelocity {
    pub stamp_s: f64,
    /// Velocity of the instrument over the bottom (x, y, z), m/s, in the DVL
    /// frame (rotate with `SensorMounting::vehicle_from_dvl` to reach the
    /// vehicle frame).
    pub velocity_mps: Vector3<f64>,
    /// False when the instrument flagged the sample (no bottom lock, bad
    /// status); invalid samples carry no information and are skipped.
    pub valid: bool,
    /// Velocity covariance in (m/s)², when the log provides one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance: Option<Matrix3<f64>>,
}

/// An attitude sample from the MRU / AHRS / compass.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Attitude {
    pub stamp_s: f64,
    pub roll_rad: f64,
    pub pitch_rad: f64,
    /// Heading of the vehicle x axis in the world frame, counter-clockwise
    /// positive (see the module doc for frame conventions).
    pub yaw_rad: f64,
    /// Yaw rate in rad/s when the unit provides it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub yaw_rate_radps: Option<f64>,
}

/// A ground-truth vehicle pose (DGPS, simulator), `world_from_vehicle`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroundTruthPose {
    pub stamp_s: f64,
    pub world_from_vehicle: Se2,
}

/// A position fix of the vehicle (GPS at the surface, USBL, a surveyed
/// mark): where the vehicle was, in a plane common to every mission of a
/// site, with its uncertainty. Used as the prior of a merge of missions
/// (`echofield run A B`), never as ground truth.
///
/// `x_m`, `y_m`: east and north, metres, in a projected plane that every
/// mission to be merged uses alike (UTM easting/northing, or a local
/// tangent plane about an agreed origin); not necessarily the mission's
/// world frame. `std_m`: standard deviation of each axis, metres (> 0).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PositionFix {
    pub stamp_s: f64,
    pub x_m: f64,
    pub y_m: f64,
    pub std_m: f64,
}

/// Which way a sonar head's transducer angle counts, seen from above (the
/// vehicle's z axis up).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AngleDirection {
    /// The angle grows counter-clockwise, like the vehicle's yaw (default).
    #[default]
    CounterClockwise,
    /// The angle grows clockwise: a head mounted upside down, or one whose
    /// driver counts the other way. The beam at angle `θ` points along
    /// `vehicle_from_sonar ⊕ Rot(−θ)`.
    Clockwise,
}

/// How each beam's stamp was obtained.
///
/// A head logs every beam with its own time ([`SweepTiming::Logged`]).
/// Some published data keep only the points of each rotation (thresholded
/// point sets); a reader that gives their beams back their times assigns
/// the rotation's beam stamps in angle order from the beam at angle 0, and
/// must assume which way the angle ran with time. A wrong assumption
/// places every beam at the time of its mirror image in the rotation, so
/// it is part of the mounting, overridable from `[mounting] sweep` and
/// estimated by `echofield calibrate`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SweepTiming {
    /// Every beam carries the stamp it was logged with (default).
    #[default]
    Logged,
    /// Stamps reconstructed assuming the logged angle increases with time:
    /// the `j`-th stamp of a rotation belongs to the beam at angle
    /// `+j · step` (modulo a turn).
    AngleIncreasing,
    /// Stamps reconstructed assuming the logged angle decreases with time:
    /// the `j`-th stamp of a rotation belongs to the beam at angle
    /// `−j · step`.
    AngleDecreasing,
}

/// Where a mission's [`SensorMounting`] came from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MountingSource {
    /// Recorded with the log (an echofield MCAP's metadata, a simulator);
    /// the default.
    #[default]
    Recorded,
    /// Filled in by a reader because the log holds none (the identity for
    /// an MCAP without metadata, a published but unverified hint for the
    /// St Pere logs). The pipeline warns about it.
    Assumed,
    /// Set by a `[mounting]` configuration (a user's, or the output of
    /// `echofield calibrate`).
    Config,
}

/// Where the sensors sit on the vehicle (2D: x, y in metres, yaw in rad),
/// and the sonar head's angle and timing conventions.
///
/// ```text
///            vehicle y (port)
///                 ▲        sonar head at (x, y), its zero direction at
///                 │          `yaw` from the vehicle's x axis; angle θ counts
///                 │    θ ↺     counter-clockwise (or clockwise, inverted head)
///                 │   ╱
///                 │  ● ── ▶ head's angle zero (yaw)
///                 │
///                 └──────────────────▶ vehicle x (forward)
/// ```
///
/// The beam at transducer angle `θ` points along `vehicle_from_sonar ⊕
/// Rot(±θ)` (`+` counter-clockwise, `−` clockwise; see [`AngleDirection`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorMounting {
    /// Pose of the sonar head frame in the vehicle frame `[x, y, yaw]`:
    /// the transducer's position and the direction of its angle zero.
    pub vehicle_from_sonar: Se2,
    /// Which way the head's angle counts. Default counter-clockwise.
    pub sonar_angle: AngleDirection,
    /// How the beams' stamps were obtained. Default: logged.
    pub sweep: SweepTiming,
    /// Pose of the DVL instrument frame in the vehicle frame `[x, y, yaw]`.
    pub vehicle_from_dvl: Se2,
    /// Added to every attitude yaw to obtain the vehicle heading in the
    /// world frame: the heading sensor's mounting misalignment plus the
    /// magnetic declination, radians. A calibration of the vehicle, so it
    /// travels with the mission (the St Pere reader sets the value fitted
    /// on that mission); the dead reckoning adds its own
    /// `heading_offset_rad` on top.
    pub heading_offset_rad: f64,
    /// Where these values came from.
    pub source: MountingSource,
}

impl Default for SensorMounting {
    fn default() -> Self {
        Self {
            vehicle_from_sonar: Se2::identity(),
            sonar_angle: AngleDirection::CounterClockwise,
            sweep: SweepTiming::Logged,
            vehicle_from_dvl: Se2::identity(),
            heading_offset_rad: 0.0,
            source: MountingSource::Recorded,
        }
    }
}

impl SensorMounting {
    /// The identity mounting, marked [`MountingSource::Assumed`]: what a
    /// reader gives a log that records no mounting.
    pub fn assumed_identity() -> Self {
        Self {
            source: MountingSource::Assumed,
            ..Self::default()
        }
    }

    /// The head's angle as a counter-clockwise angle in the sonar frame.
    pub fn counter_clockwise_angle_rad(&self, angle_rad: f64) -> f64 {
        match self.sonar_angle {
            AngleDirection::CounterClockwise => angle_rad,
            AngleDirection::Clockwise => -angle_rad,
        }
    }

    /// `vehicle_from_sonar ⊕ Rot(±angle)`: the frame of the beam at
    /// transducer angle `angle_rad` (origin at the transducer, x along the
    /// beam) in the vehicle frame.
    pub fn vehicle_from_beam(&self, angle_rad: f64) -> Se2 {
        self.vehicle_from_sonar.compose(&Se2::new(
            0.0,
            0.0,
            self.counter_clockwise_angle_rad(angle_rad),
        ))
    }
}

/// A whole mission in memory: every sensor stream sorted by time.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Mission {
    /// Human-readable name (file stem, scenario name).
    pub name: String,
    pub mounting: SensorMounting,
    pub beams: Vec<SonarBeam>,
    pub dvl: Vec<DvlVelocity>,
    pub attitude: Vec<Attitude>,
    /// Empty when the mission has no ground truth.
    pub ground_truth: Vec<GroundTruthPose>,
    /// Empty when the mission has no position fixes ([`PositionFix`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub position_fixes: Vec<PositionFix>,
    /// What the reader repaired in the log (records re-sorted, a mounting
    /// assumed, implausible samples dropped), for the run's report.
    #[serde(default, skip_serializing_if = "Warnings::is_empty")]
    pub warnings: Warnings,
}
