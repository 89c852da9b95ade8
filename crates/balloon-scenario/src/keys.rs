//! The keys of a scenario: for each system, one table of [`Key`]s that says, for every
//! parameter, where it lives in a scenario file (`[table] key`), its name (the command-line
//! flag with `_` for `-`, the Python keyword, the name in messages), its type, how a value is
//! set ([`Key::set`]), its range ([`Key::check`]) and how the recorded scenario writes it
//! ([`Key::get`]). Scenario files, the command line and the Python package all set parameters
//! through these tables, so a parameter is defined, typed and range-checked in one place.
//!
//! ```
//! use balloon_scenario::{Scenario, SystemKind, value::Value};
//! let mut s = Scenario::new(SystemKind::Shell);
//! s.set("dt", &Value::Float(0.005)).unwrap();
//! s.set("gas", &Value::Text("constant".into())).unwrap();
//! assert!(s.set("dt", &Value::Text("fast".into())).is_err());
//! s.set("dt", &Value::Float(5.0)).unwrap(); // typed: the range is checked by `validate`
//! assert_eq!(
//!     s.validate().unwrap_err().to_string(),
//!     "invalid value '5.0' for `dt`: must be a finite number in (0, 1]"
//! );
//! ```

use crate::range::End::{Closed, Open};
use crate::range::{MAX_STEPS, Real, ValueError, Whole};
use crate::value::{SetError, Value};
use std::collections::BTreeMap;

/// The type a key takes, which also says how a scenario file and the recorded scenario write it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// On or off (`false` by default).
    Bool,
    /// On, off, or unset (the program decides).
    Switch,
    /// A number.
    Number,
    /// A list of numbers (a single number is a list of one).
    Numbers,
    /// A string (a choice such as `"stvk"`, or a spec such as `"0,100,last"`).
    Text,
    /// A string naming a file or folder (in a scenario file: relative to the file).
    Path,
    /// A number or a string (`conductance = 5.0` or `conductance = "instant"`).
    NumberOrText,
    /// A thickness rule: a string `AXIS:FROM:TO` or a table `{ axis, from, to }`.
    Rule,
    /// A list of anchors or loads: in a scenario file an array of tables (`[[anchors]]`,
    /// `[[loads]]`), elsewhere specs (`below:z:0.01@200`).
    Tables,
}

/// How the recorded scenario writes a key's value.
#[derive(Clone, Debug, PartialEq)]
pub enum Recorded {
    /// `key = true` / `false`.
    Bool(bool),
    /// The value's texts (one for a scalar, one per element for a list), as a user would
    /// write them (numbers in Rust's `Display` form).
    Text(Vec<String>),
    /// Not set: the program decides (written as a comment).
    Unset,
    /// The specs of anchors or loads, one `[[table]]` each.
    Tables(Vec<String>),
}

impl Recorded {
    /// A scalar's text.
    pub fn one(text: impl ToString) -> Self {
        Recorded::Text(vec![text.to_string()])
    }

    /// An optional scalar's text.
    pub fn maybe<T: ToString>(v: Option<T>) -> Self {
        v.map_or(Recorded::Unset, Recorded::one)
    }

    /// An optional list's texts.
    pub fn list<T: ToString>(v: Option<&[T]>) -> Self {
        v.map_or(Recorded::Unset, |l| {
            Recorded::Text(l.iter().map(ToString::to_string).collect())
        })
    }
}

/// One key of a system's scenario `S`.
pub struct Key<S: 'static> {
    /// Table name (`run` for `[run]`).
    pub table: &'static str,
    /// Key in the table (`""` for an array of tables).
    pub key: &'static str,
    /// The parameter's name: the command-line flag with `_` for `-` (`newton_iters`), the
    /// Python keyword, and the name in messages ([`crate::names::PARAMETERS`]).
    pub name: &'static str,
    /// Its type.
    pub kind: Kind,
    /// Whether the recorded scenario repeats it; `false` for where and how the output is
    /// written (`out`, `overwrite`, `json`), which do not change the run.
    pub recorded: bool,
    /// Sets the value (types it, without its range).
    pub set: fn(&mut S, &Value) -> Result<(), SetError>,
    /// Checks the value against its range.
    pub check: fn(&S) -> Result<(), ValueError>,
    /// The value as the recorded scenario writes it.
    pub get: fn(&S) -> Recorded,
    /// Copies the value from another scenario of the same system (the first argument is the
    /// destination): a front end's overrides of a file's keys.
    pub copy: fn(&mut S, &S),
}

