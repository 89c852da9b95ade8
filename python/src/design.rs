//! `balloon.design`: the rest shape whose static equilibrium under a gauge pressure is a target
//! surface given as arrays (`balloon design`'s job, `balloon_run::jobs::design`).

use crate::convert::{json_to_py, points_array};
use crate::errors::{BalloonError, InvalidOption, MeshError, SolverError, spelled};
use crate::options::{Use, mesh_spec, scenario_of};
use balloon_run::jobs::design::{DesignJob, run};
use balloon_scenario::{Scenario, SystemKind};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

/// The keyword options of `design` that are the shell's wall and load keys (checked as
/// `balloon inflate` checks them).
const WALL_KEYS: &[&str] = &[
    "pressure",
    "thickness",
    "material",
    "material_preset",
    "young",
    "poisson",
    "mu",
    "c1",
    "c2",
    "jm",
    "ogden_mu",
    "ogden_alpha",
    "yeoh",
];

/// The error of a design job as a `BalloonError` subclass: a parameter out of range
/// (`InvalidOption`), a target that cannot be designed for (`MeshError`), a solve that failed
/// (`SolverError`).
fn design_err(e: anyhow::Error) -> PyErr {
    let text = spelled(&format!("{e:#}"));
    match e.downcast_ref::<balloon_design::DesignError>() {
        Some(balloon_design::DesignError::InvalidParameter { .. }) => InvalidOption::new_err(text),
        Some(balloon_design::DesignError::Target(_)) => MeshError::new_err(text),
        Some(_) => SolverError::new_err(text),
        None if text.starts_with("target") => MeshError::new_err(text),
        None if text.starts_with("material") => InvalidOption::new_err(text),
        None => BalloonError::new_err(text),
    }
}

/// A real keyword option of the design solve, in `[lo, hi]`.
fn real_in(v: &Bound<'_, PyAny>, name: &str, lo: f64, hi: f64) -> PyResult<f64> {
    let x = crate::args::real(v, name)?;
    if !(x >= lo && x <= hi) {
        return Err(InvalidOption::new_err(format!(
            "`{name}` = {x} is not allowed: it must lie in [{lo}, {hi}]"
        )));
    }
    Ok(x)
}

