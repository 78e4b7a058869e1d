//! `echofield.evaluate`: ATE and RPE as `echofield eval` computes them.

use crate::arrays::{read_trajectory, to_python};
use echofield::eval::{Alignment, ate, rpe};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use serde::Serialize;

/// What `evaluate` returns (the keys of `echofield eval --json`).
#[derive(Serialize)]
struct Evaluation {
    alignment: Alignment,
    ate: echofield::eval::AteStats,
    rpe: Vec<echofield::eval::RpeStats>,
}

/// ATE and RPE of `estimate` against `reference`, computed as
/// `echofield eval` computes them (same defaults).
///
/// Each trajectory is an `(n, 4)` array `[stamp_s, x_m, y_m, yaw_rad]`
/// with strictly increasing stamps, or the path of a TUM file.
/// Association: each pose of the shorter trajectory is paired with the
/// nearest stamp of the other, kept when they differ by less than
/// `max_time_diff` s (evo's `--t_max_diff`). `align`: `"se2"` (the rigid
/// motion of the plane that best maps the estimate's positions onto the
/// reference's, as `evo_ape -a`) or `"none"`. RPE over each of
/// `rpe_distances` (m): for each pose `i` the later pose `j` whose distance
/// along the reference is nearest to `d`, kept within `d / 10`, the pairs of
/// `evo_rpe tum REF EST --delta d --delta_unit m --all_pairs
/// --pairs_from_reference`; distances longer than the path are left out.
///
/// Returns a dict: `alignment`; `ate` with `pairs`, `rmse_m`, `mean_m`,
/// `median_m`, `max_m` and `alignment` (the `reference_from_estimate`
/// applied); `rpe`, one dict per distance with `distance_m`, `pairs`,
/// `translation_rmse_m`, `translation_rmse_percent` and
/// `rotation_rmse_deg`. Raises `echofield.Error` when no pose pairs up.
#[pyfunction]
#[pyo3(signature = (estimate, reference, align = "se2", max_time_diff = 0.01, rpe_distances = vec![10.0, 50.0]))]
pub fn evaluate<'py>(
    py: Python<'py>,
    estimate: &Bound<'py, PyAny>,
    reference: &Bound<'py, PyAny>,
    align: &str,
    max_time_diff: f64,
    rpe_distances: Vec<f64>,
) -> PyResult<Bound<'py, PyAny>> {
    let alignment = match align {
        "se2" => Alignment::Se2,
        "none" => Alignment::None,
        other => {
            return Err(PyValueError::new_err(format!(
                "align: `{other}` is not se2 or none"
            )));
        }
    };
    // The same checks as `echofield eval`'s arguments.
    if !(max_time_diff.is_finite() && max_time_diff >= 0.0) {
        return Err(PyValueError::new_err(format!(
            "max_time_diff: {max_time_diff} must be a finite number of seconds >= 0"
        )));
    }
    if let Some(d) = rpe_distances.iter().find(|d| !(d.is_finite() && **d > 0.0)) {
        return Err(PyValueError::new_err(format!(
            "rpe_distances: {d} must be a finite distance > 0 m"
        )));
    }
    let estimate = read_trajectory(estimate, "estimate")?;
    let reference = read_trajectory(reference, "reference")?;
    let evaluation = py
        .detach(|| -> anyhow::Result<Evaluation> {
            Ok(Evaluation {
                alignment,
                ate: ate(&estimate, &reference, alignment, max_time_diff)?,
                rpe: rpe(&estimate, &reference, &rpe_distances, max_time_diff),
            })
        })
        .map_err(crate::to_py_err)?;
    to_python(py, &evaluation)
}