impl<S> std::fmt::Debug for Key<S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Key")
            .field("table", &self.table)
            .field("key", &self.key)
            .field("name", &self.name)
            .field("kind", &self.kind)
            .finish()
    }
}

/// A copy of `t` (the key tables' copies, for every type of field).
pub fn dup<T: Clone>(t: &T) -> T {
    t.clone()
}

/// A check that always passes (keys without a range).
pub fn no_check<S>(_: &S) -> Result<(), ValueError> {
    Ok(())
}

/// The text of each value as its user wrote it (`1e3`, `2.0`, `"Z:3e-4:6e-4"`), by parameter
/// name: the recorded scenario repeats them as written (an integral value written `2.0` stays
/// a float), and an error about a value shows the text that was typed. Front ends fill it as
/// they set keys; a value set by other means has none (its `Display` text is used).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Literals(BTreeMap<String, Vec<String>>);

impl Literals {
    /// Records the text(s) of parameter `name` (one per element of a list).
    pub fn set(&mut self, name: &str, texts: Vec<String>) {
        self.0.insert(name.to_owned(), texts);
    }

    /// The text(s) of parameter `name`, if recorded.
    pub fn get(&self, name: &str) -> Option<&[String]> {
        self.0.get(name).map(Vec::as_slice)
    }

    /// Forgets parameter `name`'s text (its value was set without one).
    pub fn remove(&mut self, name: &str) {
        self.0.remove(name);
    }

    /// The text a user typed for the value an error is about (a list's element), if known.
    pub fn typed(&self, e: &ValueError) -> Option<&str> {
        self.get(&e.name)
            .and_then(|t| t.get(e.index.unwrap_or(0)))
            .map(String::as_str)
    }
}

/// Key-table entries, one macro per shape of field. Each takes the table, the key, the
/// parameter name and the field path (and a range where there is one).
macro_rules! flag {
    ($t:literal, $k:literal, $n:literal, $($f:ident).+) => {
        $crate::keys::Key {
            table: $t, key: $k, name: $n, kind: $crate::keys::Kind::Bool, recorded: true,
            set: |s, v| { s.$($f).+ = v.boolean()?; Ok(()) },
            check: $crate::keys::no_check,
            get: |s| $crate::keys::Recorded::Bool(s.$($f).+),
            copy: |d, s| d.$($f).+ = s.$($f).+,
        }
    };
}

macro_rules! real {
    ($t:literal, $k:literal, $n:literal, $range:expr, $($f:ident).+) => {
        $crate::keys::Key {
            table: $t, key: $k, name: $n, kind: $crate::keys::Kind::Number, recorded: true,
            set: |s, v| { s.$($f).+ = v.real()?; Ok(()) },
            check: |s| $range.check($n, s.$($f).+).map(drop),
            get: |s| $crate::keys::Recorded::one(s.$($f).+),
            copy: |d, s| d.$($f).+ = $crate::keys::dup(&s.$($f).+),
        }
    };
}

macro_rules! real_opt {
    ($t:literal, $k:literal, $n:literal, $range:expr, $($f:ident).+) => {
        $crate::keys::Key {
            table: $t, key: $k, name: $n, kind: $crate::keys::Kind::Number, recorded: true,
            set: |s, v| { s.$($f).+ = Some(v.real()?); Ok(()) },
            check: |s| match s.$($f).+ {
                Some(x) => $range.check($n, x).map(drop),
                None => Ok(()),
            },
            get: |s| $crate::keys::Recorded::maybe(s.$($f).+),
            copy: |d, s| d.$($f).+ = $crate::keys::dup(&s.$($f).+),
        }
    };
}

