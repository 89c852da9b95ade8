//! Connected shell balloons (`balloon connect`): every key of the shell and the `[connect]`
//! table (the balloons: copies of one mesh or its components, their pre-inflation, the tubes
//! and their conductance); and [`ConnectScenario::build`], which sets the run up.
//!
//! ```
//! use balloon_scenario::connect::{ConnectScenario, TubeList};
//! let mut s = ConnectScenario::default();
//! s.shell.mesh.path = "builtin:icosphere".into();
//! s.connect.copies = Some(2);
//! s.connect.pressures = Some(vec![500.0, 1000.0]);
//! s.validate().unwrap();
//! let (sim, layout) = s.build().unwrap();
//! assert_eq!((sim.balloons().len(), layout), (2, "copies"));
//! assert_eq!("0-1,1-2".parse::<TubeList>().unwrap().0, vec![(0, 1), (1, 2)]);
//! ```

use crate::error::ScenarioError;
use crate::gas::GasControl;
use crate::keys::{Key, Kind, Recorded, flag, no_check, reals_opt, whole_opt};
use crate::range::End::{Closed, Open};
use crate::range::{Real, ValueError, Whole, real_text};
use crate::shell::{SHELL_KEYS, ShellBuildError, ShellScenario, ShellSim};
use crate::value::{SetError, Value, parse_choice};
use balloon::mesh::TriMesh;
use balloon::mesh::topology::Topology;
use balloon::shell::ShellMaterialModel;
use balloon::shell::connected::{Conductance, ConnectedBalloons, Tube};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Most balloons a run may connect.
pub const MAX_BALLOONS: usize = 1000;

/// Steps in a row that must meet the tolerances for `until_settled`.
pub const SETTLE_STEPS: usize = 20;

/// Tubes given as `A-B` pairs of balloon indices (`"0-1,1-2"`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TubeList(pub Vec<(usize, usize)>);

impl FromStr for TubeList {
    type Err = String;
    /// A comma list of `A-B` pairs of 0-based balloon indices.
    fn from_str(s: &str) -> Result<Self, String> {
        let mut out = Vec::new();
        for part in s.split(',') {
            let part = part.trim();
            let pair = part.split_once('-').and_then(|(a, b)| {
                Some((
                    a.trim().parse::<usize>().ok()?,
                    b.trim().parse::<usize>().ok()?,
                ))
            });
            match pair {
                Some((a, b)) if a != b => out.push((a, b)),
                Some(_) => return Err(format!("`{part}` joins a balloon to itself")),
                None => {
                    return Err(format!(
                        "`{part}` is not a pair A-B of balloon indices (0-based, e.g. 0-1,1-2)"
                    ));
                }
            }
        }
        Ok(TubeList(out))
    }
}

impl fmt::Display for TubeList {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let pairs: Vec<String> = self.0.iter().map(|(a, b)| format!("{a}-{b}")).collect();
        f.write_str(&pairs.join(","))
    }
}

/// A tube conductance as text: `instant` or a number (its range is checked with the others).
pub fn parse_conductance(s: &str) -> Result<Conductance, String> {
    if s.trim().eq_ignore_ascii_case("instant") {
        return Ok(Conductance::Instant);
    }
    crate::range::parse_real(s)
        .map(Conductance::Finite)
        .map_err(|e| format!("{e}, or `instant`"))
}

/// The range of a tube conductance, m^3/s: (0, 1e6].
const CONDUCTANCE: Real = Real::new(Open(0.0), Closed(1e6));

/// The `[connect]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ConnectTable {
    /// Connect this many copies of the mesh, side by side along x; `None`: the balloons are the
    /// mesh's connected components.
    pub copies: Option<usize>,
    /// Pre-inflate each balloon statically to this linear stretch `(V / V0)^(1/3)`, each in
    /// [1, 10] (below 1 the membrane would be squeezed and crumple, so it is refused).
    pub stretches: Option<Vec<f64>>,
    /// Start each balloon at rest holding the ideal gas at this gauge pressure, Pa.
    pub pressures: Option<Vec<f64>>,
    /// The tubes (default: a chain 0-1, 1-2, ...).
    #[serde(with = "crate::serde_text::option")]
    pub tubes: Option<TubeList>,
    /// Conductance of every tube, m^3/s, or instant equalisation.
    pub conductance: Conductance,
    /// Stop when, for 20 steps in a row, every balloon's per-step relative gas volume change
    /// is below `volume_tol` and its largest vertex speed below `speed_tol`.
    pub until_settled: bool,
}

