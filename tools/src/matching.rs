//! Matching the rotations of a mission: the steps `echofield match`,
//! `echofield bench-matcher` and the matcher's end-to-end tests share.
//!
//! A mission is read ([`load_mission`]), navigated (dead reckoning, or a
//! vehicle at rest when the log has no DVL or no heading: the real static
//! sonar recordings), cut into rotations, and for any rotation `k` the scan
//! `S_k` and the acoustic image `I_k` are built in the frame of its central
//! pose ([`MissionRotations`]). The prior of a match of `S_K` against `I_J`
//! is the dead-reckoning motion between the two reference times, its search
//! window that of a loop candidate (`loops.gate`: `n_sigma` standard
//! deviations of that motion, clamped to the gate's windows).
//!
//! Every step reads the pipeline's own [`SlamConfig`] (the file `echofield
//! run --config` reads): its `[dead_reckoning]`, `[rotation]`,
//! `[segmentation]`, `[image]`, `[matcher]` and `[loops.gate]` sections.

pub mod evaluation;
pub mod navigation_eval;
pub mod plots;
pub mod pull;

use crate::slam::SlamConfig;
use anyhow::{Context, Result, bail};
use echofield_datasets::{mcap, miniking, ping360, stpere};
use echofield_frontend::FrontendError;
use echofield_frontend::dead_reckoning::{self, Navigation};
use echofield_frontend::image::{AcousticImage, ImageConfig};
use echofield_frontend::intensity::{self, IntensityKind};
use echofield_frontend::motion;
use echofield_frontend::rotation::{Rotation, assemble_rotations};
use echofield_frontend::scan::{Scan, build_scan};
use echofield_frontend::segmentation::SegmentationConfig;
use echofield_frontend::sensors::{GroundTruthPose, Mission};
use echofield_graph::{Se2, wrap_angle};
use nalgebra::Matrix3;
use std::path::Path;

/// Reads a mission: a St Pere log folder, a Ping360 `.bin` log, a MiniKing
/// `.bag`, or else an echofield MCAP file.
pub fn load_mission(path: &Path) -> Result<Mission> {
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let mission = if path.is_dir() {
        stpere::read_stpere_dir(path)
            .with_context(|| format!("reading the St Pere logs in {}", path.display()))?
            .mission
    } else if extension == "bin" {
        ping360::read_ping360(path)
            .with_context(|| format!("reading the Ping360 log {}", path.display()))?
            .to_mission()
    } else if extension == "bag" {
        miniking::read_miniking_bag(path)
            .with_context(|| format!("reading the MiniKing bag {}", path.display()))?
            .to_mission()
    } else {
        mcap::read_mission(path)
            .with_context(|| format!("reading the MCAP mission {}", path.display()))?
    };
    if mission.beams.is_empty() {
        bail!("{} holds no sonar beams", path.display());
    }
    Ok(mission)
}

/// A mission with its navigation and rotations.
pub struct MissionRotations {
    pub mission: Mission,
    pub navigation: Navigation,
    /// True when the mission has no DVL or no heading and the vehicle is
    /// taken to be at rest (the real static sonar recordings).
    pub stationary: bool,
    pub rotations: Vec<Rotation>,
    /// True when the beams' intensities are binary (scan-only data): the
    /// beams were prepared by `echofield_frontend::intensity::prepare`,
    /// and the scans and images are built with the settings it derives.
    pub binary: bool,
}