macro_rules! whole {
    ($t:literal, $k:literal, $n:literal, $range:expr, $($f:ident).+) => {
        $crate::keys::Key {
            table: $t, key: $k, name: $n, kind: $crate::keys::Kind::Number, recorded: true,
            set: |s, v| { s.$($f).+ = v.whole($n)?.try_into().map_err(|_| {
                $crate::value::SetError::Value($crate::range::ValueError::new(
                    $n, v.literal(), Some($range.reason()),
                ))
            })?; Ok(()) },
            check: |s| $range.check($n, $crate::keys::Count::count(s.$($f).+)).map(drop),
            get: |s| $crate::keys::Recorded::one(s.$($f).+),
            copy: |d, s| d.$($f).+ = $crate::keys::dup(&s.$($f).+),
        }
    };
}

macro_rules! whole_opt {
    ($t:literal, $k:literal, $n:literal, $range:expr, $($f:ident).+) => {
        $crate::keys::Key {
            table: $t, key: $k, name: $n, kind: $crate::keys::Kind::Number, recorded: true,
            set: |s, v| { s.$($f).+ = Some(v.whole($n)?); Ok(()) },
            check: |s| match s.$($f).+ {
                Some(x) => $range.check($n, x).map(drop),
                None => Ok(()),
            },
            get: |s| $crate::keys::Recorded::maybe(s.$($f).+),
            copy: |d, s| d.$($f).+ = $crate::keys::dup(&s.$($f).+),
        }
    };
}

macro_rules! reals_opt {
    ($t:literal, $k:literal, $n:literal, $range:expr, $($f:ident).+) => {
        $crate::keys::Key {
            table: $t, key: $k, name: $n, kind: $crate::keys::Kind::Numbers, recorded: true,
            set: |s, v| { s.$($f).+ = Some(v.reals()?); Ok(()) },
            check: |s| match &s.$($f).+ {
                Some(x) => $range.check_all($n, x),
                None => Ok(()),
            },
            get: |s| $crate::keys::Recorded::list(s.$($f).+.as_deref()),
            copy: |d, s| d.$($f).+ = $crate::keys::dup(&s.$($f).+),
        }
    };
}

/// A choice typed by `FromStr` (`$reason`: whether its parse error is shown).
macro_rules! choice {
    ($t:literal, $k:literal, $n:literal, $reason:expr, $($f:ident).+) => {
        $crate::keys::Key {
            table: $t, key: $k, name: $n, kind: $crate::keys::Kind::Text, recorded: true,
            set: |s, v| {
                s.$($f).+ = $crate::value::parse_choice($n, v.text()?, $reason)?;
                Ok(())
            },
            check: $crate::keys::no_check,
            get: |s| $crate::keys::Recorded::one(&s.$($f).+),
            copy: |d, s| d.$($f).+ = $crate::keys::dup(&s.$($f).+),
        }
    };
}

macro_rules! choice_opt {
    ($t:literal, $k:literal, $n:literal, $reason:expr, $($f:ident).+) => {
        $crate::keys::Key {
            table: $t, key: $k, name: $n, kind: $crate::keys::Kind::Text, recorded: true,
            set: |s, v| {
                s.$($f).+ = Some($crate::value::parse_choice($n, v.text()?, $reason)?);
                Ok(())
            },
            check: $crate::keys::no_check,
            get: |s| $crate::keys::Recorded::maybe(s.$($f).+.as_ref()),
            copy: |d, s| d.$($f).+ = $crate::keys::dup(&s.$($f).+),
        }
    };
}

/// A free text checked later (by `validate`).
macro_rules! text_opt {
    ($t:literal, $k:literal, $n:literal, $($f:ident).+) => {
        $crate::keys::Key {
            table: $t, key: $k, name: $n, kind: $crate::keys::Kind::Text, recorded: true,
            set: |s, v| { s.$($f).+ = Some(v.text()?.to_owned()); Ok(()) },
            check: $crate::keys::no_check,
            get: |s| $crate::keys::Recorded::maybe(s.$($f).+.as_ref()),
            copy: |d, s| d.$($f).+ = $crate::keys::dup(&s.$($f).+),
        }
    };
}

macro_rules! path_opt {
    ($t:literal, $k:literal, $n:literal, $recorded:expr, $($f:ident).+) => {
        $crate::keys::Key {
            table: $t, key: $k, name: $n, kind: $crate::keys::Kind::Path, recorded: $recorded,
            set: |s, v| { s.$($f).+ = Some(std::path::PathBuf::from(v.text()?)); Ok(()) },
            check: $crate::keys::no_check,
            get: |s| $crate::keys::Recorded::maybe(s.$($f).+.as_ref().map(|p| p.display())),
            copy: |d, s| d.$($f).+ = $crate::keys::dup(&s.$($f).+),
        }
    };
}