impl Default for ConnectTable {
    fn default() -> Self {
        Self {
            copies: None,
            stretches: None,
            pressures: None,
            tubes: None,
            conductance: Conductance::Instant,
            until_settled: false,
        }
    }
}

/// Connected balloons' scenario: the shell's keys and the `[connect]` table.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ConnectScenario {
    /// Every shell key (mesh, material, wall, time stepping, solvers, output).
    #[serde(flatten)]
    pub shell: ShellScenario,
    /// `[connect]`.
    pub connect: ConnectTable,
}

/// The keys of the `[connect]` table (the others are [`SHELL_KEYS`]).
pub static CONNECT_TABLE: &[Key<ConnectScenario>] = &[
    whole_opt!(
        "connect",
        "copies",
        "copies",
        Whole::new(1, MAX_BALLOONS),
        connect.copies
    ),
    reals_opt!(
        "connect",
        "stretches",
        "stretches",
        Real::new(Open(0.0), Closed(10.0)),
        connect.stretches
    ),
    reals_opt!(
        "connect",
        "pressures",
        "pressures",
        Real::new(Closed(-1e7), Closed(1e7)),
        connect.pressures
    ),
    Key {
        table: "connect",
        key: "tubes",
        name: "tubes",
        kind: Kind::Text,
        recorded: true,
        set: |s, v| {
            s.connect.tubes = Some(parse_choice("tubes", v.text()?, true)?);
            Ok(())
        },
        check: no_check,
        get: |s| Recorded::maybe(s.connect.tubes.as_ref()),
        copy: |d, s| d.connect.tubes.clone_from(&s.connect.tubes),
    },
    Key {
        table: "connect",
        key: "conductance",
        name: "conductance",
        kind: Kind::NumberOrText,
        recorded: true,
        set: |s, v| {
            s.connect.conductance = match v {
                Value::Text(t) => parse_conductance(t).map_err(|e| {
                    SetError::Value(ValueError::new("conductance", t.clone(), Some(e)))
                })?,
                Value::Int(_) | Value::Float(_) => Conductance::Finite(v.real()?),
                _ => return Err(SetError::Type(v.expected("a number or a string"))),
            };
            Ok(())
        },
        check: |s| match s.connect.conductance {
            Conductance::Finite(k) if !CONDUCTANCE.contains(k) => Err(ValueError::new(
                "conductance",
                real_text(k),
                Some(format!("{}, or `instant`", CONDUCTANCE.reason())),
            )),
            _ => Ok(()),
        },
        get: |s| match s.connect.conductance {
            Conductance::Finite(k) => Recorded::one(k),
            Conductance::Instant => Recorded::one("instant"),
        },
        copy: |d, s| d.connect.conductance = s.connect.conductance,
    },
    flag!(
        "connect",
        "until_settled",
        "until_settled",
        connect.until_settled
    ),
];

/// The connected balloons a scenario builds.
pub type ConnectSim = ConnectedBalloons<ShellMaterialModel>;

/// The mesh's connected components (through shared edges) as separate meshes, in the order of
/// their first triangle; vertices used by no triangle are dropped.
pub fn split_components(mesh: &TriMesh) -> Vec<TriMesh> {
    let (label, count) = Topology::new(mesh).triangle_components();
    let mut parts: Vec<(Vec<usize>, Vec<[usize; 3]>)> = vec![(Vec::new(), Vec::new()); count];
    let mut index = vec![usize::MAX; mesh.num_vertices()];
    for (t, &c) in mesh.triangles.iter().zip(&label) {
        let (verts, tris) = &mut parts[c];
        let tri = t.map(|v| {
            if index[v] == usize::MAX {
                index[v] = verts.len();
                verts.push(v);
            }
            index[v]
        });
        tris.push(tri);
    }
    parts
        .into_iter()
        .map(|(verts, tris)| TriMesh::new(verts.iter().map(|&v| mesh.vertices[v]).collect(), tris))
        .collect()
}

