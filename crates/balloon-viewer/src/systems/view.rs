//! What the server needs of a viewed system ([`ViewSystem`], [`ViewedSimulation`]) and the
//! helpers the three systems share.

use crate::ViewerError;
use crate::protocol::{ControlSpec, ControlValue, DragMode};
use balloon::Simulation;
use nalgebra::{Point3, Vector3};
use serde_json::{Map, Value};

/// A drag as the page asked for it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DragRequest {
    /// Picked vertex (of the frames' vertices).
    pub vertex: usize,
    /// Target, m.
    pub target: [f64; 3],
    /// Mode.
    pub mode: DragMode,
}

/// The stepping and drawing half of a viewed system: the runner steps, times and draws every
/// system through this, and it is implemented once, for every [`balloon::Simulation`]
/// (implemented by hand only by test doubles).
pub trait ViewedSimulation: Send {
    /// Advances one step; the error is the simulation's message.
    fn step(&mut self) -> Result<(), ViewerError>;
    /// Simulated time, s.
    fn time(&self) -> f64;
    /// Steps since the start.
    fn steps(&self) -> usize;
    /// Time step, s.
    fn dt(&self) -> f64;
    /// Triangles of the drawn surface.
    fn triangles(&self) -> Vec<[usize; 3]>;
    /// Positions of the drawn vertices, flat, m.
    fn positions(&self) -> Vec<f64>;
    /// The first drawn vertex with a non-finite coordinate (a blow-up), if any.
    fn first_non_finite(&self) -> Option<usize> {
        first_non_finite(&self.positions())
    }
}

impl<S: Simulation + Send> ViewedSimulation for S {
    fn step(&mut self) -> Result<(), ViewerError> {
        Simulation::step(self)
            .map(|_| ())
            .map_err(ViewerError::from)
    }
    fn time(&self) -> f64 {
        Simulation::time(self)
    }
    fn steps(&self) -> usize {
        Simulation::steps(self)
    }
    fn dt(&self) -> f64 {
        Simulation::dt(self)
    }
    fn triangles(&self) -> Vec<[usize; 3]> {
        self.surface().triangles.into_owned()
    }
    fn positions(&self) -> Vec<f64> {
        self.surface().positions.into_owned()
    }
    fn first_non_finite(&self) -> Option<usize> {
        first_non_finite(&self.surface().positions)
    }
}

/// A rigid sphere of the scene as the page draws it (`frame.sphere`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Sphere {
    /// Centre, m.
    pub center: [f64; 3],
    /// Radius, m.
    pub radius: f64,
}

/// One simulation as the viewer drives it: its controls (typed inside, parsed from the
/// protocol's strings once in [`ViewSystem::set_control`]), statistics, scalar fields and drags;
/// stepping and drawing go through [`ViewSystem::simulation`].
pub trait ViewSystem: Send {
    /// `shell`, `volumetric` or `two-layer`.
    fn name(&self) -> &'static str;
    /// The controls with their current values.
    fn controls(&self) -> Vec<ControlSpec>;
    /// Parses a validated value of the control `name` into the system's control type and applies
    /// it. Returns `true` when the simulation must be rebuilt.
    fn set_control(&mut self, name: &str, value: &ControlValue) -> Result<bool, ViewerError>;
    /// Rebuilds the simulation from the current control values (back to the start).
    fn rebuild(&mut self) -> Result<(), ViewerError>;
    /// The running simulation.
    fn simulation(&self) -> &dyn ViewedSimulation;
    /// The running simulation, to step it.
    fn simulation_mut(&mut self) -> &mut dyn ViewedSimulation;
    /// Numbers for the page's statistics panel.
    fn stats(&self) -> Map<String, Value>;
    /// Names of the per-vertex scalar fields, the default first.
    fn scalar_fields(&self) -> Vec<&'static str>;
    /// One scalar per drawn vertex.
    fn scalar(&self, name: &str) -> Result<Vec<f64>, ViewerError>;
    /// Supported drag modes.
    fn drag_modes(&self) -> Vec<&'static str>;
    /// The up direction of the scene (gravity points the other way).
    fn up(&self) -> [f64; 3] {
        [0.0, 1.0, 0.0]
    }
    /// Sets (or removes) the drag; called again before every step so forces follow the body.
    fn apply_drag(&mut self, drag: Option<&DragRequest>) -> Result<(), ViewerError>;
    /// The scenario file (TOML) of the current set-up, with the values changed on the page,
    /// when the system runs a scenario (`balloon run` of it repeats the run); `None` otherwise.
    fn scenario_text(&self) -> Option<String> {
        None
    }
    /// A sentence the page shows above the controls when what it draws is not what
    /// `balloon run` of the same set-up computes (a static scenario shown stepping); `None`
    /// otherwise.
    fn note(&self) -> Option<String> {
        None
    }
    /// What the last step undid, once (a drag that crushed the wall, undone): a sentence the
    /// page shows for a while; `None` otherwise. The runner drops the page's drag when there
    /// is one.
    fn take_notice(&mut self) -> Option<String> {
        None
    }
    /// The rigid sphere of the scene (a volumetric scenario's `drop-sphere`), drawn with the
    /// body; `None` when there is none.
    fn sphere(&self) -> Option<Sphere> {
        None
    }

