//! Anchors and loads written as specs: an anchor `SELECTOR[@K]` ([`parse_pin`]), a load
//! `KEY=VALUE;...` ([`parse_load`]): `gravity=GX,GY,GZ` (m/s^2),
//! `force=FX,FY,FZ;on=SELECTOR[;per=vertex|total]` (N: on each vertex, or the total spread
//! evenly over the selection) or `grab=X,Y,Z;on=SELECTOR;stiffness=K` (the vertices pulled
//! toward a point by springs of K N/m each), each active from `start` (s, default 0) until
//! `end` (s, default for ever).
//!
//! ```
//! use balloon_scenario::selection::{LoadKind, parse_load, parse_pin};
//! let p = parse_pin("below:y:0.5@250").unwrap();
//! assert_eq!(p.stiffness, Some(250.0));
//! assert_eq!(p.to_string(), "below:y:0.5@250.0");
//! let l = parse_load("grab=0,0,0.3;on=above:z:0.09;stiffness=100;end=2").unwrap();
//! assert!(matches!(l.kind, LoadKind::Grab { stiffness: 100.0, .. }) && l.end == 2.0);
//! assert!(parse_load("force=0,0,1").unwrap_err().contains("on="));
//! ```

use super::selector::{Selector, numbers, parse_selector, spec_real, stiffness};
use crate::range::{End, Real};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// An anchor: a selection, hard or with its own spring stiffness. Its serde form is the table
/// `{ spec = "SELECTOR[@K]" }` of a scenario file's `[[anchors]]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "SpecForm", into = "SpecForm")]
pub struct Pin {
    /// The pinned vertices.
    pub selector: Selector,
    /// Spring stiffness, N/m (`@K`); `None` takes the scenario's `pin_stiffness`, or pins hard.
    pub stiffness: Option<f64>,
}

/// `SELECTOR[@K]`.
pub fn parse_pin(s: &str) -> Result<Pin, String> {
    let (sel, k) = match s.rsplit_once('@') {
        Some((sel, k)) => (sel, Some(stiffness(k)?)),
        None => (s, None),
    };
    Ok(Pin {
        selector: parse_selector(sel)?,
        stiffness: k,
    })
}

impl std::fmt::Display for Pin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.selector)?;
        if let Some(k) = self.stiffness {
            write!(f, "@{k:?}")?;
        }
        Ok(())
    }
}

/// What a load does.
#[derive(Clone, Debug, PartialEq)]
pub enum LoadKind {
    /// Gravity, m/s^2, on every vertex (its lumped mass times g).
    Gravity([f64; 3]),
    /// A constant force, N, on each selected vertex (or in total, spread evenly).
    Force {
        /// The force.
        force: [f64; 3],
        /// The total over the selection rather than per vertex.
        total: bool,
    },
    /// The selected vertices pulled toward a point by zero-length springs.
    Grab {
        /// The point, m.
        target: [f64; 3],
        /// Stiffness per vertex, N/m.
        stiffness: f64,
    },
}

/// A load, active for `start <= t < end`. Its serde form is the table `{ spec = "..." }` of a
/// scenario file's `[[loads]]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "SpecForm", into = "SpecForm")]
pub struct Load {
    /// What it does.
    pub kind: LoadKind,
    /// Where (forces and grabs).
    pub on: Option<Selector>,
    /// From, s.
    pub start: f64,
    /// Until, s (infinite: for ever).
    pub end: f64,
}

