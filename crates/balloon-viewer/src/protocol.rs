//! The messages between the server and the page (see `docs/viewer.md`): parsing and validation
//! of what the client sends, and the control descriptions the server announces.
//!
//! Everything here is pure: a malformed message is an `Err(String)` whose text is sent back to
//! the client as `{"type": "error", "message": ...}`; nothing panics on client input.

use serde::Serialize;
use serde_json::{Map, Value};

/// Largest accepted client message, bytes (a drag or control message is under 200).
pub const MAX_MESSAGE_BYTES: usize = 64 * 1024;

/// How a control is edited on the page.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ControlKind {
    /// A number in `[min, max]`.
    Number,
    /// One of `choices`.
    Choice,
    /// `true` or `false`.
    Bool,
}

/// A control as announced in `hello` (and reported by `/api/state` with its current value).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ControlSpec {
    /// Name used in `{"type": "control", "name": ...}`.
    pub name: &'static str,
    /// Label for the page.
    pub label: &'static str,
    /// Kind of editor.
    pub kind: ControlKind,
    /// Current value.
    pub value: Value,
    /// Smallest allowed value (numbers).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min: Option<f64>,
    /// Largest allowed value (numbers).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max: Option<f64>,
    /// Suggested step of a slider (numbers).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub step: Option<f64>,
    /// Allowed values (choices).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub choices: Vec<&'static str>,
    /// Unit, e.g. `"Pa"` (empty when none).
    pub unit: &'static str,
    /// Changing it rebuilds the simulation.
    pub resets: bool,
}

impl ControlSpec {
    /// A number control.
    pub fn number(
        name: &'static str,
        label: &'static str,
        value: f64,
        (min, max, step): (f64, f64, f64),
        unit: &'static str,
        resets: bool,
    ) -> Self {
        Self {
            name,
            label,
            kind: ControlKind::Number,
            value: Value::from(value),
            min: Some(min),
            max: Some(max),
            step: Some(step),
            choices: Vec::new(),
            unit,
            resets,
        }
    }

    /// A choice control.
    pub fn choice(
        name: &'static str,
        label: &'static str,
        value: &str,
        choices: &[&'static str],
        resets: bool,
    ) -> Self {
        Self {
            name,
            label,
            kind: ControlKind::Choice,
            value: Value::from(value),
            min: None,
            max: None,
            step: None,
            choices: choices.to_vec(),
            unit: "",
            resets,
        }
    }

    /// A boolean control.
    pub fn boolean(name: &'static str, label: &'static str, value: bool, resets: bool) -> Self {
        Self {
            name,
            label,
            kind: ControlKind::Bool,
            value: Value::from(value),
            min: None,
            max: None,
            step: None,
            choices: Vec::new(),
            unit: "",
            resets,
        }
    }

    /// The allowed range as text, e.g. `[0, 20000] Pa` or `one of stvk, neo-hookean`.
    pub fn range_text(&self) -> String {
        match self.kind {
            ControlKind::Number => {
                let unit = if self.unit.is_empty() {
                    String::new()
                } else {
                    format!(" {}", self.unit)
                };
                format!(
                    "[{}, {}]{unit}",
                    self.min.unwrap_or(f64::NEG_INFINITY),
                    self.max.unwrap_or(f64::INFINITY)
                )
            }
            ControlKind::Choice => format!("one of {}", self.choices.join(", ")),
            ControlKind::Bool => "true or false".into(),
        }
    }
}

/// A validated control value.
#[derive(Clone, Debug, PartialEq)]
pub enum ControlValue {
    /// A finite number within the control's range.
    Number(f64),
    /// One of the control's choices.
    Choice(&'static str),
    /// A boolean.
    Bool(bool),
}

impl ControlValue {
    /// The number (0 for other kinds; validation guarantees the kind).
    pub fn number(&self) -> f64 {
        match self {
            Self::Number(v) => *v,
            _ => 0.0,
        }
    }

    /// The choice (empty for other kinds).
    pub fn choice(&self) -> &'static str {
        match self {
            Self::Choice(c) => c,
            _ => "",
        }
    }

