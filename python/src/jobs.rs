//! The whole jobs: `inflate`, `volumetric`, `two_layer`, `connect`, `run_scenario`.

use crate::convert::{detached, job_result, json_to_py, points_array, triangles_array};
use crate::errors::{BalloonError, InvalidOption, invalid};
use crate::options::{Use, record_of, scenario_of, set_option};
use balloon::Simulation;
use balloon_scenario::{Scenario, ScenarioError, SystemKind};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

fn run_shell<'py>(
    py: Python<'py>,
    scenario: Scenario,
    mesh: Option<balloon::mesh::TriMesh>,
    record: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let Scenario::Shell(mut s) = scenario else {
        return Err(BalloonError::new_err("not a shell scenario"));
    };
    s.output.json = false;
    let static_solve = s.run.static_solve;
    let (finished, points) = detached(py, move || {
        balloon_run::jobs::shell::run(&s, mesh, record.as_deref(), true)
    })?;
    let d = job_result(py, &finished, finished.sim.positions())?;
    if static_solve {
        let list = PyList::empty(py);
        for p in &points {
            list.append(json_to_py(py, p)?)?;
        }
        d.set_item("points", list)?;
    }
    d.set_item(
        "thickness",
        PyArray1::from_slice(py, finished.sim.thickness()),
    )?;
    d.set_item("triangles", triangles_array(py, finished.sim.triangles())?)?;
    Ok(d)
}

fn run_volumetric<'py>(
    py: Python<'py>,
    scenario: Scenario,
    mesh: Option<balloon::mesh::TriMesh>,
    record: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let Scenario::Volumetric(s) = scenario else {
        return Err(BalloonError::new_err("not a volumetric scenario"));
    };
    let finished = detached(py, move || {
        balloon_run::jobs::volumetric::run(&s, mesh, record.as_deref(), true)
    })?;
    let d = job_result(py, &finished, Simulation::positions(&finished.sim))?;
    let emb = &finished.sim.lattice().embedding;
    let surface: Vec<f64> = emb
        .positions(finished.sim.positions())
        .iter()
        .flat_map(|p| [p.x, p.y, p.z])
        .collect();
    d.set_item("surface_positions", points_array(py, &surface)?)?;
    d.set_item("surface_triangles", triangles_array(py, &emb.triangles)?)?;
    Ok(d)
}

fn run_connect<'py>(
    py: Python<'py>,
    scenario: Scenario,
    record: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let Scenario::Connect(mut s) = scenario else {
        return Err(BalloonError::new_err("not a connect scenario"));
    };
    s.shell.output.json = false;
    let finished = detached(py, move || {
        balloon_run::jobs::connect::run(&s, record.as_deref(), true)
    })?;
    let d = job_result(py, &finished, Simulation::positions(&finished.sim))?;
    let offsets = finished.sim.vertex_offsets();
    let triangles: Vec<[usize; 3]> = finished
        .sim
        .balloons()
        .iter()
        .zip(&offsets)
        .flat_map(|(b, &o)| b.triangles().iter().map(move |t| t.map(|i| i + o)))
        .collect();
    d.set_item("vertex_offsets", offsets)?;
    d.set_item("triangles", triangles_array(py, &triangles)?)?;
    Ok(d)
}

fn run_two_layer<'py>(
    py: Python<'py>,
    scenario: Scenario,
    record: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let Scenario::TwoLayer(s) = scenario else {
        return Err(BalloonError::new_err("not a two-layer scenario"));
    };
    let finished = detached(py, move || {
        balloon_run::jobs::two_layer::run(&s, record.as_deref(), true)
    })?;
    job_result(py, &finished, Simulation::positions(&finished.sim))
}

/// inflate(mesh="builtin", **options)
/// --
///
/// Runs `balloon inflate` on `mesh` (a path, "builtin", "builtin:NAME" or a (vertices,
/// triangles) pair of arrays) with the CLI's flags as keyword options in snake_case
/// (`steps=15, gas="constant", pressure=900.0`; True for on/off flags), the same defaults and
/// units. Returns {"summary": dict (summary.json's keys), "positions": (n, 3) float64,
/// "thickness": (m,) float64 per triangle, "triangles": (m, 3) int64}; with `static=True` (the
/// static solve, `inflate --static`) also "points": one dict per converged point (the
/// `stats.jsonl` lines, e.g. of a `gas="volume", volume_ratios="1.5:3:0.5"` continuation).
/// With `out=DIR` the run writes the CLI's output folder too. The GIL is released while it
/// runs; Ctrl-C stops it (inside the Newton solve in progress when called from the main thread,
/// else after the current step; records written, KeyboardInterrupt raised).
#[pyfunction]
#[pyo3(signature = (mesh = None, **options))]
pub(crate) fn inflate<'py>(
    py: Python<'py>,
    mesh: Option<&Bound<'py, PyAny>>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (scenario, arrays, literals) = scenario_of(SystemKind::Shell, mesh, options, Use::Job)?;
    let record = record_of(&scenario, &literals, &arrays);
    run_shell(py, scenario, arrays, record)
}