impl ConnectScenario {
    /// Checks every value against its range and the keys together: the shell's, and the keys
    /// a connected run does not use (the gas is the isothermal ideal gas; `static`,
    /// `pressure`, `pump_rate`, anchors and loads are refused), the pre-inflation.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        crate::keys::check_all(SHELL_KEYS, &self.shell)?;
        crate::keys::check_all(CONNECT_TABLE, self)?;
        self.check_together().map_err(ScenarioError::Invalid)
    }

    fn check_together(&self) -> Result<(), String> {
        let s = &self.shell;
        s.shell.material.resolve()?;
        s.mesh.check_transform()?;
        s.output
            .check_pictures("connect", crate::shell::SHELL_COLORS)?;
        if s.run.steps == 0 {
            return Err("nothing to do: `steps` is 0".into());
        }
        if !matches!(s.gas.model, GasControl::Ideal | GasControl::Pump) {
            return Err(format!(
                "`gas` = {}: connected balloons hold the isothermal ideal gas (leave `gas` out \
                 or give `gas` = ideal)",
                s.gas.model
            ));
        }
        let refused = [
            (s.run.static_solve, "static", ""),
            (s.gas.volume_ratio.is_some(), "volume_ratio", ""),
            (s.gas.volume_ratios.is_some(), "volume_ratios", ""),
            (s.gas.pump_rate.is_some(), "pump_rate", ""),
            (!s.anchors.is_empty(), "pin", ""),
            (!s.loads.is_empty(), "load", ""),
            (
                s.gas.pressure != balloon::shell::DEFAULT_GAUGE_PRESSURE,
                "pressure",
                " (give `pressures`, one gauge pressure per balloon, or `stretches`)",
            ),
        ];
        if let Some((_, name, hint)) = refused.iter().find(|(given, ..)| *given) {
            return Err(format!("`{name}`: not used by connected balloons{hint}"));
        }
        if let Some((i, l)) = self
            .connect
            .stretches
            .iter()
            .flatten()
            .enumerate()
            .find(|(_, l)| **l < 1.0)
        {
            return Err(format!(
                "`stretches`: balloon {i} has the stretch {l}, below 1: pre-inflating to less \
                 than the rest volume squeezes the membrane, which holds no compression and \
                 crumples; give stretches of at least 1 (1 is the rest shape), or `pressures` \
                 (a negative gauge pressure) to start a balloon deflating"
            ));
        }
        match (&self.connect.stretches, &self.connect.pressures) {
            (None, None) => Err(
                "give `stretches` (pre-inflate each balloon to a stretch) or `pressures` (start \
                 each at a gauge pressure), one value per balloon"
                    .into(),
            ),
            (Some(_), Some(_)) => Err("give `stretches` or `pressures`, not both".into()),
            _ => Ok(()),
        }
    }

    /// The balloons' meshes: `copies` of the mesh side by side along x (the spacing from the
    /// bounding box and the largest start stretch), or its components.
    pub fn balloon_meshes(&self) -> Result<(Vec<TriMesh>, &'static str), ShellBuildError> {
        let s = &self.shell;
        let mesh = s.mesh.load().map_err(|e| match e {
            crate::mesh::LoadError::Transform(m) => ShellBuildError::Invalid(m),
            e => ShellBuildError::Mesh(e),
        })?;
        let Some(n) = self.connect.copies else {
            let parts = split_components(&mesh);
            if parts.len() < 2 {
                return Err(ShellBuildError::Invalid(format!(
                    "`{}` has {} connected component(s): give `copies` = N to connect N copies \
                     of it, or a mesh whose components are the balloons",
                    s.mesh.path,
                    parts.len()
                )));
            }
            return Ok((parts, "components"));
        };
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for p in &mesh.vertices {
            lo = lo.min(p.x);
            hi = hi.max(p.x);
        }
        let grow = self
            .connect
            .stretches
            .iter()
            .flatten()
            .copied()
            .fold(1.5_f64, f64::max);
        let spacing = 1.3 * grow * (hi - lo);
        Ok((
            (0..n)
                .map(|i| {
                    let mut m = mesh.clone();
                    for p in &mut m.vertices {
                        p.x += spacing * i as f64;
                    }
                    m
                })
                .collect(),
            "copies",
        ))
    }

    /// The tubes: `tubes` or a chain, each with `conductance`; an index out of range names
    /// the key.
    pub fn tubes(&self, n: usize) -> Result<Vec<Tube>, String> {
        let pairs = match &self.connect.tubes {
            Some(t) => t.0.clone(),
            None => (1..n).map(|i| (i - 1, i)).collect(),
        };
        if let Some((a, b)) = pairs.iter().find(|(a, b)| *a >= n || *b >= n) {
            return Err(format!(
                "`tubes`: {a}-{b} names a balloon beyond the {n} there are (indices 0 to {})",
                n - 1
            ));
        }
        Ok(pairs
            .into_iter()
            .map(|(a, b)| Tube {
                a,
                b,
                conductance: self.connect.conductance,
            })
            .collect())
    }

    /// Builds the connected balloons: loads and places the meshes, builds every balloon as a
    /// shell run does (with the ideal gas, at its own `pressures` value), pre-inflates them to
    /// their `stretches` and joins them. Returns the balloons and their layout (`copies` or
    /// `components`). Writes nothing.
    pub fn build(&self) -> Result<(ConnectSim, &'static str), ShellBuildError> {
        let (meshes, layout) = self.balloon_meshes()?;
        let n = meshes.len();
        let tubes = self.tubes(n).map_err(ShellBuildError::Invalid)?;
        let per_balloon = |name: &str, values: &Option<Vec<f64>>| match values {
            Some(v) if v.len() != n => Err(ShellBuildError::Invalid(format!(
                "`{name}` has {} value(s) but there are {n} balloons (one value per balloon)",
                v.len()
            ))),
            v => Ok(v.clone()),
        };
        let stretches = per_balloon("stretches", &self.connect.stretches)?;
        let pressures = per_balloon("pressures", &self.connect.pressures)?;
        let mut shell = self.shell.clone();
        shell.gas.model = GasControl::Ideal;
        let options = shell.static_options();
        let mut balloons: Vec<ShellSim> = Vec::with_capacity(n);
        for (i, mesh) in meshes.into_iter().enumerate() {
            if let Some(p) = &pressures {
                shell.gas.pressure = p[i];
            }
            let (mut sim, _) = shell
                .build(Some(mesh))
                .map_err(|e| ShellBuildError::Invalid(format!("balloon {i}: {}", chain(&e))))?;
            if let Some(l) = &stretches {
                let target = sim.rest_gas_volume() * l[i].powi(3);
                sim.inflate_to_volume(target, &options).map_err(|e| {
                    ShellBuildError::Invalid(format!(
                        "balloon {i}: pre-inflating to the stretch {} (`stretches`): {e}",
                        l[i]
                    ))
                })?;
            }
            balloons.push(sim);
        }
        let sim = ConnectedBalloons::new(balloons, tubes).map_err(|source| {
            ShellBuildError::Invalid(format!("connecting the balloons: {source}"))
        })?;
        Ok((sim, layout))
    }
}

