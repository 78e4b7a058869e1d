//! `echofield.run` (the pipeline of `echofield run`) and the `RunResult`
//! it returns, whose poses are numpy arrays.

use crate::arrays::{dict_to_toml, poses_array, rows_array, stamped_array, to_python};
use crate::mission::Mission;
use echofield::output::folder::OutputFolder;
use echofield::slam::online::run_online;
use echofield::slam::outputs::{FOLDER_FILES, write_output_files};
use echofield::slam::{NoProgress, RunInfo, SlamConfig, SlamOutput, load_mission};
use echofield_frontend::sensors::Mission as RustMission;
use echofield_graph::Se2;
use numpy::PyArray1;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The text of a config argument: a dict (laid over the defaults like a
/// file) or the path of a TOML file; with a description of where it came
/// from for errors.
pub(crate) fn config_text(config: &Bound<'_, PyAny>, name: &str) -> PyResult<(String, String)> {
    if let Ok(dict) = config.cast::<PyDict>() {
        return Ok((dict_to_toml(dict, name)?, format!("({name} dict)")));
    }
    let Some(path) = crate::arrays::as_path(config)? else {
        return Err(PyTypeError::new_err(format!(
            "{name}: expected None, a dict or the path of a TOML file"
        )));
    };
    let text = echofield::config_file::read_config_text(&path).map_err(crate::py_err)?;
    Ok((text, path.display().to_string()))
}

/// The pipeline configuration from `None` (the defaults), a dict or a
/// TOML path, with the file's path when it came from one.
pub(crate) fn slam_config(
    config: Option<&Bound<'_, PyAny>>,
) -> PyResult<(SlamConfig, Option<PathBuf>)> {
    let Some(config) = config.filter(|c| !c.is_none()) else {
        return Ok((SlamConfig::default(), None));
    };
    let path = crate::arrays::as_path(config)?;
    let (text, origin) = config_text(config, "config")?;
    let parsed = SlamConfig::from_toml_str(&text).map_err(|e| {
        crate::to_py_err(anyhow::Error::new(e).context(format!("in config {origin}")))
    })?;
    Ok((parsed, path))
}

/// Runs the SLAM pipeline over a mission, as `echofield run` does.
///
/// `mission`: a `Mission` (from `load_mission` or `simulate`) or the path
/// of one (MCAP file, rosbag2 folder, St Pere folder). `config`: `None`
/// for the defaults, a dict laid over them (`{"loops": {"densify":
/// False}}`), or the path of a TOML file (`echofield config` prints every
/// key). `output`: a folder to write every output of `echofield run`
/// into (checked before any work, replaced whole; only an empty folder or
/// an earlier echofield output is replaced). `online`: replay the mission
/// record by record through the causal engine (`run --online`: forward
/// dead reckoning, no smoother, no look-ahead); the estimates as emitted
/// are then in `RunResult.emitted`.
///
/// A run judged suspect (`report["health"]["verdict"] == "suspect"`)
/// returns normally: check the verdict. Raises `echofield.Error` for bad
/// input, an invalid config or a failed solve.
#[pyfunction]
#[pyo3(signature = (mission, config = None, output = None, online = false))]
pub fn run(
    py: Python<'_>,
    mission: &Bound<'_, PyAny>,
    config: Option<&Bound<'_, PyAny>>,
    output: Option<PathBuf>,
    online: bool,
) -> PyResult<RunResult> {
    let (config, config_path) = slam_config(config)?;
    let (mission, mission_path): (Arc<RustMission>, Option<PathBuf>) =
        if let Ok(m) = mission.cast::<Mission>() {
            (Arc::clone(&m.get().inner), None)
        } else if let Some(path) = crate::arrays::as_path(mission)? {
            let read = py
                .detach(|| load_mission(&path))
                .map_err(crate::to_py_err)?;
            (Arc::new(read), Some(path))
        } else {
            return Err(PyTypeError::new_err(
                "mission: expected an echofield.Mission or the path of a mission",
            ));
        };
    let output_slam = py
        .detach(|| -> anyhow::Result<SlamOutput> {
            run_and_write(
                &mission,
                &config,
                output.as_deref(),
                online,
                mission_path.as_deref(),
                config_path.as_deref(),
            )
        })
        .map_err(crate::to_py_err)?;
    RunResult::new(py, &output_slam, output)
}

/// The run, and its outputs written into `output` when given (the folder
/// prepared before any work, as `echofield run` does).
fn run_and_write(
    mission: &RustMission,
    config: &SlamConfig,
    output: Option<&Path>,
    online: bool,
    mission_path: Option<&Path>,
    config_path: Option<&Path>,
) -> anyhow::Result<SlamOutput> {
    use anyhow::Context;
    let inputs: Vec<&Path> = mission_path.into_iter().collect();
    let run_info = output.map(|dir| RunInfo::start("run (python)", &inputs, config_path, dir));
    let folder = output
        .map(|dir| OutputFolder::prepare(dir, FOLDER_FILES))
        .transpose()?;
    let failed = || format!("SLAM on {} failed", mission.name);
    let mut slam = if online {
        run_online(mission, config, &NoProgress).with_context(failed)?
    } else {
        echofield::slam::run_mission(mission, config, &NoProgress).with_context(failed)?
    };
    if let (Some(folder), Some(dir)) = (folder, output) {
        slam.report.run = run_info;
        write_output_files(folder.path(), &slam, mission)
            .and_then(|()| folder.commit())
            .with_context(|| format!("cannot write the outputs into {}", dir.display()))?;
    }
    Ok(slam)
}

/// The defaults of the pipeline's configuration: a dict of sections (as
/// `config.toml` holds them), or with `documented=True` the TOML text of
/// `echofield config`, every key with its documentation and unit.
#[pyfunction]
#[pyo3(signature = (documented = false))]
pub fn default_config(py: Python<'_>, documented: bool) -> PyResult<Bound<'_, PyAny>> {
    if documented {
        return Ok(echofield::config_doc::DOCUMENTED_DEFAULTS
            .into_pyobject(py)?
            .into_any());
    }
    to_python(py, &SlamConfig::default())
}

/// What a run produced, as numpy arrays (see each attribute). Poses are
/// rows `[x_m, y_m, yaw_rad]`, stamped poses `[stamp_s, x_m, y_m,
/// yaw_rad]`, `world_from_vehicle` in the dead-reckoning world frame
/// (node 0 where dead reckoning puts it); ground truth is in its own
/// frame (the report's ATE aligns them).
#[pyclass(frozen, module = "echofield")]
pub struct RunResult {
    /// The mission's name.
    #[pyo3(get)]
    mission_name: String,
    /// Node stamps (the rotations' central times), s, `(n,)`.
    #[pyo3(get)]
    stamps: Py<PyAny>,
    /// Optimised node poses, `(n, 3)`.
    #[pyo3(get)]
    poses: Py<PyAny>,
    /// Optimised node poses with their stamps, `(n, 4)` (what
    /// `trajectory_tum.txt` holds; an argument of `evaluate`).
    #[pyo3(get)]
    trajectory: Py<PyAny>,
    /// Dead-reckoning node poses, `(n, 3)`.
    #[pyo3(get)]
    dead_reckoning_poses: Py<PyAny>,
    /// Dense dead reckoning at the navigation's rate, `(m, 4)`.
    #[pyo3(get)]
    dead_reckoning: Py<PyAny>,
    /// The optimised trajectory at the navigation's rate, `(m, 4)`: dead
    /// reckoning corrected by the optimised nodes, through every node pose
    /// (`trajectory_nav_tum.txt`).
    #[pyo3(get)]
    navigation_rate: Py<PyAny>,
    /// Ground truth at the node stamps it covers, `(k, 4)` in its own
    /// frame, or `None` without ground truth.
    #[pyo3(get)]
    ground_truth: Py<PyAny>,
    /// With `online=True` (and from `Engine`): each node's estimate as
    /// emitted when its rotation completed, `(n, 4)`; else `None`.
    #[pyo3(get)]
    emitted: Py<PyAny>,
    /// Every loop-closure candidate, a dict of equal-length columns (see
    /// `loops.csv`): `from`, `to`, `examined_at` (int), `accepted`,
    /// `densified`, `partial` (bool), `rejected_by` (list of str or None),
    /// `score`, `predicted_overlap`, `robust_weight`, `true_positive`
    /// (1.0, 0.0 or NaN without ground truth), `measurement` and
    /// `ground_truth` (`(k, 3)` `from_from_to` poses, NaN rows where
    /// absent).
    #[pyo3(get)]
    loops: Py<PyAny>,
    /// The content of `report.json` as a dict (ATE/RPE, loop precision
    /// and recall when the mission has ground truth, health, timings).
    #[pyo3(get)]
    report: Py<PyAny>,
    /// The effective configuration as a dict (`config.toml`).
    #[pyo3(get)]
    config: Py<PyAny>,
    /// The output folder, when one was written.
    #[pyo3(get)]
    output: Option<PathBuf>,
    nodes: usize,
}

impl RunResult {
    pub(crate) fn new(
        py: Python<'_>,
        slam: &SlamOutput,
        output: Option<PathBuf>,
    ) -> PyResult<Self> {
        let nodes = &slam.nodes;
        let stamped = |pose: fn(&echofield::slam::NodeRecord) -> Se2| {
            stamped_array(py, nodes.iter().map(|n| (n.stamp_s, pose(n))))
        };
        let ground_truth = match &slam.ground_truth {
            Some(gt) => stamped_array(py, gt.iter().copied())?.into_any().unbind(),
            None => py.None(),
        };
        let emitted = match &slam.emitted {
            Some(e) => stamped_array(py, e.iter().map(|p| (p.stamp_s, p.pose)))?
                .into_any()
                .unbind(),
            None => py.None(),
        };
        Ok(Self {
            mission_name: slam.mission_name.clone(),
            stamps: PyArray1::from_vec(py, nodes.iter().map(|n| n.stamp_s).collect())
                .into_any()
                .unbind(),
            poses: poses_array(py, nodes.iter().map(|n| n.optimised))?
                .into_any()
                .unbind(),
            trajectory: stamped(|n| n.optimised)?.into_any().unbind(),
            dead_reckoning_poses: poses_array(py, nodes.iter().map(|n| n.dead_reckoning))?
                .into_any()
                .unbind(),
            dead_reckoning: stamped_array(py, slam.dead_reckoning.iter().copied())?
                .into_any()
                .unbind(),
            navigation_rate: stamped_array(py, slam.navigation_rate_trajectory())?
                .into_any()
                .unbind(),
            ground_truth,
            emitted,
            loops: loops_dict(py, slam)?.into_any().unbind(),
            report: to_python(py, &slam.report)?.unbind(),
            config: to_python(py, &slam.config)?.unbind(),
            output,
            nodes: nodes.len(),
        })
    }
}

/// The loop candidates as columns.
fn loops_dict<'py>(py: Python<'py>, slam: &SlamOutput) -> PyResult<Bound<'py, PyDict>> {
    let loops = &slam.loops;
    let dict = PyDict::new(py);
    let ints = |f: fn(&echofield_frontend::loops::LoopRecord) -> u64| {
        PyArray1::from_vec(py, loops.iter().map(f).collect())
    };
    let bools = |f: fn(&echofield_frontend::loops::LoopRecord) -> bool| {
        PyArray1::from_vec(py, loops.iter().map(f).collect())
    };
    let floats = |f: fn(&echofield_frontend::loops::LoopRecord) -> Option<f64>| {
        PyArray1::from_vec(py, loops.iter().map(|l| f(l).unwrap_or(f64::NAN)).collect())
    };
    let poses = |f: fn(&echofield_frontend::loops::LoopRecord) -> Option<Se2>| {
        rows_array(
            py,
            loops
                .iter()
                .map(|l| f(l).map_or([f64::NAN; 3], |p| crate::arrays::pose_row(&p))),
        )
    };
    dict.set_item("from", ints(|l| l.from))?;
    dict.set_item("to", ints(|l| l.to))?;
    dict.set_item("examined_at", ints(|l| l.examined_at))?;
    dict.set_item("accepted", bools(|l| l.accepted))?;
    dict.set_item("densified", bools(|l| l.densified))?;
    dict.set_item("partial", bools(|l| l.unconstrained_direction.is_some()))?;
    let rejected: Vec<Option<String>> = loops
        .iter()
        .map(|l| {
            l.rejected_by.and_then(|r| {
                serde_json::to_value(r)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_string))
            })
        })
        .collect();
    dict.set_item("rejected_by", rejected)?;
    dict.set_item("score", floats(|l| l.score))?;
    dict.set_item("predicted_overlap", floats(|l| Some(l.predicted_overlap)))?;
    dict.set_item("robust_weight", floats(|l| l.robust_weight))?;
    dict.set_item(
        "true_positive",
        floats(|l| l.true_positive.map(|t| f64::from(u8::from(t)))),
    )?;
    dict.set_item("measurement", poses(|l| l.measurement)?)?;
    dict.set_item("ground_truth", poses(|l| l.ground_truth)?)?;
    Ok(dict)
}

#[pymethods]
impl RunResult {
    /// Number of nodes (one per sonar rotation).
    fn __len__(&self) -> usize {
        self.nodes
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        let report = self.report.bind(py);
        let ate = report
            .get_item("ate_rmse_m")
            .ok()
            .and_then(|v| v.extract::<f64>().ok())
            .map_or(String::new(), |a| format!(", ATE {a:.3} m"));
        format!(
            "<echofield.RunResult {:?}: {} nodes{ate}>",
            self.mission_name, self.nodes
        )
    }
}