/// design(target_vertices, faces, pressure, **options)
/// --
///
/// Designs the rest shape whose static equilibrium under the gauge pressure `pressure` (Pa) is
/// the target surface (`target_vertices` (n, 3) float64 in m, `faces` (m, 3) int: a closed,
/// outward-oriented mesh), and checks it by a forward static solve, as `balloon design` does
/// (docs/design.md). Options: the wall as `balloon inflate` takes it (`thickness`, `material`,
/// `young`, `poisson`, `mu`, ... and `material_preset`), `tolerance` (relative equilibrium
/// residual, in (0, 1)), `tangential_weight` (>= 0), `fallback` ("unconverged" (default),
/// "always" or "off": the shape optimisation that minimises the distance of the forward
/// equilibrium to the target where the inverse has no exact answer; its record is
/// `summary["inverse"]["fallback"]`), `fallback_iterations` (1 to 100000) and `out` (a folder
/// for rest.obj, inflated.obj, distance.csv and summary.json). Returns {"rest": (n, 3) float64, "inflated":
/// (n, 3) float64 (the check's equilibrium, rigidly aligned onto the target), "summary": dict
/// (summary.json's keys)}. A design that does not reach the pressure or the tolerance is
/// returned with `summary["converged"]` False (check it): the best rest shape found. Errors:
/// `InvalidOption` naming the parameter, `MeshError` for the arrays or a target that cannot be
/// designed for, `SolverError` for a solve that failed. The GIL is released while it runs.
#[pyfunction]
#[pyo3(signature = (target_vertices, faces, pressure, **options))]
pub(crate) fn design<'py>(
    py: Python<'py>,
    target_vertices: &Bound<'py, PyAny>,
    faces: &Bound<'py, PyAny>,
    pressure: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let pair = PyTuple::new(py, [target_vertices, faces])?;
    let (_, Some(target)) = mesh_spec(pair.as_any())?.split() else {
        return Err(MeshError::new_err("the target must be given as arrays"));
    };
    let wall = PyDict::new(py);
    wall.set_item("gas", "constant")?;
    wall.set_item("pressure", pressure)?;
    let (mut tolerance, mut tangential_weight, mut out) = (None, 0.0, None);
    let (mut fallback, mut fallback_iterations) = (None, None);
    if let Some(options) = options {
        for (k, v) in options.iter() {
            let key: String = k.extract()?;
            match key.as_str() {
                "tolerance" => {
                    tolerance = Some(real_in(
                        &v,
                        "tolerance",
                        f64::MIN_POSITIVE,
                        1.0 - f64::EPSILON,
                    )?)
                }
                "tangential_weight" => {
                    tangential_weight = real_in(&v, "tangential_weight", 0.0, 1e6)?
                }
                "fallback" => {
                    let text: String = v.extract().map_err(|_| {
                        InvalidOption::new_err(
                            "`fallback` must be \"unconverged\", \"always\" or \"off\"",
                        )
                    })?;
                    fallback = Some(
                        text.parse::<balloon_design::FallbackMode>()
                            .map_err(|e| InvalidOption::new_err(format!("`fallback`: {e}")))?,
                    );
                }
                "fallback_iterations" => {
                    let n = real_in(&v, "fallback_iterations", 1.0, 1e5)?;
                    if n.fract() != 0.0 {
                        return Err(InvalidOption::new_err(format!(
                            "`fallback_iterations` = {n} is not a whole number"
                        )));
                    }
                    fallback_iterations = Some(n as usize);
                }
                "out" if !v.is_none() => {
                    let os = py.import("os")?;
                    out = Some(std::path::PathBuf::from(
                        os.call_method1("fspath", (&v,))
                            .and_then(|p| p.extract::<String>())
                            .map_err(|_| InvalidOption::new_err("`out` must be a path"))?,
                    ));
                }
                "out" => {}
                k if WALL_KEYS.contains(&k) && k != "pressure" => wall.set_item(k, v)?,
                k => {
                    let mut known: Vec<&str> = WALL_KEYS
                        .iter()
                        .copied()
                        .filter(|n| *n != "pressure")
                        .collect();
                    known.extend([
                        "tolerance",
                        "tangential_weight",
                        "fallback",
                        "fallback_iterations",
                        "out",
                    ]);
                    return Err(InvalidOption::new_err(format!(
                        "unknown option `{k}` (the options of design are {})",
                        known.join(", ")
                    )));
                }
            }
        }
    }
    let (scenario, _, _) = scenario_of(SystemKind::Shell, None, Some(&wall), Use::Stepwise)?;
    let Scenario::Shell(shell) = scenario else {
        return Err(BalloonError::new_err("not a shell scenario"));
    };
    let mut job = DesignJob::new(target, "<arrays>", shell.gas.pressure);
    job.thickness = shell.shell.thickness;
    job.material = shell.shell.material.clone();
    if let Some(t) = tolerance {
        job.tolerance = t;
    }
    job.tangential_weight = tangential_weight;
    if let Some(f) = fallback {
        job.fallback = f;
    }
    if let Some(n) = fallback_iterations {
        job.fallback_iterations = n;
    }
    job.out = out;
    let result = py.detach(move || run(&job)).map_err(design_err)?;
    if result.interrupted.is_some() {
        return Err(crate::errors::to_py_err(anyhow::Error::new(
            balloon_run::interrupt::Interrupted {
                signal: result.interrupted.unwrap_or(2),
                steps: result.design.inverse.iterations
                    + result
                        .design
                        .inverse
                        .fallback
                        .as_ref()
                        .map_or(0, |f| f.iterations),
            },
        )));
    }
    let d = PyDict::new(py);
    d.set_item("rest", points_array(py, &result.design.rest)?)?;
    d.set_item(
        "inflated",
        points_array(py, &result.design.check.positions)?,
    )?;
    let summary =
        serde_json::to_value(&result.summary).map_err(|e| BalloonError::new_err(e.to_string()))?;
    d.set_item("summary", json_to_py(py, &summary)?)?;
    Ok(d)
}