macro_rules! unrecorded_flag {
    ($t:literal, $k:literal, $n:literal, $($f:ident).+) => {
        $crate::keys::Key { recorded: false, ..$crate::keys::flag!($t, $k, $n, $($f).+) }
    };
}

pub(crate) use {
    choice, choice_opt, flag, path_opt, real, real_opt, reals_opt, text_opt, unrecorded_flag,
    whole, whole_opt,
};

/// The keys every system's `[output]` table shares (the volumetric body adds
/// `lattice_frames`), for a scenario type with an `output: Output` field, with the range of
/// `frame_every`.
macro_rules! output_keys {
    ($s:ty, $every:expr) => {{
        let keys: [$crate::keys::Key<$s>; 11] = [
            $crate::keys::path_opt!("output", "out", "out", false, output.out),
            $crate::keys::unrecorded_flag!("output", "overwrite", "overwrite", output.overwrite),
            $crate::keys::unrecorded_flag!("output", "json", "json", output.json),
            $crate::keys::choice!("output", "format", "format", false, output.format),
            $crate::keys::whole!(
                "output",
                "frame_every",
                "frame_every",
                $every,
                output.frame_every
            ),
            $crate::keys::text_opt!("output", "render", "render", output.render),
            $crate::keys::choice_opt!("output", "color", "color", false, output.color),
            $crate::keys::flag!("output", "gif", "gif", output.gif),
            $crate::keys::flag!("output", "pov", "pov", output.pov),
            $crate::keys::Key::<$s> {
                table: "output",
                key: "image_size",
                name: "image_size",
                kind: $crate::keys::Kind::Text,
                recorded: true,
                set: |s, v| {
                    s.output.image_size =
                        $crate::output::parse_image_size(v.text()?).map_err(|e| {
                            $crate::value::SetError::Value($crate::range::ValueError::new(
                                "image_size",
                                v.literal(),
                                Some(e),
                            ))
                        })?;
                    Ok(())
                },
                check: $crate::keys::no_check,
                get: |s| {
                    $crate::keys::Recorded::one(format!(
                        "{}x{}",
                        s.output.image_size.0, s.output.image_size.1
                    ))
                },
                copy: |d, s| d.output.image_size = s.output.image_size,
            },
            $crate::keys::choice!(
                "output",
                "color_range",
                "color_range",
                true,
                output.color_range
            ),
        ];
        keys
    }};
}
pub(crate) use output_keys;

/// The `[[anchors]]` and `[[loads]]` keys, for a scenario type with `anchors: Vec<Pin>` and
/// `loads: Vec<Load>` fields.
macro_rules! anchor_keys {
    ($s:ty) => {
        [
            $crate::keys::Key::<$s> {
                table: "anchors",
                key: "",
                name: "pin",
                kind: $crate::keys::Kind::Tables,
                recorded: true,
                set: |s, v| {
                    s.anchors = $crate::keys::specs(v, "pin", $crate::selection::parse_pin)?;
                    Ok(())
                },
                check: $crate::keys::no_check,
                get: |s| {
                    $crate::keys::Recorded::Tables(
                        s.anchors.iter().map(ToString::to_string).collect(),
                    )
                },
                copy: |d, s| d.anchors.clone_from(&s.anchors),
            },
            $crate::keys::Key::<$s> {
                table: "loads",
                key: "",
                name: "load",
                kind: $crate::keys::Kind::Tables,
                recorded: true,
                set: |s, v| {
                    s.loads = $crate::keys::specs(v, "load", $crate::selection::parse_load)?;
                    Ok(())
                },
                check: $crate::keys::no_check,
                get: |s| {
                    $crate::keys::Recorded::Tables(
                        s.loads.iter().map(ToString::to_string).collect(),
                    )
                },
                copy: |d, s| d.loads.clone_from(&s.loads),
            },
        ]
    };
}
pub(crate) use anchor_keys;

