//! Results to Python: summaries as dicts, states as numpy arrays; jobs with the GIL released.

use crate::errors::{BalloonError, InvalidOption, to_py_err};
use crate::options::as_array;
use balloon::{Simulation, SimulationStats};
use balloon_run::Finished;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyList, PyString};

/// A JSON value (a summary, a stats row) as Python objects.
pub(crate) fn json_to_py<'py>(
    py: Python<'py>,
    v: &serde_json::Value,
) -> PyResult<Bound<'py, PyAny>> {
    use serde_json::Value;
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Number(n) => match (n.as_i64(), n.as_u64()) {
            (Some(i), _) => i.into_pyobject(py)?.into_any(),
            (None, Some(u)) => u.into_pyobject(py)?.into_any(),
            _ => n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any(),
        },
        Value::String(s) => PyString::new(py, s).into_any(),
        Value::Array(a) => {
            let list = PyList::empty(py);
            for x in a {
                list.append(json_to_py(py, x)?)?;
            }
            list.into_any()
        }
        Value::Object(o) => {
            let d = PyDict::new(py);
            for (k, x) in o {
                d.set_item(k, json_to_py(py, x)?)?;
            }
            d.into_any()
        }
    })
}

/// Flat `[x0, y0, z0, x1, ...]` as an `(n, 3)` float64 array (a copy).
pub(crate) fn points_array<'py>(py: Python<'py>, flat: &[f64]) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_slice(py, flat)
        .reshape([flat.len() / 3, 3])?
        .into_any())
}

/// Triangles as an `(m, 3)` int64 array.
pub(crate) fn triangles_array<'py>(
    py: Python<'py>,
    tris: &[[usize; 3]],
) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<i64> = tris
        .iter()
        .flat_map(|t| t.map(|i| i64::try_from(i).unwrap_or(i64::MAX)))
        .collect();
    Ok(PyArray1::from_vec(py, flat)
        .reshape([tris.len(), 3])?
        .into_any())
}

/// An `(n, 3)` array-like as flat `f64` values, checked for `n` rows.
pub(crate) fn flat_points(obj: &Bound<'_, PyAny>, rows: usize, what: &str) -> PyResult<Vec<f64>> {
    let a = as_array(obj, "float64")?;
    let a: PyReadonlyArray2<'_, f64> = a
        .extract()
        .map_err(|_| InvalidOption::new_err(format!("{what} must be an ({rows}, 3) array")))?;
    let view = a.as_array();
    if view.shape() != [rows, 3] {
        return Err(InvalidOption::new_err(format!(
            "{what} must be an ({rows}, 3) array, got {:?}",
            view.shape()
        )));
    }
    Ok(view.iter().copied().collect())
}

/// A step's statistics as a dict: `steps`, `time`, `dt`, `kinetic_energy` and the system's own
/// statistics (the keys of a `stats.jsonl` line).
pub(crate) fn stats_dict<'py, D: serde::Serialize>(
    py: Python<'py>,
    stats: &SimulationStats<D>,
) -> PyResult<Bound<'py, PyAny>> {
    let mut row =
        serde_json::to_value(&stats.detail).map_err(|e| BalloonError::new_err(e.to_string()))?;
    if let Some(o) = row.as_object_mut() {
        o.insert("steps".into(), stats.steps.into());
        o.insert("time".into(), stats.time.into());
        o.insert("dt".into(), stats.dt.into());
        o.insert("kinetic_energy".into(), stats.kinetic_energy.into());
    }
    json_to_py(py, &row)
}

/// Runs `job` with the GIL released and Ctrl-C checked between steps and inside its solves
/// ([`crate::cancel`]).
pub(crate) fn detached<T: Send, F: FnOnce() -> anyhow::Result<T> + Send>(
    py: Python<'_>,
    job: F,
) -> PyResult<T> {
    crate::cancel::solve(py, job, to_py_err)
}

/// The result dict of a whole job.
pub(crate) fn job_result<'py, S: Simulation>(
    py: Python<'py>,
    finished: &Finished<S>,
    positions: &[f64],
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    match &finished.summary {
        Some(s) => {
            warn_summary(py, s)?;
            d.set_item("summary", json_to_py(py, s)?)?
        }
        None => d.set_item("summary", py.None())?,
    }
    d.set_item("positions", points_array(py, positions)?)?;
    Ok(d)
}

/// Issues each of the summary's `warnings` (what the CLI prints as `warning: ...` after a
/// run) as a Python `RuntimeWarning`, so that a script sees them without reading the summary;
/// they stay in `summary["warnings"]`. With warnings turned into errors
/// (`-W error`) the first one is raised.
fn warn_summary(py: Python<'_>, summary: &serde_json::Value) -> PyResult<()> {
    let Some(warnings) = summary.get("warnings").and_then(|w| w.as_array()) else {
        return Ok(());
    };
    let category = py.get_type::<pyo3::exceptions::PyRuntimeWarning>();
    for w in warnings.iter().filter_map(|w| w.as_str()) {
        // A message with an interior NUL (none is written so) is cut there.
        let text = w.split('\0').next().unwrap_or_default();
        let message = std::ffi::CString::new(text).unwrap_or_default();
        PyErr::warn(py, &category, &message, 1)?;
    }
    Ok(())
}
