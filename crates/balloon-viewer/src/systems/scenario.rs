//! A run of any scenario (`balloon view SCENARIO.toml`, and the built-in `connect`): the
//! simulation is built by `balloon-scenario` exactly as `balloon run` builds it (mesh,
//! material, gas, anchors, pins and scheduled loads included), stepped with its loads, and the
//! page's controls edit the scenario's own keys, so that the scenario saved from the page
//! ([`ScenarioView::scenario_text`]) is what is running.

use super::shell::{DragUndo, SHELL_DRAG_RADIUS, SHELL_DRAG_STIFFNESS, ShellDrag, Undoable};
use super::view::*;
use crate::ViewerError;
use crate::protocol::{ControlSpec, ControlValue, DragMode};
use balloon::Simulation;
use balloon::integrate::TangentKind;
use balloon::integrate::implicit::BackwardEulerParams;
use balloon::material::membrane::MembraneMaterial;
use balloon::shell::{AnchorSpring, ShellMaterialModel};
use balloon::two_layer::{DragTarget, TwoLayerSimulation};
use balloon::volumetric::VolumetricSimulation;
use balloon_scenario::connect::{ConnectScenario, ConnectSim};
use balloon_scenario::gas::GasControl;
use balloon_scenario::keys::{Literals, Recorded};
use balloon_scenario::selection::apply::{two_layer_loads, volumetric_loads};
use balloon_scenario::selection::{ShellLoads, TwoLayerLoads, VolumetricLoads};
use balloon_scenario::shell::ShellSim;
use balloon_scenario::two_layer::DragSpec;
use balloon_scenario::value::{SetError, Value as KeyValue};
use balloon_scenario::{Scenario, SystemKind};
use serde_json::{Map, Value, json};

/// The simulation of a scenario with what steps it besides the simulation itself.
enum Running {
    /// A shell balloon with its anchors and scheduled loads.
    Shell(Box<ShellSim>, ShellLoads),
    /// Connected balloons.
    Connect(Box<ConnectSim>),
    /// A volumetric body with its spring anchors and loads.
    Volumetric(Box<VolumetricSimulation>, VolumetricLoads),
    /// A two-layer body with its spring anchors, loads and scripted drag.
    TwoLayer(Box<TwoLayerSimulation>, TwoLayerLoads, Option<DragSpec>),
}

/// A scenario's run in the viewer: the scenario (with the values changed on the page) and its
/// simulation.
pub struct ScenarioView {
    scenario: Scenario,
    running: Running,
    /// Drawn positions at the start (for the `displacement` field).
    start: Vec<f64>,
    /// The page's drag, applied on top of the scenario's anchors and loads before each step.
    drag: Option<ScenarioDrag>,
    /// Whether the last step ran with a drag (its springs or forces are still set).
    dragged: bool,
    /// Whether a drag switched the shell (or connected balloons) to the live view's fixed
    /// Newton iterations (until the next rebuild).
    live_newton: bool,
    /// The page's drag as last set on a two-layer body.
    page_two_layer_drag: Option<DragRequest>,
    /// The state of a shell or of connected balloons from before the page's last drag began,
    /// while a failed step may still be the drag's doing.
    undo: Option<DragUndo>,
    /// What the last step undid, for the page (taken by `take_notice`).
    notice: Option<String>,
}

/// The simulation a failed step under a drag goes back from (`DragUndo`): a shell or
/// connected balloons.
fn undoable(running: &mut Running) -> Option<&mut dyn Undoable> {
    match running {
        Running::Shell(sim, _) => Some(sim.as_mut()),
        Running::Connect(sim) => Some(sim.as_mut()),
        Running::Volumetric(..) | Running::TwoLayer(..) => None,
    }
}

/// The page's drag of a scenario run.
struct ScenarioDrag {
    /// What the page asked for.
    request: DragRequest,
    /// A shell or connected balloons: the dragged balloon (0 for a single shell), its
    /// neighbourhood of the picked vertex (numbered within that balloon) and the springs'
    /// stiffness `SHELL_DRAG_STIFFNESS E h` (N/m).
    shell: Option<(usize, ShellDrag, f64)>,
}

