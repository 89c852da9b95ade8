//! Shell balloons with thickness (seed 000, "Cute Balloons with Thickness"; Algorithms 1 and 2).
//!
//! A closed triangle mesh becomes a shell of three-prism elements (Eq. 1-4) of a hyperelastic
//! material (St. Venant-Kirchhoff, Eq. 6-9, or neo-Hookean), filled with a uniform gas (Eq. 12-17)
//! and advanced by backward Euler with Newton-Raphson (Eq. 18-23); after each solve the
//! shell-volume projection (Eq. 24-28, Algorithm 2) restores the material volume of the shell by
//! moving the vertices and the thickness, and the velocities are set to `(x_new - x_old) / dt`
//! (Algorithm 1, lines 11-12).
//!
//! The same system also runs incompressible rubber membranes (neo-Hookean, Mooney-Rivlin, Gent,
//! Ogden, Yeoh; `docs/membranes.md`): [`ShellBalloon::with_membrane`] puts a
//! [`balloon_element::HyperMembrane`] on every triangle, whose thickness follows the stretch
//! (`h = H / (l1 l2)`), so the volume projection is not needed. The element kind is part of the
//! material seam, [`ShellMaterial`].
//!
//! ```no_run
//! use balloon::shell::ShellBalloon;
//! let mesh = balloon::mesh::generate::icosphere(0.1, 3).unwrap();
//! let mut sim = ShellBalloon::new(mesh).with_gauge_pressure(2000.0).build().unwrap();
//! for _ in 0..10 {
//!     let stats = sim.step().unwrap();
//!     println!("{} {}", stats.time, stats.gas_volume);
//! }
//! ```
//!
//! Swapping a part is one line: `.with_material(NeoHookean::new(lame))`,
//! `.with_linear_solver(LinearSolverKind::Cholesky)`, `.with_gas(GasKind::Constant)` or
//! `.with_gas_model(my_gas)`, `.configure_integrator(|p| p.newton_iterations = 5)`,
//! `.with_projector(my_projector)` or `.with_projection(None)`. Each is shown below on a small
//! sphere.
//!
//! The material (any [`Material`](balloon_material::Material) on three-prism elements, or an
//! incompressible membrane, see [`Membrane`] and [`ShellBalloon::with_membrane`]):
//!
//! ```
//! use balloon::material::{Lame, NeoHookean};
//! use balloon::shell::ShellBalloon;
//! let mesh = balloon::mesh::generate::icosphere(0.1, 1).unwrap();
//! let lame = Lame::try_from_young_poisson(1e6, 0.45).unwrap();
//! let mut sim = ShellBalloon::new(mesh).with_material(NeoHookean::new(lame)).build().unwrap();
//! sim.step().unwrap();
//! ```
//!
//! The gas: a built-in kind, or a user's own [`GasModel`] used as given:
//!
//! ```
//! use balloon::gas::GasModel;
//! use balloon::shell::ShellBalloon;
//!
//! /// A gas whose pressure falls linearly with volume (a stiff "spring" of air).
//! #[derive(Clone, Debug)]
//! struct LinearGas { p0: f64, v0: f64, k: f64 }
//! impl GasModel for LinearGas {
//!     fn absolute_pressure(&self, v: f64, _t: f64) -> f64 { self.p0 - self.k * (v - self.v0) }
//!     fn dpressure_dvolume(&self, _v: f64, _t: f64) -> f64 { -self.k }
//!     fn potential(&self, _v: f64, _t: f64) -> Option<f64> { None }
//! }
//!
//! let mesh = balloon::mesh::generate::icosphere(0.1, 1).unwrap();
//! let v0 = 4.0 / 3.0 * std::f64::consts::PI * 0.1f64.powi(3);
//! let gas = LinearGas { p0: 101_325.0 + 1000.0, v0, k: 1e7 };
//! let mut sim = ShellBalloon::new(mesh).with_gas_model(gas).build().unwrap();
//! let stats = sim.step().unwrap();
//! assert!(stats.gauge_pressure > 0.0);
//! assert_eq!(sim.gas().k, 1e7);
//! ```
//!
//! The integrator: edit the shell's tuned defaults in place (exact tangent, sparse Cholesky,
//! mass damping 10 1/s stay), or replace them as a whole with `with_integrator`:
//!
//! ```
//! use balloon::integrate::TangentKind;
//! use balloon::shell::{ShellBalloon, default_integrator_params};
//! let mesh = balloon::mesh::generate::icosphere(0.1, 1).unwrap();
//! let builder = ShellBalloon::new(mesh).configure_integrator(|p| p.newton_iterations = 5);
//! assert_eq!(builder.integrator_params().newton_iterations, 5);
//! assert_eq!(builder.integrator_params().tangent, TangentKind::Exact);
//! assert_eq!(builder.integrator_params().mass_damping, default_integrator_params().mass_damping);
//! builder.build().unwrap().step().unwrap();
//! ```
//!
//! The linear solver: any [`balloon_linalg::LinearSolver`] value, the library's or a user's
//! (a new solver is a new type; see `balloon_integrate::implicit::BackwardEuler::with_linear_solver`
//! for one written from scratch):
//!
//! ```
//! use balloon::linalg::{FactorizedPcg, FactorizedPcgParams};
//! use balloon::shell::ShellBalloon;
//! let mesh = balloon::mesh::generate::icosphere(0.1, 1).unwrap();
//! let mut sim = ShellBalloon::new(mesh).build().unwrap();
//! sim.set_linear_solver(Box::new(FactorizedPcg::new(FactorizedPcgParams::default())));
//! let stats = sim.step().unwrap();
//! assert!(stats.newton_residual <= 1e-6);
//! ```
//!
//! The projector: any [`ShellProjector`] (the global projection of Algorithm 2 is the default;
//! per-element volumes, no projection, or a user's own are one call):
//!
//! ```
//! use balloon::constraint::projector::NoProjection;
//! use balloon::constraint::shell_volume::{ProjectionScope, ShellVolumeParams, ShellVolumeProjection};
//! use balloon::shell::ShellBalloon;
//! let mesh = balloon::mesh::generate::icosphere(0.1, 1).unwrap();
//! let per_element = ShellVolumeProjection::new(ShellVolumeParams {
//!     scope: ProjectionScope::PerElement,
//!     ..Default::default()
//! });
//! let mut sim = ShellBalloon::new(mesh.clone()).with_projector(per_element).build().unwrap();
//! sim.step().unwrap();
//! let mut off = ShellBalloon::new(mesh).with_projector(NoProjection).build().unwrap();
//! assert_eq!(off.step().unwrap().projection_iterations, 0);
//! ```

pub mod analytic;
pub mod connected;
pub(crate) mod connected_error;
mod membrane;
mod pins;
pub mod statics;
#[cfg(test)]
mod tests;

pub use balloon_integrate::decorators::AnchorSpring;
pub use balloon_shell::{
    Membrane, ShellElement, ShellMaterial, ShellMaterialModel, ShellSystem, membrane_sphere_stretch,
};

