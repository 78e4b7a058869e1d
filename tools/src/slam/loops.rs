//! Loop closing against the running estimate: the join of the frontend's
//! loop machinery ([`echofield_frontend::loops`]: records, the match of one
//! candidate and its checks, mutual consistency, the cover rule) with the
//! estimate the backend keeps ([`super::estimate`]).
//!
//! For each new node `k` with a scan:
//! 1. **Gating by predicted overlap** ([`candidates`]). Every older node `j`
//!    at least `min_separation_nodes` rotations back whose image holds
//!    echoes is a candidate when the fraction of `S_k`'s points that the
//!    current estimate places within `j`'s footprint (the range of 90% of
//!    `S_j`'s returns) is at least `min_predicted_overlap`. At most
//!    `max_candidates_per_node` of them are taken, largest overlap first.
//!    Pairs that an accepted loop covers ([`cover`]: both ends within
//!    `cover_spacing_m` of travel of its ends) are not candidates, and of
//!    two candidates of `k` whose older nodes lie within that spacing only
//!    the better-overlapping one is taken: the loops kept per metre of
//!    track are bounded, whatever the rotations per metre.
//! 2. **Gating by uncertainty** ([`candidates`]). The prior `j_from_k` is
//!    the current estimate; its covariance the relative uncertainty of the
//!    two nodes (module [`echofield_frontend::uncertainty`]). The search
//!    window is `n_sigma` standard deviations per axis, at least
//!    `min_window`. A candidate whose window would exceed `max_window` is
//!    *deferred*: it is retried after the next change of the accepted
//!    loops (which usually makes the relative uncertainty small), and
//!    reported as `deferred` if it never qualifies. Only when none of a
//!    node's candidates is certain enough (a first contact with a place
//!    seen long ago) are the best `WIDE_SEARCHES_PER_NODE` of them searched
//!    over `gate.max_window` at once.
//! 3. **Matching and checks** ([`closing`], [`checks`]): `S_k` vs `I_j`,
//!    quality, covariance, window edge, and the symmetric match `S_j` vs
//!    `I_k`. A candidate predicted to overlap almost entirely whose match
//!    lands on nothing is searched again over a wider window (the estimate
//!    is further off than its covariance says).
//! 4. **Mutual consistency** ([`closing`], [`consistency`]): the loops that
//!    passed their own checks form a consistency graph; the accepted loops
//!    are its maximum clique, recomputed whenever a loop is added (so a
//!    loop accepted early can be dropped later when the evidence turns
//!    against it). Accepted loops become `Loop` edges with the match
//!    covariance plus the `min_sigma` floor ([`accepted`]); the backend's
//!    robust kernel on loop edges is the last line of defence. Members
//!    whose place in the clique a rival group nearly as large contests
//!    ([`ConsistencyGraph::contested`], a lead under `DECISION_MARGIN`
//!    loops) are held out of the estimate and of the cover until the
//!    clique leads by the margin or the mission pass ends: the next
//!    candidates are then searched around an estimate that neither group
//!    made, so the rival group can still grow.
//! 5. **Densification** ([`densify`], on by default, after the mission):
//!    the pairs never examined whose relative pose the estimate already
//!    knows, and those the mission rejected only for how they were
//!    searched, are matched by a local climb from the estimate and
//!    accepted when they agree with it. Loops that share a node share its
//!    errors, so a densified loop's covariance is inflated by the design
//!    effect of the loops at its places
//!    ([`Places`](echofield_frontend::loops::places::Places)).
//!
//! Node images are read through their [`ImageResidency`], which keeps the
//! images held within a memory budget between matches; a released image
//! is built again, the same, when read.
//!
//! The matches of step 3 (a node's candidates, the retried ones, and the
//! whole densification pass) run in parallel with rayon; their records
//! are collected and judged in the candidates' order, so a run gives the
//! same result on any number of threads (timings: EXPERIMENTS.md § Speed
//! notes).

mod accepted;
mod candidates;
mod closing;
mod densify;

pub use accepted::loop_metadata;
pub use densify::COVER_ROUNDS;

