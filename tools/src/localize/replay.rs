//! The localised mission replayed causally, as on the vehicle: beams, DVL
//! and attitude samples in time order (at equal stamps: DVL, attitude,
//! then beams, as [`crate::slam::replay`]); the forward dead-reckoning
//! filter ([`ForwardFilter`]) navigates, the [`RotationStream`] cuts the
//! beams into rotations, and each rotation, once the navigation covers
//! it, becomes a node built exactly as the SLAM frontend builds one
//! ([`build_node`]: the scan `S_k` motion-compensated into the rotation's
//! central pose). The particle filter then takes the dead reckoning's
//! motion since the previous rotation (with its covariance), the compass
//! heading and `S_k`.
//!
//! Not here (the SLAM engine has them): the causal yaw-rate check that
//! raises the heading noise after a gyro fault.

use crate::slam::SlamConfig;
use crate::slam::pipeline::prepare;
use anyhow::{Context, Result, bail};
use echofield_datasets::mcap::foxglove::ScanPoint;
use echofield_frontend::dead_reckoning::{self, DeadReckoningConfig, ForwardFilter, Record};
use echofield_frontend::localization::{LocalizationStep, MonteCarloLocalizer};
use echofield_frontend::nodes::{Skip, build_node};
use echofield_frontend::rotation::{Rotation, RotationStream};
use echofield_frontend::sensors::{GroundTruthPose, Mission};
use echofield_graph::Se2;
use std::collections::VecDeque;
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
    let mut navigation = ForwardFilter::new(&dr_config, &mission.mounting, false)
        .context("dead reckoning of the localised mission")?;
    let mut stream = RotationStream::new(&config.rotation).context("rotation assembly")?;
    let mut pending: VecDeque<Rotation> = VecDeque::new();
    let mut records = dead_reckoning::merged_records(mission).peekable();
    let mut latest_s = f64::NEG_INFINITY;
    let mut state = ReplayState::default();
    let horizon_s = config.dead_reckoning.max_extrapolation_s;
    for beam in &mission.beams {
        while let Some(record) = records.next_if(|r| r.stamp_s() <= beam.stamp_s) {
            latest_s = latest_s.max(record.stamp_s());
            push(&mut navigation, record)?;
            state.process(
                mission,
                config,
                &navigation,
                &mut pending,
                latest_s,
                horizon_s,
                filter,
            )?;
        }
        if let Some(rotation) = stream.push(beam).context("rotation assembly")? {
            pending.push_back(rotation);
        }
        latest_s = latest_s.max(beam.stamp_s);
        state.process(
            mission,
            config,
            &navigation,
            &mut pending,
            latest_s,
            horizon_s,
            filter,
        )?;
    }
    for record in records {
        latest_s = latest_s.max(record.stamp_s());
        push(&mut navigation, record)?;
        state.process(
            mission,
            config,
            &navigation,
            &mut pending,
            latest_s,
            horizon_s,
            filter,
        )?;
    }
    if let Some(rotation) = stream.finish() {
        pending.push_back(rotation);
    }
    state.process(
        mission,
        config,
        &navigation,
        &mut pending,
        f64::INFINITY,
        horizon_s,
        filter,
    )?;
    if state.rotations.is_empty() {
        bail!(
            "{}: no rotation of the mission is covered by its navigation (DVL and heading)",
            mission.name
        );
    }
    Ok(Localized {
        rotations: state.rotations,
        ground_truth: mission.ground_truth.clone(),
        mission_name: mission.name.clone(),
        mounting: mission.mounting.clone(),
    })
}

fn push(filter: &mut ForwardFilter, record: Record<'_>) -> Result<()> {
    match record {
        Record::Dvl(s) => filter.push_dvl(s),
        Record::Attitude(a) => filter.push_attitude(a),
    }
    .context("dead reckoning of the localised mission")
}

/// What the replay keeps between rotations.
#[derive(Default)]
struct ReplayState {
    rotations: Vec<LocalizedRotation>,
    /// Stamp of the previous localised rotation, s.
    previous_s: Option<f64>,
}

impl ReplayState {
    /// Localises the pending rotations the navigation now covers (or that
    /// it will never cover: the latest sample is beyond their end plus the
    /// extrapolation horizon), in order.
    #[allow(clippy::too_many_arguments)]
    fn process(
        &mut self,
        mission: &Mission,
        config: &SlamConfig,
        navigation: &ForwardFilter,
        pending: &mut VecDeque<Rotation>,
        latest_s: f64,
        horizon_s: f64,
        filter: &mut MonteCarloLocalizer,
    ) -> Result<()> {
        while let Some(rotation) = pending.front() {
            let covered = navigation.latest_s() >= rotation.end_s;
            if !covered && latest_s <= rotation.end_s + horizon_s {
                return Ok(());
            }
            let Some(rotation) = pending.pop_front() else {
                return Ok(());
            };
            let Some(nav) = navigation.navigation() else {
                continue; // no navigation yet: the rotation is skipped
            };
            let t = Instant::now();
            let node = match build_node(
                &mission.beams[rotation.beams.clone()],
                &rotation,
                nav,
                &mission.mounting,
                &config.segmentation,
                &config.image,
            ) {
                Ok(node) => node,
                Err(Skip::Outside(_)) => continue,
                Err(Skip::Fatal(e)) => return Err(e.into()),
            };
            let build_s = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let motion = match self.previous_s {
                Some(from_s) => {
                    Some(nav.relative(from_s, node.stamp_s).with_context(|| {
                        format!("dead reckoning of rotation {}", rotation.index)
                    })?)
                }
                None => None,
            };
            let points = if node.in_dvl_gap {
                &[][..]
            } else {
                &node.scan.points[..]
            };
            let step = filter.step(motion.as_ref(), node.dead_reckoning.theta(), points);
            let filter_s = t.elapsed().as_secs_f64();
            self.previous_s = Some(node.stamp_s);
            let particles = filter.particles();
            let stride = particles.len().div_ceil(CLOUD_POINTS).max(1);
            let max_w = particles.iter().map(|p| p.weight).fold(0.0, f64::max);
            let cloud = particles
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
                .collect();
            self.rotations.push(LocalizedRotation {
                rotation_index: rotation.index,
                stamp_s: node.stamp_s,
                dead_reckoning: node.dead_reckoning,
                step,
                filter_s,
                build_s,
                cloud,
            });
        }
        Ok(())
    }
}
