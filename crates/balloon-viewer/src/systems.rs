//! The three simulations behind one interface: controls, stepping, positions, scalar fields and
//! drags, as the server needs them.

use crate::ViewerError;
use crate::protocol::{ControlSpec, ControlValue, DragMode};
use balloon::Simulation;
use balloon::constraint::cell_volume::{CellCorrection, CellSolver};
use balloon::fields;
use balloon::gas::GasKind;
use balloon::integrate::TangentKind;
use balloon::integrate::linear::LinearSolverKind;
use balloon::material::{Lame, MaterialKind, MaterialModel};
use balloon::mesh::TriMesh;
use balloon::mesh::lattice::LatticeParams;
use balloon::shell::{AnchorSpring, ShellBalloon, ShellSimulation};
use balloon::two_layer::{
    AxisBox, DragTarget, ExplicitMethod, SpringKind, TwoLayerBody, TwoLayerSimulation,
};
use balloon::volumetric::{VolumetricBody, VolumetricParams, VolumetricSimulation};
use nalgebra::{Point3, Vector3};
use serde_json::{Map, Value, json};

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
        crate::runner::first_non_finite(&self.positions())
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
        crate::runner::first_non_finite(&self.surface().positions)
    }
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
fn unknown_choice(control: &str, value: &str) -> ViewerError {
    ViewerError::UnknownChoice {
        control: control.to_string(),
        value: value.to_string(),
    }
}

/// The error of a validated value of the wrong kind for `control`.
fn wrong_kind(control: &str, expected: &'static str, got: &ControlValue) -> ViewerError {
    ViewerError::WrongKind {
        control: control.to_string(),
        expected,
        got: format!("{got:?}"),
    }
}

/// A validated number, or an error naming the control if the value is not a number.
fn number(control: &str, value: &ControlValue) -> Result<f64, ViewerError> {
    match value {
        ControlValue::Number(v) => Ok(*v),
        other => Err(wrong_kind(control, "a number", other)),
    }
}

/// A validated choice, or an error naming the control.
fn choice<'v>(control: &str, value: &'v ControlValue) -> Result<&'v str, ViewerError> {
    match value {
        ControlValue::Choice(c) => Ok(c),
        other => Err(wrong_kind(control, "a choice", other)),
    }
}

/// A validated boolean, or an error naming the control.
fn boolean(control: &str, value: &ControlValue) -> Result<bool, ViewerError> {
    match value {
        ControlValue::Bool(b) => Ok(*b),
        other => Err(wrong_kind(control, "true or false", other)),
    }
}

fn vertex_count(x: &[f64]) -> usize {
    x.len() / 3
}

fn p3(x: &[f64], i: usize) -> Vector3<f64> {
    Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
}

fn bbox_diagonal(x: &[f64]) -> f64 {
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for c in x.chunks_exact(3) {
        let p = Vector3::new(c[0], c[1], c[2]);
        lo = lo.inf(&p);
        hi = hi.sup(&p);
    }
    (hi - lo).norm()
}

// ---------------------------------------------------------------------------------------------
// Shell (seed 000).

/// Settings of the shell view (the controls).
#[derive(Clone, Debug)]
struct ShellSettings {
    gas: GasKind,
    pressure: f64,
    pump_rate: f64,
    thickness_mm: f64,
    material: MaterialKind,
    young_mpa: f64,
    dt: f64,
    solver: LinearSolverKind,
    tangent: TangentKind,
    hold: bool,
}

/// The protocol's names of the shell materials (the page's short ones, not `MaterialKind`'s
/// display names).
const MATERIALS: [(&str, MaterialKind); 2] = [
    ("stvk", MaterialKind::StVenantKirchhoff),
    ("neo-hookean", MaterialKind::NeoHookean),
];

/// One control of the shell view, parsed from the protocol once.
#[derive(Clone, Copy, Debug, PartialEq)]
enum ShellControl {
    /// `gas` (rebuilds).
    Gas(GasKind),
    /// `pressure`, Pa (live for the ideal and constant gases).
    Pressure(f64),
    /// `pump_rate`, m^3/s (live for the pump).
    PumpRate(f64),
    /// `thickness`, mm (rebuilds).
    ThicknessMm(f64),
    /// `material` (rebuilds).
    Material(MaterialKind),
    /// `young`, MPa (rebuilds).
    YoungMpa(f64),
    /// `dt`, s (live).
    Dt(f64),
    /// `solver` (live).
    Solver(LinearSolverKind),
    /// `tangent` (live).
    Tangent(TangentKind),
    /// `hold` (live).
    Hold(bool),
}

impl ShellControl {
    fn parse(name: &str, value: &ControlValue) -> Result<Self, ViewerError> {
        let kind = |v: &str| unknown_choice(name, v);
        Ok(match name {
            "gas" => {
                let c = choice(name, value)?;
                Self::Gas(c.parse().map_err(|_| kind(c))?)
            }
            "pressure" => Self::Pressure(number(name, value)?),
            "pump_rate" => Self::PumpRate(number(name, value)?),
            "thickness" => Self::ThicknessMm(number(name, value)?),
            "material" => Self::Material(lookup(&MATERIALS, name, choice(name, value)?)?),
            "young" => Self::YoungMpa(number(name, value)?),
            "dt" => Self::Dt(number(name, value)?),
            "solver" => {
                let c = choice(name, value)?;
                Self::Solver(c.parse().map_err(|_| kind(c))?)
            }
            "tangent" => {
                let c = choice(name, value)?;
                Self::Tangent(c.parse().map_err(|_| kind(c))?)
            }
            "hold" => Self::Hold(boolean(name, value)?),
            other => return Err(ViewerError::UnknownControl(other.to_string())),
        })
    }
}

