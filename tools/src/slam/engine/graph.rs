//! The estimate the engine grows node by node: each new node gets its
//! odometry and sequential edges, its loop closures, and the incremental
//! solves they trigger.

use super::solve_schedule::{SolveSchedule, view_due};
use crate::slam::config::SlamConfig;
use crate::slam::estimate::Estimate;
use crate::slam::loops::LoopCloser;
use crate::slam::{SlamError, sequential};
use echofield_frontend::dead_reckoning::Navigation;
use echofield_frontend::loops::SequentialRecord;
use echofield_frontend::nodes::NodeData;
use echofield_graph::{EdgeKind, Se2};
use std::time::Instant;

/// Nodes, their chain edges, the loop closer and the estimate.
pub(super) struct GraphState<'c> {
    pub config: &'c SlamConfig,
    pub nodes: Vec<NodeData>,
    /// `sequential[k - 1]` is node `k` against node `k - 1` (empty when
    /// sequential matching is off).
    pub sequential: Vec<SequentialRecord>,
    pub estimate: Estimate,
    pub closer: LoopCloser<'c>,
    /// The first failed incremental solve (the estimate stays as it was)
    /// or online view ([`Estimate::solved_view`]; the estimate is emitted).
    pub incremental_error: Option<String>,
    /// Time spent on sequential matches, s.
    pub sequential_s: f64,
    /// Time spent in `close_loops`, s (matches, validation, solves).
    pub loops_s: f64,
    /// When the incremental solves run ([`super::solve_schedule`]).
    schedule: SolveSchedule,
    /// Whether every node's event carries the graph solved with that
    /// node's edges ([`Self::emitted_poses`]); else the estimate as the
    /// solve schedule left it.
    emit_solved: bool,
    /// The poses emitted with the last node when `emit_solved`.
    emitted: Vec<Se2>,
}

impl<'c> GraphState<'c> {
    /// `emit_solved`: see the field (the online engine sets it).
    pub fn new(config: &'c SlamConfig, emit_solved: bool) -> Result<Self, SlamError> {
        Ok(Self {
            config,
            nodes: Vec::new(),
            sequential: Vec::new(),
            estimate: Estimate::new(&config.backend)?,
            closer: LoopCloser::new(&config.loops, &config.matcher),
            incremental_error: None,
            sequential_s: 0.0,
            loops_s: 0.0,
            schedule: SolveSchedule::default(),
            emit_solved,
            emitted: Vec::new(),
        })
    }

    /// The current estimate of every node as the engine emits it: with
    /// `emit_solved`, the graph solved with the last node's edges (its
    /// odometry, sequential match and heading prior, and every edge before;
    /// [`Estimate::solved_view`]; on a long mission every few nodes,
    /// [`view_due`]); else the estimate, which is solved only when the
    /// accepted loops change and places a new node by the odometry from
    /// the one before.
    pub fn emitted_poses(&self) -> &[Se2] {
        if self.emit_solved && self.emitted.len() == self.estimate.len() {
            &self.emitted
        } else {
            self.estimate.poses()
        }
    }