    /// The boolean (false for other kinds).
    pub fn boolean(&self) -> bool {
        matches!(self, Self::Bool(true))
    }
}

/// How a drag deforms the body.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DragMode {
    /// Pull the vertex and its neighbourhood towards the target (the neighbourhood keeps its
    /// shape).
    Grab,
    /// Pull the neighbourhood of the vertex together to the target (shell only).
    Pinch,
}

impl DragMode {
    /// The protocol name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Grab => "grab",
            Self::Pinch => "pinch",
        }
    }
}

/// A message from the page, structurally checked (values of controls and vertex indices are
/// checked against the running simulation by [`validate_control`] and [`validate_vertex`]).
#[derive(Clone, Debug, PartialEq)]
pub enum ClientMessage {
    /// Set a control.
    Control {
        /// Control name.
        name: String,
        /// Raw value (validated later).
        value: Value,
    },
    /// Pause the simulation.
    Pause,
    /// Resume it.
    Resume,
    /// Rebuild it from the current control values.
    Reset,
    /// Choose the scalar field of the frames.
    Scalar {
        /// Field name.
        name: String,
    },
    /// Attach or move the drag.
    Drag {
        /// Picked vertex.
        vertex: usize,
        /// Target, m.
        target: [f64; 3],
        /// Mode.
        mode: DragMode,
    },
    /// Drop the drag.
    Release,
    /// The page has drawn frame `frame`: from its first `ack` on, a connection sends a frame
    /// only when the one before it was acknowledged (or after [`ACK_TIMEOUT`]), so a page that
    /// draws slower than the server publishes gets fewer frames instead of a queue of them.
    Ack {
        /// The acknowledged frame's number.
        frame: u64,
    },
}

/// How long a connection in acknowledged mode waits for the `ack` of its last frame before it
/// sends the next one anyway (a lost `ack`, a page in a background tab that draws nothing).
pub const ACK_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(1);

fn field<'a>(obj: &'a Map<String, Value>, ty: &str, key: &str) -> Result<&'a Value, String> {
    obj.get(key)
        .ok_or_else(|| format!("`{ty}` message: missing field `{key}`"))
}

/// Parses one text message from the page.
///
/// Errors (the text names what is wrong): longer than [`MAX_MESSAGE_BYTES`], not JSON, not an
/// object, no string `type`, unknown `type`, a missing or mistyped field, a non-finite target.
pub fn parse_client_message(text: &str) -> Result<ClientMessage, String> {
    if text.len() > MAX_MESSAGE_BYTES {
        return Err(format!(
            "message of {} bytes is longer than the limit of {MAX_MESSAGE_BYTES} bytes",
            text.len()
        ));
    }
    let value: Value =
        serde_json::from_str(text).map_err(|e| format!("malformed JSON message: {e}"))?;
    let obj = value
        .as_object()
        .ok_or_else(|| "a message must be a JSON object with a `type` field".to_string())?;
    let ty = obj
        .get("type")
        .ok_or_else(|| "message without a `type` field".to_string())?
        .as_str()
        .ok_or_else(|| "the `type` field must be a string".to_string())?;
    match ty {
        "control" => {
            let name = field(obj, ty, "name")?
                .as_str()
                .ok_or_else(|| "`control` message: `name` must be a string".to_string())?;
            let value = field(obj, ty, "value")?.clone();
            Ok(ClientMessage::Control {
                name: name.to_string(),
                value,
            })
        }
        "pause" => Ok(ClientMessage::Pause),
        "resume" => Ok(ClientMessage::Resume),
        "reset" => Ok(ClientMessage::Reset),
        "release" => Ok(ClientMessage::Release),
        "ack" => {
            let frame = field(obj, ty, "frame")?.as_u64().ok_or_else(|| {
                "`ack` message: `frame` must be a non-negative integer".to_string()
            })?;
            Ok(ClientMessage::Ack { frame })
        }
        "scalar" => {
            let name = field(obj, ty, "name")?
                .as_str()
                .ok_or_else(|| "`scalar` message: `name` must be a string".to_string())?;
            Ok(ClientMessage::Scalar {
                name: name.to_string(),
            })
        }
        "drag" => {
            let vertex = field(obj, ty, "vertex")?.as_u64().ok_or_else(|| {
                "`drag` message: `vertex` must be a non-negative integer".to_string()
            })?;
            let vertex = usize::try_from(vertex)
                .map_err(|_| format!("`drag` message: vertex {vertex} is too large"))?;
            let t = field(obj, ty, "target")?.as_array().ok_or_else(|| {
                "`drag` message: `target` must be an array [x, y, z] of numbers".to_string()
            })?;
            let coords: Option<Vec<f64>> = t.iter().map(Value::as_f64).collect();
            let coords = coords.filter(|c| c.len() == 3).ok_or_else(|| {
                "`drag` message: `target` must be an array [x, y, z] of numbers".to_string()
            })?;
            if coords.iter().any(|c| !c.is_finite()) {
                return Err("`drag` message: `target` must be finite".into());
            }
            let mode = match obj.get("mode") {
                None => DragMode::Grab,
                Some(m) => match m.as_str() {
                    Some("grab") => DragMode::Grab,
                    Some("pinch") => DragMode::Pinch,
                    _ => {
                        return Err(format!(
                            "`drag` message: `mode` {m} is not one of \"grab\", \"pinch\""
                        ));
                    }
                },
            };
            Ok(ClientMessage::Drag {
                vertex,
                target: [coords[0], coords[1], coords[2]],
                mode,
            })
        }
        other => Err(format!(
            "unknown message type `{other}` (expected control, pause, resume, reset, scalar, drag or release)"
        )),
    }
}