/// Grab/pinch state of the shell: the picked vertex, its neighbourhood with weights and rest
/// offsets (taken when the drag starts).
#[derive(Clone, Debug)]
struct ShellDrag {
    vertex: usize,
    mode: DragMode,
    /// (vertex, weight, offset from the picked vertex at the start).
    neighbours: Vec<(usize, f64, Vector3<f64>)>,
}

/// A shell balloon (seed 000) in the viewer.
pub struct ShellView {
    mesh: TriMesh,
    settings: ShellSettings,
    sim: ShellSimulation,
    drag: Option<ShellDrag>,
    /// Drag neighbourhood radius, m (a fraction of the rest bounding-box diagonal).
    drag_radius: f64,
    /// The lowest vertices (along +y) at rest, held by springs to their rest positions when the
    /// `hold` control is on, like a hand holding a balloon at its knot.
    held: Vec<(usize, [f64; 3])>,
}

/// Stiffness of the shell drag springs in units of the membrane stiffness `E h` (N/m): vertex
/// `i` of the neighbourhood gets `w_i SHELL_DRAG_STIFFNESS E h`. The springs are part of the
/// implicit solve ([`ShellSimulation::set_anchor_springs`]), so they may be stiff.
const SHELL_DRAG_STIFFNESS: f64 = 10.0;
/// The vertices within this fraction of the height above the lowest one are held (`hold`).
const HELD_FRACTION: f64 = 0.04;
/// A pinch pulls the neighbourhood to this fraction of its size around the target.
const PINCH_SCALE: f64 = 0.3;

/// Newton iterations per step of the live shell (the paper's fixed count; see `ShellView`).
const VIEWER_NEWTON_ITERATIONS: usize = 3;

impl ShellView {
    /// A shell view of `mesh` (closed, outward, m) with the default controls.
    pub fn new(mesh: TriMesh) -> Result<Self, ViewerError> {
        let settings = ShellSettings {
            gas: GasKind::Constant,
            pressure: 2000.0,
            pump_rate: 1e-3,
            thickness_mm: 0.3,
            material: MaterialKind::StVenantKirchhoff,
            young_mpa: 1.0,
            dt: 0.01,
            solver: LinearSolverKind::Cholesky,
            tangent: TangentKind::Projected,
            hold: true,
        };
        let sim = Self::build(&mesh, &settings)?;
        let x = sim.positions();
        let drag_radius = 0.12 * bbox_diagonal(x);
        let (lo, hi) = x
            .chunks_exact(3)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), c| {
                (a.min(c[1]), b.max(c[1]))
            });
        let held = (0..vertex_count(x))
            .filter(|&i| x[3 * i + 1] <= lo + HELD_FRACTION * (hi - lo))
            .map(|i| (i, [x[3 * i], x[3 * i + 1], x[3 * i + 2]]))
            .collect();
        Ok(Self {
            mesh,
            settings,
            sim,
            drag: None,
            drag_radius,
            held,
        })
    }

    fn build(mesh: &TriMesh, s: &ShellSettings) -> Result<ShellSimulation, ViewerError> {
        let lame = Lame::try_from_young_poisson(s.young_mpa * 1e6, balloon::shell::DEFAULT_POISSON)
            .map_err(ViewerError::Young)?;
        ShellBalloon::new(mesh.clone())
            .with_material(MaterialModel::from_lame(s.material, lame))
            .with_gas(s.gas)
            .with_gauge_pressure(s.pressure)
            .with_pump_rate(s.pump_rate)
            .with_thickness(s.thickness_mm * 1e-3)
            .with_dt(s.dt)
            .with_linear_solver(s.solver)
            .build()
            .and_then(|mut sim| {
                sim.configure_integrator(|p| {
                    p.tangent = s.tangent;
                    // The live view runs the paper's fixed three Newton iterations per step for
                    // its frame rate: with the converged default (residual 1e-6) a drag that
                    // pinches the membrane stalled Newton on the exact tangent (relative
                    // residual 2.6e-2 after 30 iterations at dt / 4, in the e2e test). The CLI
                    // runs converged.
                    p.newton_iterations = VIEWER_NEWTON_ITERATIONS;
                    p.newton_tolerance = 0.0;
                })?;
                Ok(sim)
            })
            .map_err(ViewerError::from)
    }

    /// Applies a control; `true` when the simulation must be rebuilt.
    fn apply(&mut self, control: ShellControl) -> Result<bool, ViewerError> {
        let s = &mut self.settings;
        match control {
            ShellControl::Gas(gas) => s.gas = gas,
            ShellControl::Pressure(p) => {
                if s.gas != GasKind::Pump {
                    self.sim.set_gauge_pressure(p).map_err(ViewerError::from)?;
                }
                s.pressure = p;
                return Ok(false);
            }
            ShellControl::PumpRate(rate) => {
                if s.gas == GasKind::Pump {
                    self.sim.set_pump_rate(rate).map_err(ViewerError::from)?;
                }
                s.pump_rate = rate;
                return Ok(false);
            }
            ShellControl::ThicknessMm(h) => s.thickness_mm = h,
            ShellControl::Material(kind) => s.material = kind,
            ShellControl::YoungMpa(e) => s.young_mpa = e,
            ShellControl::Dt(dt) => {
                self.sim.set_dt(dt).map_err(ViewerError::from)?;
                s.dt = dt;
                return Ok(false);
            }
            ShellControl::Solver(kind) => {
                self.sim
                    .configure_integrator(|p| p.linear.kind = kind)
                    .map_err(ViewerError::from)?;
                s.solver = kind;
                return Ok(false);
            }
            ShellControl::Tangent(kind) => {
                self.sim
                    .configure_integrator(|p| p.tangent = kind)
                    .map_err(ViewerError::from)?;
                s.tangent = kind;
                return Ok(false);
            }
            ShellControl::Hold(hold) => {
                s.hold = hold;
                return Ok(false);
            }
        }
        Ok(true)
    }
}

