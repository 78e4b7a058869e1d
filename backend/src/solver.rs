//! The entry points: [`optimize`] and the reusable [`Solver`] that keeps
//! its orderings and symbolic factorisations between solves.

use crate::config::{Initialisation, SolverConfig};
use crate::error::SolveError;
use crate::initialise::{chordal, init_pairs};
use crate::iteration::Iteration;
use crate::linear::{BlockOrdering, BlockSystem, LinearError, fill_reducing_ordering};
use crate::linearize::{edge_slots, evaluate};
use crate::problem::Problem;
use crate::robust::RobustKernel;
use crate::summary::{SolveSummary, Termination};
use echofield_graph::{PoseGraph, Se2};
use std::time::Instant;

/// Optimises the poses of `graph` in place (see the crate documentation).
/// On error the graph is left unchanged.
pub fn optimize(graph: &mut PoseGraph, config: &SolverConfig) -> Result<SolveSummary, SolveError> {
    Solver::new(config.clone())?.optimize(graph)
}

/// A solver that can be called repeatedly, e.g. on a graph that grows during
/// a mission: the sparsity pattern, fill-reducing ordering and symbolic
/// factorisation of the last solve are kept and reused as long as the set of
/// free poses and the pattern of edges between them are unchanged; a changed
/// pattern triggers a new analysis.
pub struct Solver {
    config: SolverConfig,
    pose_system: Option<Cached<3>>,
    init_system: Option<Cached<2>>,
}

/// A block system and the pattern it was built for.
struct Cached<const D: usize> {
    variables: usize,
    /// Off-diagonal block pairs `(low, high)`, sorted, without duplicates.
    pairs: Vec<(usize, usize)>,
    ordering: BlockOrdering,
    system: BlockSystem<D>,
}

