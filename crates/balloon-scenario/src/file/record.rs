//! The recorded scenario of a run (`OUT/scenario.toml`): every key with its value (given or
//! default), the mesh path absolute, the program version; `balloon run` of it repeats the run.

use crate::gas::GasControl;
use crate::keys::{Kind, Literals, Recorded};
use crate::scenario::Scenario;
use crate::shell::ShellScenario;
use balloon::shell::{self, ShellMaterial, ShellMaterialModel};
use std::path::PathBuf;
use toml_edit::Value;

/// A string as a TOML basic string.
fn toml_string(s: &str) -> String {
    Value::from(s).to_string().trim().to_owned()
}

/// A value's text as a TOML number: an integer if it is one, else a float in round-trip form
/// (so the recorded run reads back the same `f64`); a text that is no number as a string.
fn toml_number(raw: &str) -> String {
    let raw = raw.trim();
    if let Ok(i) = raw.parse::<i64>() {
        return i.to_string();
    }
    match raw.parse::<f64>() {
        Ok(f) if f.is_finite() => format!("{f:?}"),
        _ => toml_string(raw),
    }
}

/// The recorded scenario of `scenario` (the text of `scenario.toml`): every key of its system
/// with its value, written as its user wrote it where `literals` has the text (so `2.0` stays a
/// float), else from the value; a key without a value and without a default (e.g. `pump_rate`,
/// whose default follows the body) is written as a comment. Where and how the output is
/// written (`out`, `overwrite`, `json`) is not part of it.
pub fn record(scenario: &Scenario, literals: &Literals) -> String {
    if let Scenario::Connect(c) = scenario
        && matches!(c.shell.gas.model, GasControl::Pump)
    {
        // Connected balloons hold the ideal gas (`ConnectScenario::build`): a `gas` left at
        // the shell's default (the pump), or given as the pump, is recorded as what ran.
        let mut ran = c.clone();
        ran.shell.gas.model = GasControl::Ideal;
        let mut literals = literals.clone();
        literals.remove("gas");
        return record(&Scenario::Connect(ran), &literals);
    }
    let kind = scenario.kind();
    let version = env!("CARGO_PKG_VERSION");
    let mut s = format!(
        "# The scenario of a `balloon` {version} run, every value resolved (defaults explicit).\n\
         # Repeat it with: balloon run scenario.toml --out OTHER_DIR\n\
         # (the output folder, --overwrite and --json are not part of the scenario).\n\n\
         [system]\nkind = {}\nversion = {}\n",
        toml_string(&kind.to_string()),
        toml_string(version),
    );
    let mut table = "system";
    for key in Scenario::keys(kind).iter().filter(|k| k.recorded) {
        let Some(value) = scenario.recorded(key.name) else {
            continue;
        };
        if key.kind == Kind::Tables {
            if let Recorded::Tables(specs) = value {
                for spec in specs {
                    let spec = crate::selection::rewrite_paths(key.name, &spec, None);
                    s.push_str(&format!(
                        "\n[[{}]]\nspec = {}\n",
                        key.table,
                        toml_string(&spec)
                    ));
                    table = key.table;
                }
            }
            continue;
        }
        if key.table != table {
            table = key.table;
            s.push_str(&format!("\n[{table}]\n"));
        }
        let line = match value {
            Recorded::Bool(b) => Some(b.to_string()),
            Recorded::Unset | Recorded::Tables(_) => None,
            Recorded::Text(canonical) => {
                let raw = literals.get(key.name).map_or(canonical, <[String]>::to_vec);
                Some(match key.kind {
                    Kind::Number | Kind::NumberOrText => toml_number(&raw.join(",")),
                    Kind::Numbers => format!(
                        "[{}]",
                        raw.iter()
                            .map(|r| toml_number(r))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                    Kind::Path if !raw.concat().starts_with("builtin") => {
                        let p = PathBuf::from(raw.concat());
                        toml_string(&std::path::absolute(&p).unwrap_or(p).to_string_lossy())
                    }
                    _ => toml_string(&raw.join(",")),
                })
            }
        };
        match line {
            Some(v) => s.push_str(&format!("{} = {v}\n", key.key)),
            None => s.push_str(&format!(
                "# {} = (not set: the flag's default applies)\n",
                key.key
            )),
        }
    }
    s
}

/// The recorded scenario `text` of a shell run with the defaults the run resolved written in,
/// where the record says "(not set: the flag's default applies)": the material and its
/// modulus and Poisson's ratio (the StVK default), the shell-volume projection (global, or off
/// for a membrane) and the pump's rate (0.7 rest volumes per second of this body,
/// `rest_gas_volume` m^3), so that `scenario.toml` and the summary state every physical value
/// of the run. The values are written in round-trip form, so re-running the record repeats the
/// run bit for bit.
pub fn resolve_shell_record(
    text: &str,
    scenario: &ShellScenario,
    material: &ShellMaterialModel,
    rest_gas_volume: f64,
) -> String {
    use crate::gas::GasControl;
    let spec = &scenario.shell.material;
    let mut values: Vec<(&str, String)> = Vec::new();
    if spec.material.is_none() && spec.material_preset.is_none() {
        values.push(("material", "\"stvk\"".into()));
    }
    if matches!(material, ShellMaterialModel::Solid(_)) {
        values.push(("young", format!("{:?}", shell::DEFAULT_YOUNG)));
        values.push(("poisson", format!("{:?}", shell::DEFAULT_POISSON)));
    }
    let projection = if material.thickness_follows_stretch() {
        "off"
    } else {
        "global"
    };
    values.push(("volume_projection", format!("\"{projection}\"")));
    if matches!(
        scenario.gas.model,
        GasControl::Pump | GasControl::SupplyPump
    ) {
        let rate = shell::DEFAULT_PUMP_VOLUMES_PER_SECOND * rest_gas_volume;
        values.push(("pump_rate", format!("{rate:?}")));
    }
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        let unset = values.iter().find(|(key, _)| {
            line.strip_prefix("# ")
                .and_then(|l| l.strip_prefix(key))
                .is_some_and(|l| l == " = (not set: the flag's default applies)")
        });
        match unset {
            // Written as if given, so that the record of a repeat is the same text.
            Some((key, value)) => out.push_str(&format!("{key} = {value}")),
            None => out.push_str(line),
        }
        out.push('\n');
    }
    out
}