impl ViewSystem for ShellView {
    fn name(&self) -> &'static str {
        "shell"
    }

    fn controls(&self) -> Vec<ControlSpec> {
        let s = &self.settings;
        vec![
            ControlSpec::choice(
                "gas",
                "Gas model",
                &s.gas.to_string(),
                &["ideal", "constant", "pump"],
                true,
            ),
            ControlSpec::number(
                "pressure",
                "Gauge pressure (constant gas; ideal gas: at the rest volume)",
                s.pressure,
                (0.0, 20000.0, 50.0),
                "Pa",
                false,
            ),
            ControlSpec::number(
                "pump_rate",
                "Pump rate (pump gas)",
                s.pump_rate,
                (0.0, 0.01, 1e-4),
                "m^3/s",
                false,
            ),
            ControlSpec::number(
                "thickness",
                "Thickness",
                s.thickness_mm,
                (0.05, 5.0, 0.05),
                "mm",
                true,
            ),
            ControlSpec::choice(
                "material",
                "Material",
                name_of(&MATERIALS, &s.material),
                &["stvk", "neo-hookean"],
                true,
            ),
            ControlSpec::number(
                "young",
                "Young's modulus",
                s.young_mpa,
                (0.05, 100.0, 0.05),
                "MPa",
                true,
            ),
            ControlSpec::number("dt", "Time step", s.dt, (1e-4, 0.05, 1e-3), "s", false),
            ControlSpec::choice(
                "solver",
                "Linear solver",
                &s.solver.to_string(),
                &["cholesky", "factorized-pcg", "pcg", "matrix-free-cg"],
                false,
            ),
            ControlSpec::choice(
                "tangent",
                "Newton tangent (projected: PSD per element)",
                &s.tangent.to_string(),
                &["projected", "exact"],
                false,
            ),
            ControlSpec::boolean("hold", "Hold the bottom (springs to rest)", s.hold, false),
        ]
    }

    fn set_control(&mut self, name: &str, value: &ControlValue) -> Result<bool, ViewerError> {
        self.apply(ShellControl::parse(name, value)?)
    }

    fn rebuild(&mut self) -> Result<(), ViewerError> {
        self.sim = Self::build(&self.mesh, &self.settings)?;
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
        let th = self.sim.thickness();
        let mean = th.iter().sum::<f64>() / th.len().max(1) as f64;
        let m = json!({
            "gas_volume": self.sim.gas_volume(),
            "rest_gas_volume": self.sim.rest_gas_volume(),
            "gauge_pressure": self.sim.gauge_pressure(),
            "thickness_mean": mean,
            "shell_volume_ratio": self.sim.shell_volume() / self.sim.rest_shell_volume(),
            "dt": Simulation::dt(&self.sim),
        });
        m.as_object().cloned().unwrap_or_default()
    }

    fn scalar_fields(&self) -> Vec<&'static str> {
        vec![
            "thickness",
            "stretch",
            "max_stretch",
            "speed",
            "pressure_force",
        ]
    }

    fn scalar(&self, name: &str) -> Result<Vec<f64>, ViewerError> {
        let (x, t) = (self.sim.positions(), self.sim.triangles());
        let per_face = match name {
            "thickness" => self.sim.thickness().to_vec(),
            "stretch" => fields::face_area_stretch(self.sim.rest_positions(), x, t)
                .map_err(ViewerError::from)?,
            "max_stretch" => fields::face_max_stretch(self.sim.rest_positions(), x, t)
                .map_err(ViewerError::from)?,
            "speed" => {
                return fields::vertex_speeds(self.sim.velocities()).map_err(ViewerError::from);
            }
            "pressure_force" => {
                // |f_p| per vertex (seed 000 Eq. 15), the norm of each vertex's 3-vector.
                let f = fields::pressure_forces(x, t, self.sim.gauge_pressure())
                    .map_err(ViewerError::from)?;
                return fields::vertex_speeds(&f).map_err(ViewerError::from);
            }
            other => return Err(ViewerError::UnknownField(other.to_string())),
        };
        fields::face_to_vertex(x, t, &per_face).map_err(ViewerError::from)
    }

    fn drag_modes(&self) -> Vec<&'static str> {
        vec!["grab", "pinch"]
    }

    fn apply_drag(&mut self, drag: Option<&DragRequest>) -> Result<(), ViewerError> {
        let k = SHELL_DRAG_STIFFNESS
            * self.settings.young_mpa
            * 1e6
            * self.settings.thickness_mm
            * 1e-3;
        let mut springs: Vec<AnchorSpring> = if self.settings.hold {
            self.held
                .iter()
                .map(|&(vertex, anchor)| AnchorSpring {
                    vertex,
                    anchor,
                    stiffness: k,
                })
                .collect()
        } else {
            Vec::new()
        };
        match drag {
            None => self.drag = None,
            Some(d) => {
                let x = self.sim.positions();
                let restart = self
                    .drag
                    .as_ref()
                    .is_none_or(|s| s.vertex != d.vertex || s.mode != d.mode);
                if restart {
                    let c = p3(x, d.vertex);
                    let r = self.drag_radius;
                    let neighbours = (0..vertex_count(x))
                        .filter_map(|i| {
                            let o = p3(x, i) - c;
                            let q = o.norm() / r;
                            (q < 1.0).then_some((i, 1.0 - q * q, o))
                        })
                        .collect();
                    self.drag = Some(ShellDrag {
                        vertex: d.vertex,
                        mode: d.mode,
                        neighbours,
                    });
                }
                let state = self.drag.as_ref().expect("drag set above");
                let target = Vector3::from(d.target);
                let scale = match state.mode {
                    DragMode::Grab => 1.0,
                    DragMode::Pinch => PINCH_SCALE,
                };
                springs.extend(state.neighbours.iter().map(|&(i, w, o)| AnchorSpring {
                    vertex: i,
                    anchor: (target + o * scale).into(),
                    stiffness: w * k,
                }));
            }
        }
        self.sim
            .set_anchor_springs(springs)
            .map_err(ViewerError::from)
    }
}