use balloon_constraint::projector::{ShellProjectionInput, ShellProjector};
use balloon_constraint::shell_volume::{ShellVolumeParams, ShellVolumeProjection, shell_volume};
use balloon_gas::{
    ConstantPressure, Gas, GasKind, GasLawParams, GasModel, IdealGas, PressureLoad,
    STANDARD_ATMOSPHERE,
};
use balloon_integrate::decorators::{Anchored, Anchors, Pinned};
use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
use balloon_integrate::linear::{LinearSolverKind, PcgPreconditioner};
use balloon_integrate::substep::{AdaptiveSubsteps, Attempt, Substepper};
use balloon_integrate::{ForceSystem, PhaseTimes, TangentKind};
use balloon_material::{Lame, MaterialKind, MaterialModel};
use balloon_mesh::TriMesh;
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Errors of the shell balloon: bad input (before any work) and failures during a run (naming
/// the step and the element or quantity).
#[derive(Debug, Error)]
pub enum ShellError {
    /// The mesh is not a closed, manifold, outward-oriented surface.
    #[error("invalid mesh: {0}")]
    Mesh(#[from] balloon_mesh::MeshError),
    /// A parameter is out of range.
    #[error("invalid parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name (as the CLI flag names it).
        name: &'static str,
        /// Its value.
        value: String,
        /// The allowed range.
        reason: String,
    },
    /// A material parameter is invalid.
    #[error("invalid material: {0}")]
    Material(#[from] balloon_material::MaterialError),
    /// A rest element is degenerate.
    #[error("element {element}: {source}")]
    Element {
        /// Triangle index.
        element: usize,
        /// What is wrong.
        #[source]
        source: balloon_element::ElementError,
    },
    /// The gas model could not be built or evaluated.
    #[error("gas: {0}")]
    Gas(#[from] balloon_gas::GasError),
    /// The Newton solve failed.
    #[error("step {step} (t = {time:.6} s): {source}")]
    Integrate {
        /// Step number (1-based) that failed.
        step: usize,
        /// Simulation time at the start of the step.
        time: f64,
        /// What failed.
        #[source]
        source: balloon_integrate::implicit::IntegrateError,
    },
    /// The volume projection failed.
    #[error("step {step}: volume projection: {source}")]
    Projection {
        /// Step number (1-based).
        step: usize,
        /// What failed.
        #[source]
        source: balloon_constraint::ConstraintError,
    },
    /// The gas volume ran away (non-finite, non-positive or beyond
    /// [`RUNAWAY_VOLUME_FACTOR`] times the rest volume): a physical runaway, not retried with
    /// smaller steps.
    #[error(
        "step {step} (t = {time:.6} s): diverged: gas volume: {volume:e} m^3 vs rest {rest_volume:e} m^3 (runaway above {RUNAWAY_VOLUME_FACTOR}x): the pressure exceeds what the shell can hold (e.g. above the neo-Hookean limit point) or the run is unstable"
    )]
    RunawayVolume {
        /// Step number (1-based).
        step: usize,
        /// Simulation time at the start of the step.
        time: f64,
        /// The enclosed volume reached, m^3.
        volume: f64,
        /// The rest volume, m^3.
        rest_volume: f64,
    },
    /// Newton did not converge even at the smallest sub-step the step halvings allow.
    #[error(
        "step {step} (t = {time:.6} s): Newton did not converge: relative residual {residual:.3e} after {iterations} iterations (tolerance {tolerance:e}) at a sub-step of {dt:e} s, the smallest allowed ({halvings} halvings in this step, at most {max_halvings} below the step); try a smaller --dt, more --newton-iters, a looser --newton-tol, --tangent projected, or more mass damping"
    )]
    NotConverged {
        /// Step number (1-based).
        step: usize,
        /// Simulation time at the start of the failed sub-step, s.
        time: f64,
        /// The sub-step size that failed last, s.
        dt: f64,
        /// Halvings tried in this step (a sub-step size reached in an earlier step carries
        /// over, so this can be 0 at the smallest size).
        halvings: usize,
        /// The most halvings allowed below the step (`ShellBalloon::with_max_step_halvings`).
        max_halvings: usize,
        /// Newton iterations of the last attempt.
        iterations: usize,
        /// Its final relative residual.
        residual: f64,
        /// The Newton tolerance.
        tolerance: f64,
    },
    /// The static solve (`ShellSimulation::solve_static`) failed in one of its Newton solves.
    #[error(
        "static solve (outer iteration {outer}): {source}; try more --newton-iters (per load stage), a looser --newton-tol, --tangent projected, or the dynamic run (--until-converged)"
    )]
    Static {
        /// Outer iteration (thickness fixed point / multiplier update), 0-based.
        outer: usize,
        /// What failed.
        #[source]
        source: balloon_integrate::statics::StaticError,
    },
    /// The static solve's outer loop (thickness fixed point, volume multiplier) did not settle.
    #[error(
        "static solve did not settle after {outer_iterations} outer iterations: Newton residual {residual:.3e}, thickness change {thickness_change:.3e}, volume error {volume_error:.3e}; the load may be near a limit point: try volume control (--gas volume) or a smaller load"
    )]
    StaticNotConverged {
        /// Outer iterations done.
        outer_iterations: usize,
        /// Relative Newton residual of the last solve.
        residual: f64,
        /// Relative thickness change of the last projection.
        thickness_change: f64,
        /// Relative volume error under volume control (0 otherwise).
        volume_error: f64,
    },
    /// The run diverged (non-finite or inverted state).
    #[error("step {step} (t = {time:.6} s): diverged: {quantity}: {detail}")]
    Diverged {
        /// Step number (1-based).
        step: usize,
        /// Simulation time at the start of the step.
        time: f64,
        /// The quantity that diverged (e.g. "gas volume", "thickness of element 12").
        quantity: String,
        /// Numbers that explain it, and what to try.
        detail: String,
    },
}

/// Rest thickness of the shell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Thickness {
    /// The same thickness for every element, m.
    Uniform(f64),
    /// One thickness per triangle, m.
    PerFace(Vec<f64>),
}

/// Builder of a [`ShellSimulation`]. Defaults model a latex party balloon: E = 1 MPa,
/// nu = 0.45, density 950 kg/m^3, thickness 0.3 mm (the paper's), a pump adding 2 L/s of
/// ambient air (101325 Pa) from the rest shape, dt = 10 ms, Newton to a relative residual of
/// 1e-6 (at most 30 iterations, line search on the incremental potential, sub-steps when a step
/// does not converge; `newton_tolerance = 0` with 3 iterations is the paper's fixed-count mode) on the
/// exact tangent (the Hessian of the incremental potential, mass-shifted where indefinite) solved
/// by sparse Cholesky: with the residual test, Newton on the projected (per-element positive
/// semi-definite) tangent converges only linearly on the nearly unloaded membrane (40 steps of
/// the default teddy: 1631 Newton iterations projected against 245 exact, measured), while in
/// the paper's fixed-count mode the projected tangent was the faster one (`docs/gas-and-integration.md`
/// section 7). Mass damping 10 1/s, global volume projection on. `with_gas(GasKind::Ideal)`
/// uses a fixed amount of gas at `with_gauge_pressure` (default 2 kPa) over ambient; the paper's
/// own gas model (Eq. 14, no ambient) is `with_ambient_pressure(0.0)`.
#[derive(Clone, Debug)]
pub struct ShellBalloon<M: ShellMaterial = MaterialModel, G: ShellGas = GasKind> {
    mesh: TriMesh,
    material: M,
    thickness: Thickness,
    density: f64,
    gas: G,
    gauge_pressure: f64,
    ambient_pressure: f64,
    pump_rate: PumpRate,
    gas_law: GasLawParams,
    /// `None`: on with a residual test, off in the paper's mode ([`ShellBalloon::with_follower_term`]).
    follower_term: Option<bool>,
    integrator: BackwardEulerParams,
    projector: Option<Box<dyn ShellProjector>>,
    dt: f64,
    validate_mesh: bool,
    max_step_halvings: usize,
}

/// How the shell builder makes its gas once the rest volume of the mesh is known: a built-in
/// [`GasKind`] (the default, set with [`ShellBalloon::with_gas`]) or a ready model
/// ([`CustomGas`], set with [`ShellBalloon::with_gas_model`]).
pub trait ShellGas {
    /// The gas model the simulation runs with.
    type Model: GasModel;
    /// Makes the model from the builder's settings.
    fn into_model(self, setup: &GasSetup) -> Result<Self::Model, ShellError>;
}

/// What the builder knows when it makes the gas.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GasSetup {
    /// Enclosed volume of the rest mesh, m^3.
    pub rest_volume: f64,
    /// Gauge pressure set on the builder, Pa.
    pub gauge_pressure: f64,
    /// Ambient pressure, Pa.
    pub ambient_pressure: f64,
    /// Pump rate as gas content, `p_ambient * rate`, J/s of `nRT`.
    pub pump_rate_joules: f64,
    /// Parameters of the polytropic, leaking and supply-pump gases.
    pub gas_law: GasLawParams,
}

impl ShellGas for GasKind {
    type Model = Gas;

    /// Ideal and constant gases are built from the absolute pressure, so a zero ambient (the
    /// paper's model, Eq. 14) is allowed; the pump starts at the ambient pressure.
    fn into_model(self, s: &GasSetup) -> Result<Gas, ShellError> {
        let p_abs = s.ambient_pressure + s.gauge_pressure;
        Ok(match self {
            GasKind::Ideal => Gas::Ideal(IdealGas::try_new(p_abs, s.rest_volume)?),
            GasKind::Constant => Gas::Constant(ConstantPressure::try_new(p_abs)?),
            GasKind::Pump | GasKind::Polytropic | GasKind::Leak | GasKind::SupplyPump => {
                Gas::try_from_kind_with(
                    self,
                    s.rest_volume,
                    s.gauge_pressure,
                    s.ambient_pressure,
                    s.pump_rate_joules,
                    &s.gas_law,
                )?
            }
        })
    }
}

/// A user's own gas model, used as given (the builder's pressures and pump rate do not touch it;
/// the ambient pressure still sets the outside of the load).
#[derive(Clone, Debug)]
pub struct CustomGas<G>(pub G);

impl<G: GasModel> ShellGas for CustomGas<G> {
    type Model = G;

    fn into_model(self, _setup: &GasSetup) -> Result<G, ShellError> {
        Ok(self.0)
    }
}

/// The cost of one numeric factorisation in CG iterations for the default solver's amortised
/// refresh of its kept factor (`BackwardEulerParams::refactor_cost`): one factorisation of the
/// 11k-vertex teddy's Newton matrix took as long as 7-12 triangular solve pairs with its
/// factor (`benches/examples/factor_profile.rs`, docs/benchmarks.md).
pub const DEFAULT_REFACTOR_COST: usize = 8;

/// The integrator parameters a [`ShellBalloon`] starts from: backward Euler with
/// [`DEFAULT_MASS_DAMPING`], Newton to a relative residual of 1e-6 on the exact tangent
/// ([`TangentKind::Exact`]), each Newton system solved by CG to [`DEFAULT_LINEAR_TOLERANCE`]
/// preconditioned by a sparse Cholesky factor kept across Newton iterations and steps with the
/// gas term as a Sherman-Morrison update ([`LinearSolverKind::FactorizedPcg`]; refreshed when
/// a solve needs more than 8 CG iterations, fails, or the extra iterations since the last
/// factorisation add up to [`DEFAULT_REFACTOR_COST`]; factorised on the calling thread: on
/// the rayon pool it took twice as long on 2 idle cores, see `docs/benchmarks.md`), IC(0) for
/// PCG. Start from these (not
/// from `BackwardEulerParams::default()`) when building parameters for
/// [`ShellBalloon::with_integrator`].
pub fn default_integrator_params() -> BackwardEulerParams {
    let mut integrator = BackwardEulerParams {
        mass_damping: DEFAULT_MASS_DAMPING,
        pcg_preconditioner: PcgPreconditioner::IncompleteCholesky,
        ..Default::default()
    };
    integrator.linear.kind = LinearSolverKind::FactorizedPcg;
    integrator.tangent = TangentKind::Exact;
    integrator.linear.relative_tolerance = DEFAULT_LINEAR_TOLERANCE;
    integrator.refactor_cost = DEFAULT_REFACTOR_COST;
    integrator.parallel_factorization = false;
    integrator
}

