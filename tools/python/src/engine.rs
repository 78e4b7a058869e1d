//! `echofield.Engine`: the online SLAM engine
//! ([`echofield::slam::SlamEngine`]) driven from Python, one sample at a
//! time.

use crate::arrays::{pose_row, poses_array};
use crate::run::{RunResult, slam_config};
use echofield::slam::{NodeEvent, SlamConfig, SlamEngine, SlamError};
use echofield_frontend::sensors::{
    Attitude, DvlVelocity, GroundTruthPose, SensorMounting, SonarBeam,
};
use echofield_graph::Se2;
use nalgebra::{Matrix3, Vector3};
use numpy::{PyArray2, PyReadonlyArray1};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// The engine borrows its config for its whole life; `None` once
/// `finish` has consumed it.
type MaybeEngine<'c> = Option<SlamEngine<'c>>;

// The engine borrows the config (`SlamEngine<'c>`), and a Python object
// cannot carry a lifetime: self_cell keeps both in one allocation, the
// config first, without unsafe code here.
self_cell::self_cell!(
    struct EngineCell {
        owner: SlamConfig,
        #[not_covariant]
        dependent: MaybeEngine,
    }
);

/// The online SLAM engine: push sonar beams, DVL and attitude samples as
/// they arrive (each stream in time order, the streams interleaved by
/// time); every push returns the nodes it completed, and `finish()` runs
/// the end-of-mission steps (densification, robust final solve) and
/// returns a `RunResult`.
///
/// The engine is causal: it navigates with the forward dead-reckoning
/// filter and emits a node when the navigation has caught up with its
/// rotation. Fed a mission's records in time order (at equal stamps DVL,
/// then attitude, then beams), it gives what `run(mission,
/// online=True)` gives, for a mission that needs none of what `run` does
/// before the engine: the config's `[mounting] sweep` re-stamping, the
/// screening of implausible records (dropped with a warning by `run`, an
/// error here) and the preparation of scan-only (binary) beams. A push that raises `echofield.Error` (a sample
/// out of order, a value not finite) ends the run: what was emitted
/// before stays valid, the engine accepts nothing more.
#[pyclass(module = "echofield")]
pub struct Engine {
    cell: EngineCell,
    /// Set once a push failed or `finish` ran.
    closed: Option<&'static str>,
}

impl Engine {
    /// Runs `f` on the engine unless it is closed; an error closes it.
    fn with_engine<T>(
        &mut self,
        f: impl FnOnce(&mut SlamEngine<'_>) -> Result<T, SlamError>,
    ) -> PyResult<T> {
        if let Some(why) = self.closed {
            return Err(PyRuntimeError::new_err(format!(
                "the engine is closed ({why}); create a new one"
            )));
        }
        let result = self.cell.with_dependent_mut(|_, engine| match engine {
            Some(engine) => f(engine).map_err(|e| Some(anyhow::Error::new(e))),
            None => Err(None),
        });
        match result {
            Ok(value) => Ok(value),
            Err(Some(error)) => {
                self.closed = Some("a push failed");
                Err(crate::to_py_err(error))
            }
            Err(None) => Err(PyRuntimeError::new_err("the engine is closed")),
        }
    }

    /// The events as a list of dicts.
    fn events<'py>(&self, py: Python<'py>, events: Vec<NodeEvent>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        for event in events {
            let dict = PyDict::new(py);
            dict.set_item("node_id", event.node_id)?;
            dict.set_item("rotation_index", event.rotation_index)?;
            dict.set_item("stamp_s", event.stamp_s)?;
            dict.set_item("pose", pose_row(&event.pose).to_vec())?;
            dict.set_item("poses", poses_array(py, event.poses.iter().copied())?)?;
            dict.set_item("latency_s", event.latency_s)?;
            list.append(dict)?;
        }
        Ok(list)
    }
}

#[pymethods]
impl Engine {
    /// `config`: `None`, a dict or a TOML path, as for `run`. `mounting`:
    /// the sensor mounting as a dict (`Mission.mounting` gives one; keys
    /// left out keep the identity), with the config's `[mounting]` laid
    /// over it as `run` does. `name`: the mission's name in the report.
    #[new]
    #[pyo3(signature = (config = None, mounting = None, name = "online"))]
    fn new(
        config: Option<&Bound<'_, PyAny>>,
        mounting: Option<&Bound<'_, PyDict>>,
        name: &str,
    ) -> PyResult<Self> {
        let (config, _) = slam_config(config)?;
        let given: SensorMounting = match mounting {
            None => SensorMounting::default(),
            Some(dict) => {
                let json: String = dict
                    .py()
                    .import("json")?
                    .call_method1("dumps", (dict,))?
                    .extract()?;
                serde_json::from_str(&json)
                    .map_err(|e| PyValueError::new_err(format!("mounting: {e}")))?
            }
        };
        let mounting = config.mounting.mounting_over(&given);
        let cell = EngineCell::try_new(config, |config| {
            SlamEngine::new(config, name, mounting).map(Some)
        })
        .map_err(crate::py_err)?;
        Ok(Self { cell, closed: None })
    }

