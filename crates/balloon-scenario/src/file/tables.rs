//! The tables of `[[anchors]]` and `[[loads]]` in a scenario file: a selector and options as
//! keys (`below = { axis = "z", value = 0.01 }`, `stiffness = 200`), or the spec itself as
//! `spec`; each is turned into its spec (`below:z:0.01@200.0`), with file paths joined to the
//! scenario file's folder.

use std::path::Path;
use toml_edit::{Item, Value};

/// A number of the file as text (floats in Rust's round-trip form).
pub(super) fn number_text(v: &toml_edit::Value) -> Option<String> {
    match v {
        toml_edit::Value::Integer(i) => Some(i.value().to_string()),
        toml_edit::Value::Float(f) => Some(format!("{:?}", f.value())),
        _ => None,
    }
}

/// A selector key of an `[[anchors]]` or `[[loads]]` table as a selector spec
/// (`crate::selection::parse_selector`), `None` when `key` is not a selector key.
fn selector_value(key: &str, v: &Item, base: &Path) -> Option<Result<String, String>> {
    let list = |v: &Item| -> Result<Vec<String>, String> {
        v.as_array()
            .ok_or_else(|| "expected an array".to_owned())?
            .iter()
            .map(|x| number_text(x).ok_or_else(|| "expected numbers".to_owned()))
            .collect()
    };
    Some(match key {
        "indices" => list(v).map(|l| format!("indices:{}", l.join(","))),
        "box" => list(v).map(|l| format!("box:{}", l.join(","))),
        "vertices_file" => v
            .as_str()
            .map(|p| format!("file:{}", base.join(p).display()))
            .ok_or_else(|| "expected a path (relative to the scenario file)".to_owned()),
        "vertex_group" => {
            let t = v.as_inline_table();
            let file = t.and_then(|t| t.get("file")).and_then(Value::as_str);
            let property = t.and_then(|t| t.get("property")).and_then(Value::as_str);
            match (file, property, t.map_or(0, |t| t.len())) {
                (Some(f), Some(p), 2) => Ok(format!("ply:{}:{p}", base.join(f).display())),
                _ => Err(
                    "expected { file = \"PATH.ply\" (relative to the scenario file), property = \"NAME\" }"
                        .to_owned(),
                ),
            }
        }
        "below" | "above" => {
            let t = v.as_inline_table();
            let axis = t.and_then(|t| t.get("axis")).and_then(Value::as_str);
            let value = t.and_then(|t| t.get("value")).and_then(number_text);
            match (axis, value, t.map_or(0, |t| t.len())) {
                (Some(a), Some(x), 2) => Ok(format!("{key}:{a}:{x}")),
                _ => Err("expected { axis = \"x\"|\"y\"|\"z\", value = M }".to_owned()),
            }
        }
        _ => return None,
    })
}

/// The value of the flag `id` (`pin` or `load`) of one `[[anchors]]` / `[[loads]]` table, or
/// the span and key of what is wrong. A `spec` key is the flag's value as written on the
/// command line (its `file:` path relative to the scenario file).
pub(super) fn table_value(
    id: &str,
    table: &toml_edit::Table,
    base: &Path,
) -> Result<String, (Option<std::ops::Range<usize>>, String, String)> {
    let mut selector: Option<String> = None;
    let mut parts: Vec<String> = Vec::new();
    let mut stiffness = None;
    let mut raw = None;
    let loads = id == "load";
    for (key, item) in table.iter() {
        let span = table.key(key).and_then(|k| k.span());
        let fail = |m: String| (span.clone(), key.to_owned(), m);
        if key == "spec" {
            let s = item
                .as_str()
                .ok_or_else(|| fail("expected a string".into()))?;
            raw = Some(crate::selection::rewrite_paths(id, s, Some(base)));
            continue;
        }
        if let Some(sel) = selector_value(key, item, base) {
            if selector.is_some() {
                return Err(fail(
                    "a second selector (one of indices, vertices_file, vertex_group, below, above, box)"
                        .into(),
                ));
            }
            selector = Some(sel.map_err(fail)?);
            continue;
        }
        let number = || {
            item.as_value()
                .and_then(number_text)
                .ok_or_else(|| fail("expected a number".into()))
        };
        match key {
            "stiffness" => stiffness = Some(number()?),
            "start" | "end" if loads => parts.push(format!("{key}={}", number()?)),
            "gravity" | "force" | "grab" if loads => {
                let v: Vec<String> = item
                    .as_array()
                    .map(|a| a.iter().filter_map(number_text).collect())
                    .filter(|v: &Vec<String>| v.len() == 3)
                    .ok_or_else(|| fail("expected an array of 3 numbers".into()))?;
                parts.insert(0, format!("{key}={}", v.join(",")));
            }
            "per" if loads => {
                let s = item
                    .as_str()
                    .ok_or_else(|| fail("expected a string".into()))?;
                parts.push(format!("per={s}"));
            }
            _ => {
                let known = if loads {
                    "gravity, force, grab, per, stiffness, start, end, indices, vertices_file, below, above, box, spec"
                } else {
                    "indices, vertices_file, below, above, box, stiffness, spec"
                };
                return Err(fail(format!("unknown key (the keys here are {known})")));
            }
        }
    }
    let whole = |m: &str| (table.span(), String::new(), m.to_owned());
    if let Some(r) = raw {
        if selector.is_some() || stiffness.is_some() || !parts.is_empty() {
            return Err(whole("`spec` stands alone"));
        }
        return Ok(r);
    }
    if loads {
        if let Some(k) = stiffness {
            parts.push(format!("stiffness={k}"));
        }
        if let Some(sel) = selector {
            parts.push(format!("on={sel}"));
        }
        Ok(parts.join(";"))
    } else {
        let sel = selector
            .ok_or_else(|| whole("no selector (indices, vertices_file, below, above or box)"))?;
        Ok(match stiffness {
            Some(k) => format!("{sel}@{k}"),
            None => sel,
        })
    }
}
