//! The SLAM engine: sonar beams, DVL and attitude samples in, one node per
//! completed rotation out, with the current estimate of every pose.
//!
//! [`SlamEngine`] is the one code path of echofield's SLAM: a vehicle's
//! navigation computer or a live sonar pushes samples as they arrive
//! (online), and [`crate::slam::run_mission`] replays a recorded mission
//! through it (batch). Per completed rotation the engine builds the node
//! (scan and image motion-compensated into its central pose), matches it
//! against its predecessor, adds the chain edges, looks for loop closures
//! and runs the incremental solves they trigger; online, it then emits
//! the graph solved with the new node's edges (its odometry, sequential
//! match and heading prior:
//! [`crate::slam::estimate::Estimate::solved_view`], which leaves the
//! estimate that gates the loop candidates as the solves left it, so that
//! the online and the batch run close the same loops).
//! [`SlamEngine::end_of_data`] processes the rotation the end of the data
//! completes, and [`SlamEngine::finish`] adds the end-of-mission steps
//! (loop densification, the robust final solve, the report).
//!
//! # Causality
//! With [`SlamEngine::new`] the navigation is the forward dead-reckoning
//! filter over the samples pushed so far, and a node's event depends only
//! on samples stamped up to the moment it is emitted: a rotation is
//! processed when the navigation has a sample at or after its last beam,
//! or when any sample arrives more than `dead_reckoning.max_extrapolation_s`
//! after it (the navigation then extrapolates or the rotation is skipped):
//! the rule of [`ReadyRotations`], the causal driver that
//! `echofield localize` shares.
//! The yaw-rate check runs over spans of past attitude samples and only
//! raises the noise of later ones.
//!
//! What the batch run adds over online ([`SlamEngine::with_navigation`]):
//! the navigation computed beforehand over the whole mission (the
//! Rauch-Tung-Striebel smoother with `dead_reckoning.smoothing`, the
//! yaw-rate check over every attitude sample), and, before the engine, the
//! screening of implausible records and the detection of binary
//! intensities over all beams.
//!
//! # Input contract
//! Each stream in non-decreasing stamp order: a beam or sample earlier than
//! its predecessor in the same stream is an error naming the record
//! (`beam i`, `DVL sample i`, `attitude sample i`, counting from 0 per
//! stream) and field; non-finite or implausible values likewise. A DVL or
//! attitude sample earlier than a sample of the other stream already
//! filtered is skipped and counted (a warning in the report). An error
//! ends the run: what was emitted before it stays valid, the engine is
//! not to be pushed further.
//!
//! ```no_run
//! use echofield::slam::{SlamConfig, SlamEngine, load_mission};
//! let mission = load_mission(std::path::Path::new("marina.mcap"))?;
//! let config = SlamConfig::default();
//! let mut engine = SlamEngine::new(&config, &mission.name, mission.mounting.clone())?;
//! for beam in &mission.beams {
//!     // A real vehicle interleaves push_dvl and push_attitude in time order.
//!     for event in engine.push_beam(beam.clone())? {
//!         println!("node {} at {:.1} s: {:?}", event.node_id, event.stamp_s, event.pose);
//!     }
//! }
//! // The last rotation completes when the data ends.
//! for event in engine.end_of_data()? {
//!     println!("node {} at {:.1} s: {:?}", event.node_id, event.stamp_s, event.pose);
//! }
//! let output = engine.finish(&[])?;
//! # Ok::<(), anyhow::Error>(())
//! ```

mod finish;
mod graph;
mod navigation;
mod solve_schedule;

use super::SlamError;
use super::config::SlamConfig;
use super::result::{IntensityReport, SkippedRotation, StageTimings};
use echofield_frontend::dead_reckoning::Navigation;
use echofield_frontend::intensity::IntensityKind;
use echofield_frontend::nodes::spacing::NodeSpacing;
use echofield_frontend::nodes::{NodeData, NodePlacement, Skip, build_node_from};
use echofield_frontend::replay::ReadyRotations;
use echofield_frontend::rotation::Rotation;
use echofield_frontend::sensors::{Attitude, DvlVelocity, SensorMounting, SonarBeam};
use echofield_frontend::warnings::Warnings;
use echofield_graph::Se2;
use echofield_graph::io::TrajectoryPose;
use graph::GraphState;
use navigation::NavigationSource;
use rayon::prelude::*;
use std::collections::VecDeque;
use std::ops::Range;
use std::time::Instant;

