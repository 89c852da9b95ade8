//! JSON scenario files (`balloon run s.json`): the same tables and keys as a TOML scenario,
//! written as a JSON object whose members are objects (`"mesh": {"path": "..."}` for `[mesh]`)
//! or arrays of objects (`"anchors": [{"below": {"axis": "z", "value": 0.01}}]` for
//! `[[anchors]]`). The file is turned into TOML text ([`to_toml`]), with a map from each TOML
//! line back to the JSON line it came from, so that every error names the JSON file's line.
//!
//! ```
//! let json = "{\n  \"run\": {\"steps\": 5},\n  \"anchors\": [\n    {\"indices\": [1, 2]}\n  ]\n}\n";
//! let c = balloon_scenario::file::json::to_toml(json).unwrap();
//! assert_eq!(c.toml, "[run]\nsteps = 5\n[[anchors]]\nindices = [1, 2]\n");
//! assert_eq!(c.lines, vec![2, 2, 4, 4]); // JSON line of each TOML line
//! ```

/// A JSON scenario turned into TOML.
#[derive(Clone, Debug, PartialEq)]
pub struct Converted {
    /// The TOML text, one key or table header per line.
    pub toml: String,
    /// For each line of `toml` (0-based index), the 1-based line of the JSON file it comes
    /// from.
    pub lines: Vec<usize>,
}

/// What is wrong with a JSON scenario: the 1-based line (0 if unknown) and a message.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("line {line}: {message}")]
pub struct JsonError {
    /// 1-based line of the JSON file.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

/// A JSON value with the lines of its object members and array items.
enum J {
    Obj(Vec<(String, usize, J)>),
    Arr(Vec<(usize, J)>),
    /// A string, number or boolean as TOML text.
    Scalar(String),
    Null,
}

/// A scanner over JSON text that serde_json has already accepted.
struct Scanner<'a> {
    text: &'a str,
    at: usize,
    line: usize,
}

impl Scanner<'_> {
    fn fail(&self, message: &str) -> JsonError {
        JsonError {
            line: self.line,
            message: message.to_owned(),
        }
    }

    fn peek(&self) -> Option<u8> {
        self.text.as_bytes().get(self.at).copied()
    }

    fn skip_space(&mut self) {
        while let Some(c) = self.peek() {
            match c {
                b'\n' => self.line += 1,
                b' ' | b'\t' | b'\r' => {}
                _ => break,
            }
            self.at += 1;
        }
    }

    fn string(&mut self) -> Result<String, JsonError> {
        let start = self.at;
        self.at += 1;
        loop {
            match self.peek() {
                Some(b'\\') => self.at += 2,
                Some(b'"') => break,
                Some(_) => self.at += 1,
                None => return Err(self.fail("unterminated string")),
            }
        }
        self.at += 1;
        serde_json::from_str(&self.text[start..self.at]).map_err(|e| self.fail(&e.to_string()))
    }

    fn value(&mut self) -> Result<J, JsonError> {
        self.skip_space();
        match self.peek() {
            Some(b'{') => {
                self.at += 1;
                let mut members = Vec::new();
                loop {
                    self.skip_space();
                    match self.peek() {
                        Some(b'}') => {
                            self.at += 1;
                            return Ok(J::Obj(members));
                        }
                        Some(b',') => self.at += 1,
                        Some(b'"') => {
                            let line = self.line;
                            let key = self.string()?;
                            self.skip_space();
                            if self.peek() != Some(b':') {
                                return Err(self.fail("expected `:`"));
                            }
                            self.at += 1;
                            let v = self.value()?;
                            members.push((key, line, v));
                        }
                        _ => return Err(self.fail("expected a member name")),
                    }
                }
            }
            Some(b'[') => {
                self.at += 1;
                let mut items = Vec::new();
                loop {
                    self.skip_space();
                    match self.peek() {
                        Some(b']') => {
                            self.at += 1;
                            return Ok(J::Arr(items));
                        }
                        Some(b',') => self.at += 1,
                        Some(_) => {
                            let line = self.line;
                            items.push((line, self.value()?));
                        }
                        None => return Err(self.fail("unterminated array")),
                    }
                }
            }
            Some(b'"') => {
                let s = self.string()?;
                // A JSON string literal is a valid TOML basic string.
                let quoted = serde_json::to_string(&s).map_err(|e| self.fail(&e.to_string()))?;
                Ok(J::Scalar(quoted))
            }
            Some(_) => {
                let start = self.at;
                while let Some(c) = self.peek() {
                    if c.is_ascii_alphanumeric() || matches!(c, b'+' | b'-' | b'.') {
                        self.at += 1;
                    } else {
                        break;
                    }
                }
                match &self.text[start..self.at] {
                    "null" => Ok(J::Null),
                    "" => Err(self.fail("expected a value")),
                    word => Ok(J::Scalar(word.to_owned())),
                }
            }
            None => Err(self.fail("expected a value")),
        }
    }
}

/// A member name as a TOML key (bare when it can be).
fn key(k: &str) -> String {
    if !k.is_empty()
        && k.bytes()
            .all(|c| c.is_ascii_alphanumeric() || c == b'_' || c == b'-')
    {
        k.to_owned()
    } else {
        serde_json::to_string(k).unwrap_or_default()
    }
}