/// Checks a time step (s) for the builder and [`ShellSimulation::set_dt`] with the integrator's
/// own rule ([`balloon_integrate::check_time_step`]), so that a bad dt is refused before any
/// work, with the same range the integrator enforces.
fn check_dt(dt: f64) -> Result<f64, ShellError> {
    balloon_integrate::check_time_step(dt).map_err(|_| ShellError::InvalidParameter {
        name: "dt",
        value: dt.to_string(),
        reason: "must be a positive finite number".into(),
    })
}

/// A parameter of the integrator refused by its own check
/// ([`BackwardEulerParams::validate`]) as the shell's [`ShellError::InvalidParameter`].
fn integrator_error(e: balloon_integrate::implicit::IntegrateError) -> ShellError {
    match e {
        balloon_integrate::implicit::IntegrateError::InvalidParameter {
            name,
            value,
            allowed,
        } => ShellError::InvalidParameter {
            name,
            value: value.to_string(),
            reason: format!("must be {allowed}"),
        },
        other => ShellError::Integrate {
            step: 0,
            time: 0.0,
            source: other,
        },
    }
}

fn positive(name: &'static str, value: f64) -> Result<(), ShellError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ShellError::InvalidParameter {
            name,
            value: value.to_string(),
            reason: "must be a positive finite number".into(),
        })
    }
}

/// Default Young's modulus, Pa (latex rubber).
pub const DEFAULT_YOUNG: f64 = 1.0e6;
/// Default Poisson ratio.
pub const DEFAULT_POISSON: f64 = 0.45;
/// Default density, kg/m^3 (latex).
pub const DEFAULT_DENSITY: f64 = 950.0;
/// Default rest thickness, m (0.3 mm, the paper's Table 1).
pub const DEFAULT_THICKNESS: f64 = 3.0e-4;
/// Default gauge pressure, Pa.
pub const DEFAULT_GAUGE_PRESSURE: f64 = 2000.0;
/// Default time step, s.
pub const DEFAULT_DT: f64 = 1.0e-2;
/// Default pump rate in rest volumes of ambient air per second: the flow follows the body, so a
/// default run inflates a 0.1 m model and a 1 m one alike (a fixed 2 L/s fills a 0.1 m
/// armadillo 30 times per second and barely moves a 1 m one). 0.7 is about what the former
/// fixed 2 L/s gave the built-in 2.9 L teddy.
pub const DEFAULT_PUMP_VOLUMES_PER_SECOND: f64 = 0.7;

/// The pump's flow of ambient air (free-air delivery).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum PumpRate {
    /// A fixed flow, m^3/s.
    Absolute(f64),
    /// A flow in rest volumes of the body per second, 1/s (resolved at build time).
    RestVolumesPerSecond(f64),
}

impl PumpRate {
    /// The flow in m^3/s for a body of `rest_volume` m^3.
    pub fn resolve(self, rest_volume: f64) -> f64 {
        match self {
            Self::Absolute(rate) => rate,
            Self::RestVolumesPerSecond(k) => k * rest_volume,
        }
    }
}
/// Default relative tolerance of the CG linear solves inside Newton (inexact Newton).
pub const DEFAULT_LINEAR_TOLERANCE: f64 = 1e-3;
/// Default number of times a step that fails numerically may be halved (dt / 2^10 at most: a
/// sudden load on a small, light shell moves on a time scale of a millisecond or less).
pub const DEFAULT_MAX_STEP_HALVINGS: usize = 10;
/// Default mass damping, 1/s.
pub const DEFAULT_MASS_DAMPING: f64 = 10.0;

impl ShellBalloon<MaterialModel> {
    /// A balloon of the given rest mesh (m) with the default parameters.
    pub fn new(mesh: TriMesh) -> Self {
        let lame = Lame::try_from_young_poisson(DEFAULT_YOUNG, DEFAULT_POISSON)
            .expect("default Lame parameters are valid");
        let integrator = default_integrator_params();
        Self {
            mesh,
            material: MaterialModel::from_lame(MaterialKind::StVenantKirchhoff, lame),
            thickness: Thickness::Uniform(DEFAULT_THICKNESS),
            density: DEFAULT_DENSITY,
            gas: GasKind::Pump,
            gauge_pressure: DEFAULT_GAUGE_PRESSURE,
            ambient_pressure: STANDARD_ATMOSPHERE,
            pump_rate: PumpRate::RestVolumesPerSecond(DEFAULT_PUMP_VOLUMES_PER_SECOND),
            gas_law: GasLawParams::default(),
            follower_term: None,
            integrator,
            projector: Some(Box::new(ShellVolumeProjection::new(
                ShellVolumeParams::default(),
            ))),
            dt: DEFAULT_DT,
            validate_mesh: true,
            max_step_halvings: DEFAULT_MAX_STEP_HALVINGS,
        }
    }
}

impl<M: ShellMaterial, G: ShellGas> ShellBalloon<M, G> {
    /// The same builder with the material and gas replaced by `f(material, gas)`.
    fn replace<N: ShellMaterial, H: ShellGas>(
        self,
        f: impl FnOnce(M, G) -> (N, H),
    ) -> ShellBalloon<N, H> {
        let ShellBalloon {
            mesh,
            material,
            thickness,
            density,
            gas,
            gauge_pressure,
            ambient_pressure,
            pump_rate,
            gas_law,
            follower_term,
            integrator,
            projector,
            dt,
            validate_mesh,
            max_step_halvings,
        } = self;
        let (material, gas) = f(material, gas);
        ShellBalloon {
            mesh,
            material,
            thickness,
            density,
            gas,
            gauge_pressure,
            ambient_pressure,
            pump_rate,
            gas_law,
            follower_term,
            integrator,
            projector,
            dt,
            validate_mesh,
            max_step_halvings,
        }
    }

    /// Uses another material: any [`Material`](balloon_material::Material) on three-prism elements (e.g.
    /// `NeoHookean::new(lame)`), a [`Membrane`] or a [`ShellMaterialModel`] (any
    /// [`ShellMaterial`]). The projection stays as set; [`ShellBalloon::with_membrane`] also
    /// switches it off.
    pub fn with_material<N: ShellMaterial>(self, material: N) -> ShellBalloon<N, G> {
        self.replace(|_, gas| (material, gas))
    }

    /// Uses a built-in gas model kind (the default is [`GasKind::Pump`]), built at
    /// [`ShellBalloon::build`] from the pressures and pump rate set on the builder.
    pub fn with_gas(self, kind: GasKind) -> ShellBalloon<M, GasKind> {
        self.replace(|material, _| (material, kind))
    }

    /// Uses a user's own gas model (any [`GasModel`]) as given: the simulation is then a
    /// `ShellSimulation<M, H>` and [`ShellSimulation::gas`] returns the model.
    pub fn with_gas_model<H: GasModel>(self, gas: H) -> ShellBalloon<M, CustomGas<H>> {
        self.replace(|material, _| (material, CustomGas(gas)))
    }

