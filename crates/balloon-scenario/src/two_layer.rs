//! The two-layer elastic body's scenario (`balloon two-layer`, Song 2009): the body (`[body]`:
//! dimension, construction, radii, masses, springs), its gases (`[gas]`), gravity, the
//! collision box, the integrator, the drag (`[run]`), the outputs, anchors and loads; and
//! [`TwoLayerScenario::build`].
//!
//! ```
//! use balloon_scenario::two_layer::TwoLayerScenario;
//! let mut s = TwoLayerScenario::default();
//! s.body.level = 1;
//! s.validate().unwrap();
//! let mut sim = s.build().unwrap();
//! balloon::Simulation::step(&mut sim).unwrap();
//! assert_eq!(balloon::Simulation::steps(&sim), 1);
//! ```

use crate::error::ScenarioError;
use crate::keys::{Key, anchor_keys, choice, flag, output_keys, real, real_opt, text_opt, whole};
use crate::keys::{PIN_STIFFNESS, STEPS};
use crate::output::{ColorField, Output, choices};
use crate::range::End::{Closed, Open};
use crate::range::{Real, Whole};
use crate::selection::apply::fix_two_layer;
use crate::selection::{Load, Pin, SelectionError};
use balloon::two_layer::{
    AxisBox, ExplicitMethod, SpringKind, TwoLayerBody, TwoLayerError, TwoLayerSimulation,
};
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

/// The 3D sphere construction (`sphere`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SphereChoice {
    /// Subdivided octahedron (`level`), Song 2009, Sec. 3.5.2.
    Octa,
    /// UV sphere (`slices`, `stacks`), Song 2009, Sec. 3.5.1.
    Uv,
}

choices!(
    SphereChoice,
    "a sphere construction",
    [(SphereChoice::Octa, "octa"), (SphereChoice::Uv, "uv")]
);

/// The `[body]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TwoLayerBodyTable {
    /// Dimension: 1 (hanging spring), 2 (two-layer circle), 3 (two-layer sphere).
    pub dim: u8,
    /// 3D sphere construction.
    #[serde(with = "crate::serde_text")]
    pub sphere: SphereChoice,
    /// Octahedron subdivision level (3D, `octa`).
    pub level: u32,
    /// UV sphere meridians (3D, `uv`).
    pub slices: usize,
    /// UV sphere latitude bands (3D, `uv`).
    pub stacks: usize,
    /// Particles per layer (2D).
    pub particles: usize,
    /// Rest length of the spring (1D), m.
    pub length: f64,
    /// Inner layer radius, m.
    pub inner_radius: f64,
    /// Outer layer radius, m.
    pub outer_radius: f64,
    /// Mass of each inner particle, kg.
    pub inner_mass: f64,
    /// Mass of each outer particle (the free particle in 1D), kg.
    pub outer_mass: f64,
    /// Structural spring stiffness, N/m.
    pub k_structural: f64,
    /// Radius spring stiffness, N/m.
    pub k_radius: f64,
    /// Shear spring stiffness, left and right, N/m.
    pub k_shear: f64,
    /// Left shear spring stiffness, N/m (overrides `k_shear`).
    pub k_shear_left: Option<f64>,
    /// Right shear spring stiffness, N/m (overrides `k_shear`).
    pub k_shear_right: Option<f64>,
    /// Damping of every spring type, N s/m.
    pub damping: f64,
    /// Damping of the structural springs (overrides `damping`).
    pub damping_structural: Option<f64>,
    /// Damping of the radius springs (overrides `damping`).
    pub damping_radius: Option<f64>,
    /// Damping of the shear springs (overrides `damping`).
    pub damping_shear: Option<f64>,
    /// Normalise spring forces by valence (Song 2009, Sec. 3.5.3).
    pub valence_normalization: bool,
}

impl Default for TwoLayerBodyTable {
    fn default() -> Self {
        Self {
            dim: 3,
            sphere: SphereChoice::Octa,
            level: 3,
            slices: 16,
            stacks: 12,
            particles: 24,
            length: 0.5,
            inner_radius: 0.8,
            outer_radius: 1.0,
            inner_mass: 0.01,
            outer_mass: 0.01,
            k_structural: 100.0,
            k_radius: 50.0,
            k_shear: 50.0,
            k_shear_left: None,
            k_shear_right: None,
            damping: 0.1,
            damping_structural: None,
            damping_radius: None,
            damping_shear: None,
            valence_normalization: false,
        }
    }
}

