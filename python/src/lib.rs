//! The `balloon` Python package's extension module (`balloon._balloon`, built with maturin from
//! `python/pyproject.toml`).
//!
//! It is what the Python API calls: whole jobs (`inflate`, `volumetric`, `two_layer`,
//! `connect`, `run_scenario`) and step-wise simulations (`Shell`, `Volumetric`, `TwoLayer`).
//! Keyword options are the scenario's parameters by name (`newton_tol=1e-8` sets
//! `newton_tol`, the command line's `--newton-tol`): each Python value becomes a typed value of
//! `balloon_scenario` directly (no text on the way), the scenario is checked by the library,
//! the simulation built by the scenario's `build`, and whole jobs run through `balloon_run`,
//! the command-line tool's run loop; so defaults, units, checks and results are the CLI's. It is
//! not a Rust API: Rust code uses `balloon` and `balloon-scenario`.
//!
//! From Python (the crate's tests are `python/tests`, run by pytest; a Rust doctest cannot
//! load an extension module):
//!
//! ```text
//! >>> import balloon
//! >>> r = balloon.inflate("builtin:sphere", steps=15, gas="constant", pressure=900.0)
//! >>> r["positions"].shape, r["summary"]["steps"]
//! ((2562, 3), 15)
//! ```

use balloon::shell::AnchorSpring;
use balloon::two_layer::{DragTarget, TwoLayerSimulation};
use balloon::volumetric::VolumetricSimulation;
use balloon::{Simulation, SimulationError, SimulationStats};
use balloon_run::Finished;
use balloon_run::interrupt::Interrupted;
use balloon_scenario::keys::{Kind, Literals};
use balloon_scenario::names::{Spelling, respell, value_message};
use balloon_scenario::selection::ShellLoads;
use balloon_scenario::shell::ShellSim;
use balloon_scenario::value::{SetError, Value};
use balloon_scenario::{Scenario, ScenarioError, SystemKind};
use nalgebra::{Point3, Vector3};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use std::cell::RefCell;
use std::sync::{Mutex, MutexGuard};

create_exception!(
    _balloon,
    BalloonError,
    PyException,
    "Base class of every error balloon raises; the message is the CLI's."
);
create_exception!(
    _balloon,
    InvalidOption,
    BalloonError,
    "An unknown keyword option, a value of the wrong type or outside its range, keywords that \
     do not go together, or a scenario file that does not parse."
);
create_exception!(
    _balloon,
    MeshError,
    BalloonError,
    "A mesh that cannot be read or used (missing file, unknown format, open or degenerate \
     surface, bad arrays)."
);
create_exception!(
    _balloon,
    SolverError,
    BalloonError,
    "A simulation step that failed (Newton did not converge, an inverted element, a blow-up)."
);

/// How errors spell parameters: as the command line does, so that a message reads the same
/// from Python and from the CLI (the package's tests compare them). `Spelling::Keyword`
/// (`dt=`) is the alternative `balloon_scenario::names` offers.
const SPELLING: Spelling = Spelling::Flag;

/// A library message with its parameters spelled for Python users.
fn spelled(message: &str) -> String {
    respell(message, SPELLING)
}

/// An `Exception` raised while a value is read is the value's fault; anything else (a
/// KeyboardInterrupt from Ctrl-C, SystemExit) is passed on, not taken for a wrong type.
fn not_an_exception(py: Python<'_>, e: PyErr) -> PyResult<()> {
    if e.is_instance_of::<PyException>(py) {
        Ok(())
    } else {
        Err(e)
    }
}

