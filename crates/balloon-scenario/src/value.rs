//! A value given for one key of a scenario, as a front end has it before it is typed: a TOML
//! value of a scenario file, a Python keyword's object. [`crate::keys`] turns it into the typed
//! field, with an error that says what was expected and what was found.
//!
//! ```
//! use balloon_scenario::value::Value;
//! assert_eq!(Value::Int(3).real(), Ok(3.0));
//! assert_eq!(Value::Text("x".into()).real().unwrap_err(), "expected a number, found a string");
//! ```

use crate::range::{NOT_A_WHOLE_NUMBER, ValueError};

/// A value of one key, untyped.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// `true` / `false`.
    Bool(bool),
    /// A whole number (it may stand for a real number too).
    Int(i64),
    /// A real number.
    Float(f64),
    /// A string (a choice, a spec, a path).
    Text(String),
    /// A list (of numbers, or of anchor / load specs).
    List(Vec<Value>),
    /// A table of named values (`{ axis = "z", from = 3e-4, to = 6e-4 }`).
    Table(Vec<(String, Value)>),
}

/// Why a key's value cannot be used.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SetError {
    /// The value has the wrong type (`expected a number, found a string`).
    Type(String),
    /// The value has the right type but is not one the parameter takes (an unknown choice, a
    /// negative count, a spec that does not parse).
    Value(ValueError),
}

impl From<String> for SetError {
    fn from(message: String) -> Self {
        SetError::Type(message)
    }
}

impl Value {
    /// The type as errors name it: `a string`, `an integer`, ...
    pub fn type_name(&self) -> &'static str {
        match self {
            Value::Bool(_) => "a boolean",
            Value::Int(_) => "an integer",
            Value::Float(_) => "a float",
            Value::Text(_) => "a string",
            Value::List(_) => "an array",
            Value::Table(_) => "a table",
        }
    }

    /// `expected {what}, found {type}`.
    pub fn expected(&self, what: &str) -> String {
        format!("expected {what}, found {}", self.type_name())
    }

    /// The value as the text a user would have written (numbers in Rust's round-trip form,
    /// integers as integers), for the recorded scenario and for errors.
    pub fn literal(&self) -> String {
        match self {
            Value::Bool(b) => b.to_string(),
            Value::Int(i) => i.to_string(),
            Value::Float(f) => format!("{f:?}"),
            Value::Text(s) => s.clone(),
            Value::List(l) => l.iter().map(Value::literal).collect::<Vec<_>>().join(","),
            Value::Table(t) => t
                .iter()
                .map(|(k, v)| format!("{k}={}", v.literal()))
                .collect::<Vec<_>>()
                .join(";"),
        }
    }

    /// A boolean.
    pub fn boolean(&self) -> Result<bool, String> {
        match self {
            Value::Bool(b) => Ok(*b),
            _ => Err(self.expected("a boolean (true or false)")),
        }
    }

    /// A real number (an integer converts).
    pub fn real(&self) -> Result<f64, String> {
        match self {
            Value::Int(i) => Ok(*i as f64),
            Value::Float(f) => Ok(*f),
            _ => Err(self.expected("a number")),
        }
    }

    /// A whole number >= 0 of parameter `name`: a negative one is a [`ValueError`].
    pub fn whole(&self, name: &str) -> Result<usize, SetError> {
        match self {
            Value::Int(i) => usize::try_from(*i).map_err(|_| {
                SetError::Value(ValueError::new(
                    name,
                    i.to_string(),
                    Some(NOT_A_WHOLE_NUMBER.into()),
                ))
            }),
            _ => Err(SetError::Type(self.expected("a whole number"))),
        }
    }

    /// A list of real numbers (a single number is a list of one).
    pub fn reals(&self) -> Result<Vec<f64>, String> {
        match self {
            Value::List(l) => l
                .iter()
                .map(|v| v.real().ok())
                .collect::<Option<Vec<_>>>()
                .filter(|l| !l.is_empty())
                .ok_or_else(|| "expected a non-empty array of numbers".to_owned()),
            Value::Int(_) | Value::Float(_) => Ok(vec![self.real()?]),
            _ => Err(self.expected("an array of numbers")),
        }
    }

    /// A string.
    pub fn text(&self) -> Result<&str, String> {
        match self {
            Value::Text(s) => Ok(s),
            _ => Err(self.expected("a string")),
        }
    }

    /// The named values of a table.
    pub fn table(&self) -> Option<&[(String, Value)]> {
        match self {
            Value::Table(t) => Some(t),
            _ => None,
        }
    }
}

/// Parses text into `T` for parameter `name`: a text `T` does not take is a [`ValueError`]
/// with the parser's message as its reason (`reason`), or as its hint (a choice whose value
/// alone says what is wrong to a front end that lists the choices itself).
pub fn parse_choice<T: std::str::FromStr>(
    name: &str,
    text: &str,
    reason: bool,
) -> Result<T, SetError>
where
    T::Err: std::fmt::Display,
{
    text.parse::<T>().map_err(|e| {
        let mut err = ValueError::new(name, text.to_owned(), None);
        if reason {
            err.reason = Some(e.to_string());
        } else {
            err.hint = Some(e.to_string());
        }
        SetError::Value(err)
    })
}
