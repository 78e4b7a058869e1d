//! `echofield.optimize`: a 2D pose graph solved by the backend, as
//! `echofield optimize` does.

use crate::arrays::{poses_array, read_rows, to_python};
use echofield::output::write_atomic;
use echofield_backend::{
    Algorithm, Initialisation, OutlierConfig, RobustConfig, RobustKernel, RobustSolveSummary,
    SolverConfig, graph_chi2, optimize_robust,
};
use echofield_graph::io::{read_pose_graph, write_g2o};
use echofield_graph::{Edge, EdgeKind, Node, PoseGraph, Se2};
use nalgebra::Matrix3;
use numpy::PyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::path::PathBuf;

/// The result of `optimize`.
#[pyclass(frozen, module = "echofield")]
pub struct OptimizeResult {
    /// Node ids, `(n,)` uint64, in the order of `poses` (the file's vertex
    /// order, or the rows of the `poses` argument).
    #[pyo3(get)]
    ids: Py<PyAny>,
    /// Optimised `world_from_node` poses `[x, y, yaw]`, `(n, 3)`.
    #[pyo3(get)]
    poses: Py<PyAny>,
    /// χ² (Σ eᵀ Ω e with g2o's error, see `datasets/posegraph/REFERENCE.md`)
    /// at the given poses.
    #[pyo3(get)]
    initial_chi2: f64,
    /// χ² at the optimised poses (with `robust`: over the loops not
    /// switched off).
    #[pyo3(get)]
    final_chi2: f64,
    /// Linearisations of the solve (with `robust`: of the robust and the
    /// last least-squares solve).
    #[pyo3(get)]
    iterations: usize,
    /// Why the solver stopped (`"cost_tolerance"`, `"step_tolerance"`,
    /// `"max_iterations"`, ...).
    #[pyo3(get)]
    termination: String,
    /// Whether that reason means "at a minimum".
    #[pyo3(get)]
    converged: bool,
    /// Wall time of the solve, s (reading and writing excluded).
    #[pyo3(get)]
    time_s: f64,
    /// Edge indices of the loop closures switched off (with `robust`).
    #[pyo3(get)]
    switched_off: Vec<usize>,
    /// The whole summary as `echofield optimize --summary` writes it
    /// (least-squares keys; with `robust` also `robust`).
    #[pyo3(get)]
    summary: Py<PyAny>,
}

/// `--robust` of `echofield optimize`.
fn kernel(name: &str) -> PyResult<RobustKernel> {
    Ok(match name {
        "none" => RobustKernel::None,
        "huber" => RobustKernel::HUBER_DEFAULT,
        "cauchy" => RobustKernel::CAUCHY_DEFAULT,
        "dcs" => RobustKernel::DCS_DEFAULT,
        other => {
            return Err(PyValueError::new_err(format!(
                "robust: `{other}` is not one of none, huber, cauchy, dcs"
            )));
        }
    })
}

/// The graph of the `poses` / `edges` arguments: node `i` is row `i` of
/// `poses`; an edge row is `[from, to, dx, dy, dyaw, I11, I12, I13, I22,
/// I23, I33]` like g2o's `EDGE_SE2` (the upper triangle of the
/// information); edges between consecutive ids are odometry, others loop
/// closures, as the g2o reader has them.
fn graph_from_arrays(
    poses: &Bound<'_, PyAny>,
    edges: &Bound<'_, PyAny>,
    fixed: &[u64],
) -> PyResult<PoseGraph> {
    let mut graph = PoseGraph::new();
    for (i, [x, y, yaw]) in read_rows::<3>(poses, "poses")?.into_iter().enumerate() {
        graph
            .add_node(Node {
                id: i as u64,
                pose: Se2::new(x, y, yaw),
                stamp_s: None,
            })
            .map_err(|e| PyValueError::new_err(format!("poses: row {i}: {e}")))?;
    }
    for (row, e) in read_rows::<11>(edges, "edges")?.into_iter().enumerate() {
        let id = |v: f64, column: &str| -> PyResult<u64> {
            if v >= 0.0 && v.fract() == 0.0 && v < u64::MAX as f64 {
                Ok(v as u64)
            } else {
                Err(PyValueError::new_err(format!(
                    "edges: row {row}, {column}: {v} is not a node id"
                )))
            }
        };
        let (from, to) = (id(e[0], "from")?, id(e[1], "to")?);
        let information = Matrix3::new(e[5], e[6], e[7], e[6], e[8], e[9], e[7], e[9], e[10]);
        let kind = if from.abs_diff(to) == 1 {
            EdgeKind::Odometry
        } else {
            EdgeKind::Loop
        };
        graph
            .add_edge(Edge::new(
                kind,
                from,
                to,
                Se2::new(e[2], e[3], e[4]),
                information,
            ))
            .map_err(|err| PyValueError::new_err(format!("edges: row {row}: {err}")))?;
    }
    for &id in fixed {
        graph
            .fix(id)
            .map_err(|e| PyValueError::new_err(format!("fixed: {e}")))?;
    }
    Ok(graph)
}