/// A recorded scenario's TOML `text` as a JSON object (keys in the file's order), for a
/// summary; `None` for a text that does not parse (which [`record`] never writes).
pub fn record_json(text: &str) -> Option<serde_json::Value> {
    let doc = text.parse::<toml_edit::DocumentMut>().ok()?;
    Some(table_json(doc.as_table()))
}

fn table_json(t: &toml_edit::Table) -> serde_json::Value {
    serde_json::Value::Object(
        t.iter()
            .filter_map(|(k, item)| item_json(item).map(|v| (k.to_owned(), v)))
            .collect(),
    )
}

fn item_json(item: &toml_edit::Item) -> Option<serde_json::Value> {
    use toml_edit::Item;
    match item {
        Item::None => None,
        Item::Value(v) => Some(value_json(v)),
        Item::Table(t) => Some(table_json(t)),
        Item::ArrayOfTables(a) => {
            Some(serde_json::Value::Array(a.iter().map(table_json).collect()))
        }
    }
}

fn value_json(v: &Value) -> serde_json::Value {
    use serde_json::Value as J;
    match v {
        Value::String(s) => J::from(s.value().as_str()),
        Value::Integer(i) => J::from(*i.value()),
        Value::Float(f) => serde_json::Number::from_f64(*f.value()).map_or(J::Null, J::Number),
        Value::Boolean(b) => J::from(*b.value()),
        Value::Datetime(d) => J::from(d.value().to_string()),
        Value::Array(a) => J::Array(a.iter().map(value_json).collect()),
        Value::InlineTable(t) => J::Object(
            t.iter()
                .map(|(k, v)| (k.to_owned(), value_json(v)))
                .collect(),
        ),
    }
}
