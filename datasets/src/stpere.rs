//! Reader of the Girona St Pere Pescador marina logs (Ictineu AUV, 2004).
//!
//! [`read_stpere_dir`] reads one mission folder: `<prefix>_DVL.log`,
//! `<prefix>_MTI.log`, `<prefix>_DGPS.log` (required), `<prefix>_SETUP.log`,
//! `<prefix>_IS_timestamps.log` and `<prefix>_IS.log` (optional). The
//! per-file formats are in the submodules and in
//! `datasets/stpere-marina/README.md`.
//!
//! # Frames and sign conventions
//! - World: x east, y north, metres, about the first DGPS fix
//!   ([`LocalTangentPlane`]: equirectangular projection with WGS84 radii).
//! - Vehicle: x forward, y port, z up; yaw counter-clockwise from east.
//! - Attitude: the MTi gives a compass heading ψ (degrees clockwise from
//!   north, body z down); it becomes `yaw = π/2 − ψ`, `pitch = −pitch_MTi`,
//!   yaw rate `= −rate_z`. No offset is applied to the attitude stream.
//! - DVL: bottom-track velocity in the instrument XYZ frame, cm/s → m/s.
//!   Integrating it with the yaw above matches DGPS only if the DVL's y axis
//!   points to port (the three other sign choices give 8-43 m mean error at
//!   their best offset), so the instrument frame already is x forward / y
//!   port and `vehicle_from_dvl` is the identity.
//! - Ground truth: DGPS positions; the yaw of each pose is the MTi yaw plus
//!   [`MARINA_YAW_OFFSET_RAD`], interpolated at the fix (DGPS has no heading).
//! - Sonar mounting: `vehicle_from_sonar = (0.33 m, 0, π)`, the value of the
//!   public starter code for this data set; not verified.
//!
//! # Heading offset
//! The MTi yaw needs a constant correction to match the DGPS track
//! (compass deviation of the vehicle and/or mounting). In echofield's
//! convention the correction is **added** to the yaw: [`best_yaw_offset`]
//! finds +19.4° on the marina mission ([`MARINA_YAW_OFFSET_RAD`]; dead
//! reckoning against DGPS with and without it: EXPERIMENTS.md § St Pere data).
//! In the
//! compass convention (clockwise from north) this is the "about −20°" of the
//! logs' README. The DVL's own compass reads 25.3° more than the MTi yaw (in
//! this convention), so it would need about −5.9°. [`read_stpere_dir`]
//! stores this calibration as the mission's
//! `mounting.heading_offset_rad`, which dead reckoning adds to every yaw;
//! the attitude stream stays as logged. [`StPereLogs::apply_yaw_offset`]
//! instead bakes an offset into the attitude samples: set the mounting's
//! offset to 0 then, or the heading is corrected twice.
//!
//! # Bad input
//! Wrong column counts, non-numeric or non-finite values and time going
//! backwards are [`DatasetError::Parse`] errors naming file, line and column.
//! Skipped on purpose and listed in [`StPereLogs::skipped`]: a truncated final
//! line (logger stopped mid-write), a line repeating the previous time stamp,
//! DGPS fixes with status 0. DVL samples with 32767 or a bottom status other
//! than 1 are kept with `valid = false` and zero velocity.
//!
//! # Example
//!
//! ```
//! use echofield_datasets::stpere::{MARINA_YAW_OFFSET_RAD, dead_reckoning_error, read_stpere_dir};
//!
//! let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("stpere-marina");
//! let mut logs = read_stpere_dir(&dir)?;
//! let dr = dead_reckoning_error(&logs.mission, MARINA_YAW_OFFSET_RAD).unwrap();
//! assert!(dr.mean_m < 5.0);
//! assert_eq!(logs.mission.mounting.heading_offset_rad, MARINA_YAW_OFFSET_RAD);
//! // Or bake the calibration into the attitude stream instead:
//! logs.apply_yaw_offset(MARINA_YAW_OFFSET_RAD);
//! logs.mission.mounting.heading_offset_rad = 0.0;
//! # Ok::<(), echofield_datasets::DatasetError>(())
//! ```