/// A keyword option's Python value as an untyped scenario value: booleans, integers (numpy's
/// too), floats, strings and paths (`os.fspath`), lists and tuples of them.
fn py_value(v: &Bound<'_, PyAny>) -> PyResult<Value> {
    if let Ok(b) = v.cast::<PyBool>() {
        return Ok(Value::Bool(b.is_true()));
    }
    if v.is_instance_of::<PyInt>() {
        return Ok(match v.extract::<i64>() {
            Ok(i) => Value::Int(i),
            // Beyond i64: as a real, which no whole-number parameter takes.
            Err(_) => Value::Float(v.extract::<f64>()?),
        });
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(Value::Float(v.extract::<f64>()?));
    }
    if let Ok(s) = v.cast::<PyString>() {
        return Ok(Value::Text(s.to_cow()?.into_owned()));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let items = v
            .try_iter()?
            .map(|x| py_value(&x?))
            .collect::<PyResult<Vec<_>>>()?;
        return Ok(Value::List(items));
    }
    let py = v.py();
    let os = py.import("os")?;
    match os.call_method1("fspath", (v,)) {
        Ok(p) => return Ok(Value::Text(p.extract::<String>()?)),
        Err(e) => not_an_exception(py, e)?,
    }
    // numpy integers (and anything else with `__index__`), then numpy floats and other reals.
    match v.extract::<i64>() {
        Ok(i) => return Ok(Value::Int(i)),
        Err(e) => not_an_exception(py, e)?,
    }
    match v.extract::<f64>() {
        Ok(f) => Ok(Value::Float(f)),
        Err(e) => {
            not_an_exception(py, e)?;
            Err(InvalidOption::new_err(format!(
                "cannot use a value of type {} as an option",
                v.get_type().name()?
            )))
        }
    }
}

/// The parameter names of system `kind` (the keyword options), sorted.
fn option_names(kind: SystemKind) -> Vec<&'static str> {
    let mut names: Vec<&'static str> = Scenario::keys(kind)
        .into_iter()
        .map(|k| k.name)
        .filter(|n| *n != "mesh")
        .collect();
    names.sort_unstable();
    names
}

/// Sets keyword option `key` (a parameter's name) with its Python value on `scenario`, and
/// records the value's text in `literals` (for the recorded scenario and errors, as the CLI
/// records the text typed). `None` leaves the default.
fn set_option(
    scenario: &mut Scenario,
    literals: &mut Literals,
    key: &str,
    v: &Bound<'_, PyAny>,
) -> PyResult<()> {
    let Some(info) = scenario.key(key).filter(|k| k.name != "mesh") else {
        return Err(InvalidOption::new_err(format!(
            "unknown option `{key}` (the options are {})",
            option_names(scenario.kind()).join(", ")
        )));
    };
    if v.is_none() {
        return Ok(());
    }
    let is_bool = v.is_instance_of::<PyBool>();
    match info.kind {
        Kind::Bool if !is_bool => {
            return Err(InvalidOption::new_err(format!(
                "option `{key}` is on/off: give True or False, not {}",
                v.repr().map(|r| r.to_string()).unwrap_or_default()
            )));
        }
        Kind::Bool | Kind::Switch => {}
        _ if is_bool => {
            return Err(InvalidOption::new_err(format!(
                "option `{key}`: a boolean is only valid for an on/off flag"
            )));
        }
        _ => {}
    }
    // A KeyboardInterrupt (Ctrl-C while the options are read) is not an invalid option: only
    // `Exception`s are reported as this option's.
    let value = py_value(v).map_err(|e| {
        if e.is_instance_of::<PyException>(v.py()) {
            InvalidOption::new_err(format!("option `{key}`: {}", e.value(v.py())))
        } else {
            e
        }
    })?;
    // A list for a text (`render=[0, 100, "last"]`) is its comma-separated text.
    let value = match (&value, info.kind) {
        (Value::List(items), Kind::Text | Kind::Rule | Kind::Path | Kind::NumberOrText) => {
            Value::Text(
                items
                    .iter()
                    .map(Value::literal)
                    .collect::<Vec<_>>()
                    .join(","),
            )
        }
        _ => value,
    };
    let texts: Vec<String> = match &value {
        Value::List(items) => items.iter().map(Value::literal).collect(),
        other => vec![other.literal()],
    };
    match scenario.set(key, &value) {
        Ok(()) => {}
        Err(SetError::Type(m)) => {
            return Err(InvalidOption::new_err(format!("option `{key}`: {m}")));
        }
        Err(SetError::Value(e)) => {
            let typed = texts.get(e.index.unwrap_or(0)).map(String::as_str);
            return Err(InvalidOption::new_err(value_message(&e, SPELLING, typed)));
        }
    }
    if matches!(
        info.kind,
        Kind::Number | Kind::Numbers | Kind::NumberOrText | Kind::Text | Kind::Rule
    ) {
        literals.set(key, texts);
    }
    Ok(())
}

