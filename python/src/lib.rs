//! The `balloon` Python package's extension module (`balloon._balloon`, built with maturin from
//! `python/pyproject.toml`).
//!
//! It is what the Python API calls: whole jobs (`inflate`, `volumetric`, `two_layer`,
//! `run_scenario`) and step-wise simulations (`Shell`, `Volumetric`, `TwoLayer`). It is not a
//! second implementation of the command-line tool: keyword options become the CLI's flags
//! (`newton_tol=1e-8` is `--newton-tol=1e-8`, `True` the bare flag) and are parsed by the CLI's
//! own clap structures; the simulations are made by the CLI's `build` functions and whole jobs
//! run through its `execute` functions, so defaults, units, validation messages and results are
//! the CLI's by construction. It is not a Rust API either: Rust code uses the `balloon` crate.
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
use balloon_cli::cmd_connect::{self, ConnectArgs};
use balloon_cli::cmd_inflate::{self, InflateArgs, ShellSim};
use balloon_cli::cmd_run::{self, ScenarioError, SystemArgs};
use balloon_cli::cmd_two_layer::{self, TwoLayerArgs};
use balloon_cli::cmd_volumetric::{self, VolumetricArgs};
use balloon_cli::interrupt::Interrupted;
use balloon_cli::run::Finished;
use clap::{CommandFactory, Parser};
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
    "An unknown keyword option, a value of the wrong type or outside its range, or a scenario \
     file that does not parse (the CLI flag parser's message)."
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

/// The parser of `balloon inflate`'s flags, on their own.
#[derive(Parser)]
#[command(name = "balloon.inflate", no_binary_name = true)]
struct ShellCli {
    #[command(flatten)]
    args: InflateArgs,
}

/// The parser of `balloon volumetric`'s flags, on their own.
#[derive(Parser)]
#[command(name = "balloon.volumetric", no_binary_name = true)]
struct VolumetricCli {
    #[command(flatten)]
    args: VolumetricArgs,
}

/// The parser of `balloon two-layer`'s flags, on their own.
#[derive(Parser)]
#[command(name = "balloon.two_layer", no_binary_name = true)]
struct TwoLayerCli {
    #[command(flatten)]
    args: TwoLayerArgs,
}

/// The parser of `balloon connect`'s flags, on their own.
#[derive(Parser)]
#[command(name = "balloon.connect", no_binary_name = true)]
struct ConnectCli {
    #[command(flatten)]
    args: ConnectArgs,
}

/// The CLI flag of a keyword option: `newton_tol` is `newton-tol`.
fn flag_name(keyword: &str) -> String {
    keyword.replace('_', "-")
}

/// The first line of a clap error without its `error: ` prefix.
fn clap_message(e: &clap::Error) -> String {
    let text = e.to_string();
    let line = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
    line.strip_prefix("error: ").unwrap_or(line).to_owned()
}

/// A keyword option's value as flag text: numbers in round-trip form, lists comma-separated,
/// paths through `os.fspath`.
fn value_text(v: &Bound<'_, PyAny>) -> PyResult<String> {
    if v.is_instance_of::<PyBool>() {
        return Err(InvalidOption::new_err(
            "a boolean is only valid for an on/off flag",
        ));
    }
    if v.is_instance_of::<PyInt>() {
        return Ok(v.str()?.to_cow()?.into_owned());
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(format!("{:?}", v.extract::<f64>()?));
    }
    if let Ok(s) = v.cast::<PyString>() {
        return Ok(s.to_cow()?.into_owned());
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let parts = v
            .try_iter()?
            .map(|x| value_text(&x?))
            .collect::<PyResult<Vec<_>>>()?;
        return Ok(parts.join(","));
    }
    // Each attempt below may fail with an `Exception` (try the next); anything else (a
    // KeyboardInterrupt from Ctrl-C, SystemExit) is passed on, not taken for a wrong type.
    let py = v.py();
    let not_an_exception = |e: PyErr| -> PyResult<()> {
        if e.is_instance_of::<PyException>(py) {
            Ok(())
        } else {
            Err(e)
        }
    };
    let os = py.import("os")?;
    match os.call_method1("fspath", (v,)) {
        Ok(p) => return p.extract::<String>(),
        Err(e) => not_an_exception(e)?,
    }
    // numpy integers (and anything else with `__index__`), then numpy floats and other reals.
    match v.extract::<i64>() {
        Ok(i) => return Ok(i.to_string()),
        Err(e) => not_an_exception(e)?,
    }
    match v.extract::<f64>() {
        Ok(f) => Ok(format!("{f:?}")),
        Err(e) => {
            not_an_exception(e)?;
            Err(InvalidOption::new_err(format!(
                "cannot use a value of type {} as an option",
                v.get_type().name()?
            )))
        }
    }
}

