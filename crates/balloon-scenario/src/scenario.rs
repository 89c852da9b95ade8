//! A scenario of any of the systems ([`Scenario`]): its keys by name, set from untyped values,
//! range-checked, recorded, copied; and the system it describes ([`SystemKind`]).

use crate::connect::{CONNECT_TABLE, ConnectScenario};
use crate::error::ScenarioError;
use crate::keys::{Key, Kind, Recorded};
use crate::output::Output;
use crate::range::ValueError;
use crate::shell::{SHELL_KEYS, ShellScenario};
use crate::two_layer::{TWO_LAYER_KEYS, TwoLayerScenario};
use crate::value::{SetError, Value};
use crate::volumetric::{VOLUMETRIC_KEYS, VolumetricScenario};

/// The system a scenario describes (`[system] kind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SystemKind {
    /// `shell`: a shell balloon (`balloon inflate`).
    Shell,
    /// `connect`: shell balloons joined by tubes (`balloon connect`).
    Connect,
    /// `volumetric`: a volume-conserving body (`balloon volumetric`).
    Volumetric,
    /// `two-layer`: a two-layer body (`balloon two-layer`).
    TwoLayer,
}

crate::output::choices!(
    SystemKind,
    "a system",
    [
        (SystemKind::Shell, "shell"),
        (SystemKind::Connect, "connect"),
        (SystemKind::Volumetric, "volumetric"),
        (SystemKind::TwoLayer, "two-layer"),
    ]
);

impl SystemKind {
    /// Every system.
    pub const ALL: [SystemKind; 4] = [
        SystemKind::Shell,
        SystemKind::Connect,
        SystemKind::Volumetric,
        SystemKind::TwoLayer,
    ];
}

/// A key of a system, without its functions: where it lives and what it takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeyInfo {
    /// Table name.
    pub table: &'static str,
    /// Key in the table (`""` for an array of tables).
    pub key: &'static str,
    /// The parameter's name (the flag with `_`, the Python keyword).
    pub name: &'static str,
    /// Its type.
    pub kind: Kind,
    /// Whether the recorded scenario repeats it.
    pub recorded: bool,
}

fn info<S>(k: &Key<S>) -> KeyInfo {
    KeyInfo {
        table: k.table,
        key: k.key,
        name: k.name,
        kind: k.kind,
        recorded: k.recorded,
    }
}

/// A scenario of one of the systems.
#[derive(Clone, Debug, PartialEq)]
pub enum Scenario {
    /// A shell balloon.
    Shell(ShellScenario),
    /// Connected shell balloons.
    Connect(ConnectScenario),
    /// A volumetric body.
    Volumetric(VolumetricScenario),
    /// A two-layer body.
    TwoLayer(TwoLayerScenario),
}

/// Finds a key by `name` in `keys` and applies `f` to it and `s` (a reference to the
/// scenario); `s` back when there is none.
fn by_name<S: 'static, T, R>(
    keys: &'static [Key<S>],
    name: &str,
    s: T,
    f: impl FnOnce(&'static Key<S>, T) -> R,
) -> Result<R, T> {
    match keys.iter().find(|k| k.name == name) {
        Some(k) => Ok(f(k, s)),
        None => Err(s),
    }
}

impl Scenario {
    /// The defaults of system `kind`.
    pub fn new(kind: SystemKind) -> Self {
        match kind {
            SystemKind::Shell => Scenario::Shell(ShellScenario::default()),
            SystemKind::Connect => Scenario::Connect(ConnectScenario::default()),
            SystemKind::Volumetric => Scenario::Volumetric(VolumetricScenario::default()),
            SystemKind::TwoLayer => Scenario::TwoLayer(TwoLayerScenario::default()),
        }
    }

    /// Its system.
    pub fn kind(&self) -> SystemKind {
        match self {
            Scenario::Shell(_) => SystemKind::Shell,
            Scenario::Connect(_) => SystemKind::Connect,
            Scenario::Volumetric(_) => SystemKind::Volumetric,
            Scenario::TwoLayer(_) => SystemKind::TwoLayer,
        }
    }

    /// The keys of system `kind`, in the order of the recorded scenario.
    pub fn keys(kind: SystemKind) -> Vec<KeyInfo> {
        match kind {
            SystemKind::Shell => SHELL_KEYS.iter().map(info).collect(),
            SystemKind::Connect => SHELL_KEYS
                .iter()
                .map(info)
                .chain(CONNECT_TABLE.iter().map(info))
                .collect(),
            SystemKind::Volumetric => VOLUMETRIC_KEYS.iter().map(info).collect(),
            SystemKind::TwoLayer => TWO_LAYER_KEYS.iter().map(info).collect(),
        }
    }

    /// The key of this system with parameter name `name`, if it has one.
    pub fn key(&self, name: &str) -> Option<KeyInfo> {
        Self::keys(self.kind()).into_iter().find(|k| k.name == name)
    }

    /// The key `[table] key` of this system, if it has one.
    pub fn key_at(&self, table: &str, key: &str) -> Option<KeyInfo> {
        Self::keys(self.kind())
            .into_iter()
            .find(|k| k.table == table && k.key == key)
    }