    /// Uniform rest thickness, m.
    pub fn with_thickness(mut self, thickness: f64) -> Self {
        self.thickness = Thickness::Uniform(thickness);
        self
    }
    /// Per-face rest thickness, m (one per triangle).
    pub fn with_thickness_per_face(mut self, thickness: Vec<f64>) -> Self {
        self.thickness = Thickness::PerFace(thickness);
        self
    }
    /// Shell density, kg/m^3.
    pub fn with_density(mut self, density: f64) -> Self {
        self.density = density;
        self
    }
    /// Gauge pressure, Pa: initial for the ideal gas, fixed for constant pressure.
    pub fn with_gauge_pressure(mut self, pressure: f64) -> Self {
        self.gauge_pressure = pressure;
        self
    }
    /// Ambient (outside) pressure, Pa.
    pub fn with_ambient_pressure(mut self, pressure: f64) -> Self {
        self.ambient_pressure = pressure;
        self
    }
    /// Pump rate for [`GasKind::Pump`] as a flow of ambient air, m^3/s (free-air delivery: a
    /// person blowing up a balloon manages about 1e-3 m^3/s). The gas content grows by
    /// `p_ambient * rate` joules of `nRT` per second.
    /// The default is [`DEFAULT_PUMP_VOLUMES_PER_SECOND`] rest volumes per second
    /// ([`ShellBalloon::with_relative_pump_rate`]).
    pub fn with_pump_rate(mut self, rate: f64) -> Self {
        self.pump_rate = PumpRate::Absolute(rate);
        self
    }
    /// Pump rate for [`GasKind::Pump`] in rest volumes of the body per second (1/s): the flow
    /// is `volumes_per_second` times the enclosed rest volume, m^3/s of ambient air.
    pub fn with_relative_pump_rate(mut self, volumes_per_second: f64) -> Self {
        self.pump_rate = PumpRate::RestVolumesPerSecond(volumes_per_second);
        self
    }
    /// The parameters of the polytropic ([`GasKind::Polytropic`]: `gamma`), leaking
    /// ([`GasKind::Leak`]: the conductance) and supply-pump ([`GasKind::SupplyPump`]: the gauge
    /// supply pressure; it pumps at [`ShellBalloon::with_pump_rate`]) gases
    /// (`balloon_gas::laws`).
    pub fn with_gas_law(mut self, law: GasLawParams) -> Self {
        self.gas_law = law;
        self
    }
    /// Includes (`Some(true)`) or leaves out (`Some(false)`) the area-normal (follower) term
    /// `-(p - p_ambient) d^2V/dx^2` of the pressure tangent. `None` (the default) includes it
    /// when Newton stops on a residual (`newton_tolerance > 0`): the tangent is then the exact
    /// Hessian of the incremental potential and Newton converges quadratically (on the teddy
    /// with the paper's gas: 1.09 Newton iterations per step against 1.38 without it, where
    /// convergence is linear with a rate of about 0.8 while it inflates); and leaves it out in
    /// the paper's mode (`newton_tolerance = 0`: the paper neglects it). It goes into the
    /// element blocks of the Newton matrix (`balloon_gas::add_volume_hessian_block`).
    pub fn with_follower_term(mut self, enabled: impl Into<Option<bool>>) -> Self {
        self.follower_term = enabled.into();
        self
    }
    /// Replaces the integrator parameters as a whole (Newton iterations, linear solver, tangent,
    /// damping, gravity), the shell's tuned defaults included: parameters built from
    /// `BackwardEulerParams::default()` switch off the mass damping and use the exact tangent
    /// with matrix-free CG. Build them from [`default_integrator_params`], or edit the defaults in
    /// place with [`ShellBalloon::configure_integrator`].
    pub fn with_integrator(mut self, params: BackwardEulerParams) -> Self {
        self.integrator = params;
        self
    }
    /// Edits the integrator parameters in place, keeping everything not touched (the shell's
    /// defaults, see [`default_integrator_params`]): `.configure_integrator(|p| p.newton_iterations = 5)`.
    pub fn configure_integrator(mut self, edit: impl FnOnce(&mut BackwardEulerParams)) -> Self {
        edit(&mut self.integrator);
        self
    }
    /// The integrator parameters the simulation will be built with.
    pub fn integrator_params(&self) -> &BackwardEulerParams {
        &self.integrator
    }
    /// Linear solver behind Newton.
    pub fn with_linear_solver(mut self, kind: LinearSolverKind) -> Self {
        self.integrator.linear.kind = kind;
        self
    }
    /// The built-in volume projection with `params` (global, Algorithm 2, or per element, by
    /// `params.scope`); `None` switches the projection off.
    pub fn with_projection(mut self, params: Option<ShellVolumeParams>) -> Self {
        self.projector = params.map(|p| Box::new(ShellVolumeProjection::new(p)) as _);
        self
    }
    /// Uses `projector` after every implicit step (any [`ShellProjector`], e.g. a
    /// `ShellVolumeProjection`, `NoProjection` or a user's own).
    pub fn with_projector(mut self, projector: impl ShellProjector + 'static) -> Self {
        self.projector = Some(Box::new(projector));
        self
    }
    /// Time step, s.
    pub fn with_dt(mut self, dt: f64) -> Self {
        self.dt = dt;
        self
    }
    /// How many times a failing step may be halved before the failure is reported (default
    /// [`DEFAULT_MAX_STEP_HALVINGS`]; 0 reports the first failure).
    pub fn with_max_step_halvings(mut self, halvings: usize) -> Self {
        self.max_step_halvings = halvings;
        self
    }
    /// Skips the closed-manifold validation of the mesh (only for meshes already validated).
    pub fn with_mesh_validation(mut self, enabled: bool) -> Self {
        self.validate_mesh = enabled;
        self
    }

    /// Validates everything and builds the simulation (no time step is taken).
    pub fn build(self) -> Result<ShellSimulation<M, G::Model>, ShellError> {
        if self.validate_mesh {
            balloon_mesh::validate::validate_closed_manifold(&self.mesh)?;
        }
        positive("density", self.density)?;
        check_dt(self.dt)?;
        if !(self.ambient_pressure.is_finite() && self.ambient_pressure >= 0.0) {
            return Err(ShellError::InvalidParameter {
                name: "ambient",
                value: self.ambient_pressure.to_string(),
                reason: "must be a finite pressure >= 0 Pa".into(),
            });
        }
        if !self.gauge_pressure.is_finite() {
            return Err(ShellError::InvalidParameter {
                name: "pressure",
                value: self.gauge_pressure.to_string(),
                reason: "must be finite".into(),
            });
        }
        let nt = self.mesh.num_triangles();
        let thickness = match &self.thickness {
            Thickness::Uniform(h) => {
                positive("thickness", *h)?;
                vec![*h; nt]
            }
            Thickness::PerFace(v) => {
                if v.len() != nt {
                    return Err(ShellError::InvalidParameter {
                        name: "thickness",
                        value: format!("{} values", v.len()),
                        reason: format!("need one per triangle ({nt})"),
                    });
                }
                for h in v {
                    positive("thickness", *h)?;
                }
                v.clone()
            }
        };
        let p = &self.integrator;
        if p.newton_iterations == 0 {
            return Err(ShellError::InvalidParameter {
                name: "newton-iters",
                value: "0".into(),
                reason: "at least 1".into(),
            });
        }
        if !(p.mass_damping >= 0.0 && p.stiffness_damping >= 0.0) {
            return Err(ShellError::InvalidParameter {
                name: "damping",
                value: format!("mass {} stiffness {}", p.mass_damping, p.stiffness_damping),
                reason: "damping coefficients must be >= 0".into(),
            });
        }
        let verts: Vec<Vector3<f64>> = self.mesh.vertices.iter().map(|p| p.coords).collect();
        let nv = verts.len();
        let mut elements = Vec::with_capacity(nt);
        let mut vertex_mass = vec![0.0; nv];
        let mut vertex_proj_mass = vec![0.0; nv];
        let mut element_proj_mass = Vec::with_capacity(nt);
        for (e, t) in self.mesh.triangles.iter().enumerate() {
            let el = self
                .material
                .element(t.map(|v| verts[v]), thickness[e])
                .map_err(|source| ShellError::Element { element: e, source })?;
            let m = self.material.lumped_masses(&el, self.density);
            let (mp, m4) = self.material.projection_masses(&el, self.density);
            for c in 0..3 {
                vertex_mass[t[c]] += m[c];
                vertex_proj_mass[t[c]] += mp[c];
            }
            element_proj_mass.push(m4);
            elements.push(el);
        }
        let x = self.mesh.positions_flat();
        let rest_gas_volume = balloon_gas::enclosed_volume(&x, &self.mesh.triangles)?;
        let gas = self.gas.into_model(&GasSetup {
            rest_volume: rest_gas_volume,
            gauge_pressure: self.gauge_pressure,
            ambient_pressure: self.ambient_pressure,
            pump_rate_joules: self.pump_rate.resolve(rest_gas_volume) * self.ambient_pressure,
            gas_law: self.gas_law,
        })?;
        let load = PressureLoad::new(gas)
            .with_ambient_pressure(self.ambient_pressure)?
            .with_follower_term(
                self.follower_term
                    .unwrap_or(self.integrator.newton_tolerance > 0.0),
            );
        let rest_shell_volume = shell_volume(&self.mesh.triangles, &x, &thickness);
        // A0_e H_e, conserved per element by `ProjectionScope::PerElement`.
        let rest_element_volumes: Vec<f64> = self
            .mesh
            .triangles
            .iter()
            .zip(&thickness)
            .map(|(t, h)| {
                0.5 * (verts[t[1]] - verts[t[0]])
                    .cross(&(verts[t[2]] - verts[t[0]]))
                    .norm()
                    * h
            })
            .collect();
        let system = ShellSystem::try_new(
            nv,
            self.mesh.triangles.clone(),
            elements,
            thickness,
            self.material,
            load,
            &vertex_mass,
        )
        .map_err(|e| ShellError::InvalidParameter {
            name: "mesh",
            value: format!("{nv} vertices, {nt} triangles"),
            reason: e.to_string(),
        })?;
        let integrator = BackwardEuler::new(self.integrator).map_err(integrator_error)?;
        Ok(ShellSimulation {
            v: vec![0.0; x.len()],
            x_prev: x.clone(),
            x,
            system,
            integrator,
            projection: self.projector,
            rest_element_volumes,
            vertex_inv_mass: vertex_proj_mass.iter().map(|m| 1.0 / m).collect(),
            element_inv_mass: element_proj_mass.iter().map(|m| 1.0 / m).collect(),
            rest_shell_volume,
            rest_gas_volume,
            gas_volume: rest_gas_volume,
            rest_positions: self.mesh.positions_flat(),
            time: 0.0,
            step: 0,
            dt: self.dt,
            substeps: AdaptiveSubsteps::new(self.max_step_halvings).with_size(self.dt),
            external_forces: Vec::new(),
            anchor_springs: Anchors::default(),
            pins: pins::Pins::default(),
            projection_ms: 0.0,
        })
    }
}