/// A value as TOML inline text.
fn inline(v: &J, line: usize, name: &str) -> Result<String, JsonError> {
    Ok(match v {
        J::Scalar(s) => s.clone(),
        J::Null => {
            return Err(JsonError {
                line,
                message: format!("`{name}`: null is not a value (leave the key out)"),
            });
        }
        J::Arr(items) => {
            let parts: Vec<String> = items
                .iter()
                .map(|(l, x)| inline(x, *l, name))
                .collect::<Result<_, _>>()?;
            format!("[{}]", parts.join(", "))
        }
        J::Obj(members) => {
            let parts: Vec<String> = members
                .iter()
                .map(|(k, l, x)| Ok(format!("{} = {}", key(k), inline(x, *l, k)?)))
                .collect::<Result<_, JsonError>>()?;
            format!("{{ {} }}", parts.join(", "))
        }
    })
}

/// Turns a JSON scenario into TOML text with the JSON line of each TOML line; a JSON syntax
/// error is reported with serde_json's line.
pub fn to_toml(text: &str) -> Result<Converted, JsonError> {
    serde_json::from_str::<serde_json::Value>(text).map_err(|e| JsonError {
        line: e.line(),
        message: format!("not valid JSON: {e}"),
    })?;
    let mut scanner = Scanner {
        text,
        at: 0,
        line: 1,
    };
    let J::Obj(top) = scanner.value()? else {
        return Err(JsonError {
            line: 1,
            message: "a scenario is a JSON object whose members are tables".to_owned(),
        });
    };
    let mut out = Converted {
        toml: String::new(),
        lines: Vec::new(),
    };
    let mut push = |s: String, line: usize| {
        out.toml.push_str(&s);
        out.toml.push('\n');
        out.lines.push(line);
    };
    let is_tables = |v: &J| matches!(v, J::Arr(items) if !items.is_empty() && items.iter().all(|(_, x)| matches!(x, J::Obj(_))));
    // Keys outside any table first (TOML needs them before the first table; the scenario
    // reader then names them as misplaced).
    for (k, line, v) in &top {
        if !matches!(v, J::Obj(_)) && !is_tables(v) {
            push(format!("{} = {}", key(k), inline(v, *line, k)?), *line);
        }
    }
    for (k, line, v) in &top {
        match v {
            J::Obj(members) => {
                push(format!("[{}]", key(k)), *line);
                for (mk, ml, mv) in members {
                    push(format!("{} = {}", key(mk), inline(mv, *ml, mk)?), *ml);
                }
            }
            J::Arr(items) if is_tables(v) => {
                for (il, item) in items {
                    push(format!("[[{}]]", key(k)), *il);
                    if let J::Obj(members) = item {
                        for (mk, ml, mv) in members {
                            push(format!("{} = {}", key(mk), inline(mv, *ml, mk)?), *ml);
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn members_become_tables_keys_and_inline_values_with_their_lines() {
        let json = r#"{
  "system": {"kind": "volumetric"},
  "mesh": {
    "path": "builtin:icosphere",
    "transform": [1, 0, 0, 0.5, 0, 1, 0, 0, 0, 0, 1, -2e-1]
  },
  "anchors": [
    {"below": {"axis": "z", "value": -0.06}, "stiffness": 100},
    {"spec": "indices:1,2"}
  ],
  "run": {"scene": "free", "steps": 3, "tolerance": 1E-9, "note \"q\"": true}
}"#;
        let c = to_toml(json).unwrap();
        let doc: toml_edit::DocumentMut = c.toml.parse().unwrap();
        assert_eq!(doc["mesh"]["path"].as_str(), Some("builtin:icosphere"));
        assert_eq!(doc["run"]["steps"].as_integer(), Some(3));
        assert_eq!(doc["run"]["tolerance"].as_float(), Some(1e-9));
        assert_eq!(doc["run"]["note \"q\""].as_bool(), Some(true));
        let anchors = doc["anchors"].as_array_of_tables().unwrap();
        assert_eq!(anchors.len(), 2);
        assert_eq!(
            anchors.get(0).unwrap()["below"]["value"].as_float(),
            Some(-0.06)
        );
        // Each TOML line points at its JSON line.
        let line_of = |needle: &str| {
            let i = c.toml.lines().position(|l| l.starts_with(needle)).unwrap();
            c.lines[i]
        };
        assert_eq!(line_of("transform"), 5);
        assert_eq!(
            line_of("stiffness"), /* same line as its table's members */
            8
        );
        assert_eq!(line_of("spec"), 9);
        assert_eq!(line_of("steps"), 11);
    }

    #[test]
    fn syntax_errors_and_nulls_name_their_line() {
        let e = to_toml("{\n  \"run\": {\"steps\": 5,}\n}").unwrap_err();
        assert_eq!(e.line, 2, "{e}");
        assert!(e.message.contains("not valid JSON"), "{e}");
        let e = to_toml("{\n\"run\":\n  {\"dt\": null}\n}").unwrap_err();
        assert_eq!(e.line, 3);
        assert!(e.message.contains("`dt`: null"), "{e}");
        assert!(to_toml("[1, 2]").is_err());
    }
}
