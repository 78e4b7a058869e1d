//! The mission pass of loop closing (steps 3-4 of the module doc of
//! [`super`]): a new node's candidates are matched or deferred, deferred
//! ones retried when the accepted set changes, and the loops that pass
//! their checks admitted to the consistency graph, whose maximum clique is
//! the accepted set.

use super::LoopCloser;
use crate::slam::SlamError;
use crate::slam::estimate::Estimate;
use echofield_frontend::loops::LoopRecord;
use echofield_frontend::loops::RejectReason;
use echofield_frontend::loops::checks::{Candidate, examine};
use echofield_frontend::loops::config::CONSISTENCY_MAX_CHI2;
use echofield_frontend::loops::consistency::LoopMeasurement;
use echofield_frontend::nodes::NodeData;
use echofield_frontend::uncertainty::with_floor;
use nalgebra::Matrix3;
use rayon::prelude::*;

/// Rounds of retrying deferred candidates after the accepted set changes.
const MAX_RETRY_ROUNDS: usize = 3;
/// Deferred candidates kept waiting at most; older ones stay `deferred`.
const MAX_WAITING: usize = 64;
/// Loops by which a maximum clique must lead every clique that takes one
/// of the loops it leaves out, before the members that loop conflicts with
/// go into the estimate: a lead of one loop (e.g. three loops against two
/// at a place whose walls allow two fits) is not yet a decision, since the
/// next candidates, searched around the estimate, would follow whichever
/// group the estimate holds.
const DECISION_MARGIN: usize = 2;

impl LoopCloser<'_> {
    /// Looks for loops of the newest node `k`, then retries deferred
    /// candidates while the accepted set changes. Runs the incremental
    /// solves through `optimise` whenever the accepted loops change.
    pub fn close_loops(
        &mut self,
        k: usize,
        nodes: &[NodeData],
        estimate: &mut Estimate,
        optimise: &mut dyn FnMut(&mut Estimate) -> Result<(), SlamError>,
    ) -> Result<(), SlamError> {
        self.residency.enforce(nodes.len(), |i| &nodes[i].image);
        if !self.config.enabled || k < self.config.min_separation_nodes {
            return Ok(());
        }
        let candidates = self.candidates_of(k, nodes, estimate);
        let mut changed = self.process(candidates, k, nodes, estimate)?;
        for _ in 0..MAX_RETRY_ROUNDS {
            if !changed {
                break;
            }
            optimise(estimate)?;
            changed = self.retry_deferred(k, nodes, estimate)?;
        }
        Ok(())
    }

    /// Matches or defers `candidates`; returns whether the accepted set
    /// changed.
    pub(super) fn process(
        &mut self,
        candidates: Vec<Candidate>,
        k: usize,
        nodes: &[NodeData],
        estimate: &mut Estimate,
    ) -> Result<bool, SlamError> {
        let deferred = |c: &Candidate| c.too_uncertain(&self.config.gate.max_window) && !c.wide;
        let searched: Vec<&Candidate> = candidates.iter().filter(|c| !deferred(c)).collect();
        let mut examined = self.examine_all(&searched, k, nodes)?.into_iter();
        let mut passed = Vec::new();
        for candidate in candidates {
            self.examined.insert((candidate.from, candidate.to));
            let id = self.records.len();
            if deferred(&candidate) {
                let mut record = candidate.record(k, self.config);
                record.rejected_by = Some(RejectReason::Deferred);
                self.records.push(record);
                self.candidates.push(candidate);
                self.deferred.push(id);
                if self.deferred.len() > MAX_WAITING {
                    self.deferred.remove(0);
                }
                continue;
            }
            let record = examined.next().expect("one record per searched candidate");
            if record.rejected_by.is_none() {
                passed.push(id);
            }
            self.records.push(record);
            self.candidates.push(candidate);
        }
        Ok(self.admit(passed, estimate))
    }

    /// Matches the candidates independently of each other (in parallel
    /// with rayon; each match reads only the nodes and the configs), and
    /// returns their records in the candidates' order, so the result does
    /// not depend on the number of threads. The first error, in that
    /// order, is returned.
    pub(super) fn examine_all(
        &mut self,
        candidates: &[&Candidate],
        k: usize,
        nodes: &[NodeData],
    ) -> Result<Vec<LoopRecord>, SlamError> {
        let (matcher, config) = (self.matcher, self.config);
        // Collected whole first: rayon's own `Result` collection may
        // return any of several errors.
        let records = candidates
            .par_iter()
            .map(|c| examine(c, k, nodes, matcher, config))
            .collect::<Vec<_>>()
            .into_iter()
            .collect::<Result<Vec<_>, _>>()?;
        for record in &records {
            self.matches += usize::from(record.matched.is_some() || record.no_match.is_some());
            self.matches += usize::from(record.reverse.is_some());
        }
        Ok(records)
    }

    /// Retries the deferred candidates with the current estimate.
    pub(super) fn retry_deferred(
        &mut self,
        k: usize,
        nodes: &[NodeData],
        estimate: &mut Estimate,
    ) -> Result<bool, SlamError> {
        let waiting = std::mem::take(&mut self.deferred);
        let (mut ready, mut passed) = (Vec::new(), Vec::new());
        let mut paths: Vec<(usize, Vec<Option<Matrix3<f64>>>)> = Vec::new();
        for id in waiting {
            let (j, to, overlap) = {
                let c = &self.candidates[id];
                (c.from, c.to, c.predicted_overlap)
            };
            if !paths.iter().any(|(t, _)| *t == to) {
                paths.push((to, estimate.links().relative_from(to, estimate.poses())));
            }
            let path = &paths.iter().find(|(t, _)| *t == to).expect("just added").1;
            let candidate = self.candidate(j, to, overlap, path[j].as_ref(), estimate.poses());
            if candidate.too_uncertain(&self.config.gate.max_window) {
                self.deferred.push(id);
                continue;
            }
            ready.push((id, candidate));
        }
        let searched: Vec<&Candidate> = ready.iter().map(|(_, c)| c).collect();
        let records = self.examine_all(&searched, k, nodes)?;
        for ((id, candidate), record) in ready.into_iter().zip(records) {
            if record.rejected_by.is_none() {
                passed.push(id);
            }
            self.records[id] = record;
            self.candidates[id] = candidate;
        }
        Ok(self.admit(passed, estimate))
    }

    /// Adds loops that passed their checks to the consistency graph,
    /// recomputes the maximum clique and updates the estimate's loop
    /// edges. Returns whether the accepted set changed.
    pub(super) fn admit(&mut self, passed: Vec<usize>, estimate: &mut Estimate) -> bool {
        if passed.is_empty() {
            return false;
        }
        let start = std::time::Instant::now();
        for id in passed {
            let record = &self.records[id];
            let (Some(z), Some(cov)) = (record.measurement, record.covariance) else {
                continue;
            };
            let covariance = with_floor(&cov, &self.config.gate.min_sigma);
            let measurement = LoopMeasurement {
                id,
                from: record.from as usize,
                to: record.to as usize,
                z,
                covariance,
            };
            self.consistency
                .add(measurement, &self.chain, CONSISTENCY_MAX_CHI2);
        }
        let clique = self.consistency.max_clique();
        self.inexact_cliques += usize::from(!clique.exact);
        let previous = self.in_estimate();
        self.accepted = clique;
        self.held = self.consistency.contested(DECISION_MARGIN);
        self.validation_time_s += start.elapsed().as_secs_f64();
        self.update_estimate(&previous, estimate)
    }
}