/// The small-strain Young's modulus (Pa) of a shell material: `E` of a three-prism material,
/// `3 mu0` of an incompressible membrane (`mu0` its initial shear modulus).
fn small_strain_young(material: &ShellMaterialModel) -> f64 {
    match material {
        ShellMaterialModel::Solid(m) => m.lame().young(),
        ShellMaterialModel::Membrane(m) => 3.0 * m.initial_shear_modulus(),
    }
}

/// A number control of a scenario: (parameter name, label, (min, max, step), unit). Its value
/// is the scenario's key of that name; ranges are the page's sliders (the scenario's own range
/// check still applies).
type NumberControl = (&'static str, &'static str, (f64, f64, f64), &'static str);

const SHELL_CONTROLS: &[NumberControl] = &[
    (
        "pressure",
        "Gauge pressure (initial for ideal, fixed for constant gas)",
        (-1e5, 1e5, 10.0),
        "Pa",
    ),
    ("thickness", "Rest thickness", (1e-5, 1e-2, 1e-5), "m"),
    ("dt", "Time step", (1e-5, 0.1, 1e-4), "s"),
];
const CONNECT_CONTROLS: &[NumberControl] = &[
    ("thickness", "Rest thickness", (1e-5, 1e-2, 1e-5), "m"),
    ("dt", "Time step", (1e-5, 0.1, 1e-4), "s"),
];
const VOLUMETRIC_CONTROLS: &[NumberControl] = &[
    ("gravity", "Gravity along z", (-30.0, 30.0, 0.1), "m/s^2"),
    ("dt", "Time step", (1e-5, 1e-3, 1e-5), "s"),
];
const TWO_LAYER_CONTROLS: &[NumberControl] = &[
    ("pressure", "Gas pressure", (0.0, 1e4, 1.0), "Pa"),
    ("dt", "Time step", (1e-5, 0.01, 1e-5), "s"),
];

/// Connected balloons whose pressure and stretch the statistics list one by one.
const MAX_LISTED_BALLOONS: usize = 8;

/// An error and its causes joined by `: ` (a cause the text already holds is skipped).
fn chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let t = s.to_string();
        if !text.contains(&t) {
            text = format!("{text}: {t}");
        }
        source = s.source();
    }
    text
}

fn scenario_error(e: &dyn std::error::Error) -> ViewerError {
    ViewerError::Scenario(chain(e))
}

/// The built-in `connect` of the viewer: the two-balloon experiment of
/// `examples/two-balloons` (two equal neo-Hookean rubber balloons, the built-in icosphere of
/// radius 0.1 m, pre-inflated on opposite sides of their pressure maximum and joined by a tube
/// of instant conductance), with the rest of `balloon connect`'s defaults.
pub fn builtin_connect() -> ConnectScenario {
    let mut s = Scenario::Connect(ConnectScenario::default());
    let text = |t: &str| KeyValue::Text(t.into());
    for (name, value) in [
        ("mesh", text("builtin:icosphere")),
        ("copies", KeyValue::Int(2)),
        (
            "stretches",
            KeyValue::List(vec![KeyValue::Float(1.35), KeyValue::Float(1.6)]),
        ),
        ("conductance", text("instant")),
        ("material", text("membrane-neo-hookean")),
        ("mu", KeyValue::Float(4e5)),
        ("thickness", KeyValue::Float(1e-3)),
        ("dt", KeyValue::Float(0.01)),
        ("mass_damping", KeyValue::Float(5.0)),
    ] {
        // Every key and value is one `balloon connect` takes (tested).
        let _ = s.set(name, &value);
    }
    match s {
        Scenario::Connect(c) => c,
        _ => ConnectScenario::default(),
    }
}

impl ScenarioView {
    /// Checks `scenario` ([`Scenario::validate`]) and builds its simulation as `balloon run`
    /// does; a `static` shell run is shown stepping dynamically.
    pub fn new(mut scenario: Scenario) -> Result<Self, ViewerError> {
        if let Scenario::Connect(c) = &mut scenario {
            // What runs (and what the recorded scenario says): connected balloons hold the
            // ideal gas whatever `gas` says.
            c.shell.gas.model = GasControl::Ideal;
        }
        scenario
            .validate()
            .map_err(|e| ViewerError::Scenario(chain(&e)))?;
        let running = build(&scenario)?;
        let start = drawn(&running).positions();
        Ok(Self {
            scenario,
            running,
            start,
            drag: None,
            dragged: false,
            live_newton: false,
            page_two_layer_drag: None,
            undo: None,
            notice: None,
        })
    }

