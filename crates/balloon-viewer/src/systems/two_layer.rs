//! The two-layer body (Song 2009) in the viewer.

use super::view::*;
use crate::ViewerError;
use crate::protocol::{ControlSpec, ControlValue};
use balloon::Simulation;
use balloon::fields;
use balloon::two_layer::{
    AxisBox, DragTarget, ExplicitMethod, SpringKind, TwoLayerBody, TwoLayerSimulation,
};
use nalgebra::{Point3, Vector3};
use serde_json::{Map, Value, json};

#[derive(Clone, Debug)]
pub(super) struct TwoLayerSettings {
    pub(super) pressure: f64,
    pub(super) integrator: ExplicitMethod,
    pub(super) gravity: f64,
    pub(super) dt: f64,
    pub(super) wall_box: bool,
}

/// One control of the two-layer view, parsed from the protocol once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum TwoLayerControl {
    /// `pressure`, Pa (rebuilds).
    Pressure(f64),
    /// `integrator` (live).
    Integrator(ExplicitMethod),
    /// `gravity`, m/s^2 (rebuilds).
    Gravity(f64),
    /// `dt`, s (live).
    Dt(f64),
    /// `box` (rebuilds).
    WallBox(bool),
}

impl TwoLayerControl {
    pub(super) fn parse(name: &str, value: &ControlValue) -> Result<Self, ViewerError> {
        Ok(match name {
            "pressure" => Self::Pressure(number(name, value)?),
            "integrator" => {
                let c = choice(name, value)?;
                Self::Integrator(c.parse().map_err(|_| unknown_choice(name, c))?)
            }
            "gravity" => Self::Gravity(number(name, value)?),
            "dt" => Self::Dt(number(name, value)?),
            "box" => Self::WallBox(boolean(name, value)?),
            other => return Err(ViewerError::UnknownControl(other.to_string())),
        })
    }
}

/// Subdivision level of the view's octahedron sphere (258 particles per layer).
pub(super) const TWO_LAYER_LEVEL: u32 = 3;
/// Inner and outer radius of the view's body, m.
pub(super) const TWO_LAYER_RADII: (f64, f64) = (0.8, 1.0);
/// Spring damping of the view's body, N s/m.
pub(super) const TWO_LAYER_DAMPING: f64 = 0.1;
/// Stiffness (N/m) and damping (N s/m) of the view's structural springs.
pub(super) const TWO_LAYER_STRUCTURAL: (f64, f64) = (100.0, 0.1);
/// Side of the view's wall box, m.
pub(super) const TWO_LAYER_BOX: f64 = 4.0;

/// A two-layer sphere (Song 2009) in a box in the viewer.
pub struct TwoLayerView {
    pub(super) settings: TwoLayerSettings,
    pub(super) sim: TwoLayerSimulation,
    pub(super) drag: Option<DragRequest>,
}

/// Drag spring of the two-layer view (Song 2009, Sec. 4.4): stiffness N/m and damping N s/m (the
/// damping keeps the whole 5 kg body from swinging about the target; `c dt / m` stays below 1
/// for a 0.01 kg particle at the largest dt).
const TWO_LAYER_DRAG: (f64, f64) = (20.0, 4.0);

impl TwoLayerView {
    /// A two-layer octahedron sphere (level 3) with the default controls.
    pub fn new() -> Result<Self, ViewerError> {
        let settings = TwoLayerSettings {
            pressure: 50.0,
            integrator: ExplicitMethod::Rk4,
            gravity: 9.81,
            dt: 5e-4,
            wall_box: true,
        };
        let sim = Self::build(&settings)?;
        Ok(Self {
            settings,
            sim,
            drag: None,
        })
    }

    fn build(s: &TwoLayerSettings) -> Result<TwoLayerSimulation, ViewerError> {
        let collision_box = if s.wall_box {
            Some(
                AxisBox::centered(Point3::origin(), Vector3::repeat(0.5 * TWO_LAYER_BOX))
                    .map_err(ViewerError::from)?,
            )
        } else {
            None
        };
        let (inner, outer) = TWO_LAYER_RADII;
        let (k, c) = TWO_LAYER_STRUCTURAL;
        TwoLayerBody::octahedron_sphere(TWO_LAYER_LEVEL)
            .with_radii(inner, outer)
            .with_damping(TWO_LAYER_DAMPING)
            .with_spring(SpringKind::Structural, k, c)
            .with_pressure(s.pressure, 0.5 * s.pressure)
            .with_gravity(s.gravity)
            .with_box(collision_box)
            .simulate(s.integrator, s.dt)
            .map_err(ViewerError::from)
    }