/// What the engine emits when a rotation has become a node.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeEvent {
    /// Node id (0, 1, 2, ...): index into [`NodeEvent::poses`].
    pub node_id: usize,
    /// Index of the rotation among the rotations the beams formed.
    pub rotation_index: usize,
    /// The rotation's central time, s (the node's stamp).
    pub stamp_s: f64,
    /// The node's `world_from_vehicle` estimate when emitted (dead-reckoning
    /// world frame, see [`crate::slam::result`]): online, the graph solved
    /// with this node's edges; in batch, the running estimate (the last
    /// solve with the later nodes placed by their odometry).
    pub pose: Se2,
    /// The current estimate of every node `0..=node_id`, same frame.
    pub poses: Vec<Se2>,
    /// Wall time of the work done for this rotation (node building,
    /// matching, loop closing, incremental solves), s.
    pub latency_s: f64,
    /// Loop closures accepted so far, this node's included.
    pub loops_accepted: usize,
}

/// The online SLAM engine (see the module doc).
pub struct SlamEngine<'c> {
    config: &'c SlamConfig,
    mission_name: String,
    mounting: SensorMounting,
    navigation: NavigationSource,
    /// Rotations assembled from the beams, waiting for the navigation
    /// (the causal driver `localize` shares).
    ready: ReadyRotations,
    /// Beams from index `beams_offset` on (those of rotations not yet
    /// processed and of the current unit).
    beams: VecDeque<SonarBeam>,
    beams_offset: usize,
    /// Ready rotations processed together: 1 online (each as soon as it
    /// is ready); in batch, with the whole navigation known, enough to
    /// build their nodes on every worker thread at once.
    batch_size: usize,
    /// Every rotation's beam range and the stamp of the beam after it.
    rotation_ranges: Vec<(Range<usize>, f64)>,
    /// The farthest range any beam reaches, m.
    reach_m: f64,
    graph: GraphState<'c>,
    /// Which ready rotations become nodes (`rotation.node_spacing_m`).
    spacing: NodeSpacing,
    skipped: Vec<SkippedRotation>,
    /// Online: each node's estimate as it was emitted (the output's
    /// `emitted`); `None` in batch.
    emitted: Option<Vec<TrajectoryPose>>,
    /// Dead reckoning and node building so far (the other stages are
    /// timed by [`GraphState`]).
    timings: StageTimings,
    input: EngineInput,
    started: Instant,
}

/// What the caller knows of the input that the report carries.
#[derive(Clone, Debug)]
struct EngineInput {
    intensity: IntensityReport,
    warnings: Warnings,
}

impl<'c> SlamEngine<'c> {
    /// An online engine for mission `mission_name` with the sonar and DVL
    /// `mounting` (already resolved from `config.mounting`), navigating with
    /// the causal filter. Errors: an invalid config.
    pub fn new(
        config: &'c SlamConfig,
        mission_name: &str,
        mounting: SensorMounting,
    ) -> Result<Self, SlamError> {
        config.validate()?;
        let navigation = NavigationSource::causal(&config.dead_reckoning, &mounting)?;
        Self::build(config, mission_name, mounting, navigation)
    }

    /// A batch engine that places every beam with `navigation`, computed
    /// beforehand (pushed DVL and attitude samples are then ignored).
    pub fn with_navigation(
        config: &'c SlamConfig,
        mission_name: &str,
        mounting: SensorMounting,
        navigation: Navigation,
    ) -> Result<Self, SlamError> {
        config.validate()?;
        Self::build(
            config,
            mission_name,
            mounting,
            NavigationSource::Given(navigation),
        )
    }