    /// The drag stiffness scale `SHELL_DRAG_STIFFNESS E h` (N/m) of a shell or connect
    /// scenario: `E` the material's small-strain Young's modulus, `h` the mean rest thickness.
    fn shell_drag_stiffness(&self, thickness: &[f64]) -> Result<f64, ViewerError> {
        let wall = match &self.scenario {
            Scenario::Shell(s) => &s.shell,
            Scenario::Connect(c) => &c.shell.shell,
            _ => return Err(ViewerError::Scenario("not a shell scenario".into())),
        };
        let material = wall.material.resolve().map_err(ViewerError::Scenario)?;
        let h = thickness.iter().sum::<f64>() / thickness.len().max(1) as f64;
        Ok(SHELL_DRAG_STIFFNESS * small_strain_young(&material) * h)
    }

    /// How many anchor springs each balloon's simulation holds (a shell's, or each connected
    /// balloon's); empty for the other systems.
    #[cfg(test)]
    pub(super) fn anchor_spring_counts(&self) -> Vec<usize> {
        match &self.running {
            Running::Shell(sim, _) => vec![sim.anchor_springs().len()],
            Running::Connect(sim) => sim
                .balloons()
                .iter()
                .map(|b| b.anchor_springs().len())
                .collect(),
            Running::Volumetric(..) | Running::TwoLayer(..) => Vec::new(),
        }
    }

    /// From the page's first drag on, a shell or connected balloons step with the live view's
    /// three Newton iterations, each line-searched on the incremental potential and the last
    /// one accepted whatever its residual ([`BackwardEulerParams::accept_unconverged`]), until
    /// the run is rebuilt (reset, a changed control), which brings back the scenario's own.
    /// The paper's three full steps (which the built-in shell takes while not dragged) turned a
    /// pinched balloon of `connect` inside out in 6 of 100 random drag sequences
    /// (`random_drag_sequences_of_connected_balloons`, seeds 1 and 2); with the line search and
    /// the first iterate at rest where the predictor is inside out (module docs of
    /// `balloon::integrate::implicit`), none of 160 (seeds 2 and 3) did. With
    /// the scenario's converged Newton a pinch stalled a single step of
    /// `examples/static-sphere/static-sphere.toml` and of the built-in `connect` for over
    /// 12 s, and so did the first converged step after releasing a pinch (over 30 s; debug
    /// build, load average 10). A dragged run is not `balloon run`'s anyway. The live steps
    /// linearise with the projected tangent ([`TangentKind::Projected`], as the built-in shell
    /// does): three iterations on the exact tangent of the stiff sphere of `static-sphere`
    /// after a pinch ran away (a negative thickness 10 to 17 steps after the release).
    fn live_newton(&mut self) -> Result<(), ViewerError> {
        if self.drag.is_none() || self.live_newton {
            return Ok(());
        }
        let live = |p: &mut BackwardEulerParams| {
            super::shell::dragged_newton(p);
            p.tangent = TangentKind::Projected;
        };
        match &mut self.running {
            Running::Shell(sim, _) => sim.configure_integrator(live)?,
            Running::Connect(sim) => {
                for b in 0..sim.balloons().len() {
                    sim.configure_integrator(b, live)
                        .map_err(|e| ViewerError::Scenario(chain(&e)))?;
                }
            }
            Running::Volumetric(..) | Running::TwoLayer(..) => {}
        }
        self.live_newton = true;
        Ok(())
    }