    /// Sets parameter `name` (a key's name: the flag with `_`, e.g. `newton_iters`, `gas`,
    /// `pin`) from an untyped value: typed, not range-checked ([`Scenario::validate`] does).
    /// An unknown name is a type error naming it.
    pub fn set(&mut self, name: &str, v: &Value) -> Result<(), SetError> {
        let unknown = || SetError::Type(format!("unknown parameter `{name}`"));
        match self {
            Scenario::Shell(s) => {
                by_name(SHELL_KEYS, name, s, |k, s| (k.set)(s, v)).map_err(|_| unknown())?
            }
            Scenario::Connect(c) => match by_name(CONNECT_TABLE, name, c, |k, c| (k.set)(c, v)) {
                Ok(r) => r,
                Err(c) => by_name(SHELL_KEYS, name, &mut c.shell, |k, s| (k.set)(s, v))
                    .map_err(|_| unknown())?,
            },
            Scenario::Volumetric(s) => {
                by_name(VOLUMETRIC_KEYS, name, s, |k, s| (k.set)(s, v)).map_err(|_| unknown())?
            }
            Scenario::TwoLayer(s) => {
                by_name(TWO_LAYER_KEYS, name, s, |k, s| (k.set)(s, v)).map_err(|_| unknown())?
            }
        }
    }

    /// Checks parameter `name` against its range (nothing for an unknown name).
    pub fn check(&self, name: &str) -> Result<(), ValueError> {
        let found = match self {
            Scenario::Shell(s) => by_name(SHELL_KEYS, name, s, |k, s| (k.check)(s)).ok(),
            Scenario::Connect(c) => by_name(CONNECT_TABLE, name, c, |k, c| (k.check)(c))
                .or_else(|c| by_name(SHELL_KEYS, name, &c.shell, |k, s| (k.check)(s)))
                .ok(),
            Scenario::Volumetric(s) => by_name(VOLUMETRIC_KEYS, name, s, |k, s| (k.check)(s)).ok(),
            Scenario::TwoLayer(s) => by_name(TWO_LAYER_KEYS, name, s, |k, s| (k.check)(s)).ok(),
        };
        found.unwrap_or(Ok(()))
    }

    /// How the recorded scenario writes parameter `name` (`None` for an unknown name).
    pub fn recorded(&self, name: &str) -> Option<Recorded> {
        match self {
            Scenario::Shell(s) => by_name(SHELL_KEYS, name, s, |k, s| (k.get)(s)).ok(),
            Scenario::Connect(c) => by_name(CONNECT_TABLE, name, c, |k, c| (k.get)(c))
                .or_else(|c| by_name(SHELL_KEYS, name, &c.shell, |k, s| (k.get)(s)))
                .ok(),
            Scenario::Volumetric(s) => by_name(VOLUMETRIC_KEYS, name, s, |k, s| (k.get)(s)).ok(),
            Scenario::TwoLayer(s) => by_name(TWO_LAYER_KEYS, name, s, |k, s| (k.get)(s)).ok(),
        }
    }

    /// Copies parameter `name`'s value from `other` (a scenario of the same system; nothing
    /// for another system or an unknown name): a front end's overrides of a file's keys.
    pub fn copy_from(&mut self, other: &Scenario, name: &str) {
        match (self, other) {
            (Scenario::Shell(d), Scenario::Shell(s)) => {
                let _ = by_name(SHELL_KEYS, name, d, |k, d| (k.copy)(d, s));
            }
            (Scenario::Connect(d), Scenario::Connect(s)) => {
                if let Err(d) = by_name(CONNECT_TABLE, name, d, |k, d| (k.copy)(d, s)) {
                    let _ = by_name(SHELL_KEYS, name, &mut d.shell, |k, d| (k.copy)(d, &s.shell));
                }
            }
            (Scenario::Volumetric(d), Scenario::Volumetric(s)) => {
                let _ = by_name(VOLUMETRIC_KEYS, name, d, |k, d| (k.copy)(d, s));
            }
            (Scenario::TwoLayer(d), Scenario::TwoLayer(s)) => {
                let _ = by_name(TWO_LAYER_KEYS, name, d, |k, d| (k.copy)(d, s));
            }
            _ => {}
        }
    }

    /// Checks every value against its range and the keys together ([`ShellScenario::validate`]
    /// and the others), before anything is read or built.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        match self {
            Scenario::Shell(s) => s.validate(),
            Scenario::Connect(s) => s.validate(),
            Scenario::Volumetric(s) => s.validate(),
            Scenario::TwoLayer(s) => s.validate(),
        }
    }

    /// The `[output]` table.
    pub fn output(&self) -> &Output {
        match self {
            Scenario::Shell(s) => &s.output,
            Scenario::Connect(s) => &s.shell.output,
            Scenario::Volumetric(s) => &s.output,
            Scenario::TwoLayer(s) => &s.output,
        }
    }

    /// The `[output]` table, to change.
    pub fn output_mut(&mut self) -> &mut Output {
        match self {
            Scenario::Shell(s) => &mut s.output,
            Scenario::Connect(s) => &mut s.shell.output,
            Scenario::Volumetric(s) => &mut s.output,
            Scenario::TwoLayer(s) => &mut s.output,
        }
    }
}