/// `KEY=VALUE;...` (see the module docs).
pub fn parse_load(s: &str) -> Result<Load, String> {
    let mut kind = None;
    let (mut on, mut per, mut k, mut start, mut end) = (None, None, None, 0.0, f64::INFINITY);
    for part in s.split(';').map(str::trim).filter(|p| !p.is_empty()) {
        let (key, value) = part
            .split_once('=')
            .ok_or_else(|| format!("`{part}`: expected KEY=VALUE"))?;
        let value = value.trim();
        let set_kind = |kind: &mut Option<(&'static str, [f64; 3])>, name| {
            if kind.is_some() {
                return Err("a load has one of gravity, force or grab".to_owned());
            }
            *kind = Some((name, numbers::<3>(value)?));
            Ok(())
        };
        match key.trim() {
            "gravity" => set_kind(&mut kind, "gravity")?,
            "force" => set_kind(&mut kind, "force")?,
            "grab" => set_kind(&mut kind, "grab")?,
            "on" => on = Some(parse_selector(value)?),
            "per" => {
                per = Some(match value {
                    "vertex" => false,
                    "total" => true,
                    _ => return Err(format!("per=`{value}`: expected vertex or total")),
                })
            }
            "stiffness" => k = Some(stiffness(value)?),
            "start" => start = spec_real(value, TIME)?,
            "end" => end = spec_real(value, TIME)?,
            other => {
                return Err(format!(
                    "`{other}` is not a load key (gravity, force, grab, on, per, stiffness, start, end)"
                ));
            }
        }
    }
    let (name, v) = kind.ok_or_else(|| format!("`{s}`: no gravity=, force= or grab="))?;
    if end <= start {
        return Err(format!("`{s}`: end must be after start"));
    }
    let kind = match name {
        "gravity" => {
            if on.is_some() || per.is_some() || k.is_some() {
                return Err("gravity acts on every vertex: no on=, per= or stiffness=".into());
            }
            LoadKind::Gravity(v)
        }
        "force" => {
            if k.is_some() {
                return Err("a force has no stiffness=".into());
            }
            LoadKind::Force {
                force: v,
                total: per.unwrap_or(false),
            }
        }
        _ => {
            if per.is_some() {
                return Err("a grab has no per=".into());
            }
            LoadKind::Grab {
                target: v,
                stiffness: k.ok_or("a grab needs stiffness=K (N/m)")?,
            }
        }
    };
    if name != "gravity" && on.is_none() {
        return Err(format!("`{s}`: on=SELECTOR is missing"));
    }
    Ok(Load {
        kind,
        on,
        start,
        end,
    })
}

impl std::fmt::Display for Load {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = |a: &[f64; 3]| format!("{:?},{:?},{:?}", a[0], a[1], a[2]);
        match &self.kind {
            LoadKind::Gravity(g) => write!(f, "gravity={}", v(g))?,
            LoadKind::Force { force, total } => write!(
                f,
                "force={};per={}",
                v(force),
                if *total { "total" } else { "vertex" }
            )?,
            LoadKind::Grab { target, stiffness } => {
                write!(f, "grab={};stiffness={stiffness:?}", v(target))?
            }
        }
        if let Some(on) = &self.on {
            write!(f, ";on={on}")?;
        }
        if self.start > 0.0 {
            write!(f, ";start={:?}", self.start)?;
        }
        if self.end.is_finite() {
            write!(f, ";end={:?}", self.end)?;
        }
        Ok(())
    }
}

/// The range of a load's `start` and `end`, s: [0, 1e9].
const TIME: Real = Real::new(End::Closed(0.0), End::Closed(1e9));

/// The serde form of an anchor or a load: its spec.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SpecForm {
    spec: String,
}

impl TryFrom<SpecForm> for Pin {
    type Error = String;
    fn try_from(f: SpecForm) -> Result<Self, String> {
        parse_pin(&f.spec)
    }
}

impl From<Pin> for SpecForm {
    fn from(p: Pin) -> Self {
        SpecForm {
            spec: p.to_string(),
        }
    }
}

impl TryFrom<SpecForm> for Load {
    type Error = String;
    fn try_from(f: SpecForm) -> Result<Self, String> {
        parse_load(&f.spec)
    }
}

impl From<Load> for SpecForm {
    fn from(l: Load) -> Self {
        SpecForm {
            spec: l.to_string(),
        }
    }
}

/// Rewrites an anchor (`flag` = `pin`) or a load (`load`) spec so that a `file:` path is absolute (`relative_to`:
/// joined to that folder first), for scenario files and the recorded scenario. Values that do
/// not parse are returned unchanged (the parser reports them).
pub fn rewrite_paths(flag: &str, value: &str, relative_to: Option<&Path>) -> String {
    let fix = |s: Selector| match relative_to {
        Some(base) => s.relative_to(base),
        None => s.absolute(),
    };
    match flag {
        "pin" => parse_pin(value).map_or_else(
            |_| value.to_owned(),
            |p| {
                Pin {
                    selector: fix(p.selector),
                    ..p
                }
                .to_string()
            },
        ),
        "load" => parse_load(value).map_or_else(
            |_| value.to_owned(),
            |l| {
                Load {
                    on: l.on.map(fix),
                    ..l
                }
                .to_string()
            },
        ),
        _ => value.to_owned(),
    }
}