    /// Applies the page's drag on top of what the scenario's loads set for the coming step
    /// (after their `before_step`), or takes it away after a release.
    fn apply_page_drag(&mut self) -> Result<(), ViewerError> {
        if self.drag.is_none() && !self.dragged {
            return Ok(());
        }
        self.live_newton()?;
        let drag = self.drag.as_ref();
        match &mut self.running {
            Running::Shell(sim, loads) => {
                let mut springs = loads.anchor_springs();
                if let Some(ScenarioDrag {
                    request,
                    shell: Some((_, state, k)),
                }) = drag
                {
                    springs.extend(state.springs(request.target, *k));
                }
                sim.set_anchor_springs(springs)?;
            }
            Running::Connect(sim) => {
                let dragged = drag.and_then(|d| d.shell.as_ref().map(|s| (d.request, s)));
                for b in 0..sim.balloons().len() {
                    let springs: Vec<AnchorSpring> = match dragged {
                        Some((request, (balloon, state, k))) if *balloon == b => {
                            state.springs(request.target, *k).collect()
                        }
                        _ => Vec::new(),
                    };
                    sim.set_anchor_springs(b, springs)
                        .map_err(|e| ViewerError::Scenario(chain(&e)))?;
                }
            }
            Running::Volumetric(sim, loads) => {
                let base = loads.forces(sim);
                let forces = match drag {
                    None => base,
                    Some(d) => {
                        let mut f = super::volumetric::drag_forces(sim, &d.request)?;
                        if let Some(base) = base {
                            for (f, b) in f.iter_mut().zip(base) {
                                *f += b;
                            }
                        }
                        Some(f)
                    }
                };
                sim.set_external_forces(forces.as_deref())?;
            }
            // The spring acts every step once set; it is set again only when the page moves
            // the target (as the built-in two-layer view does).
            Running::TwoLayer(sim, ..) => match drag {
                Some(d) if self.page_two_layer_drag == Some(d.request) => {}
                Some(d) => {
                    super::two_layer::set_drag(sim, &d.request)?;
                    self.page_two_layer_drag = Some(d.request);
                }
                None => {
                    sim.set_drag(None)?;
                    self.page_two_layer_drag = None;
                }
            },
        }
        self.dragged = self.drag.is_some();
        Ok(())
    }

    /// The scenario with the values changed on the page.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// The scenario file of the current set-up (TOML, every key resolved, as `balloon run`
    /// records it): `balloon run` of it repeats this run from its start.
    pub fn scenario_text(&self) -> String {
        balloon_scenario::file::record(&self.scenario, &Literals::default())
    }

    fn number_controls(&self) -> &'static [NumberControl] {
        match self.scenario.kind() {
            SystemKind::Shell => SHELL_CONTROLS,
            SystemKind::Connect => CONNECT_CONTROLS,
            SystemKind::Volumetric => VOLUMETRIC_CONTROLS,
            SystemKind::TwoLayer => TWO_LAYER_CONTROLS,
        }
    }

    /// The scenario's value of parameter `name`, or the running one when the scenario leaves
    /// it to the program (a volumetric `dt`).
    fn value_of(&self, name: &str) -> f64 {
        match self.scenario.recorded(name) {
            Some(Recorded::Text(t)) => t.first().and_then(|v| v.parse().ok()),
            _ => None,
        }
        .unwrap_or_else(|| match name {
            "dt" => ViewSystem::dt(self),
            _ => f64::NAN,
        })
    }
}

/// Builds the simulation of a validated scenario with its loads, as the run jobs do.
fn build(scenario: &Scenario) -> Result<Running, ViewerError> {
    Ok(match scenario {
        Scenario::Shell(s) => {
            let (sim, loads) = s.build(None).map_err(|e| scenario_error(&e))?;
            Running::Shell(Box::new(sim), loads)
        }
        Scenario::Connect(s) => {
            let (sim, _) = s.build().map_err(|e| scenario_error(&e))?;
            Running::Connect(Box::new(sim))
        }
        Scenario::Volumetric(s) => {
            let mut sim = s.build(None).map_err(|e| scenario_error(&e))?.sim;
            let loads = volumetric_loads(&mut sim, &s.anchors, s.body.pin_stiffness, &s.loads)
                .map_err(|e| scenario_error(&e))?;
            Running::Volumetric(Box::new(sim), loads)
        }
        Scenario::TwoLayer(s) => {
            let drag = s.drag().map_err(ViewerError::Scenario)?;
            let mut sim = s.build().map_err(|e| scenario_error(&e))?;
            let loads = two_layer_loads(&mut sim, &s.anchors, s.run.pin_stiffness, &s.loads)
                .map_err(|e| scenario_error(&e))?;
            Running::TwoLayer(Box::new(sim), loads, drag)
        }
    })
}