// ---------------------------------------------------------------------------------------------
// Volumetric (seed 003).

#[derive(Clone, Debug)]
struct VolumetricSettings {
    stiffness: f64,
    correction: CellCorrection,
    solver: CellSolver,
    gravity: f64,
    dt: f64,
}

/// One control of the volumetric view, parsed from the protocol once.
#[derive(Clone, Copy, Debug, PartialEq)]
enum VolumetricControl {
    /// `stiffness`, `k dt^2 / m` (rebuilds).
    Stiffness(f64),
    /// `correction` (rebuilds).
    Correction(CellCorrection),
    /// `solver` (rebuilds).
    Solver(CellSolver),
    /// `gravity`, m/s^2 (live).
    Gravity(f64),
    /// `dt`, s (live).
    Dt(f64),
}

/// The protocol's names of the cell-volume corrections.
const CORRECTIONS: [(&str, CellCorrection); 2] = [
    ("scaling", CellCorrection::Scaling),
    ("gradient", CellCorrection::Gradient),
];
/// The protocol's names of the cell-volume solvers.
const CELL_SOLVERS: [(&str, CellSolver); 2] = [
    ("gauss-seidel", CellSolver::GaussSeidel),
    ("global", CellSolver::Global),
];

/// The protocol name of `value` in `table`.
fn name_of<T: PartialEq>(table: &[(&'static str, T)], value: &T) -> &'static str {
    table
        .iter()
        .find(|(_, v)| v == value)
        .map_or("", |(n, _)| n)
}

/// The value named `name` in `table`.
fn lookup<T: Copy>(
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

impl VolumetricControl {
    fn parse(name: &str, value: &ControlValue) -> Result<Self, ViewerError> {
        Ok(match name {
            "stiffness" => Self::Stiffness(number(name, value)?),
            "correction" => Self::Correction(lookup(&CORRECTIONS, name, choice(name, value)?)?),
            "solver" => Self::Solver(lookup(&CELL_SOLVERS, name, choice(name, value)?)?),
            "gravity" => Self::Gravity(number(name, value)?),
            "dt" => Self::Dt(number(name, value)?),
            other => return Err(ViewerError::UnknownControl(other.to_string())),
        })
    }
}

/// A volume-conserving lattice body (seed 003) on a floor in the viewer.
pub struct VolumetricView {
    soup: TriMesh,
    settings: VolumetricSettings,
    sim: VolumetricSimulation,
}

/// Volumetric drag spring: `k = VOLUMETRIC_DRAG_GAIN m / dt^2` with `m` the effective mass of the
/// picked surface point (see `apply_drag`; explicit, so far below the stability limit 4).
const VOLUMETRIC_DRAG_GAIN: f64 = 0.05;

/// Relative cell-volume tolerance of the volumetric view.
const VOLUME_TOLERANCE: f64 = 1e-6;
/// Lattice resolution (voxels along the longest side) and voxels per cell of the volumetric view.
const LATTICE: (usize, usize) = (36, 3);

impl VolumetricView {
    /// A volumetric view of the soup `soup` (m) with the default controls.
    pub fn new(soup: TriMesh) -> Result<Self, ViewerError> {
        let settings = VolumetricSettings {
            stiffness: balloon::volumetric::DEFAULT_SPRING_STIFFNESS,
            // The paper's scaling correction gains energy on the floor and inverts cells of the
            // coarse teddy within a second; the gradient correction does not (measured with the
            // `volumetric_view_*` tests).
            correction: CellCorrection::Gradient,
            solver: CellSolver::Global,
            gravity: 9.81,
            dt: 5e-4,
        };
        let sim = Self::build(&soup, &settings)?;
        Ok(Self {
            soup,
            settings,
            sim,
        })
    }

    fn build(soup: &TriMesh, s: &VolumetricSettings) -> Result<VolumetricSimulation, ViewerError> {
        let mut params = VolumetricParams {
            lattice: LatticeParams {
                resolution: LATTICE.0,
                voxels_per_cell: LATTICE.1,
                ..LatticeParams::default()
            },
            gravity: [0.0, -s.gravity, 0.0],
            dt: s.dt,
            ..VolumetricParams::default()
        };
        // Interactive rates: cells within 1e-6 of their rest volume (the library's 1e-10 costs
        // many more Gauss-Seidel sweeps per step).
        params.volume.tolerance = VOLUME_TOLERANCE;
        params.volume.correction = s.correction;
        params.volume.solver = s.solver;
        let body = VolumetricBody::build(soup, params).map_err(ViewerError::from)?;
        // Springs relative to the particle mass and the time step with `balloon volumetric`'s
        // damping: `k = s m / dt^2` (explicit, stable for s well below 1), damping
        // `DEFAULT_SPRING_DAMPING m / dt`.
        let springs = body.default_springs(s.stiffness);
        let body = body.with_springs(springs).map_err(ViewerError::from)?;
        let sim = VolumetricSimulation::new(body);
        let lowest = sim
            .positions()
            .iter()
            .map(|p| p.y)
            .fold(f64::INFINITY, f64::min);
        // The floor just below the body (a drop would invert the coarse cells on impact).
        let height = bbox_diagonal(&flat(sim.positions()));
        let floor = balloon::constraint::rigid::Plane::new(
            Point3::new(0.0, lowest - 1e-3 * height, 0.0),
            Vector3::y(),
        )
        .ok_or(ViewerError::Floor)?;
        Ok(sim.with_plane(floor))
    }

    /// Applies a control; `true` when the simulation must be rebuilt.
    fn apply(&mut self, control: VolumetricControl) -> Result<bool, ViewerError> {
        let s = &mut self.settings;
        match control {
            VolumetricControl::Stiffness(k) => s.stiffness = k,
            VolumetricControl::Correction(c) => s.correction = c,
            VolumetricControl::Solver(solver) => s.solver = solver,
            VolumetricControl::Gravity(g) => {
                self.sim
                    .set_gravity([0.0, -g, 0.0])
                    .map_err(ViewerError::from)?;
                s.gravity = g;
                return Ok(false);
            }
            VolumetricControl::Dt(dt) => {
                VolumetricSimulation::set_dt(&mut self.sim, dt).map_err(ViewerError::from)?;
                s.dt = dt;
                return Ok(false);
            }
        }
        Ok(true)
    }
}

fn flat(p: &[Point3<f64>]) -> Vec<f64> {
    p.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
}

impl ViewSystem for VolumetricView {
    fn name(&self) -> &'static str {
        "volumetric"
    }

    fn controls(&self) -> Vec<ControlSpec> {
        let s = &self.settings;
        vec![
            ControlSpec::number(
                "stiffness",
                "Cell spring stiffness k dt^2 / m",
                s.stiffness,
                (0.002, 0.3, 0.002),
                "",
                true,
            ),
            ControlSpec::choice(
                "correction",
                "Volume correction",
                name_of(&CORRECTIONS, &s.correction),
                &["scaling", "gradient"],
                true,
            ),
            ControlSpec::choice(
                "solver",
                "Volume solver (global needs the gradient correction)",
                name_of(&CELL_SOLVERS, &s.solver),
                &["gauss-seidel", "global"],
                true,
            ),
            ControlSpec::number(
                "gravity",
                "Gravity",
                s.gravity,
                (0.0, 30.0, 0.1),
                "m/s^2",
                false,
            ),
            ControlSpec::number("dt", "Time step", s.dt, (1e-4, 1e-3, 1e-4), "s", false),
        ]
    }

    fn set_control(&mut self, name: &str, value: &ControlValue) -> Result<bool, ViewerError> {
        self.apply(VolumetricControl::parse(name, value)?)
    }

    fn rebuild(&mut self) -> Result<(), ViewerError> {
        self.sim = Self::build(&self.soup, &self.settings)?;
        Ok(())
    }

    fn simulation(&self) -> &dyn ViewedSimulation {
        &self.sim
    }

    fn simulation_mut(&mut self) -> &mut dyn ViewedSimulation {
        &mut self.sim
    }

    fn stats(&self) -> Map<String, Value> {
        let m = json!({
            "volume_ratio": self.sim.total_volume() / self.sim.body().rest_volume(),
            "kinetic_energy": self.sim.kinetic_energy(),
            "max_strain": self.sim.max_strain(),
            "particles": self.sim.positions().len(),
            "halvings": self.sim.total_halvings(),
            "dt": Simulation::dt(&self.sim),
        });
        m.as_object().cloned().unwrap_or_default()
    }

    fn scalar_fields(&self) -> Vec<&'static str> {
        vec!["speed", "stretch"]
    }

    fn scalar(&self, name: &str) -> Result<Vec<f64>, ViewerError> {
        let emb = &self.sim.lattice().embedding;
        match name {
            "speed" => {
                let v: Vec<f64> = emb
                    .vertices
                    .iter()
                    .flat_map(|e| {
                        let mut s = Vector3::zeros();
                        for (&i, &w) in e.particles.iter().zip(&e.weights) {
                            s += self.sim.velocities()[i] * w;
                        }
                        [s.x, s.y, s.z]
                    })
                    .collect();
                fields::vertex_speeds(&v).map_err(ViewerError::from)
            }
            "stretch" => {
                let rest = flat(&emb.positions(&self.sim.lattice().tet_mesh.vertices));
                let x = self.positions();
                // A soup may hold zero-area triangles: their stretch is undefined (NaN, drawn
                // in the neutral colour), the rest of the surface is coloured.
                let f = fields::face_area_stretch_or_nan(&rest, &x, &emb.triangles)
                    .map_err(ViewerError::from)?;
                fields::face_to_vertex(&x, &emb.triangles, &f).map_err(ViewerError::from)
            }
            other => Err(ViewerError::UnknownField(other.to_string())),
        }
    }

    fn drag_modes(&self) -> Vec<&'static str> {
        vec!["grab"]
    }

    fn apply_drag(&mut self, drag: Option<&DragRequest>) -> Result<(), ViewerError> {
        let Some(d) = drag else {
            return self
                .sim
                .set_external_forces(None)
                .map_err(ViewerError::from);
        };
        let e = self
            .sim
            .lattice()
            .embedding
            .vertices
            .get(d.vertex)
            .ok_or(ViewerError::VertexOutOfRange { vertex: d.vertex })?;
        let (x, v, m) = (
            self.sim.positions(),
            self.sim.velocities(),
            self.sim.masses(),
        );
        let mut p = Vector3::zeros();
        let mut vel = Vector3::zeros();
        // A force F on the embedded point spread as w_j F accelerates the point by
        // F sum w_j^2 / m_j: its effective mass is 1 / sum w_j^2 / m_j (weights may be negative
        // or above 1 outside the lattice, so the plain sum of masses would be wrong).
        let mut inv_mass = 0.0;
        for (&i, &w) in e.particles.iter().zip(&e.weights) {
            p += x[i].coords * w;
            vel += v[i] * w;
            inv_mass += w * w / m[i];
        }
        let mass = 1.0 / inv_mass;
        let dt = Simulation::dt(&self.sim);
        let k = VOLUMETRIC_DRAG_GAIN * mass / (dt * dt);
        // Critically damped for the pulled mass.
        let c = 2.0 * (k * mass).sqrt();
        // The spring stretches at most half a lattice cell: a far target pulls the body along
        // instead of tearing the picked cell inside out.
        let reach = 0.5 * self.sim.lattice().info.cell_size;
        let pull = Vector3::from(d.target) - p;
        let pull = if pull.norm() > reach {
            pull * (reach / pull.norm())
        } else {
            pull
        };
        let force = k * pull - c * vel;
        let mut f = vec![Vector3::zeros(); x.len()];
        for (&i, &w) in e.particles.iter().zip(&e.weights) {
            f[i] += force * w;
        }
        self.sim
            .set_external_forces(Some(&f))
            .map_err(ViewerError::from)
    }
}

// ---------------------------------------------------------------------------------------------
// Two-layer (seed 004).

#[derive(Clone, Debug)]
struct TwoLayerSettings {
    pressure: f64,
    integrator: ExplicitMethod,
    gravity: f64,
    dt: f64,
    wall_box: bool,
}

/// One control of the two-layer view, parsed from the protocol once.
#[derive(Clone, Copy, Debug, PartialEq)]
enum TwoLayerControl {
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
    fn parse(name: &str, value: &ControlValue) -> Result<Self, ViewerError> {
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

/// A two-layer sphere (seed 004) in a box in the viewer.
pub struct TwoLayerView {
    settings: TwoLayerSettings,
    sim: TwoLayerSimulation,
    drag: Option<DragRequest>,
}

/// Drag spring of the two-layer view (seed Sec. 4.4): stiffness N/m and damping N s/m (the
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
                AxisBox::centered(Point3::origin(), Vector3::new(2.0, 2.0, 2.0))
                    .map_err(ViewerError::from)?,
            )
        } else {
            None
        };
        TwoLayerBody::octahedron_sphere(3)
            .with_radii(0.8, 1.0)
            .with_damping(0.1)
            .with_spring(SpringKind::Structural, 100.0, 0.1)
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
        let n = self.sim.model().layer_size;
        // An inner particle picked through the mesh pulls its outer partner.
        let particle = if d.vertex < n { d.vertex + n } else { d.vertex };
        let (k, c) = TWO_LAYER_DRAG;
        self.sim
            .set_drag_particle(
                particle,
                DragTarget {
                    point: Point3::from(d.target),
                    stiffness: k,
                    damping: c,
                    rest_length: 0.0,
                },
            )
            .map_err(ViewerError::from)?;
        self.drag = Some(*d);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(sys: &mut dyn ViewSystem, seconds: f64) -> Result<(), String> {
        let t0 = std::time::Instant::now();
        while sys.time() < seconds {
            sys.step()
                .map_err(|e| format!("{e} after {:?}", t0.elapsed()))?;
        }
        eprintln!(
            "{}: {} steps in {:.2} s wall",
            sys.name(),
            sys.steps(),
            t0.elapsed().as_secs_f64()
        );
        Ok(())
    }

    #[test]
    fn default_volumetric_teddy_rests_on_its_back_instead_of_toppling() {
        // Height of the highest surface point above the lowest over 0.5 s: a standing teddy
        // toppled (0.15 m -> 0.03 m in 0.25 s); lying on its back it keeps its height.
        let soup = crate::default_mesh(crate::SystemKind::Volumetric).unwrap();
        let mut v = VolumetricView::new(soup).unwrap();
        let height = |v: &VolumetricView| {
            let x = v.positions();
            let ys = x.chunks_exact(3).map(|p| p[1]);
            ys.clone().fold(f64::MIN, f64::max) - ys.fold(f64::MAX, f64::min)
        };
        let h0 = height(&v);
        let mut lowest = h0;
        while v.time() < 0.5 {
            v.step().unwrap();
            lowest = lowest.min(height(&v));
        }
        eprintln!("height {h0} m, lowest {lowest} m, end {} m", height(&v));
        assert!(lowest > 0.8 * h0, "height {h0} m fell to {lowest} m");
    }

    #[test]
    fn volumetric_view_springs_use_the_cli_defaults() {
        // The same stiffness and damping relative to `m / dt^2` and `m / dt` as `balloon
        // volumetric` (`VolumetricBody::default_springs`), also after a stiffness change.
        use balloon::volumetric::{DEFAULT_SPRING_DAMPING, DEFAULT_SPRING_STIFFNESS};
        let soup = crate::default_mesh(crate::SystemKind::Volumetric).unwrap();
        let mut v = VolumetricView::new(soup).unwrap();
        for stiffness in [DEFAULT_SPRING_STIFFNESS, 0.05] {
            if stiffness != v.settings.stiffness {
                v.set_control("stiffness", &ControlValue::Number(stiffness))
                    .unwrap();
                v.rebuild().unwrap();
            }
            let body = v.sim.body();
            let m = body.mass() / body.masses.len() as f64;
            let dt = body.params.dt;
            let springs = body.params.springs;
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b;
            assert!(
                close(springs.edge_stiffness, stiffness * m / (dt * dt)),
                "{springs:?}"
            );
            assert!(
                close(springs.edge_damping, DEFAULT_SPRING_DAMPING * m / dt),
                "{springs:?}"
            );
            assert_eq!(springs.diagonal_damping, springs.edge_damping);
        }
    }

    #[test]
    fn volumetric_view_lands_without_failing() {
        let soup = crate::default_mesh(crate::SystemKind::Volumetric).unwrap();
        let mut v = VolumetricView::new(soup).unwrap();
        assert_eq!(v.settings.solver, CellSolver::Global);
        run(&mut v, SECONDS).unwrap();
        // The paper's Gauss-Seidel sweeps land too.
        assert!(
            v.set_control("solver", &ControlValue::Choice("gauss-seidel"))
                .unwrap()
        );
        v.rebuild().unwrap();
        run(&mut v, SECONDS).unwrap();
        // The global solver with the scaling correction is refused, naming the setting.
        v.set_control("correction", &ControlValue::Choice("scaling"))
            .unwrap();
        v.set_control("solver", &ControlValue::Choice("global"))
            .unwrap();
        let e = v
            .rebuild()
            .expect_err("global + scaling refused")
            .to_string();
        assert!(e.contains("`correction`"), "{e}");
    }
    const SECONDS: f64 = 0.25;

    fn small_shell() -> ShellView {
        ShellView::new(balloon::mesh::generate::icosphere(0.1, 2).unwrap()).unwrap()
    }

    fn position(sys: &dyn ViewSystem, i: usize) -> Vector3<f64> {
        p3(&sys.positions(), i)
    }

    /// Pulls vertex `i` `distance` outwards (from the centroid) for `seconds` and returns the
    /// distance to the target before and at the closest approach.
    fn pull(
        sys: &mut dyn ViewSystem,
        i: usize,
        distance: f64,
        mode: DragMode,
        seconds: f64,
    ) -> (f64, f64) {
        let x = sys.positions();
        let n = vertex_count(&x);
        let c = (0..n).map(|j| p3(&x, j)).sum::<Vector3<f64>>() / n as f64;
        let start = p3(&x, i);
        let target = start + (start - c).normalize() * distance;
        let req = DragRequest {
            vertex: i,
            target: target.into(),
            mode,
        };
        let t_end = sys.time() + seconds;
        let mut best = distance;
        while sys.time() < t_end {
            sys.apply_drag(Some(&req)).unwrap();
            sys.step().unwrap();
            best = best.min((position(sys, i) - target).norm());
        }
        (distance, best)
    }

    #[test]
    fn shell_grab_and_pinch_pull_the_vertex_towards_the_target() {
        for mode in [DragMode::Grab, DragMode::Pinch] {
            let mut v = small_shell();
            let (d0, d1) = pull(&mut v, 0, 0.02, mode, 0.3);
            assert!(d1 < 0.7 * d0, "{mode:?}: {d0} -> {d1}");
        }
        // A pinch draws the neighbours of the picked vertex together; a grab does not.
        let spread = |mode| {
            let mut v = small_shell();
            let x0 = v.positions();
            let near: Vec<usize> = (0..vertex_count(&x0))
                .filter(|&j| j != 0 && (p3(&x0, j) - p3(&x0, 0)).norm() < v.drag_radius)
                .collect();
            assert!(near.len() >= 3);
            pull(&mut v, 0, 0.0, mode, 0.2);
            let x = v.positions();
            near.iter()
                .map(|&j| (p3(&x, j) - p3(&x, 0)).norm())
                .sum::<f64>()
                / near.len() as f64
        };
        let (grab, pinch) = (spread(DragMode::Grab), spread(DragMode::Pinch));
        assert!(
            pinch < 0.8 * grab,
            "mean neighbour distance: grab {grab}, pinch {pinch}"
        );
    }

    #[test]
    fn shell_release_removes_the_forces_and_controls_act() {
        let mut v = small_shell();
        let held = v.held.len();
        assert!(held > 0);
        pull(&mut v, 3, 0.01, DragMode::Grab, 0.02);
        assert!(v.sim.anchor_springs().len() > held);
        v.apply_drag(None).unwrap();
        assert_eq!(v.sim.anchor_springs().len(), held);
        v.set_control("hold", &ControlValue::Bool(false)).unwrap();
        v.apply_drag(None).unwrap();
        assert!(v.sim.anchor_springs().is_empty());
        // Live pressure (constant gas by default).
        assert!(
            !v.set_control("pressure", &ControlValue::Number(500.0))
                .unwrap()
        );
        v.step().unwrap();
        assert!((v.sim.gauge_pressure() - 500.0).abs() < 1e-6);
        // A material change asks for a rebuild, which starts over.
        assert!(
            v.set_control("material", &ControlValue::Choice("neo-hookean"))
                .unwrap()
        );
        v.rebuild().unwrap();
        assert_eq!(v.steps(), 0);
        assert_eq!(
            v.controls()
                .iter()
                .find(|c| c.name == "material")
                .unwrap()
                .value,
            "neo-hookean"
        );
        assert!(
            !v.set_control("solver", &ControlValue::Choice("pcg"))
                .unwrap()
        );
        assert!(
            !v.set_control("tangent", &ControlValue::Choice("exact"))
                .unwrap()
        );
        v.step().unwrap();
        for f in v.scalar_fields() {
            assert_eq!(
                v.scalar(f).unwrap().len(),
                vertex_count(&v.positions()),
                "{f}"
            );
        }
        assert!(v.scalar("colour").is_err());
    }

    #[test]
    fn two_layer_view_drags_an_outer_particle() {
        let mut v = TwoLayerView::new().unwrap();
        v.set_control("gravity", &ControlValue::Number(0.0))
            .unwrap();
        v.rebuild().unwrap();
        let n = v.sim.model().layer_size;
        // Picking inner particle 5 pulls its outer partner 5 + n.
        let (d0, d1) = pull(&mut v, 5 + n, 0.3, DragMode::Grab, 1.0);
        assert!(d1 < 0.5 * d0, "{d0} -> {d1}");
        let req = DragRequest {
            vertex: 5,
            target: [0.0, 0.0, 3.0],
            mode: DragMode::Grab,
        };
        v.apply_drag(Some(&req)).unwrap();
        assert_eq!(v.sim.forces().drag().map(|(_, i)| i), Some(5 + n));
        v.apply_drag(None).unwrap();
        assert!(v.sim.forces().drag().is_none());
        for f in v.scalar_fields() {
            assert_eq!(v.scalar(f).unwrap().len(), 2 * n, "{f}");
        }
    }

    #[test]
    fn volumetric_view_colours_a_soup_with_a_zero_area_triangle() {
        // Seed 003 takes any soup; a sliver of three collinear points has no stretch (NaN, drawn
        // neutral) while every other vertex gets its value.
        let mut soup = balloon::mesh::generate::icosphere(0.1, 2).unwrap();
        let n = soup.vertices.len();
        for k in 0..3 {
            soup.vertices
                .push(Point3::new(0.01 * f64::from(k), 0.0, 0.0));
        }
        soup.triangles.push([n, n + 1, n + 2]);
        let mut v = VolumetricView::new(soup).unwrap();
        v.step().unwrap();
        let s = v.scalar("stretch").unwrap();
        assert_eq!(s.len(), n + 3);
        assert!(s[..n].iter().all(|x| x.is_finite()), "finite on the sphere");
        assert!(s[n..].iter().all(|x| x.is_nan()), "{:?}", &s[n..]);
    }

    #[test]
    fn volumetric_view_drag_and_fields() {
        let soup = crate::default_mesh(crate::SystemKind::Volumetric).unwrap();
        let mut v = VolumetricView::new(soup).unwrap();
        v.set_control("gravity", &ControlValue::Number(0.0))
            .unwrap();
        let (d0, d1) = pull(&mut v, 0, 0.02, DragMode::Grab, 0.1);
        assert!(d1 < 0.7 * d0, "{d0} -> {d1}");
        for f in v.scalar_fields() {
            assert_eq!(
                v.scalar(f).unwrap().len(),
                vertex_count(&v.positions()),
                "{f}"
            );
        }
        // A far target (1 m away) does not invert cells.
        let far = DragRequest {
            vertex: 7,
            target: [1.0, 0.5, 0.0],
            mode: DragMode::Grab,
        };
        let t_end = v.time() + 0.1;
        while v.time() < t_end {
            v.apply_drag(Some(&far)).unwrap();
            v.step().unwrap();
        }
        let bad = DragRequest {
            vertex: usize::MAX,
            target: [0.0; 3],
            mode: DragMode::Grab,
        };
        assert!(v.apply_drag(Some(&bad)).is_err());
    }

    /// Every value a control announces (its current value and, for a choice, every choice)
    /// parses into the system's typed control, and the parsed value of the current setting
    /// is announced back unchanged; unknown names and wrong kinds are refused.
    fn check_controls<C: std::fmt::Debug>(
        controls: &[ControlSpec],
        parse: impl Fn(&str, &ControlValue) -> Result<C, ViewerError>,
    ) {
        use crate::protocol::ControlKind;
        for c in controls {
            let values: Vec<ControlValue> = match c.kind {
                ControlKind::Number => vec![ControlValue::Number(c.value.as_f64().unwrap())],
                ControlKind::Bool => vec![ControlValue::Bool(c.value.as_bool().unwrap())],
                ControlKind::Choice => {
                    let current = c.value.as_str().unwrap();
                    assert!(c.choices.contains(&current), "{}: {current}", c.name);
                    c.choices
                        .iter()
                        .map(|ch| ControlValue::Choice(ch))
                        .collect()
                }
            };
            for v in &values {
                parse(c.name, v).unwrap_or_else(|e| panic!("{} = {v:?}: {e}", c.name));
            }
            let wrong = match c.kind {
                ControlKind::Number => ControlValue::Bool(true),
                _ => ControlValue::Number(1.0),
            };
            assert!(
                parse(c.name, &wrong).is_err(),
                "{} accepted {wrong:?}",
                c.name
            );
        }
        assert!(parse("colour", &ControlValue::Number(1.0)).is_err());
    }

    #[test]
    fn controls_are_typed_and_parse_from_what_they_announce() {
        check_controls(&small_shell().controls(), ShellControl::parse);
        check_controls(
            &TwoLayerView::new().unwrap().controls(),
            TwoLayerControl::parse,
        );
        let soup = balloon::mesh::generate::icosphere(0.1, 2).unwrap();
        let v = VolumetricView::new(soup).unwrap();
        check_controls(&v.controls(), VolumetricControl::parse);
        assert_eq!(
            VolumetricControl::parse("solver", &ControlValue::Choice("gauss-seidel")).ok(),
            Some(VolumetricControl::Solver(CellSolver::GaussSeidel))
        );
        assert_eq!(
            ShellControl::parse("solver", &ControlValue::Choice("factorized-pcg")).ok(),
            Some(ShellControl::Solver(LinearSolverKind::FactorizedPcg))
        );
        // Wrong kinds and unknown names keep their messages, now typed.
        let e = ShellControl::parse("hold", &ControlValue::Number(1.0)).unwrap_err();
        assert!(matches!(
            e,
            ViewerError::WrongKind {
                expected: "true or false",
                ..
            }
        ));
        assert_eq!(
            e.to_string(),
            "control `hold`: expected true or false, got Number(1.0)"
        );
        let e = TwoLayerControl::parse("colour", &ControlValue::Number(1.0)).unwrap_err();
        assert_eq!(e.to_string(), "unknown control `colour`");
        let e = ShellControl::parse("gas", &ControlValue::Choice("helium")).unwrap_err();
        assert_eq!(e.to_string(), "control `gas`: unknown choice `helium`");
    }

    #[test]
    fn shell_pressure_force_field_sums_to_pressure_times_area() {
        let mut v = small_shell();
        v.set_control("pressure", &ControlValue::Number(1000.0))
            .unwrap();
        v.step().unwrap();
        let f = v.scalar("pressure_force").unwrap();
        let x = v.positions();
        let area: f64 = fields::face_areas(&x, &v.triangles()).unwrap().iter().sum();
        let total: f64 = f.iter().sum();
        let want = v.sim.gauge_pressure() * area;
        assert!(
            (total - want).abs() < 0.02 * want,
            "{total} vs p A = {want}"
        );
    }
}
