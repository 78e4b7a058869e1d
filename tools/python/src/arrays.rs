//! Conversions between echofield's types and numpy arrays / Python objects.
//!
//! Row layouts (every value `float64`):
//! - pose: `[x_m, y_m, yaw_rad]`;
//! - stamped pose: `[stamp_s, x_m, y_m, yaw_rad]`.
//!
//! Arrays from Python are checked here: a wrong shape is a `ValueError`
//! naming the argument and the shape expected; a value that is not finite
//! names the argument, row and column.

use echofield_graph::Se2;
use echofield_graph::io::TrajectoryPose;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use std::path::PathBuf;

/// Names of the columns of a stamped-pose row, for errors.
const STAMPED_COLUMNS: [&str; 4] = ["stamp_s", "x_m", "y_m", "yaw_rad"];

/// An `n x columns` float64 array from its rows, in order.
pub fn rows_array<'py, const C: usize>(
    py: Python<'py>,
    rows: impl IntoIterator<Item = [f64; C]>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let flat: Vec<f64> = rows.into_iter().flatten().collect();
    let n = flat.len() / C;
    let array = Array2::from_shape_vec((n, C), flat)
        .map_err(|e| PyValueError::new_err(format!("cannot shape the array: {e}")))?;
    Ok(array.into_pyarray(py))
}

/// `[x, y, yaw]` of a pose.
pub fn pose_row(pose: &Se2) -> [f64; 3] {
    [pose.x(), pose.y(), pose.theta()]
}

/// `[stamp, x, y, yaw]` of a stamped pose.
pub fn stamped_row(stamp_s: f64, pose: &Se2) -> [f64; 4] {
    [stamp_s, pose.x(), pose.y(), pose.theta()]
}

/// An `(n, 3)` array of poses.
pub fn poses_array<'py>(
    py: Python<'py>,
    poses: impl IntoIterator<Item = Se2>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    rows_array(py, poses.into_iter().map(|p| pose_row(&p)))
}

/// An `(n, 4)` array of stamped poses.
pub fn stamped_array<'py>(
    py: Python<'py>,
    poses: impl IntoIterator<Item = (f64, Se2)>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    rows_array(py, poses.into_iter().map(|(t, p)| stamped_row(t, &p)))
}

/// A 2-D float64 array argument `name` with `columns` columns, as rows;
/// every value finite.
pub fn read_rows<const C: usize>(array: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<[f64; C]>> {
    let array: PyReadonlyArray2<f64> = array.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name}: expected a 2-D float64 numpy array with {C} columns"
        ))
    })?;
    let view = array.as_array();
    if view.ncols() != C {
        return Err(PyValueError::new_err(format!(
            "{name}: expected {C} columns, got an array of shape ({}, {})",
            view.nrows(),
            view.ncols()
        )));
    }
    let mut rows = Vec::with_capacity(view.nrows());
    for (i, row) in view.rows().into_iter().enumerate() {
        let mut out = [0.0; C];
        for (k, value) in row.iter().enumerate() {
            if !value.is_finite() {
                return Err(PyValueError::new_err(format!(
                    "{name}: row {i}, column {k}: {value} is not finite"
                )));
            }
            out[k] = *value;
        }
        rows.push(out);
    }
    Ok(rows)
}

/// A trajectory argument: an `(n, 4)` array `[stamp_s, x, y, yaw]` with
/// strictly increasing stamps, or the path of a TUM file (read as
/// `echofield eval` reads it).
pub fn read_trajectory(value: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<TrajectoryPose>> {
    if let Some(path) = as_path(value)? {
        return echofield_graph::io::read_tum(&path)
            .map_err(|e| crate::py_err(anyhow::Error::new(e).context(format!("reading {name}"))));
    }
    let rows: Vec<[f64; 4]> = read_rows(value, name)?;
    let mut poses: Vec<TrajectoryPose> = Vec::with_capacity(rows.len());
    for (i, [stamp_s, x, y, yaw]) in rows.into_iter().enumerate() {
        if let Some(last) = poses.last()
            && stamp_s <= last.stamp_s
        {
            return Err(PyValueError::new_err(format!(
                "{name}: row {i}, column {}: stamp {stamp_s} is not after the previous one ({})",
                STAMPED_COLUMNS[0], last.stamp_s
            )));
        }
        poses.push(TrajectoryPose {
            stamp_s,
            pose: Se2::new(x, y, yaw),
        });
    }
    Ok(poses)
}

/// `value` as a file path when it is a `str` or an `os.PathLike`, `None`
/// for anything else.
pub fn as_path(value: &Bound<'_, PyAny>) -> PyResult<Option<PathBuf>> {
    if value.is_instance_of::<PyString>() || value.hasattr("__fspath__")? {
        return Ok(Some(value.extract::<PathBuf>()?));
    }
    Ok(None)
}

/// A serialisable value as plain Python objects (dicts, lists, numbers,
/// strings, None), through JSON: the report's keys and values are those of
/// `report.json`.
pub fn to_python<'py>(
    py: Python<'py>,
    value: &impl serde::Serialize,
) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(crate::py_err)?;
    py.import("json")?.call_method1("loads", (text,))
}

/// A Python `dict` (JSON-compatible values) as TOML text, for the config
/// readers that lay a file over the defaults.
pub fn dict_to_toml(dict: &Bound<'_, PyDict>, name: &str) -> PyResult<String> {
    let py = dict.py();
    let json: String = py
        .import("json")?
        .call_method1("dumps", (dict,))
        .map_err(|e| {
            PyTypeError::new_err(format!(
                "{name}: the dict must hold only numbers, strings, booleans, lists and dicts ({e})"
            ))
        })?
        .extract()?;
    let value: serde_json::Value = serde_json::from_str(&json).map_err(crate::py_err)?;
    let table = toml::Value::try_from(value)
        .map_err(|e| PyValueError::new_err(format!("{name}: cannot express it in TOML: {e}")))?;
    toml::to_string(&table)
        .map_err(|e| PyValueError::new_err(format!("{name}: cannot express it in TOML: {e}")))
}