pub(crate) fn normalise(pairs: Vec<(usize, usize)>) -> Vec<(usize, usize)> {
    let mut pairs: Vec<(usize, usize)> = pairs
        .into_iter()
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

/// Makes `cache` hold a system for this pattern, reusing it if the pattern
/// is unchanged, and the ordering of `donor` if that has the same pattern.
/// Returns whether the cached system was reused.
fn prepare<const D: usize>(
    cache: &mut Option<Cached<D>>,
    variables: usize,
    pairs: Vec<(usize, usize)>,
    threads: usize,
    donor: Option<(&[(usize, usize)], &BlockOrdering)>,
) -> Result<bool, SolveError> {
    if cache
        .as_ref()
        .is_some_and(|c| c.variables == variables && c.pairs == pairs)
    {
        return Ok(true);
    }
    let ordering = match donor {
        Some((donor_pairs, ordering)) if donor_pairs == pairs.as_slice() => ordering.clone(),
        _ => fill_reducing_ordering(variables, &pairs).map_err(linear_error)?,
    };
    let system = BlockSystem::new(variables, &pairs, &ordering, threads).map_err(linear_error)?;
    *cache = Some(Cached {
        variables,
        pairs,
        ordering,
        system,
    });
    Ok(false)
}

pub(crate) fn linear_error(e: LinearError) -> SolveError {
    SolveError::Linear(e.to_string())
}

impl Solver {
    /// A solver with a validated configuration.
    pub fn new(config: SolverConfig) -> Result<Self, SolveError> {
        config.validate()?;
        Ok(Self {
            config,
            pose_system: None,
            init_system: None,
        })
    }

    pub fn config(&self) -> &SolverConfig {
        &self.config
    }

    /// Optimises the poses of `graph` in place. On error the graph is left
    /// unchanged.
    pub fn optimize(&mut self, graph: &mut PoseGraph) -> Result<SolveSummary, SolveError> {
        self.optimize_with(graph, None)
    }

    /// [`Solver::optimize`] with one kernel per edge (in the graph's edge
    /// order) instead of one per edge kind.
    pub(crate) fn optimize_with(
        &mut self,
        graph: &mut PoseGraph,
        edge_kernels: Option<&[RobustKernel]>,
    ) -> Result<SolveSummary, SolveError> {
        let start = Instant::now();
        let problem = Problem::new(graph)?;
        let kernels = self.kernels(&problem, edge_kernels);
        let mut poses = graph.poses();
        let plain = vec![RobustKernel::None; kernels.len()];
        let initial_chi2 = evaluate(&problem, &plain, &poses).chi2;
        let mut summary = self.unsolved_summary(&problem, initial_chi2);
        if problem.variables() == 0 {
            let cost = evaluate(&problem, &kernels, &poses);
            summary.initial_cost = cost.robust;
            summary.final_cost = cost.robust;
            summary.time_s = start.elapsed().as_secs_f64();
            return Ok(summary);
        }
        let variables = problem.variables();
        let pairs = normalise(problem.block_pairs());
        let threads = self.config.threads;
        summary.symbolic_reused = prepare(&mut self.pose_system, variables, pairs, threads, None)?;
        if self.config.initialisation == Initialisation::Chordal {
            let init_start = Instant::now();
            self.initialise(&problem, &kernels, &mut poses)?;
            summary.initialisation_time_s = init_start.elapsed().as_secs_f64();
            summary.initialised_chi2 = evaluate(&problem, &plain, &poses).chi2;
        }
        let system = &mut self.pose_system.as_mut().expect("prepared above").system;
        let slots = edge_slots(&problem, system);
        let mut iteration = Iteration {
            problem: &problem,
            kernels: &kernels,
            slots: &slots,
            system,
            config: &self.config,
            start,
        };
        iteration.run(&mut poses, &mut summary)?;
        graph.set_poses(&poses);
        summary.time_s = start.elapsed().as_secs_f64();
        Ok(summary)
    }

    /// One kernel per edge of `problem`: `edge_kernels` when it has one per
    /// edge, else the configured kernel of each edge's kind.
    fn kernels(
        &self,
        problem: &Problem,
        edge_kernels: Option<&[RobustKernel]>,
    ) -> Vec<RobustKernel> {
        match edge_kernels {
            Some(k) if k.len() == problem.edges.len() => k.to_vec(),
            _ => problem
                .edges
                .iter()
                .map(|e| self.config.robust.kernel(e.kind))
                .collect(),
        }
    }

    /// The summary before any iteration: χ² `initial_chi2` (no kernels)
    /// throughout, costs NaN, termination `NothingToOptimise`.
    fn unsolved_summary(&self, problem: &Problem, initial_chi2: f64) -> SolveSummary {
        SolveSummary {
            algorithm: self.config.algorithm,
            initialisation: self.config.initialisation,
            initial_chi2,
            initialised_chi2: initial_chi2,
            final_chi2: initial_chi2,
            initial_cost: f64::NAN,
            final_cost: f64::NAN,
            iterations: 0,
            termination: Termination::NothingToOptimise,
            time_s: 0.0,
            initialisation_time_s: 0.0,
            symbolic_reused: false,
            free_poses: problem.variables(),
            edges: problem.edges.len(),
            log: Vec::new(),
        }
    }

    /// The poses the iterations of [`Solver::optimize`] would start from:
    /// the chordal initialisation from the trusted edges when configured
    /// (and possible), the graph's poses otherwise.
    pub(crate) fn start_poses(&mut self, graph: &PoseGraph) -> Result<Vec<Se2>, SolveError> {
        let mut poses = graph.poses();
        if self.config.initialisation != Initialisation::Chordal {
            return Ok(poses);
        }
        let problem = Problem::new(graph)?;
        if problem.variables() == 0 {
            return Ok(poses);
        }
        let kernels: Vec<RobustKernel> = problem
            .edges
            .iter()
            .map(|e| self.config.robust.kernel(e.kind))
            .collect();
        let pairs = normalise(problem.block_pairs());
        let threads = self.config.threads;
        prepare(
            &mut self.pose_system,
            problem.variables(),
            pairs,
            threads,
            None,
        )?;
        self.initialise(&problem, &kernels, &mut poses)?;
        Ok(poses)
    }

    /// Chordal initialisation from the edges without a robust kernel (the
    /// trusted ones). If those do not tie every pose to the gauge, the
    /// current poses are kept.
    fn initialise(
        &mut self,
        problem: &Problem,
        kernels: &[RobustKernel],
        poses: &mut [Se2],
    ) -> Result<(), SolveError> {
        let used: Vec<bool> = kernels.iter().map(|k| *k == RobustKernel::None).collect();
        if !problem.is_anchored_by(&used) {
            tracing::info!(
                "chordal initialisation skipped: the trusted edges do not link every pose"
            );
            return Ok(());
        }
        let pairs = normalise(init_pairs(problem, &used));
        let donor = self
            .pose_system
            .as_ref()
            .map(|c| (c.pairs.as_slice(), &c.ordering));
        let threads = self.config.threads;
        prepare(
            &mut self.init_system,
            problem.variables(),
            pairs,
            threads,
            donor,
        )?;
        let system = &mut self.init_system.as_mut().expect("prepared above").system;
        chordal(problem, &used, system, poses)
    }
}