/// The `[gas]` table of a two-layer body: initial pressures at the rest volumes (Pa; N/m in
/// 2D), which fix the gas amounts (`nRT = P0 V0`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TwoLayerGas {
    /// Initial gas pressure of the outer layer.
    pub pressure: f64,
    /// Initial gas pressure of the inner layer.
    pub inner_pressure: f64,
}

impl Default for TwoLayerGas {
    fn default() -> Self {
        Self {
            pressure: 50.0,
            inner_pressure: 25.0,
        }
    }
}

/// The `[run]` table of a two-layer body.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TwoLayerRun {
    /// Gravitational acceleration, m/s^2, along -z (3D), -y (2D), -x (1D).
    pub gravity: f64,
    /// Side of the cubic collision box centred on the body at rest, m.
    #[serde(rename = "box")]
    pub box_size: f64,
    /// No collision box.
    pub no_box: bool,
    /// Restitution of the walls and of the inner layer against the outer.
    pub restitution: f64,
    /// The explicit integrator.
    #[serde(with = "crate::serde_text")]
    pub integrator: ExplicitMethod,
    /// Time step, s.
    pub dt: f64,
    /// Number of steps.
    pub steps: usize,
    /// Drag ("mouse") target `X,Y,Z` (m), optionally in a time window `@T0:T1` (s).
    pub drag: Option<String>,
    /// Drag spring stiffness, N/m.
    pub drag_stiffness: f64,
    /// Drag spring damping, N s/m.
    pub drag_damping: f64,
    /// Stiffness of the anchors without their own, N/m; `None`: hard pins.
    pub pin_stiffness: Option<f64>,
}

impl Default for TwoLayerRun {
    fn default() -> Self {
        Self {
            gravity: 9.81,
            box_size: 4.0,
            no_box: false,
            restitution: 0.5,
            integrator: ExplicitMethod::Rk4,
            dt: 5e-4,
            steps: 2000,
            drag: None,
            drag_stiffness: 10.0,
            drag_damping: 0.1,
            pin_stiffness: None,
        }
    }
}

/// A two-layer body's scenario: the keys of a `kind = "two-layer"` scenario file, typed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TwoLayerScenario {
    /// `[body]`.
    pub body: TwoLayerBodyTable,
    /// `[gas]`.
    pub gas: TwoLayerGas,
    /// `[run]`.
    pub run: TwoLayerRun,
    /// `[output]`.
    pub output: Output,
    /// `[[anchors]]` (on the particles, by their positions at the start).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub anchors: Vec<Pin>,
    /// `[[loads]]`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub loads: Vec<Load>,
}

impl Default for TwoLayerScenario {
    fn default() -> Self {
        Self {
            body: TwoLayerBodyTable::default(),
            gas: TwoLayerGas::default(),
            run: TwoLayerRun::default(),
            output: Output::every(20),
            anchors: Vec::new(),
            loads: Vec::new(),
        }
    }
}

/// A length or radius, m: (0, 1e3].
const LENGTH: Real = Real::new(Open(0.0), Closed(1e3));
/// A particle mass, kg: [1e-9, 1e6] (a lighter particle on a stiff spring has no stable
/// explicit step).
const MASS: Real = Real::new(Closed(1e-9), Closed(1e6));
/// A spring stiffness, N/m: [0, 1e9].
const K: Real = Real::new(Closed(0.0), Closed(1e9));
/// A spring damping, N s/m: [0, 1e6].
const DAMPING: Real = Real::new(Closed(0.0), Closed(1e6));
/// A gas pressure: [0, 1e7].
const PRESSURE: Real = Real::new(Closed(0.0), Closed(1e7));

