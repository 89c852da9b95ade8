//! The keys of a shell scenario (`kind = "shell"`, `balloon inflate`), in the order the
//! recorded scenario writes them, with their ranges.

use super::types::ShellScenario;
use crate::keys::{
    Key, Kind, Recorded, anchor_keys, choice, choice_opt, flag, no_check, output_keys, path_opt,
    real, real_opt, reals_opt, whole,
};
use crate::keys::{PIN_STIFFNESS, SCALE, STEPS, mesh_path, mesh_transform};
use crate::range::End::{Closed, Open};
use crate::range::{Real, ValueError, Whole};
use crate::value::{SetError, Value, parse_choice};

/// A modulus, Pa (its sign is the model's check): [-1e12, 1e12].
const MODULUS: Real = Real::new(Closed(-1e12), Closed(1e12));

/// A real number with no range of its own (checked with the keys it belongs to).
macro_rules! real_opt_free {
    ($t:literal, $k:literal, $n:literal, $($f:ident).+) => {
        Key {
            table: $t, key: $k, name: $n, kind: Kind::Number, recorded: true,
            set: |s, v| { s.$($f).+ = Some(v.real()?); Ok(()) },
            check: no_check,
            get: |s| Recorded::maybe(s.$($f).+),
            copy: |d, s| d.$($f).+ = s.$($f).+,
        }
    };
}

/// The `thickness_rule` key: `"AXIS:FROM:TO"` or `{ axis, from, to }`.
pub(crate) fn set_rule(v: &Value) -> Result<crate::selection::LinearRule, SetError> {
    let text = rule_text(v)?;
    crate::selection::parse_rule(&text)
        .map_err(|e| SetError::Value(ValueError::new("thickness_rule", text.clone(), Some(e))))
}

/// A rule's value as its `AXIS:FROM:TO` text.
pub(crate) fn rule_text(v: &Value) -> Result<String, SetError> {
    match v {
        Value::Text(s) => Ok(s.clone()),
        Value::Table(t) => {
            let get = |k: &str| t.iter().find(|(n, _)| n == k).map(|(_, v)| v);
            let axis = get("axis").and_then(|v| v.text().ok());
            let number = |v: Option<&Value>| match v {
                Some(n @ (Value::Int(_) | Value::Float(_))) => Some(n.literal()),
                _ => None,
            };
            match (axis, number(get("from")), number(get("to")), t.len()) {
                (Some(a), Some(f), Some(to), 3) => Ok(format!("{a}:{f}:{to}")),
                _ => Err(SetError::Type(
                    "expected { axis = \"x\"|\"y\"|\"z\", from = M, to = M } (m) or \"AXIS:FROM:TO\""
                        .to_owned(),
                )),
            }
        }
        _ => Err(SetError::Type(
            v.expected("a table { axis, from, to } or a string AXIS:FROM:TO"),
        )),
    }
}

