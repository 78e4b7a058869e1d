//! `echofield.load_mission`, `echofield.simulate` and the `Mission` they
//! return: a mission's sensor streams as numpy arrays.

use crate::arrays::{rows_array, stamped_array, to_python};
use echofield::slam::load_mission_choosing;
use echofield_datasets::mcap::{ChannelUse, TopicChoice, write_mission};
use echofield_datasets::sim::{Scenario, SimConfig, simulate_mission};
use echofield_frontend::sensors::Mission as RustMission;
use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;
use std::sync::Arc;

/// A mission in memory: sonar beams, DVL and attitude samples, ground
/// truth, and the sensor mounting, each stream in time order.
#[pyclass(frozen, module = "echofield")]
pub struct Mission {
    pub(crate) inner: Arc<RustMission>,
    /// What became of each channel of an MCAP / ROS 2 input.
    channels: Vec<ChannelUse>,
}

impl Mission {
    pub(crate) fn new(inner: RustMission, channels: Vec<ChannelUse>) -> Self {
        Self {
            inner: Arc::new(inner),
            channels,
        }
    }
}

#[pymethods]
impl Mission {
    /// The mission's name (file stem, scenario name).
    #[getter]
    fn name(&self) -> &str {
        &self.inner.name
    }

    /// The sensor mounting as a dict (the keys of a config's `[mounting]`
    /// as the mission records them: `vehicle_from_sonar`,
    /// `sonar_angle`, `sweep`, `vehicle_from_dvl`, `heading_offset_rad`,
    /// `source`).
    #[getter]
    fn mounting<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_python(py, &self.inner.mounting)
    }

    /// The sonar beams: a dict of `stamp_s`, `angle_rad` (transducer angle
    /// in the head frame), `bin_size_m`, `first_bin_range_m` (arrays of
    /// one value per beam) and `intensities` (a list of one uint8 array
    /// per beam, nearest bin first).
    #[getter]
    fn beams<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let beams = &self.inner.beams;
        let column = |f: fn(&echofield_frontend::sensors::SonarBeam) -> f64| {
            PyArray1::from_vec(py, beams.iter().map(f).collect())
        };
        let dict = PyDict::new(py);
        dict.set_item("stamp_s", column(|b| b.stamp_s))?;
        dict.set_item("angle_rad", column(|b| b.angle_rad))?;
        dict.set_item("bin_size_m", column(|b| b.bin_size_m))?;
        dict.set_item("first_bin_range_m", column(|b| b.first_bin_range_m))?;
        let intensities = PyList::empty(py);
        for beam in beams {
            intensities.append(PyArray1::from_slice(py, &beam.intensities))?;
        }
        dict.set_item("intensities", intensities)?;
        Ok(dict)
    }

    /// DVL samples, `(n, 5)`: `[stamp_s, vx_mps, vy_mps, vz_mps, valid]`
    /// (velocity over ground in the DVL frame; `valid` 1.0 or 0.0).
    #[getter]
    fn dvl<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        rows_array(
            py,
            self.inner.dvl.iter().map(|d| {
                let v = d.velocity_mps;
                [d.stamp_s, v.x, v.y, v.z, f64::from(u8::from(d.valid))]
            }),
        )
    }

    /// The DVL velocity covariances, `(n, 3, 3)` in (m/s)², NaN where the
    /// log gives none.
    #[getter]
    fn dvl_covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let mut flat = Vec::with_capacity(self.inner.dvl.len() * 9);
        for d in &self.inner.dvl {
            match d.covariance {
                // Row-major, as numpy lays out (n, 3, 3).
                Some(c) => flat.extend(c.transpose().iter().copied()),
                None => flat.extend([f64::NAN; 9]),
            }
        }
        let array = Array3::from_shape_vec((self.inner.dvl.len(), 3, 3), flat)
            .map_err(|e| PyValueError::new_err(format!("cannot shape the array: {e}")))?;
        Ok(array.into_pyarray(py))
    }

    /// Attitude samples, `(n, 5)`: `[stamp_s, roll_rad, pitch_rad,
    /// yaw_rad, yaw_rate_radps]` (yaw counter-clockwise from world x; the
    /// rate NaN where the unit gives none).
    #[getter]
    fn attitude<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        rows_array(
            py,
            self.inner.attitude.iter().map(|a| {
                [
                    a.stamp_s,
                    a.roll_rad,
                    a.pitch_rad,
                    a.yaw_rad,
                    a.yaw_rate_radps.unwrap_or(f64::NAN),
                ]
            }),
        )
    }

    /// Ground truth, `(n, 4)`: `[stamp_s, x_m, y_m, yaw_rad]` in its own
    /// frame; empty `(0, 4)` when the mission has none.
    #[getter]
    fn ground_truth<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        stamped_array(
            py,
            self.inner
                .ground_truth
                .iter()
                .map(|g| (g.stamp_s, g.world_from_vehicle)),
        )
    }

    /// What became of each channel of an MCAP or ROS 2 input: a list of
    /// dicts with `topic`, `schema`, `role` (`None` when skipped), `reason`
    /// and `messages`; empty for St Pere folders and simulated missions.
    #[getter]
    fn channels<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        for c in &self.channels {
            let dict = PyDict::new(py);
            dict.set_item("topic", &c.topic)?;
            dict.set_item("schema", &c.schema)?;
            dict.set_item("role", c.role)?;
            dict.set_item("reason", &c.reason)?;
            dict.set_item("messages", c.messages)?;
            list.append(dict)?;
        }
        Ok(list)
    }

    /// What the reader repaired (records re-sorted, a mounting assumed,
    /// samples dropped), as `report.json` → `warnings` lists it.
    #[getter]
    fn warnings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_python(py, &self.inner.warnings)
    }

    /// Writes the mission as an echofield MCAP file at `path` (what
    /// `echofield simulate` writes; `echofield run` and `load_mission`
    /// read it back).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let mission = Arc::clone(&self.inner);
        py.detach(move || write_mission(&path, &mission))
            .map_err(crate::py_err)
    }

    fn __repr__(&self) -> String {
        let m = &self.inner;
        format!(
            "<echofield.Mission {:?}: {} beams, {} DVL, {} attitude, {} ground-truth samples>",
            m.name,
            m.beams.len(),
            m.dvl.len(),
            m.attitude.len(),
            m.ground_truth.len()
        )
    }
}