    fn build(
        config: &'c SlamConfig,
        mission_name: &str,
        mounting: SensorMounting,
        navigation: NavigationSource,
    ) -> Result<Self, SlamError> {
        let ready =
            ReadyRotations::new(&config.rotation, config.dead_reckoning.max_extrapolation_s)
                .map_err(|e| SlamError::frontend("rotation assembly", e))?;
        let (batch_size, emit_solved) = match navigation {
            NavigationSource::Given(_) => (8 * rayon::current_num_threads().max(1), false),
            _ => (1, true),
        };
        Ok(Self {
            config,
            mission_name: mission_name.to_string(),
            mounting,
            navigation,
            ready,
            beams: VecDeque::new(),
            beams_offset: 0,
            batch_size,
            rotation_ranges: Vec::new(),
            reach_m: 0.0,
            graph: GraphState::new(config, emit_solved)?,
            spacing: NodeSpacing::new(config.rotation.node_spacing_m),
            skipped: Vec::new(),
            emitted: emit_solved.then(Vec::new),
            timings: StageTimings::default(),
            input: EngineInput {
                intensity: IntensityReport {
                    kind: IntensityKind::Graded,
                    derived: Vec::new(),
                },
                warnings: Warnings::new(),
            },
            started: Instant::now(),
        })
    }

    /// What the caller found about the input before the engine (the
    /// intensity scale, screening warnings); goes into the report.
    pub fn set_input_report(&mut self, intensity: IntensityReport, warnings: Warnings) {
        self.input = EngineInput {
            intensity,
            warnings,
        };
    }

    /// Nodes built so far.
    pub fn nodes(&self) -> usize {
        self.graph.nodes.len()
    }

    /// The current estimate of every node's `world_from_vehicle`: online,
    /// the graph solved with the last node's edges; in batch, the estimate
    /// that gates the loop candidates (see [`NodeEvent::poses`]).
    pub fn poses(&self) -> &[Se2] {
        self.graph.emitted_poses()
    }

    /// Takes the next sonar beam; returns the nodes it completes.
    pub fn push_beam(&mut self, beam: SonarBeam) -> Result<Vec<NodeEvent>, SlamError> {
        let t = Instant::now();
        let rotation = self
            .ready
            .push_beam(&beam)
            .map_err(|e| SlamError::frontend("rotation assembly", e))?;
        if let Some(rotation) = rotation {
            self.rotation_ranges
                .push((rotation.beams.clone(), beam.stamp_s));
        }
        self.reach_m = self.reach_m.max(beam.max_range_m());
        self.beams.push_back(beam);
        self.timings.scan_image_building_s += t.elapsed().as_secs_f64();
        self.process_ready()
    }

    /// Takes the next DVL sample; returns the nodes it completes.
    pub fn push_dvl(&mut self, sample: &DvlVelocity) -> Result<Vec<NodeEvent>, SlamError> {
        let t = Instant::now();
        self.navigation.push_dvl(sample)?;
        self.timings.dead_reckoning_s += t.elapsed().as_secs_f64();
        self.ready.observe(sample.stamp_s);
        self.process_ready()
    }

    /// Takes the next attitude sample; returns the nodes it completes.
    pub fn push_attitude(&mut self, sample: &Attitude) -> Result<Vec<NodeEvent>, SlamError> {
        let t = Instant::now();
        self.navigation.push_attitude(sample)?;
        self.timings.dead_reckoning_s += t.elapsed().as_secs_f64();
        self.ready.observe(sample.stamp_s);
        self.process_ready()
    }

    /// The end of the data: the last rotation (when kept) and every
    /// rotation still waiting for the navigation are processed now;
    /// returns the nodes they complete, the last events of an online run.
    /// [`Self::finish`] does the same (and drops the events) if this was
    /// not called; a second call returns nothing. Push nothing after it.
    pub fn end_of_data(&mut self) -> Result<Vec<NodeEvent>, SlamError> {
        if self.ready.finished() {
            return Ok(Vec::new());
        }
        if let Some(rotation) = self.ready.finish() {
            self.rotation_ranges
                .push((rotation.beams.clone(), f64::NAN));
        }
        self.process_ready()
    }