/// A scenario's check as a Python exception: a value outside its range shows the text given
/// (`invalid value '5.0' for '--dt <DT>': ...`, the CLI's message); keys that do not go
/// together are named.
fn invalid(e: ScenarioError, literals: &Literals) -> PyErr {
    match e {
        ScenarioError::Value(v) => {
            InvalidOption::new_err(value_message(&v, SPELLING, literals.typed(&v)))
        }
        e => InvalidOption::new_err(spelled(&e.to_string())),
    }
}

/// The checked scenario of system `kind` with keyword `options`, the mesh given (a path, or
/// arrays returned beside it), and the values' texts.
fn scenario_of(
    kind: SystemKind,
    mesh: Option<&Bound<'_, PyAny>>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<(Scenario, Option<balloon::mesh::TriMesh>, Literals)> {
    let mut scenario = Scenario::new(kind);
    let mut literals = Literals::default();
    let arrays = match mesh {
        Some(mesh) => {
            let (name, arrays) = mesh_spec(mesh)?.split();
            scenario
                .set("mesh", &Value::Text(name))
                .map_err(|_| MeshError::new_err("this system takes no mesh"))?;
            arrays
        }
        None => None,
    };
    if let Some(options) = options {
        for (k, v) in options.iter() {
            let key: String = k.extract()?;
            set_option(&mut scenario, &mut literals, &key, &v)?;
        }
    }
    scenario.validate().map_err(|e| invalid(e, &literals))?;
    Ok((scenario, arrays, literals))
}

/// The recorded scenario of a run (none for a mesh given as arrays, which a scenario cannot
/// name).
fn record_of(
    scenario: &Scenario,
    literals: &Literals,
    arrays: &Option<balloon::mesh::TriMesh>,
) -> Option<String> {
    arrays
        .is_none()
        .then(|| balloon_scenario::file::record(scenario, literals))
}

/// `numpy.ascontiguousarray(x, dtype=dtype)`.
fn as_array<'py>(x: &Bound<'py, PyAny>, dtype: &str) -> PyResult<Bound<'py, PyAny>> {
    let kw = PyDict::new(x.py());
    kw.set_item("dtype", dtype)?;
    x.py()
        .import("numpy")?
        .call_method("ascontiguousarray", (x,), Some(&kw))
}

/// A `mesh` argument: a path or `builtin[:NAME]` (the scenario's `mesh.path`) or a
/// `(vertices, triangles)` pair of arrays (built here; the summary's `mesh` is then `<arrays>`).
enum MeshSpec {
    Named(String),
    Arrays(balloon::mesh::TriMesh),
}

/// The mesh name of in-memory arrays in summaries.
const ARRAYS_NAME: &str = "<arrays>";