impl MissionRotations {
    pub fn new(mut mission: Mission, config: &SlamConfig) -> Result<Self> {
        let (mut segmentation, mut image) = (config.segmentation.clone(), config.image.clone());
        let prepared = intensity::prepare(&mut mission.beams, &mut segmentation, &mut image);
        let binary = matches!(prepared.kind, IntensityKind::Binary { .. });
        if binary {
            tracing::info!(
                "{}: binary intensities (scan-only data): {}",
                mission.name,
                prepared.derived.join(", ")
            );
        }
        let stationary = mission.dvl.iter().all(|d| !d.valid) || mission.attitude.is_empty();
        let navigation = if stationary {
            tracing::info!(
                "{}: no DVL or no heading; the vehicle is taken to be at rest",
                mission.name
            );
            let first = mission.beams[0].stamp_s;
            let last = mission.beams[mission.beams.len() - 1].stamp_s;
            Navigation::stationary(first, last)
        } else {
            dead_reckoning::run(&mission, &config.dead_reckoning).context("dead reckoning")?
        };
        let rotations =
            assemble_rotations(&mission.beams, &config.rotation).context("rotation assembly")?;
        Ok(Self {
            mission,
            navigation,
            stationary,
            rotations,
            binary,
        })
    }

    /// Replaces the navigation by the mission's ground truth, so that motion
    /// compensation is exact (to evaluate matching apart from the
    /// dead-reckoning errors within a rotation).
    pub fn use_ground_truth_navigation(&mut self) -> Result<()> {
        let gt = &self.mission.ground_truth;
        if gt.len() < 2 {
            bail!("{} has no ground truth to navigate with", self.mission.name);
        }
        let stamps: Vec<f64> = gt.iter().map(|g| g.stamp_s).collect();
        let poses: Vec<Se2> = gt.iter().map(|g| g.world_from_vehicle).collect();
        self.navigation = Navigation::from_poses(&stamps, &poses, 1.0)
            .context("navigation from the ground truth")?;
        self.stationary = false;
        Ok(())
    }

    /// Replaces the navigation by the dead reckoning bent
    /// ([`crate::slam::refine`]) through the optimised node poses of a run
    /// of [`crate::slam::run_mission`] with `config` (the run's dead
    /// reckoning is then the one bent). No ground truth is used. Returns
    /// the run's report.
    pub fn use_slam_navigation(
        &mut self,
        config: &SlamConfig,
    ) -> Result<crate::slam::result::Report> {
        if self.stationary {
            bail!(
                "{}: a stationary recording has no trajectory to refine",
                self.mission.name
            );
        }
        let out = crate::slam::run_mission(&self.mission, config, &crate::slam::NoProgress)
            .context("the SLAM run whose trajectory compensates the motion")?;
        let stamps: Vec<f64> = out.nodes.iter().map(|n| n.stamp_s).collect();
        let dead_reckoning: Vec<Se2> = out.nodes.iter().map(|n| n.dead_reckoning).collect();
        let optimised: Vec<Se2> = out.nodes.iter().map(|n| n.optimised).collect();
        let navigation =
            dead_reckoning::run(&self.mission, &config.dead_reckoning).context("dead reckoning")?;
        self.navigation = crate::slam::refine::refined_navigation(
            &navigation,
            &stamps,
            &dead_reckoning,
            &optimised,
            config.dead_reckoning.max_extrapolation_s,
        )
        .context("navigation from the SLAM trajectory")?;
        Ok(out.report)
    }

    /// Loads, navigates and cuts a mission file.
    pub fn load(path: &Path, config: &SlamConfig) -> Result<Self> {
        Self::new(load_mission(path)?, config)
    }

    pub fn rotation(&self, k: usize) -> Result<&Rotation> {
        self.rotations.get(k).with_context(|| {
            format!(
                "rotation {k} does not exist (the mission has {} rotations, 0-{})",
                self.rotations.len(),
                self.rotations.len().saturating_sub(1)
            )
        })
    }

    /// Beam frames of rotation `k` in its reference frame (eq. 3-4).
    pub fn frames(&self, k: usize) -> Result<Vec<Se2>> {
        let rotation = self.rotation(k)?;
        let beams = &self.mission.beams[rotation.beams.clone()];
        motion::reference_from_beams(
            beams,
            &self.navigation,
            &self.mission.mounting,
            rotation.reference_stamp_s,
        )
        .map_err(|e| {
            let hint = match (&e, self.covered_rotations()) {
                (FrontendError::OutsideNavigation { .. }, Some((first, last))) => {
                    format!(" (the navigation covers rotations {first}-{last})")
                }
                (FrontendError::OutsideNavigation { .. }, None) => {
                    " (the navigation covers no whole rotation)".to_string()
                }
                _ => String::new(),
            };
            anyhow::Error::new(e).context(format!("motion compensation of rotation {k}{hint}"))
        })
    }

