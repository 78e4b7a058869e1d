//! # echofield-python: `import echofield`
//!
//! Python bindings (pyo3, rust-numpy) of what the `echofield` command line
//! does, built into the `echofield` package by maturin from the
//! repository's `pyproject.toml` (`pip install .`):
//!
//! - [`mission`]: `load_mission` (MCAP, rosbag2 folder, St Pere folder),
//!   `simulate` (a built-in scenario) and the `Mission` it returns;
//! - [`run`]: `run` (`echofield run`: the batch pipeline, or the causal
//!   replay with `online=True`) and its `RunResult`, whose poses are numpy
//!   arrays;
//! - [`engine`]: `Engine`, the online [`SlamEngine`](echofield::slam::SlamEngine)
//!   a vehicle pushes samples into;
//! - [`optimize`]: `optimize` (`echofield optimize`) on a g2o/TORO file or
//!   on arrays;
//! - [`evaluate`]: `evaluate` (`echofield eval`: ATE and RPE with the same
//!   association and pairing rule).
//!
//! Conventions shared by every function: a pose is a row `[x, y, yaw]`
//! (metres, radians, `world_from_vehicle`), a stamped pose a row
//! `[stamp_s, x, y, yaw]`; arrays are `float64`. Every failure of the Rust
//! side is raised as `echofield.Error` with the whole error chain in its
//! message (file, record and field for bad input, as the CLI prints it);
//! arguments of the wrong shape or kind raise `ValueError` / `TypeError`.
//! Long work releases the GIL.

mod arrays;
mod engine;
mod evaluate;
mod mission;
mod optimize;
mod run;

use pyo3::prelude::*;

pyo3::create_exception!(
    echofield,
    Error,
    pyo3::exceptions::PyException,
    "A failure of echofield: bad input data (the message names the file, record and field), an invalid configuration, or a failed solve."
);

/// An `anyhow` error as an `echofield.Error` carrying the whole chain
/// (`outer: inner: ...`), as the CLI prints it.
pub(crate) fn to_py_err(error: anyhow::Error) -> PyErr {
    Error::new_err(format!("{error:#}"))
}

/// [`to_py_err`] for any error type of the crates.
pub(crate) fn py_err<E>(error: E) -> PyErr
where
    E: Into<anyhow::Error>,
{
    to_py_err(error.into())
}

/// The native module `echofield._native`; `echofield/__init__.py`
/// re-exports it.
#[pymodule]
#[pyo3(name = "_native")]
fn native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(mission::load_mission, m)?)?;
    m.add_function(wrap_pyfunction!(mission::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(run::run, m)?)?;
    m.add_function(wrap_pyfunction!(run::default_config, m)?)?;
    m.add_function(wrap_pyfunction!(optimize::optimize, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate::evaluate, m)?)?;
    m.add_class::<mission::Mission>()?;
    m.add_class::<run::RunResult>()?;
    m.add_class::<engine::Engine>()?;
    m.add_class::<optimize::OptimizeResult>()?;
    Ok(())
}