fn mesh_spec(mesh: &Bound<'_, PyAny>) -> PyResult<MeshSpec> {
    if mesh.is_instance_of::<PyTuple>() || mesh.is_instance_of::<PyList>() {
        let parts: Vec<Bound<'_, PyAny>> = mesh.try_iter()?.collect::<PyResult<_>>()?;
        if parts.len() != 2 {
            return Err(MeshError::new_err(
                "a mesh given as arrays is a pair (vertices, triangles)",
            ));
        }
        let v = as_array(&parts[0], "float64")
            .map_err(|e| MeshError::new_err(format!("vertices: {}", e.value(mesh.py()))))?;
        let t = as_array(&parts[1], "int64")
            .map_err(|e| MeshError::new_err(format!("triangles: {}", e.value(mesh.py()))))?;
        let v: PyReadonlyArray2<'_, f64> = v
            .extract()
            .map_err(|_| MeshError::new_err("vertices must be an (n, 3) array"))?;
        let t: PyReadonlyArray2<'_, i64> = t
            .extract()
            .map_err(|_| MeshError::new_err("triangles must be an (m, 3) array"))?;
        let (v, t) = (v.as_array(), t.as_array());
        if v.ncols() != 3 || t.ncols() != 3 {
            return Err(MeshError::new_err(format!(
                "vertices must be (n, 3) and triangles (m, 3); got {:?} and {:?}",
                v.shape(),
                t.shape()
            )));
        }
        let n = v.nrows();
        let vertices = v
            .rows()
            .into_iter()
            .map(|r| Point3::new(r[0], r[1], r[2]))
            .collect();
        let triangles = t
            .rows()
            .into_iter()
            .enumerate()
            .map(|(i, r)| {
                let mut tri = [0usize; 3];
                for k in 0..3 {
                    tri[k] = usize::try_from(r[k])
                        .ok()
                        .filter(|&j| j < n)
                        .ok_or_else(|| {
                            MeshError::new_err(format!(
                                "triangle {i} has vertex index {} outside 0..{n}",
                                r[k]
                            ))
                        })?;
                }
                Ok(tri)
            })
            .collect::<PyResult<Vec<_>>>()?;
        return Ok(MeshSpec::Arrays(balloon::mesh::TriMesh::new(
            vertices, triangles,
        )));
    }
    let os = mesh.py().import("os")?;
    let path = os
        .call_method1("fspath", (mesh,))
        .and_then(|p| p.extract::<String>())
        .map_err(|_| {
            MeshError::new_err(
                "mesh must be a path, \"builtin\", \"builtin:NAME\" or a (vertices, triangles) pair",
            )
        })?;
    Ok(MeshSpec::Named(path))
}

impl MeshSpec {
    /// The scenario's mesh path and the in-memory mesh.
    fn split(self) -> (String, Option<balloon::mesh::TriMesh>) {
        match self {
            MeshSpec::Named(p) => (p, None),
            MeshSpec::Arrays(m) => (ARRAYS_NAME.to_owned(), Some(m)),
        }
    }
}

thread_local! {
    /// The exception Python's signal handler raised while a run checked for Ctrl-C (re-raised
    /// once the run has written its records).
    static SIGNAL_ERROR: RefCell<Option<PyErr>> = const { RefCell::new(None) };
}

/// The interruption check of the CLI's run loop, between steps: runs Python's signal handlers
/// (Ctrl-C raises `KeyboardInterrupt` there) and stops the run when one raised.
fn check_python_signals() -> Option<i32> {
    Python::attach(|py| match py.check_signals() {
        Ok(()) => None,
        Err(e) => {
            SIGNAL_ERROR.with(|s| *s.borrow_mut() = Some(e));
            Some(2)
        }
    })
}

/// The Python exception of a job's error: the signal's exception for an interrupted run, else a
/// [`BalloonError`] subclass by the error's kind, with the CLI's message.
fn to_py_err(e: anyhow::Error) -> PyErr {
    if e.chain().any(|c| c.is::<Interrupted>()) {
        return SIGNAL_ERROR
            .with(|s| s.borrow_mut().take())
            .unwrap_or_else(|| PyKeyboardInterrupt::new_err(error_chain(&e)));
    }
    let msg = error_chain(&e);
    if e.chain().any(|c| c.is::<ScenarioError>()) {
        InvalidOption::new_err(msg)
    } else if e.chain().any(|c| c.is::<SimulationError>()) {
        SolverError::new_err(msg)
    } else if e.chain().any(|c| c.is::<balloon::mesh::MeshError>()) {
        MeshError::new_err(msg)
    } else {
        BalloonError::new_err(msg)
    }
}

/// The error and its causes joined by `: ` (skipping a cause the message already holds), with
/// the parameters spelled for Python users: the CLI's message.
fn error_chain(e: &anyhow::Error) -> String {
    let mut msg = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if msg.contains(&text) {
            continue;
        }
        if !msg.is_empty() {
            msg.push_str(": ");
        }
        msg.push_str(&text);
    }
    spelled(&msg)
}

/// A library error of a step-wise simulation's setter.
fn setter_err(e: impl std::fmt::Display) -> PyErr {
    InvalidOption::new_err(spelled(&e.to_string()))
}

/// A JSON value (a summary, a stats row) as Python objects.
fn json_to_py<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
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
fn points_array<'py>(py: Python<'py>, flat: &[f64]) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_slice(py, flat)
        .reshape([flat.len() / 3, 3])?
        .into_any())
}