/// Every key of a two-layer scenario, in the order the recorded scenario writes them.
pub static TWO_LAYER_KEYS: &[Key<TwoLayerScenario>] = &{
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
    ] = output_keys!(TwoLayerScenario, STEPS);
    let [anchors, loads] = anchor_keys!(TwoLayerScenario);
    [
        whole!("body", "dim", "dim", Whole::new(1, 3), body.dim),
        choice!("body", "sphere", "sphere", false, body.sphere),
        whole!("body", "level", "level", Whole::new(0, 7), body.level),
        whole!("body", "slices", "slices", Whole::new(3, 4096), body.slices),
        whole!("body", "stacks", "stacks", Whole::new(2, 4096), body.stacks),
        whole!(
            "body",
            "particles",
            "particles",
            Whole::new(3, 1_000_000),
            body.particles
        ),
        real!("body", "length", "length", LENGTH, body.length),
        real!(
            "body",
            "inner_radius",
            "inner_radius",
            LENGTH,
            body.inner_radius
        ),
        real!(
            "body",
            "outer_radius",
            "outer_radius",
            LENGTH,
            body.outer_radius
        ),
        real!("body", "inner_mass", "inner_mass", MASS, body.inner_mass),
        real!("body", "outer_mass", "outer_mass", MASS, body.outer_mass),
        real!("body", "k_structural", "k_structural", K, body.k_structural),
        real!("body", "k_radius", "k_radius", K, body.k_radius),
        real!("body", "k_shear", "k_shear", K, body.k_shear),
        real_opt!("body", "k_shear_left", "k_shear_left", K, body.k_shear_left),
        real_opt!(
            "body",
            "k_shear_right",
            "k_shear_right",
            K,
            body.k_shear_right
        ),
        real!("body", "damping", "damping", DAMPING, body.damping),
        real_opt!(
            "body",
            "damping_structural",
            "damping_structural",
            DAMPING,
            body.damping_structural
        ),
        real_opt!(
            "body",
            "damping_radius",
            "damping_radius",
            DAMPING,
            body.damping_radius
        ),
        real_opt!(
            "body",
            "damping_shear",
            "damping_shear",
            DAMPING,
            body.damping_shear
        ),
        flag!(
            "body",
            "valence_normalization",
            "valence_normalization",
            body.valence_normalization
        ),
        real!("gas", "pressure", "pressure", PRESSURE, gas.pressure),
        real!(
            "gas",
            "inner_pressure",
            "inner_pressure",
            PRESSURE,
            gas.inner_pressure
        ),
        real!(
            "run",
            "gravity",
            "gravity",
            Real::new(Closed(-1e3), Closed(1e3)),
            run.gravity
        ),
        real!(
            "run",
            "box",
            "box",
            Real::new(Open(0.0), Closed(1e4)),
            run.box_size
        ),
        flag!("run", "no_box", "no_box", run.no_box),
        real!(
            "run",
            "restitution",
            "restitution",
            Real::new(Closed(0.0), Closed(1.0)),
            run.restitution
        ),
        choice!("run", "integrator", "integrator", true, run.integrator),
        real!("run", "dt", "dt", Real::new(Open(0.0), Closed(0.1)), run.dt),
        whole!("run", "steps", "steps", STEPS, run.steps),
        text_opt!("run", "drag", "drag", run.drag),
        real!(
            "run",
            "drag_stiffness",
            "drag_stiffness",
            K,
            run.drag_stiffness
        ),
        real!(
            "run",
            "drag_damping",
            "drag_damping",
            DAMPING,
            run.drag_damping
        ),
        real_opt!(
            "run",
            "pin_stiffness",
            "pin_stiffness",
            PIN_STIFFNESS,
            run.pin_stiffness
        ),
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

/// The colours a two-layer run can draw.
pub const TWO_LAYER_COLORS: &[ColorField] = &[ColorField::Speed, ColorField::Stretch];

/// A parsed drag: the target point (m) and the time window (s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DragSpec {
    /// The point the nearest particle is pulled toward, m.
    pub point: Point3<f64>,
    /// From and until, s.
    pub window: (f64, f64),
}

/// Parses a drag `X,Y,Z[@T0:T1]`; the error names `drag` and the text.
///
/// ```
/// use balloon_scenario::two_layer::parse_drag;
/// let d = parse_drag("0,0,2@0.1:0.5").unwrap();
/// assert_eq!((d.point.z, d.window), (2.0, (0.1, 0.5)));
/// assert!(parse_drag("1,2").is_err());
/// ```
pub fn parse_drag(s: &str) -> Result<DragSpec, String> {
    let (pt, window) = match s.split_once('@') {
        Some((p, w)) => (p, Some(w)),
        None => (s, None),
    };
    let c: Vec<f64> = pt
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("`drag` `{s}`: the point must be X,Y,Z in metres: {e}"))?;
    if c.len() != 3 || c.iter().any(|v| !v.is_finite()) {
        return Err(format!(
            "`drag` `{s}`: the point must be three finite numbers X,Y,Z"
        ));
    }
    let window = match window {
        None => (0.0, f64::INFINITY),
        Some(w) => {
            let (a, b) = w
                .split_once(':')
                .ok_or_else(|| format!("`drag` `{s}`: the time window must be @T0:T1"))?;
            let t0: f64 = a
                .trim()
                .parse()
                .map_err(|e| format!("`drag` `{s}`: bad start time `{a}`: {e}"))?;
            let t1: f64 = b
                .trim()
                .parse()
                .map_err(|e| format!("`drag` `{s}`: bad end time `{b}`: {e}"))?;
            if !(t0.is_finite() && t1 >= t0) {
                return Err(format!("`drag` `{s}`: need finite T0 <= T1"));
            }
            (t0, t1)
        }
    };
    Ok(DragSpec {
        point: Point3::new(c[0], c[1], c[2]),
        window,
    })
}