    /// The first and last rotations whose beams all lie within the
    /// navigation's span (e.g. on the St Pere logs the beams start ~183 s
    /// before the first DVL sample).
    pub fn covered_rotations(&self) -> Option<(usize, usize)> {
        let covered = |r: &Rotation| {
            let beams = &self.mission.beams[r.beams.clone()];
            match (beams.first(), beams.last()) {
                (Some(a), Some(b)) => {
                    self.navigation.pose_at(a.stamp_s).is_ok()
                        && self.navigation.pose_at(b.stamp_s).is_ok()
                }
                _ => false,
            }
        };
        let first = self.rotations.iter().position(covered)?;
        let last = self.rotations.iter().rposition(covered)?;
        Some((first, last))
    }

    /// `S_k` and `I_k` of rotation `k`. The image is built with the scan's
    /// [`Scan::image_frames`], so that the two agree.
    pub fn scan_and_image(&self, k: usize, config: &SlamConfig) -> Result<(Scan, AcousticImage)> {
        let frames = self.frames(k)?;
        let scan = self.scan_with(k, &frames, config)?;
        let image = self.image_with(k, &scan.image_frames(&frames), config)?;
        Ok((scan, image))
    }

    /// `I_k` alone, built as [`MissionRotations::scan_and_image`] builds it
    /// (from the beam frames that its scan corrected; the uncorrected ones
    /// when the rotation has too few ranges for a scan).
    pub fn image(&self, k: usize, config: &SlamConfig) -> Result<AcousticImage> {
        let frames = self.frames(k)?;
        let frames = match self.scan_with(k, &frames, config) {
            Ok(scan) => scan.image_frames(&frames),
            Err(_) => frames,
        };
        self.image_with(k, &frames, config)
    }

    /// `S_k` alone.
    pub fn scan(&self, k: usize, config: &SlamConfig) -> Result<Scan> {
        self.scan_with(k, &self.frames(k)?, config)
    }

    /// `config`'s segmentation and image settings, with those that binary
    /// data changes changed ([`intensity::binary_settings`]).
    fn settings(&self, config: &SlamConfig) -> (SegmentationConfig, ImageConfig) {
        let (mut segmentation, mut image) = (config.segmentation.clone(), config.image.clone());
        if self.binary {
            intensity::binary_settings(&mut segmentation, &mut image);
        }
        (segmentation, image)
    }

    fn scan_with(&self, k: usize, frames: &[Se2], config: &SlamConfig) -> Result<Scan> {
        let rotation = self.rotation(k)?;
        let beams = &self.mission.beams[rotation.beams.clone()];
        let (segmentation, _) = self.settings(config);
        build_scan(beams, frames, rotation.reference_stamp_s, &segmentation)
            .with_context(|| format!("scan of rotation {k}"))
    }

    fn image_with(&self, k: usize, frames: &[Se2], config: &SlamConfig) -> Result<AcousticImage> {
        let rotation = self.rotation(k)?;
        let beams = &self.mission.beams[rotation.beams.clone()];
        let (_, image) = self.settings(config);
        AcousticImage::build(beams, frames, &image)
            .with_context(|| format!("acoustic image of rotation {k}"))
    }

    /// Dead-reckoning prior of `image_from_scan` for `S_scan` on `I_image`,
    /// with its covariance.
    pub fn prior(&self, scan: usize, image: usize) -> Result<(Se2, Matrix3<f64>)> {
        let (from, to) = (self.rotation(image)?, self.rotation(scan)?);
        self.navigation
            .relative(from.reference_stamp_s, to.reference_stamp_s)
            .with_context(|| format!("dead-reckoning motion from rotation {image} to {scan}"))
    }