/// Triangles as an `(m, 3)` int64 array.
fn triangles_array<'py>(py: Python<'py>, tris: &[[usize; 3]]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<i64> = tris
        .iter()
        .flat_map(|t| t.map(|i| i64::try_from(i).unwrap_or(i64::MAX)))
        .collect();
    Ok(PyArray1::from_vec(py, flat)
        .reshape([tris.len(), 3])?
        .into_any())
}

/// An `(n, 3)` array-like as flat `f64` values, checked for `n` rows.
fn flat_points(obj: &Bound<'_, PyAny>, rows: usize, what: &str) -> PyResult<Vec<f64>> {
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
fn stats_dict<'py, D: serde::Serialize>(
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

/// Runs `job` with the GIL released and Ctrl-C checked between steps.
fn detached<T: Send, F: FnOnce() -> anyhow::Result<T> + Send>(
    py: Python<'_>,
    job: F,
) -> PyResult<T> {
    py.detach(job).map_err(to_py_err)
}

/// The result dict of a whole job.
fn job_result<'py, S: Simulation>(
    py: Python<'py>,
    finished: &Finished<S>,
    positions: &[f64],
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    match &finished.summary {
        Some(s) => d.set_item("summary", json_to_py(py, s)?)?,
        None => d.set_item("summary", py.None())?,
    }
    d.set_item("positions", points_array(py, positions)?)?;
    Ok(d)
}

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
/// runs; Ctrl-C stops it after the current step (records written, KeyboardInterrupt raised).
#[pyfunction]
#[pyo3(signature = (mesh = None, **options))]
fn inflate<'py>(
    py: Python<'py>,
    mesh: Option<&Bound<'py, PyAny>>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (scenario, arrays, literals) = scenario_of(SystemKind::Shell, mesh, options)?;
    let record = record_of(&scenario, &literals, &arrays);
    run_shell(py, scenario, arrays, record)
}

/// volumetric(mesh="builtin", **options)
/// --
///
/// Runs `balloon volumetric` (a volume-conserving body, seed 003) on `mesh` with the CLI's
/// flags as keyword options. Returns {"summary": dict, "positions": (n, 3) lattice particle
/// positions, "surface_positions": (k, 3) the embedded surface, "surface_triangles": (m, 3)}.
#[pyfunction]
#[pyo3(signature = (mesh = None, **options))]
fn volumetric<'py>(
    py: Python<'py>,
    mesh: Option<&Bound<'py, PyAny>>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (scenario, arrays, literals) = scenario_of(SystemKind::Volumetric, mesh, options)?;
    let record = record_of(&scenario, &literals, &arrays);
    run_volumetric(py, scenario, arrays, record)
}

/// two_layer(**options)
/// --
///
/// Runs `balloon two-layer` (a two-layer mass-spring body, seed 004) with the CLI's flags as
/// keyword options (`dim=3, integrator="rk4", steps=2000`, ...). Returns {"summary": dict,
/// "positions": (n, 3) particle positions}.
#[pyfunction]
#[pyo3(signature = (**options))]
fn two_layer<'py>(
    py: Python<'py>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (scenario, _, literals) = scenario_of(SystemKind::TwoLayer, None, options)?;
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
fn connect<'py>(
    py: Python<'py>,
    mesh: Option<&Bound<'py, PyAny>>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (scenario, arrays, literals) = scenario_of(SystemKind::Connect, mesh, options)?;
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
fn run_scenario<'py>(
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

/// Locks a simulation (a poisoned lock means an earlier call panicked: refused).
fn lock<T>(m: &Mutex<T>) -> PyResult<MutexGuard<'_, T>> {
    m.lock()
        .map_err(|_| BalloonError::new_err("the simulation is unusable after an internal error"))
}

/// Shell(mesh="builtin", **options)
/// --
///
/// A shell balloon (seed 000) built exactly as `balloon inflate` builds it from the same
/// options, driven step by step from Python: `step()` returns the step's statistics;
/// `positions`, `velocities`, `thickness`, `time`, `gauge_pressure`, `gas_volume` read the
/// state; `set_pressure`, `set_pump_rate`, `set_external_forces`, `set_anchor_springs`,
/// `set_dt` steer it. Output options (`out`, `render`, ...) are accepted and ignored.
#[pyclass(module = "balloon._balloon")]
struct Shell {
    sim: Mutex<ShellSim>,
    /// The anchor springs and scheduled loads of the options (`pin`, `load`), applied before
    /// every step as the CLI applies them.
    loads: Mutex<ShellLoads>,
}