/// Why a two-layer scenario could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum TwoLayerBuildError {
    /// The collision box is refused.
    #[error("`box` = {size}")]
    Box {
        /// The box side, m.
        size: f64,
        /// Why.
        #[source]
        source: balloon::constraint::ConstraintError,
    },
    /// The body cannot be simulated.
    #[error(transparent)]
    Body(#[from] TwoLayerError),
    /// An anchor cannot be used.
    #[error(transparent)]
    Selection(#[from] SelectionError),
}

impl TwoLayerScenario {
    /// Checks every value against its range and the keys together (the drag, the pictures),
    /// before anything is built.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        crate::keys::check_all(TWO_LAYER_KEYS, self)?;
        let spec = self
            .output
            .check_pictures("two-layer", TWO_LAYER_COLORS)
            .map_err(ScenarioError::Invalid)?;
        if self.body.dim == 1 && (spec.is_some() || self.output.gif || self.output.pov) {
            return Err(ScenarioError::Invalid(
                "`render`, `gif` and `pov` need a surface: use `dim` = 2 or 3 (1D has two \
                 particles)"
                    .into(),
            ));
        }
        self.drag().map_err(ScenarioError::Invalid)?;
        Ok(())
    }

    /// The parsed `drag`, if any.
    pub fn drag(&self) -> Result<Option<DragSpec>, String> {
        self.run.drag.as_deref().map(parse_drag).transpose()
    }

    /// The body with its springs, gases, gravity, box and restitution.
    pub fn body(&self) -> Result<TwoLayerBody, TwoLayerBuildError> {
        let b = &self.body;
        let body = match b.dim {
            1 => TwoLayerBody::line(b.length),
            2 => TwoLayerBody::circle(b.particles),
            _ => match b.sphere {
                SphereChoice::Octa => TwoLayerBody::octahedron_sphere(b.level),
                SphereChoice::Uv => TwoLayerBody::uv_sphere(b.slices, b.stacks),
            },
        };
        let d = b.damping;
        let r = &self.run;
        let collision_box = if r.no_box {
            None
        } else {
            let h = 0.5 * r.box_size;
            Some(
                AxisBox::centered(Point3::origin(), Vector3::new(h, h, h)).map_err(|source| {
                    TwoLayerBuildError::Box {
                        size: r.box_size,
                        source,
                    }
                })?,
            )
        };
        Ok(body
            .with_radii(b.inner_radius, b.outer_radius)
            .with_masses(b.inner_mass, b.outer_mass)
            .with_spring(
                SpringKind::Structural,
                b.k_structural,
                b.damping_structural.unwrap_or(d),
            )
            .with_spring(
                SpringKind::Radius,
                b.k_radius,
                b.damping_radius.unwrap_or(d),
            )
            .with_spring(
                SpringKind::ShearLeft,
                b.k_shear_left.unwrap_or(b.k_shear),
                b.damping_shear.unwrap_or(d),
            )
            .with_spring(
                SpringKind::ShearRight,
                b.k_shear_right.unwrap_or(b.k_shear),
                b.damping_shear.unwrap_or(d),
            )
            .with_pressure(self.gas.pressure, self.gas.inner_pressure)
            .with_gravity(r.gravity)
            .with_box(collision_box)
            .with_restitution(r.restitution)
            .with_valence_normalization(b.valence_normalization))
    }

    /// Builds the simulation: the body, its integrator and time step, and the hard anchors.
    /// The spring anchors and loads are applied by
    /// [`crate::selection::apply::two_layer_loads`]. Writes nothing.
    pub fn build(&self) -> Result<TwoLayerSimulation, TwoLayerBuildError> {
        let body = self.body()?;
        let mut sim = body.simulate(self.run.integrator, self.run.dt)?;
        fix_two_layer(&mut sim, &self.anchors, self.run.pin_stiffness)?;
        Ok(sim)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drag_spec_parses_point_and_window() {
        let d = parse_drag("1, -2.5,3").unwrap();
        assert_eq!(d.point, Point3::new(1.0, -2.5, 3.0));
        assert_eq!(d.window, (0.0, f64::INFINITY));
        let d = parse_drag("0,0,2@0.1:0.5").unwrap();
        assert_eq!(d.window, (0.1, 0.5));
        for bad in ["1,2", "a,b,c", "1,2,3@0.5", "1,2,3@0.5:0.1", "1,2,nan"] {
            assert!(parse_drag(bad).is_err(), "{bad} should not parse");
        }
    }
}