mod dead_reckoning;
mod dgps;
mod dvl;
pub mod keyframes;
mod local_frame;
mod mti;
pub mod point_bands;
mod sonar;
mod text;

pub use dead_reckoning::{DeadReckoningError, best_yaw_offset, dead_reckoning_error};
pub use dgps::DgpsFix;
pub use dvl::DVL_INVALID_CMPS;
pub use local_frame::{LocalTangentPlane, nmea_to_degrees};
pub use mti::compass_to_yaw_rad;
pub use sonar::{BeamStamp, SonarSetup};
pub use text::{SkipReason, SkippedLine};

use crate::error::DatasetError;
use echofield_frontend::sensors::{
    Attitude, GroundTruthPose, Mission, MountingSource, SensorMounting, SonarBeam, SweepTiming,
};
use echofield_graph::{Se2, wrap_angle};
use std::path::{Path, PathBuf};
use text::TextLog;

/// Yaw offset (radians) to add to the MTi yaw of the marina mission
/// (`_040825_1735`) so that DVL dead reckoning matches DGPS; measured with
/// [`best_yaw_offset`] (+19.44°, rounded to +19.4°).
pub const MARINA_YAW_OFFSET_RAD: f64 = 19.4 * std::f64::consts::PI / 180.0;

/// Everything read from one St Pere mission folder.
#[derive(Clone, Debug)]
pub struct StPereLogs {
    /// DVL, MTi attitude, DGPS ground truth and (when `_IS.log` exists) beams,
    /// in echofield frames.
    pub mission: Mission,
    /// One stamp per beam from `_IS_timestamps.log` (empty if absent).
    pub beam_stamps: Vec<BeamStamp>,
    /// From `_SETUP.log` (`None` if absent).
    pub sonar_setup: Option<SonarSetup>,
    /// The DGPS fixes with status > 0, as read, with local coordinates.
    pub dgps: Vec<DgpsFix>,
    /// The frame of `dgps` and of the ground truth.
    pub local_frame: LocalTangentPlane,
    /// The DVL's own compass, converted like the MTi (for cross-checks).
    pub dvl_compass: Vec<Attitude>,
    /// Yaw offset applied to the attitude stream so far (0 after reading).
    pub applied_yaw_offset_rad: f64,
    /// Data lines left out on purpose (see the module doc).
    pub skipped: Vec<SkippedLine>,
}

impl StPereLogs {
    /// Adds `offset_rad` to every attitude yaw (wrapped) and records it.
    pub fn apply_yaw_offset(&mut self, offset_rad: f64) {
        for a in &mut self.mission.attitude {
            a.yaw_rad = wrap_angle(a.yaw_rad + offset_rad);
        }
        self.applied_yaw_offset_rad = wrap_angle(self.applied_yaw_offset_rad + offset_rad);
    }
}

/// The log files of one mission folder.
struct MissionFiles {
    prefix: String,
    dvl: PathBuf,
    mti: PathBuf,
    dgps: PathBuf,
    setup: Option<PathBuf>,
    beam_stamps: Option<PathBuf>,
    beams: Option<PathBuf>,
}

