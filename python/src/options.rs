//! Keyword options and the mesh argument: each Python value becomes a typed value of the
//! library's scenario (`balloon_scenario`), checked by the library.

use crate::errors::{InvalidOption, MeshError, SPELLING, invalid};
use balloon_scenario::keys::{Kind, Literals};
use balloon_scenario::names::value_message;
use balloon_scenario::value::{SetError, Value};
use balloon_scenario::{Scenario, SystemKind};
use nalgebra::Point3;
use numpy::PyReadonlyArray2;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

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
pub(crate) fn set_option(
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

/// What a scenario is for: a whole job, or a step-wise simulation (whose output options are
/// accepted and ignored: it writes nothing).
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Use {
    /// A whole job with its outputs.
    Job,
    /// A simulation stepped from Python.
    Stepwise,
}

/// The checked scenario of system `kind` with keyword `options`, the mesh given (a path, or
/// arrays returned beside it), and the values' texts.
pub(crate) fn scenario_of(
    kind: SystemKind,
    mesh: Option<&Bound<'_, PyAny>>,
    options: Option<&Bound<'_, PyDict>>,
    purpose: Use,
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
    if purpose == Use::Stepwise {
        // Nothing is written: the pictures (which need a folder) are left out.
        let output = scenario.output_mut();
        output.out = None;
        output.render = None;
        output.gif = false;
        output.pov = false;
        output.color = None;
    }
    scenario.validate().map_err(|e| invalid(e, &literals))?;
    Ok((scenario, arrays, literals))
}

/// The recorded scenario of a run (none for a mesh given as arrays, which a scenario cannot
/// name).
pub(crate) fn record_of(
    scenario: &Scenario,
    literals: &Literals,
    arrays: &Option<balloon::mesh::TriMesh>,
) -> Option<String> {
    arrays
        .is_none()
        .then(|| balloon_scenario::file::record(scenario, literals))
}

/// `numpy.ascontiguousarray(x, dtype=dtype)`.
pub(crate) fn as_array<'py>(x: &Bound<'py, PyAny>, dtype: &str) -> PyResult<Bound<'py, PyAny>> {
    let kw = PyDict::new(x.py());
    kw.set_item("dtype", dtype)?;
    x.py()
        .import("numpy")?
        .call_method("ascontiguousarray", (x,), Some(&kw))
}

/// A `mesh` argument: a path or `builtin[:NAME]` (the scenario's `mesh.path`) or a
/// `(vertices, triangles)` pair of arrays (built here; the summary's `mesh` is then `<arrays>`).
pub(crate) enum MeshSpec {
    Named(String),
    Arrays(balloon::mesh::TriMesh),
}

/// The mesh name of in-memory arrays in summaries.
const ARRAYS_NAME: &str = "<arrays>";

pub(crate) fn mesh_spec(mesh: &Bound<'_, PyAny>) -> PyResult<MeshSpec> {
    if mesh.is_instance_of::<PyTuple>() || mesh.is_instance_of::<PyList>() {
        let parts: Vec<Bound<'_, PyAny>> = mesh.try_iter()?.collect::<PyResult<_>>()?;
        if parts.len() != 2 {
            return Err(MeshError::new_err(
                "a mesh given as arrays is a pair (vertices, triangles)",
            ));
        }
        let v = as_array(&parts[0], "float64")
            .map_err(|e| MeshError::new_err(format!("vertices: {}", e.value(mesh.py()))))?;
        let t = crate::args::index_array(&parts[1], "triangles")
            .map_err(|e| MeshError::new_err(e.value(mesh.py()).to_string()))?;
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
    pub(crate) fn split(self) -> (String, Option<balloon::mesh::TriMesh>) {
        match self {
            MeshSpec::Named(p) => (p, None),
            MeshSpec::Arrays(m) => (ARRAYS_NAME.to_owned(), Some(m)),
        }
    }
}
