//! The shell scenario's tables as types.

use crate::gas::{GasControl, GasLaws, VolumeRatios};
use crate::material::MaterialSpec;
use crate::mesh::MeshSpec;
use crate::output::{ColorField, Output, choices};
use crate::selection::{LinearRule, Load, Pin};
use crate::serde_text;
use balloon::integrate::TangentKind;
use balloon::integrate::linear::{LinearSolverKind, PcgPreconditioner};
use balloon::shell;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// The shell-volume projection (`volume_projection`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ProjectionMode {
    /// The global shell-volume projection of Wang et al. 2015 (Eq. 24-28, Algorithm 2).
    Global,
    /// Every element keeps its own material volume (thickness H A0 / A per element).
    PerElement,
    /// No projection: the thickness stays at its rest value (a membrane's still follows its
    /// stretch).
    Off,
}

choices!(
    ProjectionMode,
    "a volume projection",
    [
        (ProjectionMode::Global, "global"),
        (ProjectionMode::PerElement, "per-element"),
        (ProjectionMode::Off, "off"),
    ]
);

/// The `[shell]` table: the material and the wall.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Wall {
    /// The material and its parameters.
    #[serde(flatten)]
    pub material: MaterialSpec,
    /// Rest shell thickness, m (the paper uses 0.3 mm).
    pub thickness: f64,
    /// A rest-thickness map file (one value per face or per vertex, m); replaces `thickness`.
    pub thickness_file: Option<PathBuf>,
    /// A rest thickness linear in a coordinate; replaces `thickness`.
    pub thickness_rule: Option<LinearRule>,
    /// Stiffness of the anchors without their own, N/m; `None`: hard pins.
    pub pin_stiffness: Option<f64>,
    /// Shell density, kg/m^3.
    pub density: f64,
    /// The shell-volume projection [default: global; off for membranes].
    #[serde(with = "serde_text::option")]
    pub volume_projection: Option<ProjectionMode>,
    /// Factor on the wall's plate bending modulus `Y h^3 / (12 (1 - nu^2))` (a discrete-shell
    /// hinge per interior edge); 0 (the default): none, the paper's three-prism wall.
    pub bending: f64,
}

impl Default for Wall {
    fn default() -> Self {
        Self {
            material: MaterialSpec::default(),
            thickness: shell::DEFAULT_THICKNESS,
            thickness_file: None,
            thickness_rule: None,
            pin_stiffness: None,
            density: shell::DEFAULT_DENSITY,
            volume_projection: None,
            bending: 0.0,
        }
    }
}

/// The `[gas]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Gas {
    /// How the gas is held.
    #[serde(with = "serde_text")]
    pub model: GasControl,
    /// Gauge pressure, Pa: initial for `ideal`, fixed for `constant`, unused by `pump`.
    pub pressure: f64,
    /// Ambient (outside) pressure, Pa.
    pub ambient: f64,
    /// Pump rate of `pump`, m^3/s of ambient air; `None`: 0.7 rest volumes per second.
    pub pump_rate: Option<f64>,
    /// The parameters of the other gas laws.
    #[serde(flatten)]
    pub laws: GasLaws,
    /// Static volume control: the enclosed volume over the rest volume.
    pub volume_ratio: Option<f64>,
    /// Static volume control: a continuation of volume ratios.
    pub volume_ratios: Option<VolumeRatios>,
}

impl Default for Gas {
    fn default() -> Self {
        Self {
            model: GasControl::Pump,
            pressure: shell::DEFAULT_GAUGE_PRESSURE,
            ambient: balloon::gas::STANDARD_ATMOSPHERE,
            pump_rate: None,
            laws: GasLaws::default(),
            volume_ratio: None,
            volume_ratios: None,
        }
    }
}