/// Reads a St Pere mission folder (see the module doc for frames and the
/// handling of bad lines).
pub fn read_stpere_dir(dir: &Path) -> Result<StPereLogs, DatasetError> {
    let files = find_files(dir)?;
    let dvl = dvl::parse_dvl(&TextLog::read(&files.dvl)?)?;
    let mti = mti::parse_mti(&TextLog::read(&files.mti)?)?;
    let dgps = dgps::parse_dgps(&TextLog::read(&files.dgps)?)?;
    let mut skipped = [dvl.skipped, mti.skipped, dgps.skipped].concat();
    let local_frame = dgps.frame.ok_or_else(|| DatasetError::Missing {
        path: files.dgps.clone(),
        what: "a DGPS fix with status > 0".into(),
    })?;
    if mti.samples.is_empty() {
        return Err(DatasetError::Missing {
            path: files.mti.clone(),
            what: "attitude samples".into(),
        });
    }
    // A mission without DVL would convert silently into one that no run
    // can use (issue 35).
    if dvl.samples.is_empty() {
        return Err(DatasetError::Missing {
            path: files.dvl.clone(),
            what: "DVL samples (the log has no data line)".into(),
        });
    }
    let sonar = read_sonar_logs(&files, &mut skipped)?;
    let ground_truth = ground_truth(&dgps.fixes, &mti.samples);
    let mission = Mission {
        name: files.prefix.trim_matches('_').to_string(),
        mounting: assumed_mounting(),
        beams: sonar.beams,
        dvl: dvl.samples,
        attitude: mti.samples,
        ground_truth,
        // The DGPS is the ground truth of every evaluation on these logs:
        // as position fixes it would be the prior of a merge of missions,
        // and the merged error against it would measure nothing. A log of
        // this vehicle has no other position source.
        position_fixes: Vec::new(),
        warnings: Default::default(),
    };
    Ok(StPereLogs {
        mission,
        beam_stamps: sonar.beam_stamps,
        sonar_setup: sonar.setup,
        dgps: dgps.fixes,
        local_frame,
        dvl_compass: dvl.compass,
        applied_yaw_offset_rad: 0.0,
        skipped,
    })
}

/// The St Pere mounting: the head's pose is the public starter code's
/// hint and the angle and sweep conventions are the head's as logged, none
/// of it verified (`echofield calibrate` checks them), so it is marked
/// assumed; the MTi yaw is stored as logged and the heading offset (fitted
/// against DGPS, see the module doc) turns it into the heading.
fn assumed_mounting() -> SensorMounting {
    SensorMounting {
        vehicle_from_sonar: Se2::new(0.33, 0.0, std::f64::consts::PI),
        vehicle_from_dvl: Se2::identity(),
        heading_offset_rad: MARINA_YAW_OFFSET_RAD,
        source: MountingSource::Assumed,
        ..SensorMounting::default()
    }
}

/// What the optional sonar logs of a mission folder hold (empty when
/// absent).
struct SonarLogs {
    setup: Option<SonarSetup>,
    beam_stamps: Vec<BeamStamp>,
    beams: Vec<SonarBeam>,
}

/// Reads `_SETUP.log`, `_IS_timestamps.log` and `_IS.log` when present,
/// adding their skipped lines to `skipped`. Errors: a log that does not
/// parse, or beams without the setup that gives their bin size.
fn read_sonar_logs(
    files: &MissionFiles,
    skipped: &mut Vec<SkippedLine>,
) -> Result<SonarLogs, DatasetError> {
    let setup = match &files.setup {
        Some(path) => Some(sonar::parse_setup(&TextLog::read(path)?)?),
        None => None,
    };
    let beam_stamps = match &files.beam_stamps {
        Some(path) => {
            let (stamps, skips) = sonar::parse_beam_stamps(&TextLog::read(path)?)?;
            skipped.extend(skips);
            stamps
        }
        None => Vec::new(),
    };
    let beams = match (&files.beams, &setup) {
        (Some(path), Some(setup)) => {
            let (beams, skips) = sonar::parse_beams(&TextLog::read(path)?, setup)?;
            skipped.extend(skips);
            beams
        }
        (Some(path), None) => {
            return Err(DatasetError::Missing {
                path: path.clone(),
                what: "the _SETUP.log that gives the bin size of these beams".into(),
            });
        }
        (None, _) => Vec::new(),
    };
    Ok(SonarLogs {
        setup,
        beam_stamps,
        beams,
    })
}