/// Checks a control value against the announced controls. The error names the control and its
/// allowed range (or lists the known controls when the name is unknown).
pub fn validate_control(
    controls: &[ControlSpec],
    name: &str,
    value: &Value,
) -> Result<ControlValue, String> {
    let Some(spec) = controls.iter().find(|c| c.name == name) else {
        let known: Vec<&str> = controls.iter().map(|c| c.name).collect();
        return Err(format!(
            "unknown control `{name}` (this system has: {})",
            known.join(", ")
        ));
    };
    let bad = || {
        format!(
            "invalid value {value} for control `{name}`: allowed {}",
            spec.range_text()
        )
    };
    match spec.kind {
        ControlKind::Number => {
            let v = value.as_f64().filter(|v| v.is_finite()).ok_or_else(bad)?;
            let (lo, hi) = (
                spec.min.unwrap_or(f64::NEG_INFINITY),
                spec.max.unwrap_or(f64::INFINITY),
            );
            if !(lo..=hi).contains(&v) {
                return Err(bad());
            }
            Ok(ControlValue::Number(v))
        }
        ControlKind::Choice => {
            let s = value.as_str().ok_or_else(bad)?;
            spec.choices
                .iter()
                .find(|c| **c == s)
                .map(|c| ControlValue::Choice(c))
                .ok_or_else(bad)
        }
        ControlKind::Bool => value.as_bool().map(ControlValue::Bool).ok_or_else(bad),
    }
}

/// Checks a picked vertex index against the vertex count of the frames.
pub fn validate_vertex(vertex: usize, vertex_count: usize) -> Result<(), String> {
    if vertex < vertex_count {
        Ok(())
    } else {
        Err(format!(
            "`drag` message: vertex {vertex} is out of range (the body has {vertex_count} vertices, 0..{})",
            vertex_count.saturating_sub(1)
        ))
    }
}

/// The `{"type": "error", "message": ...}` message.
pub fn error_message(message: &str) -> String {
    serde_json::json!({"type": "error", "message": message}).to_string()
}