/// volumetric(mesh="builtin", **options)
/// --
///
/// Runs `balloon volumetric` (a volume-conserving body, Diziol, Bender and Bayer 2011) on `mesh` with the CLI's
/// flags as keyword options. Returns {"summary": dict, "positions": (n, 3) lattice particle
/// positions, "surface_positions": (k, 3) the embedded surface, "surface_triangles": (m, 3)}.
#[pyfunction]
#[pyo3(signature = (mesh = None, **options))]
pub(crate) fn volumetric<'py>(
    py: Python<'py>,
    mesh: Option<&Bound<'py, PyAny>>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (scenario, arrays, literals) =
        scenario_of(SystemKind::Volumetric, mesh, options, Use::Job)?;
    let record = record_of(&scenario, &literals, &arrays);
    run_volumetric(py, scenario, arrays, record)
}

/// two_layer(**options)
/// --
///
/// Runs `balloon two-layer` (a two-layer mass-spring body, Song 2009) with the CLI's flags as
/// keyword options (`dim=3, integrator="rk4", steps=2000`, ...). Returns {"summary": dict,
/// "positions": (n, 3) particle positions}.
#[pyfunction]
#[pyo3(signature = (**options))]
pub(crate) fn two_layer<'py>(
    py: Python<'py>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (scenario, _, literals) = scenario_of(SystemKind::TwoLayer, None, options, Use::Job)?;
    let record = Some(balloon_scenario::file::record(&scenario, &literals));
    run_two_layer(py, scenario, record)
}

/// connect(mesh="builtin", **options)
/// --
///
/// Runs `balloon connect` (balloons of isothermal ideal gas joined by tubes: the two-balloon
/// experiment) on `mesh` (a path or "builtin:NAME"; its connected components are the balloons,
/// or `copies=N` copies of it) with the CLI's flags as keyword options (`copies=2,
/// stretches=[1.35, 1.6], conductance="instant", until_settled=True`, plus every `inflate`
/// option). Returns {"summary": dict (summary.json's keys: per-balloon end states, the analytic
/// end state where there is one), "positions": (n, 3) all balloons' vertices,
/// "vertex_offsets": the first vertex of each balloon then the vertex count (balloon `i` is
/// rows `offsets[i]..offsets[i + 1]`), "triangles": (m, 3) int64}.
#[pyfunction]
#[pyo3(signature = (mesh = None, **options))]
pub(crate) fn connect<'py>(
    py: Python<'py>,
    mesh: Option<&Bound<'py, PyAny>>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (scenario, arrays, literals) = scenario_of(SystemKind::Connect, mesh, options, Use::Job)?;
    if arrays.is_some() {
        return Err(InvalidOption::new_err(
            "connect takes a mesh path or \"builtin:NAME\", not arrays: write the mesh to a file",
        ));
    }
    let record = Some(balloon_scenario::file::record(&scenario, &literals));
    run_connect(py, scenario, record)
}

/// run_scenario(path, **overrides)
/// --
///
/// Runs a scenario file (`balloon run PATH`): `[system] kind` selects inflate, volumetric,
/// two_layer or connect; keyword `overrides` are that system's options and replace the file's
/// values.
/// Returns what the matching whole-job function returns.
#[pyfunction]
#[pyo3(signature = (path, **overrides))]
pub(crate) fn run_scenario<'py>(
    py: Python<'py>,
    path: &Bound<'py, PyAny>,
    overrides: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let path: String = py
        .import("os")?
        .call_method1("fspath", (path,))?
        .extract()?;
    let file = std::path::Path::new(&path);
    let scenario_error = |e: ScenarioError| InvalidOption::new_err(e.to_string());
    let kind = balloon_scenario::file::system_of(file).map_err(scenario_error)?;
    // The overrides' names first: their values in the file are replaced, not checked.
    let mut given: Vec<String> = Vec::new();
    if let Some(o) = overrides {
        for (k, _) in o.iter() {
            let key: String = k.extract()?;
            if Scenario::new(kind).key(&key).is_none() {
                return Err(InvalidOption::new_err(format!("unknown option `{key}`")));
            }
            given.push(key);
        }
    }
    let names: Vec<&str> = given.iter().map(String::as_str).collect();
    let read = balloon_scenario::file::read(file, &names).map_err(scenario_error)?;
    let (mut scenario, mut literals) = (read.scenario, read.literals);
    if let Some(o) = overrides {
        for (k, v) in o.iter() {
            let key: String = k.extract()?;
            literals.remove(&key);
            set_option(&mut scenario, &mut literals, &key, &v)?;
        }
    }
    scenario.validate().map_err(|e| invalid(e, &literals))?;
    let record = Some(balloon_scenario::file::record(&scenario, &literals));
    match scenario.kind() {
        SystemKind::Shell => run_shell(py, scenario, None, record),
        SystemKind::Connect => run_connect(py, scenario, record),
        SystemKind::Volumetric => run_volumetric(py, scenario, None, record),
        SystemKind::TwoLayer => run_two_layer(py, scenario, record),
    }
}