/// The command-line arguments of keyword `options` for the flags of `cmd`: `--name=value`;
/// for an on/off flag `--name` for `True` and nothing for `False`; for a switch with a default
/// of its own (`follower_term`) `--name=true` or `--name=false`; nothing for `None`. Unknown
/// keywords are refused with the list of the known ones.
fn option_args(cmd: &clap::Command, options: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<String>> {
    let mut out = Vec::new();
    let Some(options) = options else {
        return Ok(out);
    };
    for (k, v) in options.iter() {
        let key: String = k.extract()?;
        let long = flag_name(&key);
        let Some(arg) = cmd
            .get_arguments()
            .find(|a| a.get_long() == Some(long.as_str()))
        else {
            let mut known: Vec<String> = cmd
                .get_arguments()
                .filter_map(|a| a.get_long())
                .filter(|l| *l != "help" && *l != "version")
                .map(|l| l.replace('-', "_"))
                .collect();
            known.sort();
            return Err(InvalidOption::new_err(format!(
                "unknown option `{key}` (the options are {})",
                known.join(", ")
            )));
        };
        if v.is_none() {
            continue;
        }
        if matches!(arg.get_action(), clap::ArgAction::SetTrue) {
            let on = v.cast::<PyBool>().map_err(|_| {
                InvalidOption::new_err(format!(
                    "option `{key}` is on/off: give True or False, not {}",
                    v.repr().map(|r| r.to_string()).unwrap_or_default()
                ))
            })?;
            if on.is_true() {
                out.push(format!("--{long}"));
            }
            continue;
        }
        // A switch with a default of its own (`--flag[=true|false]`): the value spelled out.
        if let Ok(on) = v.cast::<PyBool>()
            && arg.get_num_args().is_some_and(|r| r.min_values() == 0)
        {
            out.push(format!("--{long}={}", on.is_true()));
            continue;
        }
        // A KeyboardInterrupt (Ctrl-C while the options are read) is not an invalid option:
        // only `Exception`s are reported as this option's.
        let text = value_text(&v).map_err(|e| {
            if e.is_instance_of::<PyException>(v.py()) {
                InvalidOption::new_err(format!("option `{key}`: {}", e.value(v.py())))
            } else {
                e
            }
        })?;
        out.push(format!("--{long}={text}"));
    }
    Ok(out)
}

/// Parses `argv` with parser `C` as the CLI would, returning the arguments and their scenario
/// record (written to `OUT/scenario.toml` as the CLI writes it).
fn parse_args<C: Parser>(argv: &[String]) -> PyResult<(C, clap::ArgMatches)> {
    let matches = C::command()
        .try_get_matches_from(argv)
        .map_err(|e| InvalidOption::new_err(clap_message(&e)))?;
    let cli =
        C::from_arg_matches(&matches).map_err(|e| InvalidOption::new_err(clap_message(&e)))?;
    Ok((cli, matches))
}

/// `numpy.ascontiguousarray(x, dtype=dtype)`.
fn as_array<'py>(x: &Bound<'py, PyAny>, dtype: &str) -> PyResult<Bound<'py, PyAny>> {
    let kw = PyDict::new(x.py());
    kw.set_item("dtype", dtype)?;
    x.py()
        .import("numpy")?
        .call_method("ascontiguousarray", (x,), Some(&kw))
}

/// A `mesh` argument: a path or `builtin[:NAME]` (passed to the CLI as its positional MESH) or
/// a `(vertices, triangles)` pair of arrays (built here; the summary's `mesh` is then `<arrays>`).
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
    /// The positional MESH argument and the in-memory mesh.
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