    /// Processes the pending rotations whose time has come (see the
    /// module doc), in order; in batch, once [`Self::batch_size`] of them
    /// are ready (or at the end), their nodes built in parallel.
    fn process_ready(&mut self) -> Result<Vec<NodeEvent>, SlamError> {
        let covered_s = self.navigation.covered_until_s();
        let mut rotations = self.ready.take_ready(covered_s, self.batch_size);
        self.thin(&mut rotations);
        if rotations.is_empty() {
            return Ok(Vec::new());
        }
        let t = Instant::now();
        let built = self.build_nodes(&rotations);
        let build_s = t.elapsed().as_secs_f64() / rotations.len() as f64;
        self.timings.scan_image_building_s += t.elapsed().as_secs_f64();
        let mut events = Vec::new();
        for (rotation, node) in rotations.iter().zip(built) {
            events.extend(self.add(rotation, node, build_s)?);
        }
        Ok(events)
    }

    /// Drops from `rotations` those that [`NodeSpacing`] does not make
    /// nodes (their beams are dropped when the next node is built,
    /// [`Self::build_nodes`]). A rotation the
    /// navigation does not place is kept, to be skipped and reported.
    fn thin(&mut self, rotations: &mut Vec<Rotation>) {
        if self.config.rotation.node_spacing_m <= 0.0 {
            return;
        }
        let Some(navigation) = self.navigation.current() else {
            return;
        };
        let (spacing, reach_m) = (&mut self.spacing, self.reach_m);
        rotations.retain(
            |rotation| match navigation.pose_at(rotation.reference_stamp_s) {
                Ok(pose) => spacing.keep(&pose, reach_m),
                Err(_) => true,
            },
        );
    }

    /// The nodes of `rotations` (consecutive, the oldest pending ones), in
    /// parallel when there are several; their beams move into the nodes,
    /// and the beams before them are dropped.
    fn build_nodes(&mut self, rotations: &[Rotation]) -> Vec<Result<NodeData, Skip>> {
        let owned: Vec<Vec<SonarBeam>> = rotations
            .iter()
            .map(|rotation| {
                // Rotations are disjoint and in order (the stream cuts
                // each where the last ended).
                let skipped = rotation.beams.start.saturating_sub(self.beams_offset);
                self.beams.drain(..skipped);
                self.beams_offset = rotation.beams.end;
                self.beams.drain(..rotation.beams.len()).collect()
            })
            .collect();
        let build = |(rotation, beams): (&Rotation, Vec<SonarBeam>)| match self.navigation.current()
        {
            Some(navigation) => {
                let place = NodePlacement {
                    navigation,
                    mounting: &self.mounting,
                    segmentation: &self.config.segmentation,
                    image: &self.config.image,
                };
                build_node_from(beams, rotation, &place)
            }
            None => Err(Skip::Outside(format!(
                "no navigation yet at t = {:.3} s (no time with both a valid DVL sample and a heading)",
                rotation.end_s
            ))),
        };
        if rotations.len() > 1 {
            rotations.par_iter().zip(owned).map(build).collect()
        } else {
            rotations.iter().zip(owned).map(build).collect()
        }
    }

    /// Adds the node built for `rotation` (which took `build_s`) to the
    /// graph; `None` when the navigation did not cover it (skipped and
    /// reported).
    fn add(
        &mut self,
        rotation: &Rotation,
        built: Result<NodeData, Skip>,
        build_s: f64,
    ) -> Result<Option<NodeEvent>, SlamError> {
        let t = Instant::now();
        let node = match built {
            Ok(node) => node,
            Err(Skip::Outside(reason)) => {
                self.skipped.push(SkippedRotation {
                    rotation_index: rotation.index,
                    start_s: rotation.start_s,
                    end_s: rotation.end_s,
                    reason,
                });
                return Ok(None);
            }
            Err(Skip::Fatal(error)) => return Err(error.into()),
        };
        let Some(navigation) = self.navigation.current() else {
            return Ok(None);
        };
        self.graph.add(node, navigation)?;
        let latency_s = build_s + t.elapsed().as_secs_f64();
        let poses = self.graph.emitted_poses().to_vec();
        let node_id = poses.len() - 1;
        if let Some(track) = &mut self.emitted {
            track.push(TrajectoryPose {
                stamp_s: rotation.reference_stamp_s,
                pose: poses[node_id],
            });
        }
        Ok(Some(NodeEvent {
            node_id,
            rotation_index: rotation.index,
            stamp_s: rotation.reference_stamp_s,
            pose: poses[node_id],
            poses,
            latency_s,
            loops_accepted: self.graph.closer.accepted.ids.len(),
        }))
    }
}