#[pymethods]
impl Shell {
    #[new]
    #[pyo3(signature = (mesh = None, **options))]
    fn new(
        py: Python<'_>,
        mesh: Option<&Bound<'_, PyAny>>,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let (scenario, arrays, _) = scenario_of(SystemKind::Shell, mesh, options)?;
        let Scenario::Shell(s) = scenario else {
            return Err(BalloonError::new_err("not a shell scenario"));
        };
        let (sim, loads) = detached(py, move || Ok(s.build(arrays)?))?;
        Ok(Self {
            sim: Mutex::new(sim),
            loads: Mutex::new(loads),
        })
    }

    /// Advances one time step (GIL released) and returns its statistics as a dict (the keys of
    /// a `stats.jsonl` line plus `steps`, `time`, `dt`, `kinetic_energy`). Raises SolverError
    /// when the step fails (the state is rolled back to the start of the step).
    fn step<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut guard = lock(&self.sim)?;
        let sim = &mut *guard;
        lock(&self.loads)?
            .before_step(sim)
            .map_err(|e| to_py_err(e.into()))?;
        let stats = py
            .detach(|| Simulation::step(sim))
            .map_err(|e| to_py_err(e.into()))?;
        stats_dict(py, &stats)
    }

    /// Vertex positions, m: an (n, 3) float64 array (a copy of the current state).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_array(py, lock(&self.sim)?.positions())
    }

    /// Vertex velocities, m/s: an (n, 3) float64 array.
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_array(py, lock(&self.sim)?.velocities())
    }

    /// The triangles: an (m, 3) int64 array.
    #[getter]
    fn triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        triangles_array(py, lock(&self.sim)?.triangles())
    }

    /// Current shell thickness per triangle, m: an (m,) float64 array.
    #[getter]
    fn thickness<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        Ok(PyArray1::from_slice(py, lock(&self.sim)?.thickness()))
    }

    /// Simulated time, s.
    #[getter]
    fn time(&self) -> PyResult<f64> {
        Ok(lock(&self.sim)?.time())
    }

    /// Steps taken.
    #[getter]
    fn steps(&self) -> PyResult<usize> {
        Ok(Simulation::steps(&*lock(&self.sim)?))
    }

    /// The time step of the following steps, s.
    #[getter]
    fn dt(&self) -> PyResult<f64> {
        Ok(lock(&self.sim)?.dt())
    }

    /// Gauge pressure of the gas, Pa.
    #[getter]
    fn gauge_pressure(&self) -> PyResult<f64> {
        Ok(lock(&self.sim)?.gauge_pressure())
    }

    /// Enclosed gas volume, m^3.
    #[getter]
    fn gas_volume(&self) -> PyResult<f64> {
        Ok(lock(&self.sim)?.gas_volume())
    }

    /// Changes the time step (s) of the following steps.
    fn set_dt(&self, dt: f64) -> PyResult<()> {
        lock(&self.sim)?.set_dt(dt).map_err(setter_err)
    }

    /// Sets the gauge pressure, Pa (held pressure of `gas="constant"`, the amount of the
    /// ideal gas at the rest volume, ...; an error for the pump).
    fn set_pressure(&self, pressure: f64) -> PyResult<()> {
        lock(&self.sim)?
            .set_gauge_pressure(pressure)
            .map_err(setter_err)
    }

    /// Sets the pump rate, m^3/s of ambient air, of `gas="pump"` from now on.
    fn set_pump_rate(&self, rate: f64) -> PyResult<()> {
        lock(&self.sim)?.set_pump_rate(rate).map_err(setter_err)
    }

    /// Sets external forces, N: an (n, 3) array, one per vertex, applied in every following
    /// step; None removes them.
    #[pyo3(signature = (forces = None))]
    fn set_external_forces(&self, forces: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let mut sim = lock(&self.sim)?;
        let f = match forces {
            Some(f) => Some(flat_points(f, sim.positions().len() / 3, "forces")?),
            None => None,
        };
        sim.set_external_forces(f.as_deref()).map_err(setter_err)
    }

    /// Replaces the anchor springs: a list of (vertex, (x, y, z), stiffness N/m), zero-length
    /// springs pulling the vertex to the fixed point (integrated implicitly); [] removes them.
    fn set_anchor_springs(&self, springs: Vec<(usize, [f64; 3], f64)>) -> PyResult<()> {
        let springs = springs
            .into_iter()
            .map(|(vertex, anchor, stiffness)| AnchorSpring {
                vertex,
                anchor,
                stiffness,
            })
            .collect();
        lock(&self.sim)?
            .set_anchor_springs(springs)
            .map_err(setter_err)
    }
}

