//! The end of a run: the last rotation, the rotations still waiting for
//! the navigation, loop densification, the robust final solve, and the
//! output with its report (see [`report`]).

use super::SlamEngine;
use super::graph::solve_incrementally;
use crate::slam::estimate::Estimate;
use crate::slam::loops::LoopCloser;
use crate::slam::result::SlamOutput;
use crate::slam::{SlamConfig, SlamError, input_checks};
use echofield_backend::{RobustSolveSummary, edge_error};
use echofield_frontend::FrontendError;
use echofield_frontend::loops::RejectReason;
use echofield_frontend::sensors::GroundTruthPose;
use echofield_frontend::warnings::{Warning, WarningKind, Warnings};
use echofield_graph::{EdgeKind, PoseGraph};
use std::collections::HashSet;
use std::time::Instant;

mod report;

impl SlamEngine<'_> {
    /// Ends the run: processes the last rotation and those still waiting
    /// (unless [`Self::end_of_data`] did), densifies the loops, runs the
    /// robust final solve and builds the output; evaluates it against
    /// `ground_truth` when not empty (strictly after the estimation).
    /// Errors: no rotation became a node, no node has a scan or an image,
    /// the navigation never started, a failed final solve.
    pub fn finish(mut self, ground_truth: &[GroundTruthPose]) -> Result<SlamOutput, SlamError> {
        self.end_of_data()?;
        if self.rotation_ranges.is_empty() {
            let error = FrontendError::insufficient(
                "rotation assembly",
                format!(
                    "no complete rotation or sector sweep in {} beams (set keep_partial to keep partial ones)",
                    self.ready.beams()
                ),
            );
            return Err(SlamError::frontend("rotation assembly", error));
        }
        if self.graph.nodes.is_empty() {
            return Err(SlamError::NoNodes {
                mission: self.mission_name.clone(),
                reason: self
                    .skipped
                    .first()
                    .map_or_else(|| "no rotation".to_string(), |s| s.reason.clone()),
            });
        }
        input_checks::scans_and_images(
            &self.mission_name,
            self.reach_m,
            &self.graph.nodes,
            self.config,
        )?;
        let mut warnings = Warnings::new();
        self.close_graph(&mut warnings)?;
        let t = Instant::now();
        let (graph, summary) = final_solve(
            self.config,
            &mut self.graph.estimate,
            &mut self.graph.closer,
        )?;
        let final_solve_s = t.elapsed().as_secs_f64();
        self.output(graph, summary, final_solve_s, warnings, ground_truth)
    }

    /// Densified loops (straight into the final solve), the clique's loops
    /// weighed by their places where their errors are shared
    /// (`LoopConfig::shared_place_errors`), and the warnings of the
    /// node-by-node stage.
    fn close_graph(&mut self, warnings: &mut Warnings) -> Result<(), SlamError> {
        let graph = &mut self.graph;
        let t = Instant::now();
        let rebuilt = |nodes: &[echofield_frontend::nodes::NodeData]| -> usize {
            nodes.iter().map(|n| n.image.rebuilds()).sum()
        };
        let before = rebuilt(&graph.nodes);
        let settled = graph.closer.settle(&mut graph.estimate);
        solve_incrementally(
            &mut graph.estimate,
            settled && graph.config.backend.incremental,
            &mut graph.incremental_error,
        );
        graph.closer.densify(&graph.nodes, &mut graph.estimate)?;
        graph.closer.weigh_shared_places(&mut graph.estimate);
        tracing::debug!(
            mission_pass = before,
            densification = rebuilt(&graph.nodes) - before,
            "images rebuilt for matches"
        );
        graph.closer.finish();
        graph.loops_s += t.elapsed().as_secs_f64();
        if let Some(e) = &graph.incremental_error {
            warnings.push(Warning::new(
                WarningKind::Solver,
                1,
                format!("an incremental solve failed ({e}); the final batch solve was run anyway"),
            ));
        }
        if graph.closer.inexact_cliques > 0 {
            warnings.push(format!(
                "{} consistency searches stopped at the work limit (the largest clique found by then was used)",
                graph.closer.inexact_cliques
            ));
        }
        Ok(())
    }
}

/// The final solve: `optimize_robust` with the loop edges as suspects.
/// Loops it switches off are rejected (`robust_kernel`) and leave the
/// graph; every accepted loop records its weight under the loop kernel at
/// the solution.
fn final_solve(
    config: &SlamConfig,
    estimate: &mut Estimate,
    closer: &mut LoopCloser,
) -> Result<(PoseGraph, RobustSolveSummary), SlamError> {
    let kernel = config.backend.solver.robust.kernel(EdgeKind::Loop);
    closer.attach_metadata(estimate);
    let (mut graph, summary) = estimate.optimise_robust(&config.backend)?;
    let switched: HashSet<(u64, u64)> = summary
        .switched_off
        .iter()
        .map(|s| (s.from, s.to))
        .collect();
    let poses = graph.poses();
    let mut outliers = Vec::new();
    for measurement in closer.accepted_measurements() {
        let (from, to) = (measurement.from as u64, measurement.to as u64);
        let edge = graph
            .edges()
            .find(|e| e.kind == EdgeKind::Loop && e.from == from && e.to == to);
        let Some(edge) = edge else { continue };
        let e = edge_error(edge, &poses[measurement.from], &poses[measurement.to]);
        let (_, weight) = kernel.evaluate(e.dot(&(edge.information * e)));
        closer.records[measurement.id].robust_weight = Some(weight);
        if switched.contains(&(from, to)) {
            outliers.push(measurement.id);
        }
    }
    if !outliers.is_empty() {
        closer.reject(&outliers, RejectReason::RobustKernel, estimate);
        closer.attach_metadata(estimate);
        graph = estimate.graph()?;
    }
    Ok((graph, summary))
}