    /// Adds `node` (the next node, id `nodes.len()`): sequential match
    /// against its predecessor, chain edges, loop closures. `navigation`
    /// must cover both node stamps.
    pub fn add(&mut self, node: NodeData, navigation: &Navigation) -> Result<(), SlamError> {
        let k = self.nodes.len();
        if let Some(prev) = self.nodes.last() {
            let t = Instant::now();
            let history = sequential::submap_history(
                &self.nodes,
                &self.sequential,
                k,
                self.config.sequential.submap_rotations,
                navigation,
            )?;
            let record = sequential::match_next(
                prev,
                &history,
                &node,
                k,
                navigation,
                (&self.config.sequential, &self.config.matcher),
            )?;
            self.sequential.extend(record);
            self.sequential_s += t.elapsed().as_secs_f64();
        }
        self.nodes.push(node);
        self.add_chain(k, navigation)?;
        let t = Instant::now();
        let solves_before = self.estimate.incremental_solves;
        let incremental = self.config.backend.incremental;
        let (error, schedule) = (&mut self.incremental_error, &mut self.schedule);
        let mut optimise = |estimate: &mut Estimate| -> Result<(), SlamError> {
            solve_incrementally(estimate, incremental && schedule.on_change(k), error);
            Ok(())
        };
        self.closer
            .close_loops(k, &self.nodes, &mut self.estimate, &mut optimise)?;
        solve_incrementally(
            &mut self.estimate,
            incremental && self.schedule.after_node(k),
            &mut self.incremental_error,
        );
        if self.emit_solved {
            self.emitted = if self.estimate.incremental_solves > solves_before {
                self.estimate.poses().to_vec()
            } else if !view_due(k) {
                self.estimate.extended(&self.emitted)
            } else {
                // A failed view is kept with the failed solves (the first
                // goes into the report) and the estimate's poses are
                // emitted instead ([`Self::emitted_poses`]).
                self.estimate
                    .solved_view(&self.emitted)
                    .unwrap_or_else(|e| {
                        self.incremental_error.get_or_insert(e.to_string());
                        Vec::new()
                    })
            };
        }
        self.loops_s += t.elapsed().as_secs_f64();
        Ok(())
    }

    /// Adds node `k` with its odometry and (accepted) sequential edges; its
    /// initial pose follows the previous node's current estimate.
    fn add_chain(&mut self, k: usize, navigation: &Navigation) -> Result<(), SlamError> {
        let (nodes, config) = (&self.nodes, self.config);
        let node = &nodes[k];
        let heading_var = navigation
            .covariance_at(node.stamp_s)
            .map_err(|e| SlamError::frontend("dead-reckoning covariance", e))?[(2, 2)];
        if k == 0 {
            self.estimate.add_node(node.stamp_s, node.dead_reckoning);
            let zero = nalgebra::Matrix3::zeros();
            self.closer
                .chain
                .push(node.dead_reckoning, heading_var, &zero);
            return Ok(());
        }
        let (odometry, odometry_cov) = sequential::odometry(navigation, &nodes[k - 1], node)?;
        // The odometry, not the match: its heading is tied to the compass,
        // while chained matches let the heading random-walk.
        let pose = self.estimate.poses()[k - 1].compose(&odometry);
        self.estimate.add_node(node.stamp_s, pose);
        let dt_s = node.stamp_s - nodes[k - 1].stamp_s;
        if let Some(sigma) = config
            .backend
            .heading_prior_sigma(&config.dead_reckoning, dt_s)
        {
            self.estimate
                .add_heading_prior(k, node.dead_reckoning, sigma)?;
        }
        self.estimate.add_chain_edge(
            EdgeKind::Odometry,
            k - 1,
            k,
            odometry,
            &odometry_cov,
            None,
        )?;
        let dead_reckoning = node.dead_reckoning;
        self.add_sequential_edge(k)?;
        self.closer
            .chain
            .push(dead_reckoning, heading_var, &odometry_cov);
        Ok(())
    }

    /// The accepted sequential match of node `k` as a `Sequential` edge.
    fn add_sequential_edge(&mut self, k: usize) -> Result<(), SlamError> {
        let Some(record) = self.sequential.get(k - 1).filter(|s| s.accepted) else {
            return Ok(());
        };
        let (Some(z), Some(cov)) = (
            record.measurement,
            sequential::edge_covariance(record, &self.config.sequential),
        ) else {
            return Ok(());
        };
        let metadata = record.quality.as_ref().map(|q| {
            serde_json::json!({
                "mean_intensity": q.mean_intensity,
                "inside_fraction": q.inside_fraction,
                "points": q.points,
            })
        });
        self.estimate
            .add_chain_edge(EdgeKind::Sequential, k - 1, k, z, &cov, metadata)
    }
}

/// An incremental solve of `estimate` when `due`. A failed one leaves the
/// estimate as it was and is kept in `error` (the first only): the final
/// batch solve decides.
pub(super) fn solve_incrementally(estimate: &mut Estimate, due: bool, error: &mut Option<String>) {
    if due && let Err(e) = estimate.optimise_incremental() {
        error.get_or_insert(e.to_string());
    }
}