/// Reads a mission: an echofield or ROS 2 MCAP file, a rosbag2 folder, or
/// a St Pere log folder (as `echofield run MISSION` does).
///
/// `topics` chooses the topic of each stream of a ROS 2 recording, as
/// `--topic ROLE=/name` does: a dict like `{"ground_truth": "/gps/odom"}`
/// (roles: sonar, dvl, heading, ground_truth, position_fix). Raises `echofield.Error`
/// naming the file, record and field of bad input.
#[pyfunction]
#[pyo3(signature = (path, topics = None))]
pub fn load_mission(
    py: Python<'_>,
    path: PathBuf,
    topics: Option<&Bound<'_, PyDict>>,
) -> PyResult<Mission> {
    let mut choice = TopicChoice::default();
    if let Some(topics) = topics {
        for (role, topic) in topics.iter() {
            let (role, topic): (String, String) = (role.extract()?, topic.extract()?);
            choice
                .assign(&format!("{role}={topic}"))
                .map_err(|e| PyValueError::new_err(format!("topics: {e}")))?;
        }
    }
    let (mission, channels) = py
        .detach(|| load_mission_choosing(&path, &choice))
        .map_err(crate::to_py_err)?;
    Ok(Mission::new(mission, channels))
}

/// Simulates a built-in scenario (`"tank"`: 20 m x 14 m, about 2 min;
/// `"marina"`: about 40 min; `"canyon"`: about 18 min) with ground truth,
/// as `echofield simulate --scenario NAME --seed SEED` does: the same
/// scenario, seed and config give the same mission.
///
/// `config`: the simulator's configuration laid over its defaults (a dict
/// with the sections of `echofield simulate --config`, or the path of
/// such a TOML file); unknown keys raise `echofield.Error` naming them.
#[pyfunction]
#[pyo3(signature = (scenario = "tank", seed = 1, config = None))]
pub fn simulate(
    py: Python<'_>,
    scenario: &str,
    seed: u64,
    config: Option<&Bound<'_, PyAny>>,
) -> PyResult<Mission> {
    let config = sim_config(config)?;
    let scenario_name = scenario.to_string();
    let mission = py
        .detach(move || -> anyhow::Result<RustMission> {
            let scenario = Scenario::build(&scenario_name, config, None)
                .map_err(anyhow::Error::new)
                .map_err(|e| e.context(format!("cannot set up scenario `{scenario_name}`")))?;
            simulate_mission(&scenario, seed)
                .map_err(anyhow::Error::new)
                .map_err(|e| e.context("simulation failed"))
        })
        .map_err(crate::to_py_err)?;
    Ok(Mission::new(mission, Vec::new()))
}

/// The simulator config from `None`, a dict or a TOML path.
fn sim_config(config: Option<&Bound<'_, PyAny>>) -> PyResult<SimConfig> {
    let Some(config) = config else {
        return Ok(SimConfig::default());
    };
    let (text, origin) = crate::run::config_text(config, "config")?;
    echofield::config_file::from_toml_over(&text, &SimConfig::default()).map_err(|e| {
        crate::to_py_err(
            anyhow::Error::new(e).context(format!("invalid simulator config {origin}")),
        )
    })
}