    /// Triangles of the drawn surface.
    fn triangles(&self) -> Vec<[usize; 3]> {
        self.simulation().triangles()
    }
    /// Positions of the drawn vertices, flat, m.
    fn positions(&self) -> Vec<f64> {
        self.simulation().positions()
    }
    /// Simulated time, s.
    fn time(&self) -> f64 {
        self.simulation().time()
    }
    /// Steps since the last rebuild.
    fn steps(&self) -> usize {
        self.simulation().steps()
    }
    /// Time step, s.
    fn dt(&self) -> f64 {
        self.simulation().dt()
    }
    /// Advances one step (the drag forces set by `apply_drag` act on it).
    fn step(&mut self) -> Result<(), ViewerError> {
        self.simulation_mut().step()
    }
}

/// The error text of a choice the protocol validated but this system does not know (only
/// reachable if a control's choice list and its parser disagree).
pub(super) fn unknown_choice(control: &str, value: &str) -> ViewerError {
    ViewerError::UnknownChoice {
        control: control.to_string(),
        value: value.to_string(),
    }
}

/// The error of a validated value of the wrong kind for `control`.
pub(super) fn wrong_kind(control: &str, expected: &'static str, got: &ControlValue) -> ViewerError {
    ViewerError::WrongKind {
        control: control.to_string(),
        expected,
        got: format!("{got:?}"),
    }
}

/// A validated number, or an error naming the control if the value is not a number.
pub(super) fn number(control: &str, value: &ControlValue) -> Result<f64, ViewerError> {
    match value {
        ControlValue::Number(v) => Ok(*v),
        other => Err(wrong_kind(control, "a number", other)),
    }
}

/// A validated choice, or an error naming the control.
pub(super) fn choice<'v>(control: &str, value: &'v ControlValue) -> Result<&'v str, ViewerError> {
    match value {
        ControlValue::Choice(c) => Ok(c),
        other => Err(wrong_kind(control, "a choice", other)),
    }
}

/// A validated boolean, or an error naming the control.
pub(super) fn boolean(control: &str, value: &ControlValue) -> Result<bool, ViewerError> {
    match value {
        ControlValue::Bool(b) => Ok(*b),
        other => Err(wrong_kind(control, "true or false", other)),
    }
}

pub(super) fn vertex_count(x: &[f64]) -> usize {
    x.len() / 3
}

pub(super) fn p3(x: &[f64], i: usize) -> Vector3<f64> {
    Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
}

pub(super) fn bbox_diagonal(x: &[f64]) -> f64 {
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for c in x.chunks_exact(3) {
        let p = Vector3::new(c[0], c[1], c[2]);
        lo = lo.inf(&p);
        hi = hi.sup(&p);
    }
    (hi - lo).norm()
}

/// The first vertex of the flat positions `x` with a non-finite coordinate, if any.
pub fn first_non_finite(x: &[f64]) -> Option<usize> {
    x.iter().position(|v| !v.is_finite()).map(|k| k / 3)
}

pub(super) fn name_of<T: PartialEq>(table: &[(&'static str, T)], value: &T) -> &'static str {
    table
        .iter()
        .find(|(_, v)| v == value)
        .map_or("", |(n, _)| n)
}

/// The value named `name` in `table`.
pub(super) fn lookup<T: Copy>(
    table: &[(&'static str, T)],
    control: &str,
    name: &str,
) -> Result<T, ViewerError> {
    table
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, v)| *v)
        .ok_or_else(|| unknown_choice(control, name))
}

pub(super) fn flat(p: &[Point3<f64>]) -> Vec<f64> {
    p.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
}