/// What one step did and where the balloon is.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ShellStepStats {
    /// Step number, 1-based: the first step is 1 (the state after `step` steps).
    pub step: usize,
    /// Simulation time at the end of the step, s.
    pub time: f64,
    /// Enclosed gas volume, m^3.
    pub gas_volume: f64,
    /// Gauge pressure `p - p_ambient`, Pa.
    pub gauge_pressure: f64,
    /// Shell material volume / rest shell material volume (1 when the projection is exact).
    pub shell_volume_ratio: f64,
    /// Newton iterations performed, including those of sub-step attempts that did not
    /// converge and were retried at half the size.
    pub newton_iterations: usize,
    /// Linear (CG) iterations summed over the Newton iterations (0 for Cholesky).
    pub linear_iterations: usize,
    /// Numeric sparse Cholesky factorisations done by the linear solver in the accepted
    /// sub-steps of this step (`StepInfo::factorizations`; attempts rolled back are not
    /// counted).
    #[serde(default)]
    pub factorizations: usize,
    /// Relative Newton residual of the result (`StepInfo::relative_residual`: the residual
    /// force over the force scale), the largest over the sub-steps.
    pub newton_residual: f64,
    /// Newton steps shortened by the line search (halvings), summed over the sub-steps.
    pub line_search_cuts: usize,
    /// Linear solves retried with a larger mass shift because the Newton matrix was indefinite
    /// (`StepInfo::regularized_solves`), summed over the accepted sub-steps.
    #[serde(default)]
    pub regularized_solves: usize,
    /// The smallest sub-step taken, s (`dt` when the step was not split).
    pub dt_used: f64,
    /// Sub-steps rolled back and retried at half the size in this step.
    pub halvings: usize,
    /// Projection iterations.
    pub projection_iterations: usize,
    /// Sub-steps the step took: 1 normally, more when it had to be halved after a numerical
    /// failure or started from a sub-step size a hard earlier step left (see
    /// `ShellBalloon::with_max_step_halvings`); they add up to `dt`.
    pub substeps: usize,
    /// Largest vertex speed, m/s.
    pub max_speed: f64,
    /// Relative gas-volume change over the step, |dV| / V.
    pub volume_change: f64,
    /// Mean / min / max thickness, m.
    pub thickness_mean: f64,
    /// Minimum thickness, m.
    pub thickness_min: f64,
    /// Maximum thickness, m.
    pub thickness_max: f64,
    /// Wall-clock time of the step, ms.
    pub step_ms: f64,
    /// Where the step's time went, ms: the integrator's phases (forces, energies of the line
    /// search, assembly, factorisations, linear solves) and the shell-volume projection, over
    /// every sub-step including those rolled back and retried. `step_ms` minus their sum is
    /// the rest (state checks, statistics, copies).
    #[serde(default)]
    pub times: PhaseTimes,
}

/// Work summed over the sub-steps of one step.
#[derive(Debug, Default)]
struct StepTotals {
    newton_iterations: usize,
    linear_iterations: usize,
    factorizations: usize,
    newton_residual: f64,
    line_search_cuts: usize,
    regularized_solves: usize,
    projection_iterations: usize,
    substeps: usize,
    halvings: usize,
    min_dt: f64,
}

pub use balloon_integrate::substep::{EASY_NEWTON_ITERATIONS, MAX_EASY_BEFORE_GROWTH};

/// A running shell balloon simulation.
#[derive(Debug)]
pub struct ShellSimulation<M: ShellMaterial = MaterialModel, G: GasModel = Gas> {
    system: ShellSystem<M, G>,
    integrator: BackwardEuler,
    projection: Option<Box<dyn ShellProjector>>,
    /// Rest material volume per element, `A0_e H_e` (m^3), for per-element projectors.
    rest_element_volumes: Vec<f64>,
    x: Vec<f64>,
    v: Vec<f64>,
    x_prev: Vec<f64>,
    vertex_inv_mass: Vec<f64>,
    element_inv_mass: Vec<f64>,
    rest_shell_volume: f64,
    rest_gas_volume: f64,
    /// Enclosed gas volume of the current positions (m^3), computed once per (sub-)step by the
    /// state check.
    gas_volume: f64,
    rest_positions: Vec<f64>,
    time: f64,
    step: usize,
    dt: f64,
    /// The sub-step controller: halvings allowed, the sub-step size reached, when it grows.
    substeps: AdaptiveSubsteps,
    /// External forces per degree of freedom (N), held constant over each step; empty = none.
    external_forces: Vec<f64>,
    /// Zero-length springs to fixed anchors, part of the implicit solve; empty = none.
    anchor_springs: Anchors,
    /// Hard pins: vertices removed from the solve (`pins.rs`); none by default.
    pins: pins::Pins,
    /// Wall-clock time of every shell-volume projection so far (also of sub-steps rolled
    /// back), ms: with [`BackwardEuler::phase_times`] the running total of
    /// [`ShellStepStats::times`].
    projection_ms: f64,
}

/// One shell simulation as the sub-step controller drives it (`step`: the step number for
/// the errors).
struct ShellSubsteps<'a, M: ShellMaterial, G: GasModel> {
    sim: &'a mut ShellSimulation<M, G>,
    step: usize,
}

impl<M: ShellMaterial, G: GasModel> Substepper for ShellSubsteps<'_, M, G> {
    type State = (Vec<f64>, Vec<f64>, Vec<f64>);
    type Info = (balloon_integrate::implicit::StepInfo, usize);
    type Error = ShellError;

    fn save(&self) -> Self::State {
        (
            self.sim.x.clone(),
            self.sim.v.clone(),
            self.sim.system.thickness.clone(),
        )
    }

    fn restore(&mut self, (x, v, thickness): Self::State) {
        (self.sim.x, self.sim.v, self.sim.system.thickness) = (x, v, thickness);
    }

    fn substep(&mut self, time: f64, dt: f64) -> Result<Self::Info, ShellError> {
        self.sim.x_prev.copy_from_slice(&self.sim.x);
        self.sim.step_inner(self.step, time, dt)
    }

    fn is_easy((info, _): &Self::Info) -> bool {
        info.newton_iterations <= EASY_NEWTON_ITERATIONS && info.line_search_cuts == 0
    }

    /// A physical runaway of the gas volume is not retried.
    fn may_retry(error: &ShellError) -> bool {
        !matches!(error, ShellError::RunawayVolume { .. })
    }
}

/// Gas volume growth beyond this factor of the rest volume is reported as a runaway.
pub const RUNAWAY_VOLUME_FACTOR: f64 = 1.0e4;