use echofield_frontend::image::ImageResidency;
use echofield_frontend::loops::checks::Candidate;
use echofield_frontend::loops::consistency::{
    Clique, ConsistencyGraph, DeadReckoningChain, LoopMeasurement,
};
use echofield_frontend::loops::cover::LoopCover;
use echofield_frontend::loops::{LoopConfig, LoopRecord};
#[cfg(doc)]
use echofield_frontend::loops::{checks, consistency, cover};
use echofield_frontend::matcher::MatcherConfig;
use echofield_frontend::uncertainty::DriftModel;
use std::collections::HashSet;

/// The loop-closing state of a run.
pub struct LoopCloser<'a> {
    config: &'a LoopConfig,
    matcher: &'a MatcherConfig,
    /// Every candidate considered, in order; the record index is the loop id.
    pub records: Vec<LoopRecord>,
    candidates: Vec<Candidate>,
    examined: HashSet<(usize, usize)>,
    /// Record indices of deferred candidates still waiting.
    deferred: Vec<usize>,
    consistency: ConsistencyGraph,
    pub chain: DeadReckoningChain,
    /// The current maximum clique.
    pub accepted: Clique,
    /// Its contested members (ids ascending, [`ConsistencyGraph::contested`]),
    /// held out of the estimate and of the cover until the clique decides
    /// them, or the mission pass ends ([`Self::settle`]).
    held: Vec<usize>,
    /// Loops of the densification pass, accepted against the estimate.
    dense: Vec<LoopMeasurement>,
    /// Clique searches that stopped at the work limit.
    pub inexact_cliques: usize,
    /// Matches run (forward and reverse).
    pub matches: usize,
    /// Time spent on mutual consistency, s.
    pub validation_time_s: f64,
    /// Candidates searched over `max_window` (first contacts).
    pub wide_searches: usize,
    /// The accepted loops (clique and densified), for the cover rule.
    cover: LoopCover,
    /// Which nodes' images stay in memory between matches.
    pub residency: ImageResidency,
}

impl<'a> LoopCloser<'a> {
    pub fn new(config: &'a LoopConfig, matcher: &'a MatcherConfig) -> Self {
        let drift = DriftModel {
            drift_fraction: config.drift_fraction,
            heading_sigma_rad: config.drift_heading_sigma_rad,
        };
        Self {
            config,
            matcher,
            records: Vec::new(),
            candidates: Vec::new(),
            examined: HashSet::new(),
            deferred: Vec::new(),
            consistency: ConsistencyGraph::new(),
            chain: DeadReckoningChain::new(drift),
            accepted: Clique {
                ids: Vec::new(),
                exact: true,
            },
            held: Vec::new(),
            dense: Vec::new(),
            inexact_cliques: 0,
            matches: 0,
            validation_time_s: 0.0,
            wide_searches: 0,
            cover: LoopCover::new(config.cover_spacing_m),
            residency: ImageResidency::default(),
        }
    }
}

/// Fixtures shared by the tests of the submodules.
#[cfg(test)]
mod fixtures {
    use super::LoopCloser;
    use echofield_frontend::loops::LoopConfig;
    use echofield_frontend::loops::consistency::LoopMeasurement;
    use echofield_frontend::matcher::MatcherConfig;
    use echofield_graph::Se2;
    use nalgebra::Matrix3;

    pub fn measurement(id: usize, from: usize, to: usize) -> LoopMeasurement {
        LoopMeasurement {
            id,
            from,
            to,
            z: Se2::identity(),
            covariance: Matrix3::identity(),
        }
    }

    /// A closer whose dead-reckoning chain has nodes 1 m apart along x.
    pub fn closer_on_a_line<'a>(
        config: &'a LoopConfig,
        matcher: &'a MatcherConfig,
    ) -> LoopCloser<'a> {
        let mut closer = LoopCloser::new(config, matcher);
        for i in 0..40 {
            let cov = Matrix3::identity() * 1e-4;
            closer.chain.push(Se2::new(i as f64, 0.0, 0.0), 1e-4, &cov);
        }
        closer
    }
}