/// The Python exception of a CLI error: the signal's exception for an interrupted run, else a
/// [`BalloonError`] subclass by the error's kind, with the CLI's message.
fn to_py_err(e: anyhow::Error) -> PyErr {
    if e.chain().any(|c| c.is::<Interrupted>()) {
        return SIGNAL_ERROR
            .with(|s| s.borrow_mut().take())
            .unwrap_or_else(|| PyKeyboardInterrupt::new_err(balloon_cli::error_chain(&e)));
    }
    let msg = balloon_cli::error_chain(&e);
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

/// The flags of a command that runs on a mesh (`C`: the CLI's parser of `inflate` or
/// `volumetric`): the mesh's name as the first argument (in-memory arrays are returned beside
/// it, with a placeholder name), then the keyword options; with the parsed matches, from which
/// the run's scenario record is written.
fn mesh_command_args<C: Parser>(
    mesh: Option<&Bound<'_, PyAny>>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<(C, Option<balloon::mesh::TriMesh>, clap::ArgMatches)> {
    let (name, arrays) = match mesh {
        Some(mesh) => mesh_spec(mesh)?.split(),
        None => ("builtin".to_owned(), None),
    };
    let mut argv = vec![name];
    argv.extend(option_args(&C::command(), options)?);
    let (cli, m) = parse_args::<C>(&argv)?;
    Ok((cli, arrays, m))
}

fn two_layer_args(
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<(TwoLayerArgs, clap::ArgMatches)> {
    let argv = option_args(&TwoLayerCli::command(), options)?;
    let (cli, m) = parse_args::<TwoLayerCli>(&argv)?;
    Ok((cli.args, m))
}

fn run_shell<'py>(
    py: Python<'py>,
    mut args: InflateArgs,
    mesh: Option<balloon::mesh::TriMesh>,
) -> PyResult<Bound<'py, PyDict>> {
    args.json = false;
    let static_solve = args.static_solve;
    let (finished, points) = detached(py, move || {
        cmd_inflate::execute_with_points(&args, mesh, true)
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
    args: VolumetricArgs,
    mesh: Option<balloon::mesh::TriMesh>,
) -> PyResult<Bound<'py, PyDict>> {
    let finished = detached(py, move || cmd_volumetric::execute(&args, mesh, true))?;
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

fn run_connect<'py>(py: Python<'py>, mut args: ConnectArgs) -> PyResult<Bound<'py, PyDict>> {
    args.shell.json = false;
    let finished = detached(py, move || cmd_connect::execute(args, true))?;
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

fn run_two_layer<'py>(py: Python<'py>, args: TwoLayerArgs) -> PyResult<Bound<'py, PyDict>> {
    let finished = detached(py, move || cmd_two_layer::execute(&args, true))?;
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
    let (cli, arrays, m) = mesh_command_args::<ShellCli>(mesh, options)?;
    let mut args = cli.args;
    // A recorded scenario names its mesh file: in-memory arrays have none, so none is written.
    if arrays.is_none() {
        args.scenario_record = Some(cmd_run::record(&cmd_run::SHELL, &m));
    }
    run_shell(py, args, arrays)
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
    let (cli, arrays, m) = mesh_command_args::<VolumetricCli>(mesh, options)?;
    let mut args = cli.args;
    // A recorded scenario names its mesh file: in-memory arrays have none, so none is written.
    if arrays.is_none() {
        args.scenario_record = Some(cmd_run::record(&cmd_run::VOLUMETRIC, &m));
    }
    run_volumetric(py, args, arrays)
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
    let (mut args, m) = two_layer_args(options)?;
    args.scenario_record = Some(cmd_run::record(&cmd_run::TWO_LAYER, &m));
    run_two_layer(py, args)
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
    let (cli, arrays, m) = mesh_command_args::<ConnectCli>(mesh, options)?;
    if arrays.is_some() {
        return Err(InvalidOption::new_err(
            "connect takes a mesh path or \"builtin:NAME\", not arrays: write the mesh to a file",
        ));
    }
    let mut args = cli.args;
    args.shell.scenario_record = Some(cmd_run::record(&cmd_run::CONNECT, &m));
    run_connect(py, args)
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
    // The overrides are checked against the flags of the file's system by `scenario_args`;
    // their names against the union of the three systems' flags here.
    let mut flags = Vec::new();
    if let Some(o) = overrides {
        for (k, v) in o.iter() {
            let one = PyDict::new(py);
            one.set_item(&k, &v)?;
            let key: String = k.extract()?;
            let long = flag_name(&key);
            let cmd = [
                ShellCli::command(),
                VolumetricCli::command(),
                TwoLayerCli::command(),
                ConnectCli::command(),
            ]
            .into_iter()
            .find(|c| {
                c.get_arguments()
                    .any(|a| a.get_long() == Some(long.as_str()))
            })
            .ok_or_else(|| InvalidOption::new_err(format!("unknown option `{key}`")))?;
            flags.extend(option_args(&cmd, Some(&one))?);
        }
    }
    let file = std::path::Path::new(&path);
    if let Some(a) = cmd_run::connect_scenario_args(file, &flags)
        .map_err(|e| InvalidOption::new_err(e.to_string()))?
    {
        return run_connect(py, a);
    }
    let args =
        cmd_run::scenario_args(file, &flags).map_err(|e| InvalidOption::new_err(e.to_string()))?;
    match args {
        SystemArgs::Shell(a) => run_shell(py, *a, None),
        SystemArgs::Volumetric(a) => run_volumetric(py, *a, None),
        SystemArgs::TwoLayer(a) => run_two_layer(py, *a),
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
    loads: Mutex<balloon_cli::selection::ShellLoads>,
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
        let (cli, arrays, _) = mesh_command_args::<ShellCli>(mesh, options)?;
        let args = cli.args;
        let (sim, loads) = detached(py, move || cmd_inflate::build_with_loads(&args, arrays))?;
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
        lock(&self.sim)?
            .set_dt(dt)
            .map_err(|e| InvalidOption::new_err(e.to_string()))
    }

    /// Sets the gauge pressure, Pa (held pressure of `gas="constant"`, the amount of the
    /// ideal gas at the rest volume, ...; an error for the pump).
    fn set_pressure(&self, pressure: f64) -> PyResult<()> {
        lock(&self.sim)?
            .set_gauge_pressure(pressure)
            .map_err(|e| InvalidOption::new_err(e.to_string()))
    }

    /// Sets the pump rate, m^3/s of ambient air, of `gas="pump"` from now on.
    fn set_pump_rate(&self, rate: f64) -> PyResult<()> {
        lock(&self.sim)?
            .set_pump_rate(rate)
            .map_err(|e| InvalidOption::new_err(e.to_string()))
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
        sim.set_external_forces(f.as_deref())
            .map_err(|e| InvalidOption::new_err(e.to_string()))
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
            .map_err(|e| InvalidOption::new_err(e.to_string()))
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
        let (cli, arrays, _) = mesh_command_args::<VolumetricCli>(mesh, options)?;
        let args = cli.args;
        let built = detached(py, move || cmd_volumetric::build(&args, arrays))?;
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
        Simulation::set_dt(&mut *lock(&self.sim)?, dt)
            .map_err(|e| InvalidOption::new_err(e.to_string()))
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
        sim.set_external_forces(f.as_deref())
            .map_err(|e| InvalidOption::new_err(e.to_string()))
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
        let (args, _) = two_layer_args(options)?;
        let sim = detached(py, move || cmd_two_layer::build(&args))?;
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
        Simulation::set_dt(&mut *lock(&self.sim)?, dt)
            .map_err(|e| InvalidOption::new_err(e.to_string()))
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
        lock(&self.sim)?
            .set_drag(target)
            .map_err(|e| InvalidOption::new_err(e.to_string()))
    }
}

/// The extension module `balloon._balloon`.
#[pymodule]
fn _balloon(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    // Ctrl-C as Python sees it stops the CLI's run loops between steps.
    balloon_cli::interrupt::set_checker(check_python_signals);
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
