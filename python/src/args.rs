//! Arguments of the step-wise simulations' setters, checked as the command line checks its
//! flags: a value of the wrong type or outside the parameter's range is an `InvalidOption`
//! naming the parameter (never pyo3's `TypeError` / `OverflowError` / `ValueError`), and an
//! index must be a whole number (a float is refused, not truncated).

use crate::errors::{InvalidOption, SPELLING, spelled};
use balloon_scenario::names::value_message;
use balloon_scenario::value::{SetError, Value};
use balloon_scenario::{Scenario, SystemKind};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyFloat, PyInt};

/// The Python type name of `obj`, for messages.
fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}

/// A real number for parameter `name`: an int or a float (numpy's too), not a bool or text.
pub(crate) fn real(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
    let refused = || {
        InvalidOption::new_err(spelled(&format!(
            "`{name}` must be a number, got {} ({})",
            type_name(obj),
            obj.repr().map(|r| r.to_string()).unwrap_or_default()
        )))
    };
    if obj.is_instance_of::<PyBool>() || obj.is_instance_of::<pyo3::types::PyString>() {
        return Err(refused());
    }
    obj.extract::<f64>().map_err(|e| {
        // Ctrl-C while the value converts itself stays a KeyboardInterrupt.
        if e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(obj.py()) {
            e
        } else {
            refused()
        }
    })
}

/// A real number for parameter `name` of system `kind`, inside the range its scenario key
/// (and command-line flag) takes: the CLI's message otherwise.
pub(crate) fn ranged(kind: SystemKind, obj: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
    let v = real(obj, name)?;
    let mut s = Scenario::new(kind);
    s.set(name, &Value::Float(v)).map_err(|e| {
        InvalidOption::new_err(match e {
            SetError::Type(m) => spelled(&m),
            SetError::Value(e) => value_message(&e, SPELLING, None),
        })
    })?;
    s.check(name)
        .map_err(|e| InvalidOption::new_err(value_message(&e, SPELLING, None)))?;
    Ok(v)
}

/// A whole-number index for `what` (e.g. "vertex of anchor spring 2"): a Python or numpy
/// integer >= 0; a float (even 3.0) or a bool is refused rather than truncated.
pub(crate) fn index(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<usize> {
    let refused = |why: &str| {
        InvalidOption::new_err(format!(
            "{what} must be a whole number >= 0, got {} ({why})",
            obj.repr().map(|r| r.to_string()).unwrap_or_default()
        ))
    };
    let integral = obj.is_instance_of::<PyInt>()
        || obj
            .py()
            .import("numpy")
            .and_then(|np| np.getattr("integer"))
            .and_then(|t| obj.is_instance(&t))
            .unwrap_or(false);
    if obj.is_instance_of::<PyBool>() || !integral {
        let why = if obj.is_instance_of::<PyFloat>() {
            "a float is not an index".to_owned()
        } else {
            format!("a {}", type_name(obj))
        };
        return Err(refused(&why));
    }
    let i: i128 = obj.extract().map_err(|_| refused("not an integer"))?;
    usize::try_from(i).map_err(|_| refused("negative or too large"))
}

/// Three real numbers `(x, y, z)` for `what`.
pub(crate) fn point(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<[f64; 3]> {
    let refused = || InvalidOption::new_err(format!("{what} must be three numbers (x, y, z)"));
    if obj.is_instance_of::<pyo3::types::PyString>() {
        return Err(refused());
    }
    let items: Vec<Bound<'_, PyAny>> = obj
        .try_iter()
        .map_err(|_| refused())?
        .collect::<PyResult<_>>()
        .map_err(|_| refused())?;
    if items.len() != 3 {
        return Err(refused());
    }
    let mut p = [0.0; 3];
    for (k, item) in items.iter().enumerate() {
        p[k] = real(item, what).map_err(|_| refused())?;
        if !p[k].is_finite() {
            return Err(InvalidOption::new_err(format!(
                "{what} must be finite, got {:?}",
                p
            )));
        }
    }
    Ok(p)
}

/// `numpy.asarray(x)` as an int64 array of indices: integer arrays as they are, float arrays
/// only when every value is a whole number (no silent truncation of 1.7 to 1), anything else
/// refused; `what` names the argument in errors.
pub(crate) fn index_array<'py>(x: &Bound<'py, PyAny>, what: &str) -> PyResult<Bound<'py, PyAny>> {
    let np = x.py().import("numpy")?;
    let a = np
        .call_method1("asarray", (x,))
        .map_err(|e| InvalidOption::new_err(format!("{what}: {}", e.value(x.py()))))?;
    let kind: String = a.getattr("dtype")?.getattr("kind")?.extract()?;
    match kind.as_str() {
        "i" | "u" => {}
        "f" => {
            let whole: bool = np
                .call_method1(
                    "all",
                    (np.call_method1("equal", (&a, np.call_method1("floor", (&a,))?))?,),
                )?
                .extract()?;
            if !whole {
                return Err(InvalidOption::new_err(format!(
                    "{what} must be whole-number vertex indices; got non-integer values (a \
                     float index is refused, not truncated)"
                )));
            }
        }
        _ => {
            return Err(InvalidOption::new_err(format!(
                "{what} must be an array of whole-number vertex indices, got dtype {}",
                a.getattr("dtype")?.str()?
            )));
        }
    }
    let kw = pyo3::types::PyDict::new(x.py());
    kw.set_item("dtype", "int64")?;
    np.call_method("ascontiguousarray", (&a,), Some(&kw))
}