/// The `[run]` table: time stepping (or the static solve), convergence, damping, Newton and
/// the linear solver.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ShellRun {
    /// Time step, s.
    pub dt: f64,
    /// Number of steps (the most with `until_converged`).
    pub steps: usize,
    /// Solve for the rest shape directly instead of stepping in time.
    #[serde(rename = "static")]
    pub static_solve: bool,
    /// Stop when the largest vertex speed is below `speed_tol` and the per-step relative gas
    /// volume change below `volume_tol`.
    pub until_converged: bool,
    /// Speed tolerance of `until_converged`, m/s.
    pub speed_tol: f64,
    /// Relative per-step volume change tolerance of `until_converged`.
    pub volume_tol: f64,
    /// Mass-proportional damping alpha, 1/s.
    pub mass_damping: f64,
    /// Stiffness-proportional damping beta, s.
    pub stiffness_damping: f64,
    /// Maximum Newton iterations per (sub-)step.
    pub newton_iters: usize,
    /// Newton's relative residual tolerance (0: the paper's fixed iterations).
    pub newton_tol: f64,
    /// The linear solver.
    #[serde(with = "serde_text")]
    pub linear_solver: LinearSolverKind,
    /// The Newton tangent.
    #[serde(with = "serde_text")]
    pub tangent: TangentKind,
    /// The preconditioner of the `pcg` solver.
    #[serde(with = "serde_text")]
    pub pcg_preconditioner: PcgPreconditioner,
    /// Relative tolerance of the CG solvers.
    pub cg_tol: f64,
    /// Inexact Newton: the fraction of `newton_tol` each CG solve is asked for.
    pub inexact_forcing: f64,
    /// Maximum CG iterations per Newton iteration.
    pub cg_max_iters: usize,
    /// The pressure tangent's follower term (`None`: on with the residual test, off in the
    /// paper's mode).
    pub follower_term: Option<bool>,
    /// Solve each step with the wall thickness extrapolated to its end and coupled to the
    /// projection (`None`: off, the paper's Algorithm 1).
    pub thickness_prediction: Option<bool>,
    /// `static`: report the smallest eigenvalue of each equilibrium's stiffness (whether it is
    /// stable under the load as held; a sign change along a `volume_ratios` continuation marks a
    /// limit point or a bifurcation).
    pub stability: bool,
}

impl Default for ShellRun {
    fn default() -> Self {
        let integrator = shell::default_integrator_params();
        Self {
            dt: shell::DEFAULT_DT,
            steps: 300,
            static_solve: false,
            until_converged: false,
            speed_tol: 1e-3,
            volume_tol: 1e-6,
            mass_damping: integrator.mass_damping,
            stiffness_damping: integrator.stiffness_damping,
            newton_iters: integrator.newton_iterations,
            newton_tol: integrator.newton_tolerance,
            linear_solver: integrator.linear.kind,
            tangent: integrator.tangent,
            pcg_preconditioner: integrator.pcg_preconditioner,
            cg_tol: integrator.linear.relative_tolerance,
            inexact_forcing: integrator.inexact_forcing,
            cg_max_iters: integrator.linear.max_iterations,
            follower_term: None,
            thickness_prediction: None,
            stability: false,
        }
    }
}

/// A shell balloon's scenario: the keys of a `kind = "shell"` scenario file, typed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ShellScenario {
    /// `[mesh]`.
    pub mesh: MeshSpec,
    /// `[shell]`: the material and the wall.
    pub shell: Wall,
    /// `[gas]`.
    pub gas: Gas,
    /// `[run]`.
    pub run: ShellRun,
    /// `[output]`.
    pub output: Output,
    /// `[[anchors]]`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub anchors: Vec<Pin>,
    /// `[[loads]]`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub loads: Vec<Load>,
}

impl Default for ShellScenario {
    fn default() -> Self {
        Self {
            mesh: MeshSpec::default(),
            shell: Wall::default(),
            gas: Gas::default(),
            run: ShellRun::default(),
            output: Output::every(10),
            anchors: Vec::new(),
            loads: Vec::new(),
        }
    }
}

/// The colours a shell run can draw.
pub const SHELL_COLORS: &[ColorField] = &[
    ColorField::Thickness,
    ColorField::Stretch,
    ColorField::Speed,
];