    /// Ground-truth `image_from_scan`, when the mission has ground truth
    /// covering both reference times.
    pub fn ground_truth(&self, scan: usize, image: usize) -> Option<Se2> {
        let gt = &self.mission.ground_truth;
        let a = ground_truth_at(gt, self.rotations.get(image)?.reference_stamp_s)?;
        let b = ground_truth_at(gt, self.rotations.get(scan)?.reference_stamp_s)?;
        Some(a.between(&b))
    }
}

/// Ground truth at `stamp_s`, interpolated linearly (angle on the shorter
/// arc) between the samples around it; `None` outside their span.
pub fn ground_truth_at(samples: &[GroundTruthPose], stamp_s: f64) -> Option<Se2> {
    let after = samples.partition_point(|s| s.stamp_s < stamp_s);
    if after == samples.len() {
        return None;
    }
    let b = &samples[after];
    if b.stamp_s == stamp_s || after == 0 {
        return (b.stamp_s == stamp_s).then_some(b.world_from_vehicle);
    }
    let a = &samples[after - 1];
    let f = (stamp_s - a.stamp_s) / (b.stamp_s - a.stamp_s);
    let (pa, pb) = (a.world_from_vehicle, b.world_from_vehicle);
    Some(Se2::new(
        pa.x() + f * (pb.x() - pa.x()),
        pa.y() + f * (pb.y() - pa.y()),
        pa.theta() + f * wrap_angle(pb.theta() - pa.theta()),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use echofield_frontend::off_axis::OffAxisSuppression;

    #[test]
    fn ground_truth_is_interpolated_on_the_short_arc() {
        let samples = vec![
            GroundTruthPose {
                stamp_s: 10.0,
                world_from_vehicle: Se2::new(0.0, 0.0, 3.0),
            },
            GroundTruthPose {
                stamp_s: 12.0,
                world_from_vehicle: Se2::new(2.0, -4.0, -3.0),
            },
        ];
        let mid = ground_truth_at(&samples, 11.0).unwrap();
        assert!((mid.x() - 1.0).abs() < 1e-12 && (mid.y() + 2.0).abs() < 1e-12);
        // Halfway from 3 rad to -3 rad across ±π is π.
        assert!((mid.theta().abs() - std::f64::consts::PI).abs() < 1e-9);
        assert_eq!(
            ground_truth_at(&samples, 12.0).unwrap(),
            samples[1].world_from_vehicle
        );
        assert_eq!(
            ground_truth_at(&samples, 10.0).unwrap(),
            samples[0].world_from_vehicle
        );
        assert!(ground_truth_at(&samples, 9.0).is_none());
        assert!(ground_truth_at(&samples, 12.5).is_none());
        assert!(ground_truth_at(&[], 1.0).is_none());
    }

    #[test]
    fn the_matching_steps_read_the_pipelines_config() {
        // One config file for `run` and `match`: a section set in part
        // keeps its other defaults (the image's off-axis margin is not its
        // type's), and the window of a match is the loop gate's.
        let cfg = SlamConfig::from_toml_str(
            "[image]\ncell_size_m = 0.1\n[loops.gate]\nn_sigma = 2.0\n[image.off_axis]\nenabled = false\n",
        )
        .unwrap();
        assert_eq!(cfg.image.cell_size_m, Some(0.1));
        assert_eq!(cfg.loops.gate.n_sigma, 2.0);
        assert_eq!(cfg.matcher, SlamConfig::default().matcher);
        let expected = ImageConfig::default().off_axis;
        assert_eq!(cfg.image.off_axis.margin, expected.margin);
        assert_ne!(expected.margin, OffAxisSuppression::default().margin);
        let err = SlamConfig::from_toml_str("[image]\ncell_size = 0.1\n").unwrap_err();
        assert!(err.to_string().contains("image.cell_size"), "{err}");
    }
}