impl<M: ShellMaterial, G: GasModel> ShellSimulation<M, G> {
    /// Advances one time step (Algorithm 1, lines 5-12). On error the state is rolled back to the
    /// start of the step, so what was written before stays consistent.
    pub fn step(&mut self) -> Result<ShellStepStats, ShellError> {
        let start = std::time::Instant::now();
        // Steps are numbered from 1 (the first step is step 1), in the stats and the errors.
        let (step, time, dt) = (self.step + 1, self.time, self.dt);
        let volume_old = self.system.gas.state().volume;
        let mut totals = StepTotals::default();
        let mut times = self.integrator.phase_times();
        times.projection_ms = self.projection_ms;
        self.advance(step, time, dt, &mut totals)?;
        let mut now = self.integrator.phase_times();
        now.projection_ms = self.projection_ms;
        let times = now - times;
        self.time = time + dt;
        // A gas with a history (a leak, a supply pump) keeps the amount the step reached.
        let end_volume = self.gas_volume;
        self.system.gas.gas_mut().end_step(end_volume, self.time);
        self.step += 1;
        let gas = self.system.gas.state();
        let max_speed = self
            .v
            .chunks_exact(3)
            .map(|c| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt())
            .fold(0.0, f64::max);
        let th = &self.system.thickness;
        let (tmin, tmax) = th
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &h| (a.min(h), b.max(h)));
        let volume_now = self.gas_volume;
        Ok(ShellStepStats {
            step,
            time: self.time,
            gas_volume: volume_now,
            gauge_pressure: gas.gauge_pressure,
            shell_volume_ratio: self.shell_volume() / self.rest_shell_volume,
            newton_iterations: totals.newton_iterations,
            linear_iterations: totals.linear_iterations,
            factorizations: totals.factorizations,
            newton_residual: totals.newton_residual,
            line_search_cuts: totals.line_search_cuts,
            regularized_solves: totals.regularized_solves,
            dt_used: totals.min_dt,
            halvings: totals.halvings,
            projection_iterations: totals.projection_iterations,
            substeps: totals.substeps,
            max_speed,
            volume_change: if volume_old > 0.0 {
                (volume_now - volume_old).abs() / volume_old
            } else {
                0.0
            },
            thickness_mean: th.iter().sum::<f64>() / th.len() as f64,
            thickness_min: tmin,
            thickness_max: tmax,
            step_ms: start.elapsed().as_secs_f64() * 1e3,
            times,
        })
    }

    /// Advances from `time` by `dt` in sub-steps that add up to `dt` exactly (so the step ends
    /// at the time the user asked for). A sub-step that fails numerically (Newton does not
    /// converge, the linear solver breaks down, a non-finite state, an element or thickness
    /// that degenerates in the projection) is rolled back and retried at half the size, at most
    /// `max_step_halvings` halvings below `dt` (the remedy of seed 003, Sec. 4, applied to the
    /// shell); after easy sub-steps (Newton converged in at most [`EASY_NEWTON_ITERATIONS`]
    /// iterations without line-search cuts) the size doubles again, up to `dt`, as
    /// [`SubstepGrowth`] says when. The size reached is where the next step starts. A physical
    /// runaway of the gas volume is not retried.
    fn advance(
        &mut self,
        step: usize,
        time: f64,
        dt: f64,
        totals: &mut StepTotals,
    ) -> Result<(), ShellError> {
        let mut substeps = self.substeps;
        let max_halvings = substeps.max_halvings();
        let advanced = substeps.advance(
            &mut ShellSubsteps { sim: self, step },
            time,
            dt,
            |attempt| match attempt {
                Attempt::Accepted {
                    info: (info, proj_iters),
                    ..
                } => {
                    totals.newton_iterations += info.newton_iterations;
                    totals.linear_iterations += info.total_linear_iterations();
                    totals.factorizations += info.factorizations;
                    totals.newton_residual = totals.newton_residual.max(info.relative_residual);
                    totals.line_search_cuts += info.line_search_cuts;
                    totals.regularized_solves += info.regularized_solves;
                    totals.projection_iterations += proj_iters;
                }
                Attempt::Failed {
                    error:
                        ShellError::Integrate {
                            source:
                                balloon_integrate::implicit::IntegrateError::NotConverged {
                                    iterations,
                                    ..
                                },
                            ..
                        },
                    ..
                } => totals.newton_iterations += iterations,
                Attempt::Failed { .. } => {}
            },
        );
        self.substeps = substeps;
        match advanced {
            Ok(report) => {
                totals.substeps = report.substeps;
                totals.halvings = report.halvings;
                totals.min_dt = report.min_dt;
                Ok(())
            }
            Err(failure) => Err(Self::explain(
                failure.error,
                failure.halvings,
                max_halvings,
                failure.dt,
            )),
        }
    }

    /// A Newton solve that still does not converge at the smallest sub-step becomes
    /// [`ShellError::NotConverged`] (with what to try); other errors pass unchanged.
    fn explain(e: ShellError, halvings: usize, max_halvings: usize, dt: f64) -> ShellError {
        match e {
            ShellError::Integrate {
                step,
                time,
                source:
                    balloon_integrate::implicit::IntegrateError::NotConverged {
                        iterations,
                        residual,
                        tolerance,
                        ..
                    },
            } => ShellError::NotConverged {
                step,
                time,
                dt,
                halvings,
                max_halvings,
                iterations,
                residual,
                tolerance,
            },
            other => other,
        }
    }

    fn step_inner(
        &mut self,
        step: usize,
        time: f64,
        dt: f64,
    ) -> Result<(balloon_integrate::implicit::StepInfo, usize), ShellError> {
        let gravity = self.integrator.params().gravity;
        let integrator = &mut self.integrator;
        let (x, v) = (&mut self.x, &mut self.v);
        let info = if self.pins.active() {
            let pins = &mut self.pins;
            pins.prepare(v, &self.external_forces, gravity);
            let external = (!pins.external.is_empty()).then_some(&pins.external[..]);
            if self.anchor_springs.is_empty() {
                let mut system = Pinned::new(&mut self.system, &mut pins.dofs)?;
                integrator.step(&mut system, time, dt, x, v, external)
            } else {
                let mut anchored = Anchored::new(&mut self.system, &self.anchor_springs)?;
                let mut system = Pinned::new(&mut anchored, &mut pins.dofs)?;
                integrator.step(&mut system, time, dt, x, v, external)
            }
        } else {
            let external = (!self.external_forces.is_empty()).then_some(&self.external_forces[..]);
            if self.anchor_springs.is_empty() {
                integrator.step(&mut self.system, time, dt, x, v, external)
            } else {
                let mut system = Anchored::new(&mut self.system, &self.anchor_springs)?;
                integrator.step(&mut system, time, dt, x, v, external)
            }
        }
        .map_err(|source| ShellError::Integrate { step, time, source })?;
        // A membrane's thickness is `H / (l1 l2)` of the new positions (a no-op for the
        // three-prism, whose thickness only the projection moves).
        self.system.refresh_thickness(&self.x);
        let mut proj_iters = 0;
        if let Some(proj) = &mut self.projection {
            let (triangles, thickness) = self.system.triangles_and_thickness_mut();
            let input = ShellProjectionInput {
                triangles,
                vertex_inverse_mass: if self.pins.active() {
                    &self.pins.vertex_inverse_mass
                } else {
                    &self.vertex_inv_mass
                },
                element_inverse_mass: &self.element_inv_mass,
                rest_shell_volume: self.rest_shell_volume,
                rest_element_volumes: &self.rest_element_volumes,
            };
            let started = std::time::Instant::now();
            let projected = proj.project(&input, &mut self.x, thickness);
            self.projection_ms += started.elapsed().as_secs_f64() * 1e3;
            let pi = projected.map_err(|source| ShellError::Projection { step, source })?;
            proj_iters = pi.iterations;
            self.system.refresh_thickness(&self.x);
        }
        // Algorithm 1, lines 11-12.
        for ((v, x), x0) in self.v.iter_mut().zip(&self.x).zip(&self.x_prev) {
            *v = (x - x0) / dt;
        }
        self.gas_volume = self.check_state(step, time)?;
        Ok((info, proj_iters))
    }

    /// Checks the state after a (sub-)step and returns the enclosed gas volume.
    fn check_state(&self, step: usize, time: f64) -> Result<f64, ShellError> {
        if let Some(i) = self.x.iter().position(|v| !v.is_finite()) {
            return Err(ShellError::Diverged {
                step,
                time,
                quantity: format!("position of vertex {}", i / 3),
                detail: "became NaN or infinite; reduce --dt".into(),
            });
        }
        if let Some((e, h)) = self
            .system
            .thickness
            .iter()
            .enumerate()
            .find(|(_, h)| !(h.is_finite() && **h > 0.0))
        {
            return Err(ShellError::Diverged {
                step,
                time,
                quantity: format!("thickness of element {e}"),
                detail: format!(
                    "{h:e} m is not positive; the element inverted or degenerated; reduce --dt or the pressure"
                ),
            });
        }
        let vol =
            balloon_gas::enclosed_volume(&self.x, self.system.triangles()).unwrap_or(f64::NAN);
        if !(vol.is_finite() && vol > 0.0 && vol < RUNAWAY_VOLUME_FACTOR * self.rest_gas_volume) {
            return Err(ShellError::RunawayVolume {
                step,
                time,
                volume: vol,
                rest_volume: self.rest_gas_volume,
            });
        }
        Ok(vol)
    }

    /// Current positions, flat `[x0, y0, z0, ...]`, m.
    pub fn positions(&self) -> &[f64] {
        &self.x
    }
    /// Rest positions, flat, m.
    pub fn rest_positions(&self) -> &[f64] {
        &self.rest_positions
    }
    /// Current velocities, flat, m/s.
    pub fn velocities(&self) -> &[f64] {
        &self.v
    }
    /// Current thickness per element, m.
    pub fn thickness(&self) -> &[f64] {
        &self.system.thickness
    }
    /// Triangles.
    pub fn triangles(&self) -> &[[usize; 3]] {
        self.system.triangles()
    }
    /// The current surface as a mesh.
    pub fn mesh(&self) -> TriMesh {
        TriMesh::new(
            self.x
                .chunks_exact(3)
                .map(|c| Point3::new(c[0], c[1], c[2]))
                .collect(),
            self.system.triangles().to_vec(),
        )
    }
    /// Simulation time, s.
    pub fn time(&self) -> f64 {
        self.time
    }
    /// Steps taken.
    pub fn steps_taken(&self) -> usize {
        self.step
    }
    /// Time step, s.
    pub fn dt(&self) -> f64 {
        self.dt
    }
    /// Enclosed gas volume at the rest shape, m^3.
    pub fn rest_gas_volume(&self) -> f64 {
        self.rest_gas_volume
    }
    /// Current enclosed gas volume, m^3.
    pub fn gas_volume(&self) -> f64 {
        self.gas_volume
    }
    /// Whether the Newton tangent includes the pressure follower term
    /// ([`ShellBalloon::with_follower_term`], resolved).
    pub fn follower_term(&self) -> bool {
        self.system.gas.follower_term()
    }
    /// Gauge pressure at the last force evaluation, Pa.
    pub fn gauge_pressure(&self) -> f64 {
        self.system.gas.state().gauge_pressure
    }
    /// The gas state at the last force evaluation.
    pub fn gas_state(&self) -> balloon_gas::GasState {
        self.system.gas.state()
    }
    /// Current shell material volume `sum_e A_e h_e` (Eq. 26), m^3.
    pub fn shell_volume(&self) -> f64 {
        shell_volume(self.system.triangles(), &self.x, &self.system.thickness)
    }
    /// Rest shell material volume, m^3.
    pub fn rest_shell_volume(&self) -> f64 {
        self.rest_shell_volume
    }
    /// The gas model (its kind and parameters, or the user's own model).
    pub fn gas(&self) -> &G {
        self.system.gas.gas()
    }
    /// The force system (for diagnostics: energies, forces).
    pub fn system(&self) -> &ShellSystem<M, G> {
        &self.system
    }
    /// The integrator's parameters (change them with [`ShellSimulation::configure_integrator`]).
    pub fn integrator_params(&self) -> &BackwardEulerParams {
        self.integrator.params()
    }

    /// Edits the integrator's parameters from the next step on (`edit` gets a copy); refused,
    /// with nothing changed, when an edited parameter is out of range
    /// ([`BackwardEulerParams::validate`]).
    pub fn configure_integrator(
        &mut self,
        edit: impl FnOnce(&mut BackwardEulerParams),
    ) -> Result<(), ShellError> {
        let mut params = *self.integrator.params();
        edit(&mut params);
        self.integrator.set_params(params).map_err(integrator_error)
    }
    /// Solves Newton's linear systems with `solver` from the next step on: any
    /// [`balloon_linalg::LinearSolver`], the library's own (`CholeskySolver`, `FactorizedPcg`,
    /// `AssembledPcg`, `MatrixFreeCg`) or a user's type. It stays until
    /// [`ShellSimulation::use_configured_linear_solver`].
    pub fn set_linear_solver(&mut self, solver: Box<dyn balloon_linalg::LinearSolver>) {
        self.integrator.set_linear_solver(solver);
    }
    /// Goes back to the linear solver the integrator parameters name.
    pub fn use_configured_linear_solver(&mut self) {
        self.integrator.use_configured_linear_solver();
    }
    /// Vertex lumped masses per degree of freedom, kg.
    pub fn masses(&self) -> &[f64] {
        self.system.masses()
    }
}

