//! # echofield-backend
//!
//! Sparse Gauss-Newton and Levenberg-Marquardt optimisation of SE(2) pose
//! graphs on faer's sparse Cholesky factorisation.
//!
//! ## The problem
//!
//! For every edge `i -> j` with measurement `Z` and information `Ω` the error
//! is g2o's: `e = vec(Z⁻¹ (X_i⁻¹ X_j))`, the vector form `(x, y, θ)` of the
//! residual transform with θ wrapped to (-π, π]; a prior on node `i`
//! (an [`EdgeKind::Prior`](echofield_graph::EdgeKind::Prior) self-loop)
//! has `e = vec(Z⁻¹ X_i)`. The solver minimises
//! `Σ ρ_k(eᵀΩe)` where `ρ_k` is the robust kernel chosen for the edge's kind
//! ([`RobustKernel`], none by default, so the cost is χ² = Σ eᵀΩe). This is
//! the "g2o error" column of `datasets/posegraph/REFERENCE.md`.
//!
//! **Gauge.** Nodes marked fixed in the graph (g2o `FIX`) are held at their
//! poses; priors tie poses to the world. When the graph has neither, its
//! first node is held fixed. Every connected component must contain a fixed
//! node or a prior, otherwise the solve fails with
//! [`SolveError::Disconnected`].
//!
//! **Parametrisation.** Each free pose has three unknowns, an additive
//! increment of its vector form `(x, y, θ)`, as g2o's `VertexSE2`. With this
//! choice the Jacobians are exactly those of
//! [`Se2::between_with_jacobians`](echofield_graph::Se2::between_with_jacobians)
//! chained with
//! [`Se2::compose_with_jacobians`](echofield_graph::Se2::compose_with_jacobians)
//! for the left factor `Z⁻¹`, which the graph crate tests against central
//! differences, and θ never needs a chart change in the plane.
//!
//! ## Initialisation, and why
//!
//! Gauss-Newton and LM are local methods; started from dead reckoning they
//! stop in local minima on several standard benchmarks (GTSAM on MIT, g2o
//! on manhattan and city10000, see REFERENCE.md). Almost all of the
//! non-convexity of a pose graph lies in the orientations: once they are
//! known, the positions follow from a linear least-squares problem. So by
//! default ([`Initialisation::Chordal`]) the solver first estimates the
//! orientations alone by the *chordal relaxation* (each heading a free
//! 2-vector, each edge the linear constraint `r_j = R(θ_z) r_i`, then a
//! projection back to angles). Compared with LAGO's linear least squares on
//! angle differences it needs no wrap-around resolution along a spanning
//! tree (which goes wrong when a tree path accumulates heading errors of
//! the order of π); compared
//! with a spanning-tree start it averages all loop closures instead of
//! trusting one path. Positions are then solved linearly given the
//! orientations, and LM refines the result. Both initialisation solves share
//! the fill-reducing ordering of the main system and cost about as much as
//! one LM iteration. With this start LM reaches the best known χ² of every
//! file in `datasets/posegraph` in 4–6 iterations (tests in
//! `tests/tests/posegraph_benchmarks.rs`); on MIT it finds χ² = 41.163,
//! far below the 526.33 that REFERENCE.md lists as best (g2o's LM from the
//! file's start; GTSAM stops at 770.24, and so does echofield's LM from the
//! file's start, `Initialisation::Current`). From the file's start
//! echofield's LM does reach the best value on manhattan and city10000,
//! where g2o stops early.
//!
//! Only edges *without* a robust kernel feed the initialisation: a
//! robustified kind is one you do not trust, and a false loop closure would
//! corrupt a linear solve. If the trusted edges do not tie every pose to the
//! gauge, the current poses are used. [`Initialisation::Current`] skips the
//! initialisation, e.g. to warm-start from the previous solution while
//! re-optimising a growing graph.
//!
//! ## Iteration
//!
//! Levenberg-Marquardt (default) or Gauss-Newton on the normal equations
//! `(H + λD) δ = −g`, with Marquardt's diagonal scaling and Nielsen's
//! damping update, starting from a tiny λ (details in the `iteration`
//! module). It stops when an accepted step lowers the cost by less than
//! [`SolverConfig::relative_cost_tolerance`] of it, when the step norm falls
//! below [`SolverConfig::step_tolerance`], or after
//! [`SolverConfig::max_iterations`] linearisations; [`SolveSummary`] says
//! which, with the per-iteration log. Robust kernels enter by iteratively
//! reweighted least squares ([`RobustKernel`]).
//!
//! ## Linear algebra
//!
//! The normal equations are assembled block by block into a fixed sparsity
//! pattern and solved with faer's supernodal sparse Cholesky (module
//! `linear`, the only place that touches faer). The pattern, an AMD ordering
//! of the pose graph and the symbolic factorisation are computed once per
//! pattern; a [`Solver`] keeps them across calls while the set of free poses
//! and edges is unchanged, which is what re-optimising during a mission
//! needs. [`SolverConfig::threads`] > 1 parallelises the factorisation with
//! rayon.
//!
//! ## Example
//!
//! ```
//! use echofield_backend::{optimize, SolverConfig};
//! use echofield_graph::synthetic::{circle_pose_graph, Noise};
//!
//! let mut fixture = circle_pose_graph(60, 2, Noise::new(0.05, 0.01), 7);
//! let summary = optimize(&mut fixture.graph, &SolverConfig::default()).unwrap();
//! assert!(summary.termination.is_converged());
//! assert!(summary.final_chi2 < summary.initial_chi2);
//! ```

mod config;
mod error;
mod initialise;
mod iteration;
mod linear;
mod linearize;
mod outliers;
mod problem;
mod robust;
mod solver;
mod summary;

pub use config::{Algorithm, ConfigError, Initialisation, RobustConfig, SolverConfig};
pub use error::SolveError;
pub use linearize::{edge_error, graph_chi2};
pub use outliers::{OutlierConfig, RobustSolveSummary, SwitchedOff, optimize_robust};
pub use robust::RobustKernel;
pub use solver::{Solver, optimize};
pub use summary::{IterationLog, SolveSummary, Termination};