/// Every key of a shell scenario, in the order the recorded scenario writes them.
pub static SHELL_KEYS: &[Key<ShellScenario>] = &{
    let [
        out,
        overwrite,
        json,
        format,
        frame_every,
        render,
        color,
        gif,
        pov,
        image_size,
        color_range,
    ] = output_keys!(ShellScenario, STEPS);
    let [anchors, loads] = anchor_keys!(ShellScenario);
    [
        mesh_path!(ShellScenario, mesh.path),
        real!("mesh", "scale", "scale", SCALE, mesh.scale),
        mesh_transform!(mesh.transform),
        choice_opt!(
            "shell",
            "material",
            "material",
            true,
            shell.material.material
        ),
        choice_opt!(
            "shell",
            "material_preset",
            "material_preset",
            true,
            shell.material.material_preset
        ),
        real_opt!("shell", "young", "young", MODULUS, shell.material.young),
        real_opt!(
            "shell",
            "poisson",
            "poisson",
            Real::new(Closed(-1e3), Closed(1e3)),
            shell.material.poisson
        ),
        real_opt!("shell", "mu", "mu", MODULUS, shell.material.mu),
        real_opt!("shell", "c1", "c1", MODULUS, shell.material.c1),
        real_opt!("shell", "c2", "c2", MODULUS, shell.material.c2),
        real_opt!(
            "shell",
            "jm",
            "jm",
            Real::new(Closed(-1e6), Closed(1e6)),
            shell.material.jm
        ),
        reals_opt!(
            "shell",
            "ogden_mu",
            "ogden_mu",
            MODULUS,
            shell.material.ogden_mu
        ),
        reals_opt!(
            "shell",
            "ogden_alpha",
            "ogden_alpha",
            Real::new(Closed(-100.0), Closed(100.0)),
            shell.material.ogden_alpha
        ),
        reals_opt!("shell", "yeoh", "yeoh", MODULUS, shell.material.yeoh),
        real!(
            "shell",
            "thickness",
            "thickness",
            crate::selection::thickness::THICKNESS,
            shell.thickness
        ),
        path_opt!(
            "shell",
            "thickness_file",
            "thickness_file",
            true,
            shell.thickness_file
        ),
        Key {
            table: "shell",
            key: "thickness_rule",
            name: "thickness_rule",
            kind: Kind::Rule,
            recorded: true,
            set: |s, v| {
                s.shell.thickness_rule = Some(set_rule(v)?);
                Ok(())
            },
            check: no_check,
            get: |s| Recorded::maybe(s.shell.thickness_rule),
            copy: |d, s| d.shell.thickness_rule = s.shell.thickness_rule,
        },
        real_opt!(
            "shell",
            "pin_stiffness",
            "pin_stiffness",
            PIN_STIFFNESS,
            shell.pin_stiffness
        ),
        real!(
            "shell",
            "density",
            "density",
            Real::new(Open(0.0), Closed(1e5)),
            shell.density
        ),
        real!(
            "shell",
            "bending",
            "bending",
            Real::new(Closed(0.0), Closed(1e6)),
            shell.bending
        ),
        choice_opt!(
            "shell",
            "volume_projection",
            "volume_projection",
            false,
            shell.volume_projection
        ),
        choice!("gas", "model", "gas", false, gas.model),
        real!(
            "gas",
            "pressure",
            "pressure",
            Real::new(Closed(-1e7), Closed(1e7)),
            gas.pressure
        ),
        real!(
            "gas",
            "ambient",
            "ambient",
            Real::new(Closed(0.0), Closed(1e7)),
            gas.ambient
        ),
        real_opt!(
            "gas",
            "pump_rate",
            "pump_rate",
            Real::new(Closed(0.0), Closed(100.0)),
            gas.pump_rate
        ),
        real_opt_free!("gas", "gamma", "gamma", gas.laws.gamma),
        real_opt_free!(
            "gas",
            "leak_conductance",
            "leak_conductance",
            gas.laws.leak_conductance
        ),
        real_opt_free!(
            "gas",
            "supply_pressure",
            "supply_pressure",
            gas.laws.supply_pressure
        ),
        real_opt!(
            "gas",
            "volume_ratio",
            "volume_ratio",
            Real::new(Open(0.0), Closed(1e3)),
            gas.volume_ratio
        ),
        Key {
            table: "gas",
            key: "volume_ratios",
            name: "volume_ratios",
            kind: Kind::Text,
            recorded: true,
            set: |s, v| {
                s.gas.volume_ratios = Some(parse_choice("volume_ratios", v.text()?, true)?);
                Ok(())
            },
            check: no_check,
            get: |s| Recorded::maybe(s.gas.volume_ratios.as_ref()),
            copy: |d, s| d.gas.volume_ratios.clone_from(&s.gas.volume_ratios),
        },
        real!("run", "dt", "dt", Real::new(Open(0.0), Closed(1.0)), run.dt),
        whole!("run", "steps", "steps", STEPS, run.steps),
        flag!("run", "static", "static", run.static_solve),
        flag!("run", "stability", "stability", run.stability),
        flag!(
            "run",
            "until_converged",
            "until_converged",
            run.until_converged
        ),
        real!(
            "run",
            "speed_tol",
            "speed_tol",
            Real::new(Open(0.0), Closed(1e3)),
            run.speed_tol
        ),
        real!(
            "run",
            "volume_tol",
            "volume_tol",
            Real::new(Open(0.0), Open(1.0)),
            run.volume_tol
        ),
        real!(
            "run",
            "mass_damping",
            "mass_damping",
            Real::new(Closed(0.0), Closed(1e6)),
            run.mass_damping
        ),
        real!(
            "run",
            "stiffness_damping",
            "stiffness_damping",
            Real::new(Closed(0.0), Closed(10.0)),
            run.stiffness_damping
        ),
        whole!(
            "run",
            "newton_iters",
            "newton_iters",
            Whole::new(1, balloon::integrate::implicit::MAX_NEWTON_ITERATIONS),
            run.newton_iters
        ),
        real!(
            "run",
            "newton_tol",
            "newton_tol",
            Real::new(Closed(0.0), Closed(f64::INFINITY))
                .because("must be a finite tolerance >= 0 (0 runs the paper's fixed iterations)"),
            run.newton_tol
        ),
        choice!(
            "run",
            "linear_solver",
            "linear_solver",
            true,
            run.linear_solver
        ),
        choice!("run", "tangent", "tangent", true, run.tangent),
        choice!(
            "run",
            "pcg_preconditioner",
            "pcg_preconditioner",
            true,
            run.pcg_preconditioner
        ),
        real!(
            "run",
            "cg_tol",
            "cg_tol",
            Real::new(Open(0.0), Open(1.0)),
            run.cg_tol
        ),
        real!(
            "run",
            "inexact_forcing",
            "inexact_forcing",
            Real::new(Closed(0.0), Closed(1.0)),
            run.inexact_forcing
        ),
        whole!(
            "run",
            "cg_max_iters",
            "cg_max_iters",
            Whole::new(1, 1_000_000),
            run.cg_max_iters
        ),
        Key {
            table: "run",
            key: "follower_term",
            name: "follower_term",
            kind: Kind::Switch,
            recorded: true,
            set: |s, v| {
                s.run.follower_term = Some(v.boolean()?);
                Ok(())
            },
            check: no_check,
            get: |s| s.run.follower_term.map_or(Recorded::Unset, Recorded::Bool),
            copy: |d, s| d.run.follower_term = s.run.follower_term,
        },
        Key {
            table: "run",
            key: "thickness_prediction",
            name: "thickness_prediction",
            kind: Kind::Switch,
            recorded: true,
            set: |s, v| {
                s.run.thickness_prediction = Some(v.boolean()?);
                Ok(())
            },
            check: no_check,
            get: |s| {
                s.run
                    .thickness_prediction
                    .map_or(Recorded::Unset, Recorded::Bool)
            },
            copy: |d, s| d.run.thickness_prediction = s.run.thickness_prediction,
        },
        out,
        overwrite,
        json,
        format,
        frame_every,
        render,
        color,
        gif,
        pov,
        image_size,
        color_range,
        anchors,
        loads,
    ]
};