/// Reads a St Pere mission folder whose beams come from a folder of
/// thresholded point sets (`keyFrameTimeStamps.csv` and `pclKeyFrameK.pcd`,
/// see [`keyframes`]) instead of an `_IS.log`. The navigation folder must
/// hold `_SETUP.log` and `_IS_timestamps.log`, and no `_IS.log` (two
/// sources of beams would be ambiguous). The mission's
/// `mounting.sweep` records the assumed `sweep`.
pub fn read_stpere_with_keyframes(
    nav_dir: &Path,
    keyframe_dir: &Path,
    sweep: SweepTiming,
) -> Result<(StPereLogs, keyframes::KeyframeBeams), DatasetError> {
    let files = find_files(nav_dir)?;
    if let Some(beams) = &files.beams {
        return Err(DatasetError::Format {
            path: beams.clone(),
            message: format!(
                "the navigation folder holds raw beams and the keyframes in {} are beams                  too; give one of them",
                keyframe_dir.display()
            ),
        });
    }
    let mut logs = read_stpere_dir(nav_dir)?;
    let setup = logs
        .sonar_setup
        .clone()
        .ok_or_else(|| DatasetError::Missing {
            path: nav_dir.to_path_buf(),
            what: "a `*_SETUP.log` file (the bin size and angle step of the point sets)".into(),
        })?;
    if logs.beam_stamps.is_empty() {
        return Err(DatasetError::Missing {
            path: nav_dir.to_path_buf(),
            what: "a `*_IS_timestamps.log` file (the beam times of the point sets)".into(),
        });
    }
    let kf = keyframes::read_keyframes(keyframe_dir, &setup, &logs.beam_stamps, sweep)?;
    logs.mission.beams = kf.beams.clone();
    logs.mission.mounting.sweep = sweep;
    Ok((logs, kf))
}

/// DGPS positions with the offset-corrected MTi yaw (nearest-in-time linear
/// interpolation on the shorter arc; clamped outside the MTi span).
fn ground_truth(fixes: &[DgpsFix], attitude: &[Attitude]) -> Vec<GroundTruthPose> {
    fixes
        .iter()
        .map(|fix| {
            let k = attitude.partition_point(|a| a.stamp_s < fix.stamp_s);
            let yaw_rad = match k {
                0 => attitude[0].yaw_rad,
                k if k == attitude.len() => attitude[k - 1].yaw_rad,
                k => {
                    let (a, b) = (&attitude[k - 1], &attitude[k]);
                    let f = (fix.stamp_s - a.stamp_s) / (b.stamp_s - a.stamp_s);
                    a.yaw_rad + f * wrap_angle(b.yaw_rad - a.yaw_rad)
                }
            };
            GroundTruthPose {
                stamp_s: fix.stamp_s,
                world_from_vehicle: Se2::new(
                    fix.east_m,
                    fix.north_m,
                    wrap_angle(yaw_rad + MARINA_YAW_OFFSET_RAD),
                ),
            }
        })
        .collect()
}

/// Finds the `<prefix>_<KIND>.log` files; each kind at most once.
fn find_files(dir: &Path) -> Result<MissionFiles, DatasetError> {
    let entries = std::fs::read_dir(dir).map_err(|e| DatasetError::io(dir, e))?;
    let mut names = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| DatasetError::io(dir, e))?;
        if let Some(name) = entry.file_name().to_str() {
            names.push(name.to_string());
        }
    }
    names.sort();
    let find = |suffix: &str| -> Result<Option<(String, PathBuf)>, DatasetError> {
        let hits: Vec<&String> = names.iter().filter(|n| n.ends_with(suffix)).collect();
        match hits.as_slice() {
            [] => Ok(None),
            [one] => Ok(Some((
                one[..one.len() - suffix.len()].to_string(),
                dir.join(one),
            ))),
            many => Err(DatasetError::Format {
                path: dir.to_path_buf(),
                message: format!(
                    "several `*{suffix}` files ({many:?}); keep one mission per folder"
                ),
            }),
        }
    };
    let required = |suffix: &str| {
        find(suffix)?.ok_or_else(|| DatasetError::Missing {
            path: dir.to_path_buf(),
            what: format!("a `*{suffix}` file"),
        })
    };
    let (prefix, dvl) = required("_DVL.log")?;
    Ok(MissionFiles {
        prefix,
        dvl,
        mti: required("_MTI.log")?.1,
        dgps: required("_DGPS.log")?.1,
        setup: find("_SETUP.log")?.map(|f| f.1),
        beam_stamps: find("_IS_timestamps.log")?.map(|f| f.1),
        beams: find("_IS.log")?.map(|f| f.1),
    })
}