fn drawn(running: &Running) -> &dyn ViewedSimulation {
    match running {
        Running::Shell(s, _) => s.as_ref(),
        Running::Connect(s) => s.as_ref(),
        Running::Volumetric(s, _) => s.as_ref(),
        Running::TwoLayer(s, ..) => s.as_ref(),
    }
}

/// Switches the two-layer body's scripted drag (`drag = "X,Y,Z@T0:T1"`) on inside its window
/// and off outside, as `balloon two-layer` does.
fn two_layer_drag(
    sim: &mut TwoLayerSimulation,
    drag: &DragSpec,
    scenario: &Scenario,
) -> Result<(), ViewerError> {
    let Scenario::TwoLayer(s) = scenario else {
        return Ok(());
    };
    let active = sim.forces().drag().is_some();
    let t = sim.time();
    let inside = t >= drag.window.0 && t <= drag.window.1;
    if inside && !active {
        sim.set_drag(Some(DragTarget {
            point: drag.point,
            stiffness: s.run.drag_stiffness,
            damping: s.run.drag_damping,
            rest_length: 0.0,
        }))?;
    } else if !inside && active {
        sim.set_drag(None)?;
    }
    Ok(())
}

impl ViewSystem for ScenarioView {
    fn name(&self) -> &'static str {
        match self.scenario.kind() {
            SystemKind::Shell => "shell",
            SystemKind::Connect => "connect",
            SystemKind::Volumetric => "volumetric",
            SystemKind::TwoLayer => "two-layer",
        }
    }

    fn controls(&self) -> Vec<ControlSpec> {
        self.number_controls()
            .iter()
            .map(|&(name, label, range, unit)| {
                ControlSpec::number(name, label, self.value_of(name), range, unit, true)
            })
            .collect()
    }

    /// Sets the scenario's key (range-checked with the scenario's own check, the scenario
    /// unchanged when refused); the simulation is rebuilt from the changed scenario.
    fn set_control(&mut self, name: &str, value: &ControlValue) -> Result<bool, ViewerError> {
        if !self.number_controls().iter().any(|c| c.0 == name) {
            return Err(ViewerError::UnknownControl(name.to_string()));
        }
        let v = number(name, value)?;
        let mut next = self.scenario.clone();
        next.set(name, &KeyValue::Float(v)).map_err(|e| {
            ViewerError::Rejected(match e {
                SetError::Type(t) => format!("control `{name}`: {t}"),
                SetError::Value(v) => format!("control `{name}`: {v}"),
            })
        })?;
        next.validate()
            .map_err(|e| ViewerError::Rejected(format!("control `{name}`: {}", chain(&e))))?;
        self.scenario = next;
        Ok(true)
    }

    fn rebuild(&mut self) -> Result<(), ViewerError> {
        self.running = build(&self.scenario)?;
        self.start = drawn(&self.running).positions();
        self.drag = None;
        self.dragged = false;
        self.live_newton = false;
        self.page_two_layer_drag = None;
        self.undo = None;
        self.notice = None;
        Ok(())
    }

    fn simulation(&self) -> &dyn ViewedSimulation {
        drawn(&self.running)
    }

    fn simulation_mut(&mut self) -> &mut dyn ViewedSimulation {
        match &mut self.running {
            Running::Shell(s, _) => s.as_mut(),
            Running::Connect(s) => s.as_mut(),
            Running::Volumetric(s, _) => s.as_mut(),
            Running::TwoLayer(s, ..) => s.as_mut(),
        }
    }

    /// Applies the scheduled loads (and the two-layer body's scripted drag) of the coming step,
    /// as the run jobs' `before_step` does, then the page's drag on top of them (its springs
    /// added to the anchors' and grabs', its forces to the loads'; on a two-layer body it
    /// replaces the scripted drag while it lasts), then steps. Without a page drag the steps
    /// are `balloon run`'s.
    fn step(&mut self) -> Result<(), ViewerError> {
        let page_drag = self.drag.is_some() || self.dragged;
        let loads = match &mut self.running {
            Running::Shell(sim, loads) => loads.before_step(sim.as_mut()),
            Running::Connect(_) => Ok(()),
            Running::Volumetric(sim, loads) => loads.before_step(sim.as_mut()),
            Running::TwoLayer(sim, loads, drag) => {
                let applied = loads.before_step(sim.as_mut());
                if applied.is_ok()
                    && !page_drag
                    && let Some(d) = drag
                {
                    two_layer_drag(sim.as_mut(), d, &self.scenario)?;
                }
                applied
            }
        };
        loads.map_err(|e| scenario_error(&e))?;
        // The state saved before a drag of a shell or of connected balloons (their loads
        // set, the page's drag not yet).
        let dragging = self.drag.is_some();
        if let Some(sim) = undoable(&mut self.running) {
            DragUndo::keep(&mut self.undo, sim, dragging);
        }
        self.apply_page_drag()?;
        match self.simulation_mut().step() {
            Ok(()) => Ok(()),
            Err(e) => {
                let Some(sim) = undoable(&mut self.running) else {
                    return Err(e);
                };
                self.notice = Some(DragUndo::undo(&mut self.undo, sim, e)?);
                self.drag = None;
                self.dragged = false;
                Ok(())
            }
        }
    }

    fn take_notice(&mut self) -> Option<String> {
        self.notice.take()
    }

    fn stats(&self) -> Map<String, Value> {
        let mut m = Map::new();
        let sim = &self.running;
        let (kinetic, extra) = match sim {
            Running::Shell(s, _) => (
                Simulation::kinetic_energy(s.as_ref()),
                json!({
                    "gauge_pressure": s.gauge_pressure(),
                    "volume_ratio": s.gas_volume() / s.rest_gas_volume(),
                }),
            ),
            Running::Connect(s) => {
                // One number per entry (the page's panel shows numbers): each balloon's gauge
                // pressure and stretch, numbered from 1.
                let mut per = Map::new();
                per.insert("balloons".into(), json!(s.balloons().len()));
                let (p, l) = (s.gauge_pressures(), s.stretches());
                for (i, (p, l)) in p.iter().zip(&l).enumerate().take(MAX_LISTED_BALLOONS) {
                    per.insert(format!("gauge_pressure_{}", i + 1), json!(p));
                    per.insert(format!("stretch_{}", i + 1), json!(l));
                }
                (Simulation::kinetic_energy(s.as_ref()), Value::Object(per))
            }
            Running::Volumetric(s, _) => (
                Simulation::kinetic_energy(s.as_ref()),
                json!({"volume_ratio": s.total_volume() / s.body().rest_volume()}),
            ),
            Running::TwoLayer(s, ..) => (Simulation::kinetic_energy(s.as_ref()), json!({})),
        };
        m.insert("kinetic_energy".into(), json!(kinetic));
        m.insert("dt".into(), json!(ViewSystem::dt(self)));
        if let Value::Object(extra) = extra {
            m.extend(extra);
        }
        m
    }

    fn scalar_fields(&self) -> Vec<&'static str> {
        vec!["displacement", "height"]
    }

    fn scalar(&self, name: &str) -> Result<Vec<f64>, ViewerError> {
        let x = self.positions();
        match name {
            "displacement" => {
                if self.start.len() != x.len() {
                    return Err(ViewerError::UnknownField(name.to_string()));
                }
                Ok((0..vertex_count(&x))
                    .map(|i| (p3(&x, i) - p3(&self.start, i)).norm())
                    .collect())
            }
            "height" => {
                let up = nalgebra::Vector3::from(self.up());
                Ok((0..vertex_count(&x)).map(|i| p3(&x, i).dot(&up)).collect())
            }
            other => Err(ViewerError::UnknownField(other.to_string())),
        }
    }

    /// Every scenario is dragged as its built-in system is: a shell or connected balloons by
    /// grabbing or pinching, the volumetric and two-layer bodies by grabbing.
    fn drag_modes(&self) -> Vec<&'static str> {
        match self.scenario.kind() {
            SystemKind::Shell | SystemKind::Connect => vec!["grab", "pinch"],
            SystemKind::Volumetric | SystemKind::TwoLayer => vec!["grab"],
        }
    }

    /// The volumetric body's `up` axis (z by default), the two-layer body's z, the shell's y.
    fn up(&self) -> [f64; 3] {
        match &self.scenario {
            Scenario::Volumetric(v) => v.run.up.vector().into(),
            Scenario::TwoLayer(_) => [0.0, 0.0, 1.0],
            Scenario::Shell(_) | Scenario::Connect(_) => [0.0, 1.0, 0.0],
        }
    }

    /// Records the page's drag; it acts from the next step on, on top of the scenario's
    /// anchors and loads (see `step`). A shell's neighbourhood is taken when the drag starts.
    fn apply_drag(&mut self, drag: Option<&DragRequest>) -> Result<(), ViewerError> {
        let Some(d) = drag else {
            self.drag = None;
            return Ok(());
        };
        let count = vertex_count(&self.positions());
        if d.vertex >= count {
            return Err(ViewerError::VertexOutOfRange { vertex: d.vertex });
        }
        if d.mode == DragMode::Pinch && !self.drag_modes().contains(&"pinch") {
            return Err(ViewerError::DragMode {
                mode: "pinch",
                system: self.name(),
                available: self.drag_modes().join(", "),
            });
        }
        let previous = self.drag.take().and_then(|p| p.shell);
        let shell = match &self.running {
            Running::Shell(sim, _) => {
                let current = previous.filter(|p| p.0 == 0);
                let k = match &current {
                    Some((_, _, k)) => *k,
                    None => self.shell_drag_stiffness(sim.thickness())?,
                };
                let x = sim.positions();
                let radius = SHELL_DRAG_RADIUS * bbox_diagonal(sim.rest_positions());
                let state = ShellDrag::follow(current.map(|p| p.1), x, d.vertex, d.mode, radius);
                Some((0, state, k))
            }
            Running::Connect(sim) => {
                let offsets = sim.vertex_offsets();
                let b = offsets.partition_point(|&o| o <= d.vertex) - 1;
                let balloon = &sim.balloons()[b];
                let current = previous.filter(|p| p.0 == b);
                let k = match &current {
                    Some((_, _, k)) => *k,
                    None => self.shell_drag_stiffness(balloon.thickness())?,
                };
                let radius = SHELL_DRAG_RADIUS * bbox_diagonal(balloon.rest_positions());
                let state = ShellDrag::follow(
                    current.map(|p| p.1),
                    balloon.positions(),
                    d.vertex - offsets[b],
                    d.mode,
                    radius,
                );
                Some((b, state, k))
            }
            Running::Volumetric(..) | Running::TwoLayer(..) => None,
        };
        self.drag = Some(ScenarioDrag { request: *d, shell });
        Ok(())
    }

    fn scenario_text(&self) -> Option<String> {
        Some(ScenarioView::scenario_text(self))
    }

    /// A volumetric scenario's rigid sphere (the `drop-sphere` scene, Fig. 4 of Diziol, Bender
    /// and Bayer 2011) where it is now.
    fn sphere(&self) -> Option<Sphere> {
        match &self.running {
            Running::Volumetric(sim, _) => sim.sphere().map(|s| Sphere {
                center: s.position.into(),
                radius: s.radius,
            }),
            _ => None,
        }
    }

    /// A `static` shell scenario is shown stepping dynamically (backward Euler from rest under
    /// the same loads): the page says so, since `balloon run` solves for the equilibrium.
    fn note(&self) -> Option<String> {
        match &self.scenario {
            Scenario::Shell(s) if s.run.static_solve => Some(STATIC_NOTE.into()),
            _ => None,
        }
    }
}

/// What the page says for a `static` shell scenario.
pub const STATIC_NOTE: &str = "This scenario is a static solve (`static = true`): the viewer \
     shows it stepping dynamically from rest under the same gas and loads, not the equilibrium \
     that `balloon run` solves for. The saved scenario is still the static one.";