    /// Takes the next sonar beam: its stamp (s), transducer angle in the
    /// head frame (rad), bin length (m), intensities (uint8, one per bin,
    /// nearest first) and the range of bin 0's start (m). Returns the
    /// nodes it completed: a list of dicts with `node_id`,
    /// `rotation_index`, `stamp_s`, `pose` (`[x, y, yaw]` when emitted),
    /// `poses` (every node's current estimate, `(node_id + 1, 3)`) and
    /// `latency_s` (the work for that rotation).
    #[pyo3(signature = (stamp_s, angle_rad, bin_size_m, intensities, first_bin_range_m = 0.0))]
    fn push_beam<'py>(
        &mut self,
        py: Python<'py>,
        stamp_s: f64,
        angle_rad: f64,
        bin_size_m: f64,
        intensities: &Bound<'py, PyAny>,
        first_bin_range_m: f64,
    ) -> PyResult<Bound<'py, PyList>> {
        let intensities: Vec<u8> = match intensities.extract::<PyReadonlyArray1<'_, u8>>() {
            Ok(array) => array.as_array().to_vec(),
            Err(_) => intensities.extract::<Vec<u8>>().map_err(|_| {
                PyTypeError::new_err(
                    "intensities: expected a 1-D uint8 numpy array, bytes or a sequence of ints 0-255",
                )
            })?,
        };
        let beam = SonarBeam {
            stamp_s,
            angle_rad,
            bin_size_m,
            first_bin_range_m,
            intensities,
        };
        let events = self.with_engine(|engine| engine.push_beam(beam))?;
        self.events(py, events)
    }

    /// Takes the next DVL sample: stamp (s), velocity over ground in the
    /// DVL frame `(vx, vy, vz)` (m/s), whether the instrument marked it
    /// valid, and its 3x3 covariance ((m/s)²) when known. Returns the
    /// nodes it completed (as `push_beam`).
    #[pyo3(signature = (stamp_s, velocity_mps, valid = true, covariance = None))]
    fn push_dvl<'py>(
        &mut self,
        py: Python<'py>,
        stamp_s: f64,
        velocity_mps: [f64; 3],
        valid: bool,
        covariance: Option<[[f64; 3]; 3]>,
    ) -> PyResult<Bound<'py, PyList>> {
        let sample = DvlVelocity {
            stamp_s,
            velocity_mps: Vector3::from(velocity_mps),
            valid,
            covariance: covariance.map(|rows| Matrix3::from_fn(|r, c| rows[r][c])),
        };
        let events = self.with_engine(|engine| engine.push_dvl(&sample))?;
        self.events(py, events)
    }

    /// Takes the next attitude sample: stamp (s), roll, pitch and yaw
    /// (rad; yaw counter-clockwise from world x) and the yaw rate (rad/s)
    /// when the unit gives one. Returns the nodes it completed.
    #[pyo3(signature = (stamp_s, roll_rad, pitch_rad, yaw_rad, yaw_rate_radps = None))]
    fn push_attitude<'py>(
        &mut self,
        py: Python<'py>,
        stamp_s: f64,
        roll_rad: f64,
        pitch_rad: f64,
        yaw_rad: f64,
        yaw_rate_radps: Option<f64>,
    ) -> PyResult<Bound<'py, PyList>> {
        let sample = Attitude {
            stamp_s,
            roll_rad,
            pitch_rad,
            yaw_rad,
            yaw_rate_radps,
        };
        let events = self.with_engine(|engine| engine.push_attitude(&sample))?;
        self.events(py, events)
    }

    /// The end of the data: processes the last rotation and those still
    /// waiting for the navigation; returns the nodes they complete (as
    /// `push_beam`). `finish()` does it too when this was not called;
    /// push nothing after it.
    fn end_of_data<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let events = self.with_engine(|engine| engine.end_of_data())?;
        self.events(py, events)
    }

    /// Nodes built so far.
    #[getter]
    fn nodes(&mut self) -> PyResult<usize> {
        self.with_engine(|engine| Ok(engine.nodes()))
    }

    /// The current estimate of every node, `(n, 3)`.
    #[getter]
    fn poses<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let poses: Vec<Se2> = self.with_engine(|engine| Ok(engine.poses().to_vec()))?;
        poses_array(py, poses)
    }

    /// Ends the run: the last rotation, loop densification and the robust
    /// final solve. `ground_truth` (`(n, 4)` stamped poses), when given,
    /// is evaluated against (strictly after the estimation). Returns the
    /// `RunResult` (its `emitted` holds every estimate as it was emitted);
    /// the engine is closed afterwards.
    #[pyo3(signature = (ground_truth = None))]
    fn finish(
        &mut self,
        py: Python<'_>,
        ground_truth: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<RunResult> {
        let ground_truth: Vec<GroundTruthPose> = match ground_truth {
            None => Vec::new(),
            Some(array) => crate::arrays::read_rows::<4>(array, "ground_truth")?
                .into_iter()
                .map(|[stamp_s, x, y, yaw]| GroundTruthPose {
                    stamp_s,
                    world_from_vehicle: Se2::new(x, y, yaw),
                })
                .collect(),
        };
        if let Some(why) = self.closed {
            return Err(PyRuntimeError::new_err(format!(
                "the engine is closed ({why}); create a new one"
            )));
        }
        self.closed = Some("finish() ran");
        let output = self
            .cell
            .with_dependent_mut(|_, engine| engine.take().map(|e| e.finish(&ground_truth)));
        match output {
            Some(Ok(output)) => RunResult::new(py, &output, None),
            Some(Err(error)) => Err(crate::py_err(error)),
            None => Err(PyRuntimeError::new_err("the engine is closed")),
        }
    }
}
