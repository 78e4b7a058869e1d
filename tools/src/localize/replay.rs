//! The localised mission replayed causally, as on the vehicle, by the
//! causal driver the SLAM engine uses ([`echofield_frontend::replay`]):
//! beams, DVL and attitude samples in time order ([`mission_records`]);
//! the forward dead-reckoning filter ([`ForwardFilter`]) navigates,
//! [`ReadyRotations`] cuts the beams into rotations and holds each until
//! the navigation covers it (or the extrapolation horizon has passed),
//! and each ready rotation becomes a node built exactly as the SLAM
//! frontend builds one
//! ([`build_node`]: the scan `S_k` motion-compensated into the rotation's
//! central pose). The particle filter then takes the motion since the
//! previous rotation (the dead reckoning's fused with the sonar's
//! sequential match, [`super::odometry`], once the filter has tracked for
//! `CONFIRM_ROTATIONS` rotations since its last seeding; the dead
//! reckoning's alone before), with its covariance, the compass heading
//! and `S_k`.
//!
//! Not here (the SLAM engine has them): the causal yaw-rate check that
//! raises the heading noise after a gyro fault.

use super::odometry::SonarOdometry;
use crate::slam::SlamConfig;
use crate::slam::pipeline::prepare;
use anyhow::{Context, Result, bail};
use echofield_datasets::mcap::foxglove::ScanPoint;
use echofield_frontend::dead_reckoning::{DeadReckoningConfig, ForwardFilter};
use echofield_frontend::localization::filter::CONFIRM_ROTATIONS;
use echofield_frontend::localization::{LocalizationStep, MonteCarloLocalizer, Particle};
use echofield_frontend::nodes::{Skip, build_node};
use echofield_frontend::replay::{MissionRecord, ReadyRotations, mission_records};
use echofield_frontend::rotation::Rotation;
use echofield_frontend::sensors::{GroundTruthPose, Mission};
use echofield_graph::Se2;
use nalgebra::Matrix3;
use std::time::Instant;

/// Particles kept per rotation for the MCAP's cloud (every n-th).
const CLOUD_POINTS: usize = 2000;

/// One rotation of the localised mission.
#[derive(Clone, Debug)]
pub struct LocalizedRotation {
    /// Index of the rotation among those the beams formed.
    pub rotation_index: usize,
    /// The rotation's central time, s.
    pub stamp_s: f64,
    /// Forward dead reckoning at `stamp_s` (the mission's own frame).
    pub dead_reckoning: Se2,
    /// The motion `previous_from_current` since the previous rotation of
    /// [`Localized::rotations`] and its covariance in `(x, y, θ)` (m, rad),
    /// as the filter took it ([`super::odometry`]); `None` at the first.
    pub motion: Option<(Se2, Matrix3<f64>)>,
    /// Whether the sonar's sequential match went into `motion` (else it is
    /// the dead reckoning's alone).
    pub sonar_motion: bool,
    pub step: LocalizationStep,
    /// Wall time of the filter step, s.
    pub filter_s: f64,
    /// Wall time of building the rotation's scan and image, s.
    pub build_s: f64,
    /// Particles after the step (positions, weights as intensity), at most
    /// [`CLOUD_POINTS`].
    pub cloud: Vec<ScanPoint>,
}

/// The mission after localisation.
pub struct Localized {
    pub rotations: Vec<LocalizedRotation>,
    /// The offline smoothed pose of every rotation (map frame,
    /// [`super::smooth`]); `None` when it was not computed or failed.
    pub smoothed: Option<Vec<Se2>>,
    pub ground_truth: Vec<GroundTruthPose>,
    pub mission_name: String,
    pub mounting: echofield_frontend::sensors::SensorMounting,
}

/// Localises `mission` with `filter`, the scans built with `config` (the
/// map run's). Errors: bad records (naming them), a mission without the
/// sensors the filter needs, no rotation the navigation covers.
pub fn localize_mission(
    mission: &Mission,
    config: &SlamConfig,
    filter: &mut MonteCarloLocalizer,
) -> Result<Localized> {
    let (mission, config, _, _) = prepare(mission, config)?;
    let (mission, config): (&Mission, &SlamConfig) = (&mission, &config);
    let offset = mission.mounting.heading_offset_rad;
    let dr_config = DeadReckoningConfig {
        heading_offset_rad: config.dead_reckoning.heading_offset_rad + offset,
        ..config.dead_reckoning.clone()
    };
    let navigation = ForwardFilter::new(&dr_config, &mission.mounting, false)
        .context("dead reckoning of the localised mission")?;
    let ready = ReadyRotations::new(&config.rotation, config.dead_reckoning.max_extrapolation_s)
        .context("rotation assembly")?;
    let mut replay = Replay {
        mission,
        config,
        navigation,
        ready,
        filter,
        odometry: SonarOdometry::new(config),
        tracked: 0,
        rotations: Vec::new(),
        previous_s: None,
    };
    for record in mission_records(mission) {
        replay.push(record)?;
    }
    replay.ready.finish();
    replay.localize_ready()?;
    if replay.rotations.is_empty() {
        bail!(
            "{}: no rotation of the mission is covered by its navigation (DVL and heading)",
            mission.name
        );
    }
    Ok(Localized {
        rotations: replay.rotations,
        smoothed: None,
        ground_truth: mission.ground_truth.clone(),
        mission_name: mission.name.clone(),
        mounting: mission.mounting.clone(),
    })
}

