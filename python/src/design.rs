//! `balloon.design`: the rest shape whose static equilibrium under a gauge pressure is a target
//! surface given as arrays (`balloon design`'s job, `balloon_run::jobs::design`).

use crate::convert::{json_to_py, points_array};
use crate::errors::{BalloonError, InvalidOption, MeshError, SolverError, spelled};
use crate::options::{Use, mesh_spec, scenario_of};
use balloon_design::DesignParams;
use balloon_run::jobs::design::{DesignJob, run};
use balloon_scenario::design::{DESIGN_OPTIONS, OptionError, OptionValue, set_design_option};
use balloon_scenario::{Scenario, SystemKind};
use numpy::PyArrayMethods;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyTuple};

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

/// Sets design option `key` ([`DESIGN_OPTIONS`]) from the Python value `v` (a bool, a string,
/// or a number: int, float or a numpy scalar) with the scenario reader's checks
/// ([`set_design_option`]).
fn set_option(params: &mut DesignParams, key: &str, v: &Bound<'_, PyAny>) -> PyResult<()> {
    let shown = || v.repr().map(|r| r.to_string()).unwrap_or_default();
    let value = if v.is_instance_of::<PyBool>() {
        OptionValue::Bool(v.extract()?)
    } else if let Ok(text) = v.extract::<String>() {
        OptionValue::Text(text)
    } else {
        match crate::args::real(v, key) {
            Ok(x) => OptionValue::Number(x),
            // A value of no kind an option takes: say which kind this one takes.
            Err(e) => match set_design_option(params, key, &OptionValue::Number(f64::NAN)) {
                Err(OptionError::Expected(kind)) => {
                    return Err(InvalidOption::new_err(spelled(&format!(
                        "`{key}` must be {kind}, got {}",
                        shown()
                    ))));
                }
                _ => return Err(e),
            },
        }
    };
    match set_design_option(params, key, &value) {
        Ok(_) => Ok(()),
        Err(OptionError::Expected(kind)) => Err(InvalidOption::new_err(spelled(&format!(
            "`{key}` must be {kind}, got {}",
            shown()
        )))),
        Err(OptionError::Invalid(allowed)) => Err(InvalidOption::new_err(spelled(&format!(
            "`{key}` = {} is not allowed: it must be {allowed}",
            shown()
        )))),
    }
}