/// A notice for the page (`{"type": "notice", "message": ...}`): something the server did on
/// its own that the user should know of (a drag undone), not an error.
pub fn notice_message(message: &str) -> String {
    serde_json::json!({"type": "notice", "message": message}).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn controls() -> Vec<ControlSpec> {
        vec![
            ControlSpec::number(
                "pressure",
                "Pressure",
                2000.0,
                (0.0, 20000.0, 100.0),
                "Pa",
                false,
            ),
            ControlSpec::choice(
                "material",
                "Material",
                "stvk",
                &["stvk", "neo-hookean"],
                true,
            ),
            ControlSpec::boolean("box", "Wall box", true, true),
        ]
    }

    #[test]
    fn a_17_digit_number_arrives_as_the_nearest_double() {
        // Without serde_json's `float_roundtrip` this value arrived as ...344 (one unit in the
        // last place off): the page sends JavaScript's shortest round-trip text of a double.
        let cases = [
            ("0.00020248393365432342", 0.000_202_483_933_654_323_42_f64),
            ("0.1", 0.1),
            ("2.2250738585072014e-308", f64::MIN_POSITIVE),
            ("1.7976931348623157e308", f64::MAX),
            ("0.30000000000000004", 0.1 + 0.2),
        ];
        for (text, want) in cases {
            let m = parse_client_message(&format!(
                r#"{{"type":"control","name":"dt","value":{text}}}"#
            ))
            .unwrap();
            let ClientMessage::Control { value, .. } = m else {
                panic!("not a control message: {m:?}")
            };
            let got = value.as_f64().unwrap();
            assert_eq!(got.to_bits(), want.to_bits(), "{text}: {got:e}");
            // And every double's shortest text comes back to the same bits.
            assert_eq!(
                format!("{got:?}").parse::<f64>().unwrap().to_bits(),
                want.to_bits()
            );
        }
        let mut x = 1.234_567_890_123_456_7e-4_f64;
        for _ in 0..2000 {
            x = (x * 1.618_033_988_749_895).fract() * 1e-3 + 1e-5;
            let m = parse_client_message(&format!(
                r#"{{"type":"control","name":"dt","value":{x:?}}}"#
            ))
            .unwrap();
            let ClientMessage::Control { value, .. } = m else {
                panic!("not a control message")
            };
            assert_eq!(value.as_f64().unwrap().to_bits(), x.to_bits(), "{x:?}");
        }
    }

    #[test]
    fn acknowledgements_parse() {
        assert_eq!(
            parse_client_message(r#"{"type":"ack","frame":12}"#).unwrap(),
            ClientMessage::Ack { frame: 12 }
        );
        for bad in [r#"{"type":"ack"}"#, r#"{"type":"ack","frame":-1}"#] {
            let e = parse_client_message(bad).unwrap_err();
            assert!(e.contains("`ack` message"), "{e}");
        }
    }

    #[test]
    fn every_message_type_parses() {
        let p = |s: &str| parse_client_message(s).unwrap();
        assert_eq!(
            p(r#"{"type":"control","name":"pressure","value":3}"#),
            ClientMessage::Control {
                name: "pressure".into(),
                value: json!(3)
            }
        );
        assert_eq!(p(r#"{"type":"pause"}"#), ClientMessage::Pause);
        assert_eq!(p(r#"{"type":"resume"}"#), ClientMessage::Resume);
        assert_eq!(p(r#"{"type":"reset"}"#), ClientMessage::Reset);
        assert_eq!(p(r#"{"type":"release"}"#), ClientMessage::Release);
        assert_eq!(
            p(r#"{"type":"scalar","name":"stretch"}"#),
            ClientMessage::Scalar {
                name: "stretch".into()
            }
        );
        assert_eq!(
            p(r#"{"type":"drag","vertex":7,"target":[1,2.5,-3],"mode":"pinch"}"#),
            ClientMessage::Drag {
                vertex: 7,
                target: [1.0, 2.5, -3.0],
                mode: DragMode::Pinch
            }
        );
        // The mode defaults to grab.
        assert_eq!(
            p(r#"{"type":"drag","vertex":0,"target":[0,0,0]}"#),
            ClientMessage::Drag {
                vertex: 0,
                target: [0.0; 3],
                mode: DragMode::Grab
            }
        );
    }

    #[test]
    fn malformed_messages_are_rejected_with_a_reason() {
        let cases: &[(&str, &str)] = &[
            ("{not json", "malformed JSON"),
            ("", "malformed JSON"),
            ("[1,2]", "JSON object"),
            ("42", "JSON object"),
            (r#"{"name":"x"}"#, "without a `type`"),
            (r#"{"type":3}"#, "must be a string"),
            (r#"{"type":"explode"}"#, "unknown message type `explode`"),
            (r#"{"type":"control","value":1}"#, "missing field `name`"),
            (
                r#"{"type":"control","name":5,"value":1}"#,
                "`name` must be a string",
            ),
            (
                r#"{"type":"control","name":"pressure"}"#,
                "missing field `value`",
            ),
            (r#"{"type":"scalar"}"#, "missing field `name`"),
            (r#"{"type":"scalar","name":[]}"#, "`name` must be a string"),
            (
                r#"{"type":"drag","target":[0,0,0]}"#,
                "missing field `vertex`",
            ),
            (
                r#"{"type":"drag","vertex":-1,"target":[0,0,0]}"#,
                "non-negative integer",
            ),
            (
                r#"{"type":"drag","vertex":1.5,"target":[0,0,0]}"#,
                "non-negative integer",
            ),
            (r#"{"type":"drag","vertex":1}"#, "missing field `target`"),
            (r#"{"type":"drag","vertex":1,"target":[0,0]}"#, "[x, y, z]"),
            (
                r#"{"type":"drag","vertex":1,"target":[0,"a",0]}"#,
                "[x, y, z]",
            ),
            (r#"{"type":"drag","vertex":1,"target":"up"}"#, "[x, y, z]"),
            (
                r#"{"type":"drag","vertex":1,"target":[0,0,1e999]}"#,
                "malformed JSON",
            ),
            (
                r#"{"type":"drag","vertex":1,"target":[0,0,0],"mode":"poke"}"#,
                "`mode`",
            ),
        ];
        for (text, want) in cases {
            let e = parse_client_message(text).unwrap_err();
            assert!(e.contains(want), "{text}: `{e}` lacks `{want}`");
        }
        let long = format!(
            r#"{{"type":"pause","pad":"{}"}}"#,
            "x".repeat(MAX_MESSAGE_BYTES)
        );
        assert!(parse_client_message(&long).unwrap_err().contains("limit"));
    }

    #[test]
    fn control_values_are_checked_against_the_spec() {
        let c = controls();
        assert_eq!(
            validate_control(&c, "pressure", &json!(150.5)).unwrap(),
            ControlValue::Number(150.5)
        );
        assert_eq!(
            validate_control(&c, "material", &json!("neo-hookean")).unwrap(),
            ControlValue::Choice("neo-hookean")
        );
        assert_eq!(
            validate_control(&c, "box", &json!(false)).unwrap(),
            ControlValue::Bool(false)
        );
        let err = |name: &str, v: Value| validate_control(&c, name, &v).unwrap_err();
        let e = err("pressure", json!(1e9));
        assert!(
            e.contains("`pressure`") && e.contains("[0, 20000] Pa"),
            "{e}"
        );
        assert!(err("pressure", json!(-1)).contains("[0, 20000] Pa"));
        assert!(err("pressure", json!("high")).contains("`pressure`"));
        assert!(err("pressure", json!(null)).contains("`pressure`"));
        let e = err("material", json!("rubber"));
        assert!(
            e.contains("`material`") && e.contains("one of stvk, neo-hookean"),
            "{e}"
        );
        assert!(err("material", json!(1)).contains("`material`"));
        assert!(err("box", json!("yes")).contains("true or false"));
        let e = err("colour", json!(1));
        assert!(e.contains("unknown control `colour`") && e.contains("pressure, material, box"));
    }

    #[test]
    fn vertex_indices_are_checked() {
        assert!(validate_vertex(9, 10).is_ok());
        let e = validate_vertex(10, 10).unwrap_err();
        assert!(
            e.contains("vertex 10 is out of range") && e.contains("0..9"),
            "{e}"
        );
    }

    #[test]
    fn control_specs_serialise_as_the_protocol_says() {
        let v = serde_json::to_value(controls()).unwrap();
        assert_eq!(v[0]["kind"], "number");
        assert_eq!(v[0]["min"], 0.0);
        assert_eq!(v[0]["unit"], "Pa");
        assert_eq!(v[1]["kind"], "choice");
        assert_eq!(v[1]["choices"], json!(["stvk", "neo-hookean"]));
        assert_eq!(v[1]["resets"], true);
        assert_eq!(v[2]["kind"], "bool");
        let e: Value = serde_json::from_str(&error_message("bad \"x\"")).unwrap();
        assert_eq!(e, json!({"type": "error", "message": "bad \"x\""}));
    }
}