/// The causal replay's state: the navigation, the rotations waiting for
/// it, and what was localised so far.
struct Replay<'a> {
    mission: &'a Mission,
    config: &'a SlamConfig,
    navigation: ForwardFilter,
    ready: ReadyRotations,
    filter: &'a mut MonteCarloLocalizer,
    odometry: SonarOdometry<'a>,
    /// Rotations in a row localised or coasting since the last seeding.
    tracked: usize,
    rotations: Vec<LocalizedRotation>,
    /// Stamp of the previous localised rotation, s.
    previous_s: Option<f64>,
}

impl Replay<'_> {
    /// Takes the next record and localises the rotations it makes ready.
    fn push(&mut self, record: MissionRecord<'_>) -> Result<()> {
        match record {
            MissionRecord::Dvl(s) => self.navigation.push_dvl(s),
            MissionRecord::Attitude(a) => self.navigation.push_attitude(a),
            MissionRecord::Beam(_, beam) => {
                self.ready.push_beam(beam).context("rotation assembly")?;
                return self.localize_ready();
            }
        }
        .context("dead reckoning of the localised mission")?;
        self.ready.observe(record.stamp_s());
        self.localize_ready()
    }

    /// Localises the rotations the navigation now covers (or will never
    /// cover: [`ReadyRotations`]), in order.
    fn localize_ready(&mut self) -> Result<()> {
        for rotation in self.ready.take_ready(self.navigation.latest_s(), 1) {
            self.localize(&rotation)?;
        }
        Ok(())
    }

    /// Localises one ready rotation; rotations without navigation yet, or
    /// outside it, are skipped.
    fn localize(&mut self, rotation: &Rotation) -> Result<()> {
        let (mission, config) = (self.mission, self.config);
        let Some(nav) = self.navigation.navigation() else {
            return Ok(()); // no navigation yet: the rotation is skipped
        };
        let t = Instant::now();
        let node = match build_node(
            &mission.beams[rotation.beams.clone()],
            rotation,
            nav,
            &mission.mounting,
            &config.segmentation,
            &config.image,
        ) {
            Ok(node) => node,
            Err(Skip::Outside(_)) => return Ok(()),
            Err(Skip::Fatal(e)) => return Err(e.into()),
        };
        let build_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let dead_reckoning = self
            .previous_s
            .map(|from_s| nav.relative(from_s, node.stamp_s))
            .transpose()
            .with_context(|| format!("dead reckoning of rotation {}", rotation.index))?;
        let fused = self.odometry.motion(&node, nav, dead_reckoning)?;
        // After a (re)seeding the cloud is no tracking belief yet (the
        // first weighing leaves a few particles with all the weight, often
        // a metre or more off): the dead reckoning's wider motion lets it
        // move to the right place, and the fused, narrower one takes over
        // once the filter has been localised for as many rotations in a
        // row as it needs to claim `localised`.
        let (motion, sonar_motion) = if self.tracked >= CONFIRM_ROTATIONS {
            fused
        } else {
            (dead_reckoning, false)
        };
        // A rotation in a DVL gap is weighed too (unlike the SLAM
        // frontend, which does not match it): its scan was compensated with
        // the held velocity, so it is somewhat distorted, but a particle
        // weight is a score, not a constraint kept in a graph, and the scan
        // still places the cloud far better than the dead reckoning alone,
        // which is all the filter has in the gap (EXPERIMENTS.md
        // § Localisation through DVL gaps).
        let points = &node.scan.points[..];
        let step = self
            .filter
            .step(motion.as_ref(), node.dead_reckoning.theta(), points);
        let filter_s = t.elapsed().as_secs_f64();
        self.tracked = if step.reseeded || !step.state.is_localised() {
            0
        } else {
            self.tracked + 1
        };
        self.previous_s = Some(node.stamp_s);
        let cloud = particle_cloud(self.filter.particles());
        let (stamp_s, dead_reckoning) = (node.stamp_s, node.dead_reckoning);
        self.odometry.push(node);
        self.rotations.push(LocalizedRotation {
            rotation_index: rotation.index,
            stamp_s,
            dead_reckoning,
            motion,
            sonar_motion,
            step,
            filter_s,
            build_s,
            cloud,
        });
        Ok(())
    }
}

/// The particles as a point cloud for the MCAP: every n-th, at most
/// [`CLOUD_POINTS`], the intensity their weight relative to the largest (1
/// when every weight is 0).
fn particle_cloud(particles: &[Particle]) -> Vec<ScanPoint> {
    let stride = particles.len().div_ceil(CLOUD_POINTS).max(1);
    let max_w = particles.iter().map(|p| p.weight).fold(0.0, f64::max);
    particles
        .iter()
        .step_by(stride)
        .map(|p| ScanPoint {
            x_m: p.pose.x(),
            y_m: p.pose.y(),
            intensity: if max_w > 0.0 {
                (p.weight / max_w) as f32
            } else {
                1.0
            },
        })
        .collect()
}