/// The values of a list of specs (a string is a list of one), each parsed by `parse`; a spec
/// that does not parse is an error naming parameter `name` and the spec.
pub fn specs<T>(
    v: &Value,
    name: &str,
    parse: fn(&str) -> Result<T, String>,
) -> Result<Vec<T>, SetError> {
    let one = |v: &Value, i: usize| -> Result<T, SetError> {
        let text = v.text()?;
        parse(text).map_err(|e| {
            let err = ValueError::new(name, text.to_owned(), Some(e));
            SetError::Value(if i > 0 { err.at(i) } else { err })
        })
    };
    match v {
        Value::List(l) => l.iter().enumerate().map(|(i, x)| one(x, i)).collect(),
        _ => Ok(vec![one(v, 0)?]),
    }
}

/// A whole-number field (`usize`, `u32`, `u8`) as a count, for its range check.
pub trait Count: Copy {
    /// The value as a `usize` (saturating).
    fn count(self) -> usize;
}

impl Count for usize {
    fn count(self) -> usize {
        self
    }
}

impl Count for u32 {
    fn count(self) -> usize {
        usize::try_from(self).unwrap_or(usize::MAX)
    }
}

impl Count for u8 {
    fn count(self) -> usize {
        usize::from(self)
    }
}

/// Finds the key of `keys` with parameter name `name`.
pub fn by_name<'k, S>(keys: &'k [Key<S>], name: &str) -> Option<&'k Key<S>> {
    keys.iter().find(|k| k.name == name)
}

/// Every key's range, in table order: the first value outside its range.
pub fn check_all<S>(keys: &[Key<S>], s: &S) -> Result<(), ValueError> {
    keys.iter().try_for_each(|k| (k.check)(s))
}

/// The scale of a mesh (mesh units -> metres): (0, 1e6].
pub const SCALE: Real = Real::new(Open(0.0), Closed(1e6));
/// Each number of an affine map: [-1e6, 1e6].
pub const TRANSFORM: Real = Real::new(Closed(-1e6), Closed(1e6));
/// The stiffness of an anchor without its own, N/m: (0, 1e12].
pub const PIN_STIFFNESS: Real = crate::selection::STIFFNESS;
/// Steps of a run: 0 to 1e8.
pub const STEPS: Whole = Whole::new(0, MAX_STEPS);

/// The `[mesh] path` key (a file, or `builtin[:NAME]`).
macro_rules! mesh_path {
    ($s:ty, $($f:ident).+) => {
        $crate::keys::Key::<$s> {
            table: "mesh",
            key: "path",
            name: "mesh",
            kind: $crate::keys::Kind::Path,
            recorded: true,
            set: |s, v| {
                s.$($f).+ = v.text()?.to_owned();
                Ok(())
            },
            check: $crate::keys::no_check,
            get: |s| $crate::keys::Recorded::one(&s.$($f).+),
            copy: |d, s| d.$($f).+.clone_from(&s.$($f).+),
        }
    };
}
pub(crate) use mesh_path;

/// The `[mesh] transform` key: its numbers in [`TRANSFORM`], and the map itself checked on its
/// own (12 numbers, orientation kept), so a scenario file's error names its line.
macro_rules! mesh_transform {
    ($($f:ident).+) => {
        $crate::keys::Key {
            check: |s| match &s.$($f).+ {
                Some(x) => {
                    $crate::keys::TRANSFORM.check_all("transform", x)?;
                    $crate::keys::check_transform_map(x)
                }
                None => Ok(()),
            },
            ..$crate::keys::reals_opt!(
                "mesh", "transform", "transform", $crate::keys::TRANSFORM, $($f).+
            )
        }
    };
}
pub(crate) use mesh_transform;

/// The map of a `transform` (12 numbers, a positive determinant) as a key's check.
pub(crate) fn check_transform_map(m: &[f64]) -> Result<(), ValueError> {
    let spec = crate::mesh::MeshSpec {
        transform: Some(m.to_vec()),
        ..crate::mesh::MeshSpec::default()
    };
    spec.check_transform().map_err(|why| {
        let why = why
            .strip_prefix("`transform`: ")
            .or_else(|| why.strip_prefix("`transform` "))
            .unwrap_or(&why)
            .to_owned();
        let text: Vec<String> = m.iter().map(|v| crate::range::real_text(*v)).collect();
        ValueError::new("transform", text.join(","), Some(why))
    })
}