/// Optimises a 2D pose graph with the backend, as `echofield optimize`
/// does (same options and defaults).
///
/// Either `graph`, the path of a g2o or TORO file, or the arrays `poses`
/// (`(n, 3)` initial `[x, y, yaw]`, node `i` in row `i`) and `edges`
/// (`(e, 11)` rows `[from, to, dx, dy, dyaw, I11, I12, I13, I22, I23,
/// I33]`, like g2o's `EDGE_SE2`), with `fixed` node ids (a graph without
/// fixed nodes is anchored as the g2o reader's is). `solver`: `"lm"` or
/// `"gn"`; `robust`: `"none"`, `"huber"`, `"cauchy"` or `"dcs"` (on the
/// loop closures, with false loops switched off); `init`: `"chordal"` or
/// `"file"` (the given poses); `output`: where to write the optimised graph
/// as g2o. Raises `echofield.Error` for a bad file (naming its line and
/// field) or a failed solve, `ValueError` for bad arrays.
#[pyfunction]
#[pyo3(signature = (
    graph = None, *, poses = None, edges = None, fixed = Vec::new(), solver = "lm",
    robust = "none", init = "chordal", max_iterations = None, threads = 1, output = None
))]
#[allow(clippy::too_many_arguments)]
pub fn optimize(
    py: Python<'_>,
    graph: Option<PathBuf>,
    poses: Option<&Bound<'_, PyAny>>,
    edges: Option<&Bound<'_, PyAny>>,
    fixed: Vec<u64>,
    solver: &str,
    robust: &str,
    init: &str,
    max_iterations: Option<usize>,
    threads: usize,
    output: Option<PathBuf>,
) -> PyResult<OptimizeResult> {
    let config = solver_config(solver, robust, init, max_iterations, threads)?;
    let start = start_graph(py, graph, poses, edges, &fixed)?;
    let with_kernel = robust != "none";
    let (solved, summary) = py
        .detach(|| -> anyhow::Result<(PoseGraph, RobustSolveSummary)> {
            let mut solved = start.clone();
            let summary = optimize_robust(&mut solved, &config, &OutlierConfig::default())?;
            if let Some(path) = &output {
                write_atomic(path, |w| Ok(write_g2o(&solved, w)?))?;
            }
            Ok((solved, summary))
        })
        .map_err(crate::to_py_err)?;
    let least_squares = &summary.least_squares;
    let summary_value = summary_json(&summary, with_kernel)?;
    let termination = serde_json::to_value(least_squares.termination)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_else(|| format!("{:?}", least_squares.termination));
    let ids: Vec<u64> = solved.nodes().map(|n| n.id).collect();
    Ok(OptimizeResult {
        ids: PyArray1::from_vec(py, ids).into_any().unbind(),
        poses: poses_array(py, solved.poses())?.into_any().unbind(),
        initial_chi2: graph_chi2(&start),
        final_chi2: least_squares.final_chi2,
        iterations: least_squares.iterations
            + if with_kernel {
                summary.robust.iterations
            } else {
                0
            },
        termination,
        converged: least_squares.termination.is_converged(),
        time_s: summary.time_s,
        switched_off: summary.switched_off.iter().map(|s| s.edge).collect(),
        summary: to_python(py, &summary_value)?.unbind(),
    })
}

/// The solver options of [`optimize`]; `ValueError` for an unknown
/// solver, init or kernel name, `echofield.Error` for values out of range.
fn solver_config(
    solver: &str,
    robust: &str,
    init: &str,
    max_iterations: Option<usize>,
    threads: usize,
) -> PyResult<SolverConfig> {
    let defaults = SolverConfig::default();
    let config = SolverConfig {
        algorithm: match solver {
            "lm" => Algorithm::LevenbergMarquardt,
            "gn" => Algorithm::GaussNewton,
            other => {
                return Err(PyValueError::new_err(format!(
                    "solver: `{other}` is not lm or gn"
                )));
            }
        },
        initialisation: match init {
            "chordal" => Initialisation::Chordal,
            "file" => Initialisation::Current,
            other => {
                return Err(PyValueError::new_err(format!(
                    "init: `{other}` is not chordal or file"
                )));
            }
        },
        robust: RobustConfig::loops_only(kernel(robust)?),
        max_iterations: max_iterations.unwrap_or(defaults.max_iterations),
        threads,
        ..defaults
    };
    config
        .validate()
        .map_err(|e| crate::to_py_err(anyhow::Error::new(e).context("invalid solver options")))?;
    Ok(config)
}

/// The graph to optimise: read from `graph` (a g2o or TORO path), or
/// built from the `poses` and `edges` arrays; exactly one of the two must
/// be given.
fn start_graph(
    py: Python<'_>,
    graph: Option<PathBuf>,
    poses: Option<&Bound<'_, PyAny>>,
    edges: Option<&Bound<'_, PyAny>>,
    fixed: &[u64],
) -> PyResult<PoseGraph> {
    match (graph, poses, edges) {
        (Some(path), None, None) => py.detach(|| read_pose_graph(&path)).map_err(|e| {
            crate::to_py_err(
                anyhow::Error::new(e).context(format!("cannot read pose graph {}", path.display())),
            )
        }),
        (None, Some(poses), Some(edges)) => graph_from_arrays(poses, edges, fixed),
        _ => Err(PyValueError::new_err(
            "give either graph (a g2o or TORO path) or both poses and edges",
        )),
    }
}

/// The least-squares solve's summary as JSON, with the whole robust
/// summary under `robust` when a kernel was used.
fn summary_json(summary: &RobustSolveSummary, with_kernel: bool) -> PyResult<serde_json::Value> {
    let mut value = serde_json::to_value(&summary.least_squares).map_err(crate::py_err)?;
    if with_kernel && let Some(map) = value.as_object_mut() {
        map.insert(
            "robust".into(),
            serde_json::to_value(summary).map_err(crate::py_err)?,
        );
    }
    Ok(value)
}

#[pymethods]
impl OptimizeResult {
    fn __repr__(&self) -> String {
        format!(
            "<echofield.OptimizeResult: chi2 {:.6} -> {:.6} in {} iterations ({})>",
            self.initial_chi2, self.final_chi2, self.iterations, self.termination
        )
    }
}