impl<M: ShellMaterial, G: GasModel> ShellSimulation<M, G> {
    /// Sets external forces (N) per degree of freedom, flat `[fx0, fy0, fz0, ...]`, applied in
    /// every following step as the `f_ext` of backward Euler (Eq. 18-19) until changed; `None`
    /// removes them. Used by the live viewer for grabbing and pinching. The length must be
    /// `3 * vertices` and every value finite.
    pub fn set_external_forces(&mut self, forces: Option<&[f64]>) -> Result<(), ShellError> {
        match forces {
            None => self.external_forces.clear(),
            Some(f) => {
                if f.len() != self.x.len() {
                    return Err(ShellError::InvalidParameter {
                        name: "external forces",
                        value: format!("{} values", f.len()),
                        reason: format!("need 3 per vertex ({})", self.x.len()),
                    });
                }
                if let Some(i) = f.iter().position(|v| !v.is_finite()) {
                    return Err(ShellError::InvalidParameter {
                        name: "external forces",
                        value: f[i].to_string(),
                        reason: format!("component {i} must be finite"),
                    });
                }
                self.external_forces.clear();
                self.external_forces.extend_from_slice(f);
            }
        }
        Ok(())
    }

    /// The external forces set by [`ShellSimulation::set_external_forces`] (empty when none).
    pub fn external_forces(&self) -> &[f64] {
        &self.external_forces
    }

    /// Changes the time step (s, positive and finite) for the following steps. The sub-step
    /// size reached so far (the old `dt`, or less after a hard step) is kept: a larger `dt` is
    /// reached by doubling it after easy sub-steps (see [`EASY_NEWTON_ITERATIONS`]), a smaller
    /// one caps it at once.
    pub fn set_dt(&mut self, dt: f64) -> Result<(), ShellError> {
        self.dt = check_dt(dt)?;
        Ok(())
    }
}

impl<M: ShellMaterial> ShellSimulation<M, Gas> {
    /// Changes the gas while the simulation runs (the pressure control of the live viewer):
    /// for a constant-pressure gas the held gauge pressure becomes `gauge` (Pa); for the ideal
    /// gas the amount `nRT = p0 V0` (Eq. 12, 14) is set so that the gas would have gauge pressure
    /// `gauge` at the rest volume, `nRT = (p_ambient + gauge) V_rest` (likewise the polytropic
    /// invariant and the leaking gas's amount, which then leaks from now on); for the supply
    /// pump it is the supply pressure; for the pump it is an error (use
    /// [`ShellSimulation::set_pump_rate`]). The absolute pressure must stay positive.
    pub fn set_gauge_pressure(&mut self, gauge: f64) -> Result<(), ShellError> {
        let ambient = self.system.gas.ambient_pressure();
        let p_abs = ambient + gauge;
        if !(gauge.is_finite() && p_abs > 0.0) {
            return Err(ShellError::InvalidParameter {
                name: "pressure",
                value: gauge.to_string(),
                reason: format!("the absolute pressure {ambient} Pa + gauge must be positive"),
            });
        }
        let rest_volume = self.rest_gas_volume;
        match self.system.gas.gas_mut() {
            Gas::Constant(c) => c.pressure = p_abs,
            Gas::Ideal(g) => g.initial_pressure = p_abs * rest_volume / g.initial_volume,
            Gas::Polytropic(g) => {
                g.initial_pressure = p_abs * (rest_volume / g.initial_volume).powf(g.gamma);
            }
            Gas::Leak(g) => {
                g.amount = p_abs * rest_volume;
                g.time = self.time;
            }
            Gas::SupplyPump(g) => g.supply_pressure = p_abs,
            Gas::Pump(_) => {
                return Err(ShellError::InvalidParameter {
                    name: "pressure",
                    value: gauge.to_string(),
                    reason: "the pump gas has no set pressure; change its pump rate".into(),
                });
            }
        }
        Ok(())
    }

    /// The amount of an isothermal ideal gas, `nRT = p V` (J; seed 000 Eq. 12), or `None` for
    /// the other gases.
    pub fn gas_amount(&self) -> Option<f64> {
        match self.system.gas.gas() {
            Gas::Ideal(g) => Some(g.amount()),
            _ => None,
        }
    }

    /// The ambient (outside) pressure, Pa.
    pub fn ambient_pressure(&self) -> f64 {
        self.system.gas.ambient_pressure()
    }

    /// Sets the amount `nRT` (J, positive and finite) of an isothermal ideal gas from now on
    /// (gas let in or out between steps, as [`connected::ConnectedBalloons`] does); the pressure
    /// at volume `V` becomes `amount / V`. Errors for the other gases.
    pub fn set_gas_amount(&mut self, amount: f64) -> Result<(), ShellError> {
        if !(amount.is_finite() && amount > 0.0) {
            return Err(ShellError::InvalidParameter {
                name: "gas-amount",
                value: amount.to_string(),
                reason: "must be a positive, finite amount nRT in J".into(),
            });
        }
        match self.system.gas.gas_mut() {
            Gas::Ideal(g) => {
                g.initial_pressure = amount / g.initial_volume;
                Ok(())
            }
            _ => Err(ShellError::InvalidParameter {
                name: "gas-amount",
                value: amount.to_string(),
                reason: "only the isothermal ideal gas (--gas ideal) has a settable amount".into(),
            }),
        }
    }

    /// Changes the pump rate (m^3/s of ambient air, >= 0) of a [`GasKind::Pump`] gas from now
    /// on: the gas content pumped so far is kept and grows by `p_ambient * rate` J/s from the
    /// current time. Errors for the other gases.
    pub fn set_pump_rate(&mut self, rate: f64) -> Result<(), ShellError> {
        if !(rate.is_finite() && rate >= 0.0) {
            return Err(ShellError::InvalidParameter {
                name: "pump-rate",
                value: rate.to_string(),
                reason: "must be a finite flow >= 0 m^3/s".into(),
            });
        }
        let now = self.time;
        let ambient = self.system.gas.ambient_pressure();
        match self.system.gas.gas_mut() {
            Gas::Pump(p) => {
                p.initial_amount = p.amount(now);
                p.start_time = now;
                p.rate = rate * ambient;
                Ok(())
            }
            _ => Err(ShellError::InvalidParameter {
                name: "pump-rate",
                value: rate.to_string(),
                reason: "only the pump gas has a pump rate".into(),
            }),
        }
    }
}

impl<M: ShellMaterial, G: GasModel> ShellSimulation<M, G> {
    /// Replaces the anchor springs acting in the following steps (an empty list removes them):
    /// zero-length springs from vertices to fixed points, integrated implicitly with the shell
    /// (backward Euler, Eq. 18-23) so stiff springs stay stable
    /// ([`balloon_integrate::decorators::Anchored`]). The live viewer grabs and pinches the
    /// shell with them. Every vertex must exist, every anchor be finite and every stiffness
    /// finite and >= 0.
    pub fn set_anchor_springs(&mut self, springs: Vec<AnchorSpring>) -> Result<(), ShellError> {
        self.anchor_springs = Anchors::new(self.x.len() / 3, springs)?;
        Ok(())
    }

    /// The anchor springs set by [`ShellSimulation::set_anchor_springs`].
    pub fn anchor_springs(&self) -> &[AnchorSpring] {
        self.anchor_springs.springs()
    }

    /// Pins `vertices` hard from the next step on (an empty list frees them): a pinned vertex
    /// does not move at all. Its degrees of freedom are removed from the backward Euler solve
    /// (Eq. 18-23: zero residual, identity rows and columns of the Newton matrix, zero
    /// velocity; [`balloon_integrate::decorators::Pinned`]) and from the shell-volume
    /// projection (Algorithm 2: zero inverse mass), so its position stays bit for bit what it
    /// was. Duplicates are ignored; every vertex must exist. The static solve
    /// ([`ShellSimulation::solve_static`]) keeps them in place too.
    ///
    /// ```
    /// use balloon::shell::ShellBalloon;
    /// let mesh = balloon::mesh::generate::icosphere(0.1, 2)?;
    /// let mut sim = ShellBalloon::new(mesh).build()?;
    /// let bottom: Vec<usize> = (0..sim.positions().len() / 3)
    ///     .filter(|&v| sim.positions()[3 * v + 2] < -0.09)
    ///     .collect();
    /// sim.set_pinned_vertices(bottom.clone())?;
    /// let before = sim.positions().to_vec();
    /// for _ in 0..5 {
    ///     sim.step()?;
    /// }
    /// for &v in &bottom {
    ///     assert_eq!(sim.positions()[3 * v..3 * v + 3], before[3 * v..3 * v + 3]);
    /// }
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn set_pinned_vertices(&mut self, vertices: Vec<usize>) -> Result<(), ShellError> {
        self.pins = pins::Pins::new(vertices, &self.vertex_inv_mass)?;
        for &p in self.pins.dofs.vertices() {
            self.v[3 * p..3 * p + 3].fill(0.0);
        }
        Ok(())
    }