/// Volumetric(mesh="builtin", **options)
/// --
///
/// A volume-conserving body (seed 003) built exactly as `balloon volumetric` builds it, driven
/// step by step: `step()`, `positions` (lattice particles), `surface_positions` (the embedded
/// surface), `time`, `set_external_forces`, `set_dt`.
#[pyclass(module = "balloon._balloon")]
struct Volumetric {
    sim: Mutex<VolumetricSimulation>,
}

#[pymethods]
impl Volumetric {
    #[new]
    #[pyo3(signature = (mesh = None, **options))]
    fn new(
        py: Python<'_>,
        mesh: Option<&Bound<'_, PyAny>>,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let (scenario, arrays, _) = scenario_of(SystemKind::Volumetric, mesh, options)?;
        let Scenario::Volumetric(s) = scenario else {
            return Err(BalloonError::new_err("not a volumetric scenario"));
        };
        let built = detached(py, move || Ok(s.build(arrays)?))?;
        Ok(Self {
            sim: Mutex::new(built.sim),
        })
    }

    /// Advances one time step (GIL released) and returns its statistics as a dict.
    fn step<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut guard = lock(&self.sim)?;
        let sim = &mut *guard;
        let stats = py
            .detach(|| Simulation::step(sim))
            .map_err(|e| to_py_err(e.into()))?;
        stats_dict(py, &stats)
    }

    /// Lattice particle positions, m: an (n, 3) float64 array.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_array(py, Simulation::positions(&*lock(&self.sim)?))
    }

    /// Lattice particle velocities, m/s: an (n, 3) float64 array.
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_array(py, Simulation::velocities(&*lock(&self.sim)?))
    }

    /// The embedded surface (the input soup deformed with the lattice), m: (k, 3).
    #[getter]
    fn surface_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let sim = lock(&self.sim)?;
        let flat: Vec<f64> = sim
            .lattice()
            .embedding
            .positions(sim.positions())
            .iter()
            .flat_map(|p| [p.x, p.y, p.z])
            .collect();
        points_array(py, &flat)
    }

    /// The embedded surface's triangles: (m, 3) int64.
    #[getter]
    fn surface_triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        triangles_array(py, &lock(&self.sim)?.lattice().embedding.triangles)
    }

    /// Simulated time, s.
    #[getter]
    fn time(&self) -> PyResult<f64> {
        Ok(lock(&self.sim)?.time())
    }

    /// Steps taken.
    #[getter]
    fn steps(&self) -> PyResult<usize> {
        Ok(Simulation::steps(&*lock(&self.sim)?))
    }

    /// The time step of the following steps, s.
    #[getter]
    fn dt(&self) -> PyResult<f64> {
        Ok(Simulation::dt(&*lock(&self.sim)?))
    }

    /// Changes the time step (s) of the following steps.
    fn set_dt(&self, dt: f64) -> PyResult<()> {
        Simulation::set_dt(&mut *lock(&self.sim)?, dt).map_err(setter_err)
    }

    /// Sets external forces, N: an (n, 3) array, one per lattice particle; None removes them.
    #[pyo3(signature = (forces = None))]
    fn set_external_forces(&self, forces: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let mut sim = lock(&self.sim)?;
        let f = match forces {
            Some(f) => {
                let flat = flat_points(f, sim.positions().len(), "forces")?;
                Some(
                    flat.chunks_exact(3)
                        .map(|c| Vector3::new(c[0], c[1], c[2]))
                        .collect::<Vec<_>>(),
                )
            }
            None => None,
        };
        sim.set_external_forces(f.as_deref()).map_err(setter_err)
    }
}