/// An error and its causes joined by `: ` (skipping a cause the message already holds).
fn chain(e: &dyn std::error::Error) -> String {
    let mut msg = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let text = s.to_string();
        if !msg.contains(&text) {
            msg = format!("{msg}: {text}");
        }
        source = s.source();
    }
    msg
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tubes_and_conductances_parse_and_refuse_nonsense() {
        assert_eq!(
            "0-1, 1-2".parse::<TubeList>().unwrap(),
            TubeList(vec![(0, 1), (1, 2)])
        );
        for bad in ["0-0", "0", "a-b", "0-1,", "-1-2"] {
            assert!(bad.parse::<TubeList>().is_err(), "{bad}");
        }
        assert_eq!(parse_conductance("instant").unwrap(), Conductance::Instant);
        assert_eq!(parse_conductance("2.5").unwrap(), Conductance::Finite(2.5));
        let mut s = ConnectScenario::default();
        for bad in [0.0, -1.0, f64::INFINITY, f64::NAN] {
            s.connect.conductance = Conductance::Finite(bad);
            let e = crate::keys::check_all(CONNECT_TABLE, &s).unwrap_err();
            assert!(e.to_string().contains("instant"), "{bad}: {e}");
        }
        assert!(parse_conductance("fast").unwrap_err().contains("instant"));
    }

    #[test]
    fn components_become_separate_meshes() {
        let a = balloon::mesh::generate::icosphere(0.1, 1).unwrap();
        let n = a.num_vertices();
        let mut both = a.clone();
        both.vertices
            .extend(a.vertices.iter().map(|p| p + nalgebra::Vector3::x() * 0.5));
        both.triangles
            .extend(a.triangles.iter().map(|t| t.map(|i| i + n)));
        let parts = split_components(&both);
        assert_eq!(parts.len(), 2);
        for (k, p) in parts.iter().enumerate() {
            assert_eq!(p.num_vertices(), n);
            assert_eq!(p.triangles.len(), a.triangles.len());
            let x = p.vertices.iter().map(|v| v.x).sum::<f64>() / n as f64;
            assert!((x - 0.5 * k as f64).abs() < 1e-12, "{x}");
            let volume = balloon::mesh::geometry::enclosed_volume;
            assert!((volume(p) / volume(&a) - 1.0).abs() < 1e-12);
        }
    }
}