    /// Applies a control; `true` when the simulation must be rebuilt.
    fn apply(&mut self, control: TwoLayerControl) -> Result<bool, ViewerError> {
        let s = &mut self.settings;
        match control {
            TwoLayerControl::Pressure(p) => s.pressure = p,
            TwoLayerControl::Gravity(g) => s.gravity = g,
            TwoLayerControl::WallBox(on) => s.wall_box = on,
            TwoLayerControl::Integrator(method) => {
                self.sim.set_method(method);
                s.integrator = method;
                return Ok(false);
            }
            TwoLayerControl::Dt(dt) => {
                TwoLayerSimulation::set_dt(&mut self.sim, dt).map_err(ViewerError::from)?;
                s.dt = dt;
                return Ok(false);
            }
        }
        Ok(true)
    }
}

impl ViewSystem for TwoLayerView {
    fn name(&self) -> &'static str {
        "two-layer"
    }

    fn controls(&self) -> Vec<ControlSpec> {
        let s = &self.settings;
        vec![
            ControlSpec::number(
                "pressure",
                "Gas amount (outer pressure at rest; inner half of it)",
                s.pressure,
                (0.0, 500.0, 5.0),
                "Pa",
                true,
            ),
            ControlSpec::choice(
                "integrator",
                "Integrator",
                s.integrator.name(),
                &["euler", "midpoint", "rk4", "symplectic"],
                false,
            ),
            ControlSpec::number(
                "gravity",
                "Gravity",
                s.gravity,
                (0.0, 30.0, 0.1),
                "m/s^2",
                true,
            ),
            ControlSpec::number("dt", "Time step", s.dt, (1e-5, 2e-3, 1e-5), "s", false),
            ControlSpec::boolean("box", "Wall box (4 m cube)", s.wall_box, true),
        ]
    }

    fn set_control(&mut self, name: &str, value: &ControlValue) -> Result<bool, ViewerError> {
        self.apply(TwoLayerControl::parse(name, value)?)
    }

    fn rebuild(&mut self) -> Result<(), ViewerError> {
        self.sim = Self::build(&self.settings)?;
        self.drag = None;
        Ok(())
    }

    fn simulation(&self) -> &dyn ViewedSimulation {
        &self.sim
    }

    fn simulation_mut(&mut self) -> &mut dyn ViewedSimulation {
        &mut self.sim
    }

    fn stats(&self) -> Map<String, Value> {
        let s = self.sim.stats();
        let m = json!({
            "volume_outer": s.volume_outer,
            "volume_inner": s.volume_inner,
            "pressure_outer": s.pressure_outer,
            "pressure_inner": s.pressure_inner,
            "kinetic": s.kinetic,
            "total_energy": s.total,
            "collisions": s.collisions,
            "dt": Simulation::dt(&self.sim),
        });
        m.as_object().cloned().unwrap_or_default()
    }

    fn scalar_fields(&self) -> Vec<&'static str> {
        vec!["speed", "layer"]
    }

    fn scalar(&self, name: &str) -> Result<Vec<f64>, ViewerError> {
        match name {
            "speed" => fields::vertex_speeds(self.sim.velocities()).map_err(ViewerError::from),
            "layer" => {
                let n = self.sim.model().layer_size;
                Ok((0..self.sim.model().num_particles())
                    .map(|i| if i < n { 0.0 } else { 1.0 })
                    .collect())
            }
            other => Err(ViewerError::UnknownField(other.to_string())),
        }
    }

    fn drag_modes(&self) -> Vec<&'static str> {
        vec!["grab"]
    }

    fn up(&self) -> [f64; 3] {
        [0.0, 0.0, 1.0]
    }

    /// The built-in set-up as a two-layer scenario ([`TwoLayerView::scenario`]).
    fn scenario_text(&self) -> Option<String> {
        Some(balloon_scenario::file::record(
            &balloon_scenario::Scenario::TwoLayer(self.scenario()),
            &balloon_scenario::keys::Literals::default(),
        ))
    }

    fn apply_drag(&mut self, drag: Option<&DragRequest>) -> Result<(), ViewerError> {
        let Some(d) = drag else {
            self.drag = None;
            return self
                .sim
                .set_drag(None)
                .map(|_| ())
                .map_err(ViewerError::from);
        };
        // The target moves only when the page sends a new one; the spring itself acts every
        // step without being set again.
        if self.drag.as_ref() == Some(d) {
            return Ok(());
        }
        set_drag(&mut self.sim, d)?;
        self.drag = Some(*d);
        Ok(())
    }
}

/// Sets Song 2009's drag spring (`TWO_LAYER_DRAG`) of the drag `d` on the two-layer body: on
/// the picked outer particle, or on the outer partner of a picked inner one.
pub(super) fn set_drag(sim: &mut TwoLayerSimulation, d: &DragRequest) -> Result<(), ViewerError> {
    let n = sim.model().layer_size;
    // An inner particle picked through the mesh pulls its outer partner.
    let particle = if sim.model().has_layers() && d.vertex < n {
        d.vertex + n
    } else {
        d.vertex
    };
    let (k, c) = TWO_LAYER_DRAG;
    sim.set_drag_particle(
        particle,
        DragTarget {
            point: Point3::from(d.target),
            stiffness: k,
            damping: c,
            rest_length: 0.0,
        },
    )
    .map_err(ViewerError::from)?;
    Ok(())
}