/// TwoLayer(**options)
/// --
///
/// A two-layer mass-spring body (seed 004) built exactly as `balloon two-layer` builds it,
/// driven step by step: `step()`, `positions`, `time`, `set_drag`, `set_dt`.
#[pyclass(module = "balloon._balloon")]
struct TwoLayer {
    sim: Mutex<TwoLayerSimulation>,
}

#[pymethods]
impl TwoLayer {
    #[new]
    #[pyo3(signature = (**options))]
    fn new(py: Python<'_>, options: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let (scenario, _, _) = scenario_of(SystemKind::TwoLayer, None, options)?;
        let Scenario::TwoLayer(s) = scenario else {
            return Err(BalloonError::new_err("not a two-layer scenario"));
        };
        let sim = detached(py, move || Ok(s.build()?))?;
        Ok(Self {
            sim: Mutex::new(sim),
        })
    }

    /// Advances one time step (GIL released) and returns its statistics as a dict.
    fn step<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut guard = lock(&self.sim)?;
        let sim = &mut *guard;
        let stats = py
            .detach(|| Simulation::step(sim))
            .map_err(|e| to_py_err(e.into()))?;
        stats_dict(py, &stats)
    }

    /// Particle positions, m: an (n, 3) float64 array.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_array(py, Simulation::positions(&*lock(&self.sim)?))
    }

    /// Particle velocities, m/s: an (n, 3) float64 array.
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_array(py, Simulation::velocities(&*lock(&self.sim)?))
    }

    /// Simulated time, s.
    #[getter]
    fn time(&self) -> PyResult<f64> {
        Ok(lock(&self.sim)?.time())
    }

    /// Steps taken.
    #[getter]
    fn steps(&self) -> PyResult<usize> {
        Ok(Simulation::steps(&*lock(&self.sim)?))
    }

    /// The time step of the following steps, s.
    #[getter]
    fn dt(&self) -> PyResult<f64> {
        Ok(Simulation::dt(&*lock(&self.sim)?))
    }

    /// Changes the time step (s) of the following steps.
    fn set_dt(&self, dt: f64) -> PyResult<()> {
        Simulation::set_dt(&mut *lock(&self.sim)?, dt).map_err(setter_err)
    }

    /// Drags the body ("mouse"): a spring of `stiffness` N/m and `damping` N s/m from the
    /// nearest particle to `point` (x, y, z), m; None releases it. Returns the dragged particle.
    #[pyo3(signature = (point = None, stiffness = 10.0, damping = 0.1))]
    fn set_drag(
        &self,
        point: Option<[f64; 3]>,
        stiffness: f64,
        damping: f64,
    ) -> PyResult<Option<usize>> {
        let target = point.map(|p| DragTarget {
            point: Point3::new(p[0], p[1], p[2]),
            stiffness,
            damping,
            rest_length: 0.0,
        });
        lock(&self.sim)?.set_drag(target).map_err(setter_err)
    }
}

/// The extension module `balloon._balloon`.
#[pymodule]
fn _balloon(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    // Ctrl-C as Python sees it stops the run loops between steps.
    balloon_run::interrupt::set_checker(check_python_signals);
    m.add("BalloonError", py.get_type::<BalloonError>())?;
    m.add("InvalidOption", py.get_type::<InvalidOption>())?;
    m.add("MeshError", py.get_type::<MeshError>())?;
    m.add("SolverError", py.get_type::<SolverError>())?;
    m.add_function(wrap_pyfunction!(inflate, m)?)?;
    m.add_function(wrap_pyfunction!(volumetric, m)?)?;
    m.add_function(wrap_pyfunction!(two_layer, m)?)?;
    m.add_function(wrap_pyfunction!(connect, m)?)?;
    m.add_function(wrap_pyfunction!(run_scenario, m)?)?;
    m.add_class::<Shell>()?;
    m.add_class::<Volumetric>()?;
    m.add_class::<TwoLayer>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