    /// The hard-pinned vertices ([`ShellSimulation::set_pinned_vertices`]), sorted.
    pub fn pinned_vertices(&self) -> &[usize] {
        self.pins.dofs.vertices()
    }
}

#[cfg(test)]
mod viewer_api_tests {
    use super::*;

    fn small() -> ShellSimulation {
        let mesh = balloon_mesh::generate::icosphere(0.1, 1).unwrap();
        ShellBalloon::new(mesh)
            .with_gas(GasKind::Constant)
            .with_gauge_pressure(0.0)
            .with_projection(None)
            .build()
            .unwrap()
    }

    #[test]
    fn constant_external_force_accelerates_a_free_shell_by_f_over_m() {
        let mut sim = small();
        sim.configure_integrator(|p| p.mass_damping = 0.0).unwrap();
        let n = sim.positions().len();
        let total_mass: f64 = sim.masses().iter().step_by(3).sum();
        // 1 N in total along +x, shared by mass so every vertex gets the same acceleration.
        let f: Vec<f64> = sim
            .masses()
            .iter()
            .enumerate()
            .map(|(i, m)| if i % 3 == 0 { m / total_mass } else { 0.0 })
            .collect();
        sim.set_external_forces(Some(&f)).unwrap();
        assert_eq!(sim.external_forces().len(), n);
        let steps = 5;
        for _ in 0..steps {
            sim.step().unwrap();
        }
        let mean_vx = sim.velocities().iter().step_by(3).sum::<f64>() / (n / 3) as f64;
        let expected = sim.time() / total_mass;
        assert!(
            (mean_vx - expected).abs() < 1e-3 * expected,
            "mean vx {mean_vx} vs F t / m = {expected}"
        );
        sim.set_external_forces(None).unwrap();
        assert!(sim.external_forces().is_empty());
    }

    #[test]
    fn bad_external_forces_are_rejected() {
        let mut sim = small();
        assert!(sim.set_external_forces(Some(&[1.0])).is_err());
        let mut f = vec![0.0; sim.positions().len()];
        f[4] = f64::NAN;
        let e = sim.set_external_forces(Some(&f)).unwrap_err().to_string();
        assert!(e.contains("component 4"), "{e}");
        assert!(sim.set_dt(0.0).is_err());
        sim.set_dt(0.005).unwrap();
        assert_eq!(sim.dt(), 0.005);
    }

    /// The default pump delivers DEFAULT_PUMP_VOLUMES_PER_SECOND rest volumes of ambient air
    /// per second whatever the body's size: read back from the ideal gas law on the state
    /// (p V = p_amb V0 (1 + k t)), at 5 cm and 1 m.
    #[test]
    fn the_default_pump_follows_the_body_size() {
        for radius in [0.05, 1.0] {
            let mesh = balloon_mesh::generate::icosphere(radius, 1).unwrap();
            let mut sim = ShellBalloon::new(mesh).build().unwrap();
            let v0 = sim.rest_gas_volume();
            for _ in 0..3 {
                sim.step().unwrap();
            }
            let s = sim.gas_state();
            let pumped = s.absolute_pressure * s.volume / (STANDARD_ATMOSPHERE * v0) - 1.0;
            let expected = DEFAULT_PUMP_VOLUMES_PER_SECOND * sim.time();
            assert!(
                (pumped - expected).abs() < 1e-9 * expected.max(1.0),
                "radius {radius}: pumped {pumped} rest volumes, expected {expected}"
            );
            assert!(s.volume > v0, "radius {radius}: the body did not grow");
        }
        // An absolute rate stays absolute.
        let mesh = balloon_mesh::generate::icosphere(0.05, 1).unwrap();
        let mut sim = ShellBalloon::new(mesh)
            .with_pump_rate(1e-4)
            .build()
            .unwrap();
        sim.step().unwrap();
        let s = sim.gas_state();
        let pumped = s.absolute_pressure * s.volume - STANDARD_ATMOSPHERE * sim.rest_gas_volume();
        assert!((pumped - STANDARD_ATMOSPHERE * 1e-4 * sim.time()).abs() < 1e-9);
    }

    #[test]
    fn gas_setters_act_live() {
        let mut sim = small();
        sim.set_gauge_pressure(1500.0).unwrap();
        match sim.gas() {
            Gas::Constant(c) => assert!((c.pressure - (STANDARD_ATMOSPHERE + 1500.0)).abs() < 1e-9),
            g => panic!("{g:?}"),
        }
        sim.step().unwrap();
        assert!((sim.gauge_pressure() - 1500.0).abs() < 1e-6);
        assert!(sim.set_gauge_pressure(-2.0 * STANDARD_ATMOSPHERE).is_err());
        assert!(sim.set_pump_rate(1e-3).is_err());

        let mesh = balloon_mesh::generate::icosphere(0.1, 1).unwrap();
        let mut ideal = ShellBalloon::new(mesh.clone())
            .with_gas(GasKind::Ideal)
            .build()
            .unwrap();
        ideal.set_gauge_pressure(500.0).unwrap();
        match ideal.gas() {
            Gas::Ideal(g) => {
                let want = (STANDARD_ATMOSPHERE + 500.0) * ideal.rest_gas_volume();
                assert!((g.amount() - want).abs() < 1e-9 * want);
            }
            g => panic!("{g:?}"),
        }

        let mut pump = ShellBalloon::new(mesh).with_pump_rate(0.0).build().unwrap();
        pump.step().unwrap();
        let v0 = pump.gas_volume();
        pump.set_pump_rate(2e-3).unwrap();
        let amount_then = match pump.gas() {
            Gas::Pump(p) => p.amount(pump.time()),
            g => panic!("{g:?}"),
        };
        for _ in 0..3 {
            pump.step().unwrap();
        }
        match pump.gas() {
            Gas::Pump(p) => {
                let added = p.amount(pump.time()) - amount_then;
                let want = 2e-3 * STANDARD_ATMOSPHERE * 3.0 * pump.dt();
                assert!((added - want).abs() < 1e-9 * want, "{added} vs {want}");
            }
            g => panic!("{g:?}"),
        }
        assert!(pump.gas_volume() > v0);
        assert!(pump.set_pump_rate(-1.0).is_err());
        assert!(pump.set_gauge_pressure(100.0).is_err());
    }

    #[test]
    fn stiff_anchor_springs_pull_a_vertex_out_stably_with_every_solver() {
        for solver in [
            LinearSolverKind::Pcg,
            LinearSolverKind::Cholesky,
            LinearSolverKind::MatrixFreeCg,
        ] {
            let mesh = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
            let mut sim = ShellBalloon::new(mesh)
                .with_gas(GasKind::Constant)
                .with_gauge_pressure(1000.0)
                .with_linear_solver(solver)
                .build()
                .unwrap();
            let start = Vector3::new(sim.positions()[0], sim.positions()[1], sim.positions()[2]);
            let target = start * 1.3;
            // 1000 N/m on a vertex of ~0.2 g at dt = 10 ms: k dt^2 / m ~ 500, far beyond what an
            // explicit spring survives.
            sim.set_anchor_springs(vec![AnchorSpring {
                vertex: 0,
                anchor: target.into(),
                stiffness: 1000.0,
            }])
            .unwrap();
            for _ in 0..30 {
                sim.step().unwrap();
            }
            let x = sim.positions();
            let now = Vector3::new(x[0], x[1], x[2]);
            // A free balloon follows the vertex: it reaches the target without blowing up.
            assert!(
                (now - target).norm() < 0.5 * (start - target).norm(),
                "{solver:?}: {start:?} -> {now:?}, target {target:?}"
            );
            sim.set_anchor_springs(Vec::new()).unwrap();
            assert!(sim.anchor_springs().is_empty());
        }
        // The same spring as an explicit external force does not survive.
        let mesh = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
        let mut sim = ShellBalloon::new(mesh)
            .with_gas(GasKind::Constant)
            .with_gauge_pressure(1000.0)
            .build()
            .unwrap();
        let target: Vec<f64> = sim.positions()[..3].iter().map(|c| 1.3 * c).collect();
        let explicit = (0..30).try_for_each(|_| {
            let mut f = vec![0.0; sim.positions().len()];
            for d in 0..3 {
                f[d] = 1000.0 * (target[d] - sim.positions()[d]);
            }
            sim.set_external_forces(Some(&f))?;
            sim.step().map(|_| ())
        });
        assert!(
            explicit.is_err(),
            "the explicit spring survived: {explicit:?}"
        );
        let mesh = balloon_mesh::generate::icosphere(0.1, 1).unwrap();
        let mut sim = ShellBalloon::new(mesh).build().unwrap();
        let bad = |vertex, stiffness: f64| AnchorSpring {
            vertex,
            anchor: [0.0; 3],
            stiffness,
        };
        assert!(sim.set_anchor_springs(vec![bad(1000, 1.0)]).is_err());
        assert!(sim.set_anchor_springs(vec![bad(0, -1.0)]).is_err());
        assert!(sim.set_anchor_springs(vec![bad(0, f64::NAN)]).is_err());
    }
}