/// design(target_vertices, faces, pressure=None, **options)
/// --
///
/// Designs the rest shape whose static equilibrium under the gauge pressure `pressure` (Pa) is
/// the target surface (or, with `gas_amount=` instead of `pressure`, under an amount of
/// isothermal ideal gas `nRT = p_abs V` in J against the `ambient` pressure, 101325 Pa unless
/// given: its gauge pressure at the target is `gas_amount / V - ambient`) (`target_vertices` (n, 3) float64 in m, `faces` (m, 3) int: a closed,
/// outward-oriented mesh), and checks it by a forward static solve, as `balloon design` does
/// (docs/design.md). Options: the wall as `balloon inflate` takes it (`thickness`, `material`,
/// `young`, `poisson`, `mu`, ... and `material_preset`), the solve's options as a scenario's
/// `[design]` table takes them: `tolerance` (relative equilibrium residual, in (0, 1)),
/// `tangential_weight` (in [0, 1e6]), `fallback` ("unconverged" (default), "always" or "off":
/// the shape optimisation that minimises the distance of the forward equilibrium to the target
/// where the inverse has no exact answer; its record is `summary["inverse"]["fallback"]`),
/// `fallback_iterations` (1 to 100000), `accept_distance` (in [0, 1]: a design whose inverse
/// has no exact answer still answers the target, `summary["accepted"]`, when its forward check
/// lies within this fraction of the target's diagonal; 0 = only an exact design), `method`
/// ("gauss-newton" (default) or "lbfgs"),
/// `shape_weight` (the rest-mesh shape term's weight, in [0, 1e6], 0 = off), `shape_stages`
/// (1 to 20), `newton_polish` and `warm_start` (bools; `warm_start` also for the thickness
/// fit), `bending_weight`,
/// `inverse_bending_weight` (the rest-mesh bending term of D17, in [0, 1e6], 0 = off) and
/// `inverse_bending_stages` (1 to 20), `bending` (the wall's bending stiffness as a factor on a
/// plate's, in [0, 1e6], 0 = none, as `balloon.inflate`'s; docs/design.md D20),
/// `fit_thickness` (bool: after the rest shape, fit the
/// wall's thickness per face with that rest shape fixed, docs/design.md D18), `thickness_min`
/// and `thickness_max` (its bounds, m) and `thickness_iterations` (1 to 100000),
/// `conditioning` (bool: after the check, the smallest singular values of the inverse's
/// Jacobian at the rest shape, `summary["conditioning"]`, docs/design.md D19) with
/// `conditioning_modes` (1 to 64) and `conditioning_iterations` (1 to 1000); and `out` (a
/// folder for rest.obj, inflated.obj, distance.csv and summary.json, and rest.ply with a fitted
/// thickness; the parameters used are `summary["params"]`; a folder holding the files of an
/// earlier design is refused unless `overwrite` = True), `rest` ((n, 3) float64: a rest
/// shape to keep instead of designing one, with the target's faces; it is checked, and its
/// wall fitted with `fit_thickness`). Returns {"rest": (n, 3) float64,
/// "inflated": (n, 3) float64 (the check's equilibrium, rigidly aligned onto the target),
/// "thickness": (m,) float64 (the rest thickness per face: the fitted one with
/// `fit_thickness`, else the wall's), "conditioning_modes": (k, n, 3) float64 (the
/// conditioning report's singular vectors, unit norm each, in the order of
/// `summary["conditioning"]["smallest"]`; None without `conditioning`), "summary": dict (summary.json's keys; the fit's record is
/// `summary["thickness_fit"]`)}. A design that does not reach the pressure or the tolerance is
/// returned with `summary["converged"]` False (check it, or `summary["accepted"]` with
/// `accept_distance`): the best rest shape found. Errors:
/// `InvalidOption` naming the parameter, `MeshError` for the arrays or a target that cannot be
/// designed for, `SolverError` for a solve that failed. The GIL is released while it runs.
#[pyfunction]
#[pyo3(signature = (target_vertices, faces, pressure=None, **options))]
pub(crate) fn design<'py>(
    py: Python<'py>,
    target_vertices: &Bound<'py, PyAny>,
    faces: &Bound<'py, PyAny>,
    pressure: Option<&Bound<'py, PyAny>>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let pair = PyTuple::new(py, [target_vertices, faces])?;
    let (_, Some(target)) = mesh_spec(pair.as_any())?.split() else {
        return Err(MeshError::new_err("the target must be given as arrays"));
    };
    let wall = PyDict::new(py);
    wall.set_item("gas", "constant")?;
    if let Some(p) = pressure.filter(|p| !p.is_none()) {
        wall.set_item("pressure", p)?;
    }
    let mut params = DesignParams::default();
    let mut out = None;
    let mut overwrite = false;
    let (mut gas_amount, mut ambient) = (None, None);
    let mut rest = None;
    if let Some(options) = options {
        for (k, v) in options.iter() {
            let key: String = k.extract()?;
            match key.as_str() {
                k if DESIGN_OPTIONS.iter().any(|(name, _)| *name == k) => {
                    set_option(&mut params, k, &v)?;
                }
                "gas_amount" => {
                    let a = crate::args::real(&v, "gas_amount")?;
                    if !(a > 0.0 && a <= 1e12) {
                        return Err(InvalidOption::new_err(format!(
                            "`gas_amount` = {a} is not allowed: it must be a positive amount nRT \
                             in J, at most 1e12"
                        )));
                    }
                    gas_amount = Some(a);
                }
                "ambient" => {
                    let a = crate::args::real(&v, "ambient")?;
                    if !(a > 0.0 && a <= 1e7) {
                        return Err(InvalidOption::new_err(format!(
                            "`ambient` = {a} is not allowed: it must be a positive pressure in \
                             Pa, at most 1e7"
                        )));
                    }
                    ambient = Some(a);
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
                "overwrite" => {
                    if !v.is_instance_of::<PyBool>() {
                        return Err(InvalidOption::new_err("`overwrite` must be True or False"));
                    }
                    overwrite = v.extract::<bool>()?;
                }
                "rest" if !v.is_none() => {
                    let pair = PyTuple::new(py, [&v, faces])?;
                    let (_, Some(mesh)) = mesh_spec(pair.as_any())?.split() else {
                        return Err(MeshError::new_err("`rest` must be an (n, 3) array"));
                    };
                    rest = Some(mesh);
                }
                "rest" => {}
                k if WALL_KEYS.contains(&k) && k != "pressure" => wall.set_item(k, v)?,
                k => {
                    let mut known: Vec<&str> = WALL_KEYS
                        .iter()
                        .copied()
                        .filter(|n| *n != "pressure")
                        .collect();
                    known.extend(DESIGN_OPTIONS.iter().map(|(name, _)| *name));
                    known.extend(["gas_amount", "ambient", "rest", "out", "overwrite"]);
                    return Err(InvalidOption::new_err(format!(
                        "unknown option `{k}` (the options of design are {})",
                        known.join(", ")
                    )));
                }
            }
        }
    }
    let given = pressure.is_some_and(|p| !p.is_none());
    match (given, gas_amount, ambient) {
        (false, None, _) => {
            return Err(InvalidOption::new_err(
                "give the load: `pressure` (Pa) or `gas_amount` (J)",
            ));
        }
        (true, Some(_), _) => {
            return Err(InvalidOption::new_err(
                "give either `pressure` or `gas_amount`, not both",
            ));
        }
        (_, None, Some(_)) => {
            return Err(InvalidOption::new_err(
                "`ambient` is the ambient pressure of `gas_amount`, which is not given",
            ));
        }
        _ => {}
    }
    let (scenario, _, _) = scenario_of(SystemKind::Shell, None, Some(&wall), Use::Stepwise)?;
    let Scenario::Shell(shell) = scenario else {
        return Err(BalloonError::new_err("not a shell scenario"));
    };
    let mut job = DesignJob::new(target, "<arrays>", shell.gas.pressure);
    job.gas_amount = gas_amount;
    if let Some(a) = ambient {
        job.ambient = a;
    }
    job.thickness = shell.shell.thickness;
    job.material = shell.shell.material.clone();
    job.params = params;
    job.out = out;
    job.overwrite = overwrite;
    job.rest = rest;
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
    let thickness = match &result.design.thickness {
        Some(fit) => fit.thickness.clone(),
        None => vec![result.summary.thickness; result.summary.triangles],
    };
    d.set_item("thickness", numpy::PyArray1::from_vec(py, thickness))?;
    let modes = match &result.design.conditioning {
        Some(c) if !c.modes.is_empty() => {
            let flat: Vec<f64> = c.modes.concat();
            let n = c.modes[0].len() / 3;
            Some(
                numpy::PyArray1::from_vec(py, flat)
                    .reshape([c.modes.len(), n, 3])?
                    .into_any(),
            )
        }
        _ => None,
    };
    d.set_item("conditioning_modes", modes)?;
    let summary =
        serde_json::to_value(&result.summary).map_err(|e| BalloonError::new_err(e.to_string()))?;
    d.set_item("summary", json_to_py(py, &summary)?)?;
    Ok(d)
}
