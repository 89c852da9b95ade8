//! Shell balloons with thickness (Wang et al. 2015, "Cute Balloons with Thickness";
//! Algorithms 1 and 2): the builder [`ShellBalloon`], its defaults and its gas set-up.
//!
//! A closed triangle mesh becomes a shell of three-prism elements (Eq. 1-4) of a hyperelastic
//! material (St. Venant-Kirchhoff, Eq. 6-9, or neo-Hookean), filled with a uniform gas (Eq. 12-17)
//! and advanced by backward Euler with Newton-Raphson (Eq. 18-23); after each solve the
//! shell-volume projection (Eq. 24-28, Algorithm 2) restores the material volume of the shell by
//! moving the vertices and the thickness, and the velocities are set to `(x_new - x_old) / dt`
//! (Algorithm 1, lines 11-12).
//!
//! The running balloon, [`ShellSimulation`] (its step, sub-steps, live controls, statistics,
//! errors and static rest shape, [`statics`]), and the connected balloons ([`connected`]) are
//! those of the `balloon-shell` stage crate, re-exported here; this module builds them.
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

mod membrane;
#[cfg(test)]
mod tests;

pub use balloon_integrate::decorators::AnchorSpring;
pub use balloon_integrate::substep::{EASY_NEWTON_ITERATIONS, MAX_EASY_BEFORE_GROWTH};
pub use balloon_shell::{
    Membrane, RUNAWAY_VOLUME_FACTOR, ShellElement, ShellError, ShellMaterial, ShellMaterialModel,
    ShellSimulation, ShellSnapshot, ShellStepStats, ShellSystem, analytic, connected,
    membrane_sphere_stretch, statics,
};

use balloon_constraint::projector::ShellProjector;
use balloon_constraint::shell_volume::{ShellVolumeParams, ShellVolumeProjection};
use balloon_gas::{
    ConstantPressure, Gas, GasKind, GasLawParams, GasModel, IdealGas, PressureLoad,
    STANDARD_ATMOSPHERE,
};
use balloon_integrate::TangentKind;
use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
use balloon_integrate::linear::{LinearSolverKind, PcgPreconditioner};
use balloon_material::{Lame, MaterialKind, MaterialModel};
use balloon_mesh::TriMesh;
use balloon_shell::ShellSystemError;
use balloon_shell::run::check_dt;
use serde::{Deserialize, Serialize};

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
    /// Factor on the wall's plate bending modulus (0: none, the paper's wall).
    wall_bending: f64,
    /// `None`: off ([`ShellBalloon::with_thickness_prediction`]).
    thickness_prediction: Option<bool>,
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
            wall_bending: 0.0,
            thickness_prediction: None,
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
            wall_bending,
            thickness_prediction,
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
            wall_bending,
            thickness_prediction,
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
    /// Gives the wall the bending stiffness of a plate of its material and thickness times
    /// `factor` (`D = factor Y h^3 / (12 (1 - nu^2))` per interior edge, a discrete-shell
    /// hinge; [`ShellSystem::set_wall_bending`]). Default 0: the three-prism wall of Wang et al.
    /// 2015 has no bending stiffness. 1 is the bending stiffness of a real wall of the same
    /// rubber.
    pub fn with_wall_bending(mut self, factor: f64) -> Self {
        self.wall_bending = factor;
        self
    }

    /// Solves each step with the wall thickness extrapolated to its end and coupled to the
    /// projection (`Some(true)`) or with the thickness at its start (`Some(false)` or `None`,
    /// the default: the paper's Algorithm 1); [`ShellSimulation::set_thickness_prediction`].
    pub fn with_thickness_prediction(mut self, enabled: impl Into<Option<bool>>) -> Self {
        self.thickness_prediction = enabled.into();
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

    /// Validates everything and builds the simulation (no time step is taken): the rest
    /// elements and masses ([`ShellSystem::from_rest_shape`]), the gas from the rest volume
    /// ([`ShellGas`]), the integrator, and the running [`ShellSimulation`] of them.
    pub fn build(self) -> Result<ShellSimulation<M, G::Model>, ShellError> {
        if self.validate_mesh {
            balloon_mesh::validate::validate_closed_manifold(&self.mesh)?;
        }
        positive("density", self.density)?;
        check_dt(self.dt)?;
        if !(self.ambient_pressure.is_finite() && self.ambient_pressure >= 0.0) {
            return Err(ShellError::InvalidParameter {
                name: "ambient_pressure",
                value: self.ambient_pressure.to_string(),
                reason: "must be a finite pressure >= 0 Pa".into(),
            });
        }
        if !self.gauge_pressure.is_finite() {
            return Err(ShellError::InvalidParameter {
                name: "gauge_pressure",
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
                name: "newton_iterations",
                value: "0".into(),
                reason: "at least 1".into(),
            });
        }
        for (name, damping) in [
            ("mass_damping", p.mass_damping),
            ("stiffness_damping", p.stiffness_damping),
        ] {
            if damping.is_nan() || damping < 0.0 {
                return Err(ShellError::InvalidParameter {
                    name,
                    value: damping.to_string(),
                    reason: "damping coefficients must be >= 0".into(),
                });
            }
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
        let nv = self.mesh.vertices.len();
        let triangles = self.mesh.triangles;
        let system = ShellSystem::from_rest_shape(
            &x,
            triangles,
            thickness,
            self.density,
            self.material,
            load,
        )
        .map_err(|e| match e {
            ShellSystemError::Element { element, source } => {
                ShellError::Element { element, source }
            }
            e => ShellError::InvalidParameter {
                name: "mesh",
                value: format!("{nv} vertices, {nt} triangles"),
                reason: e.to_string(),
            },
        })?;
        if !(self.wall_bending.is_finite() && self.wall_bending >= 0.0) {
            return Err(ShellError::InvalidParameter {
                name: "wall_bending",
                value: self.wall_bending.to_string(),
                reason: "must be a finite factor >= 0 (0: no bending stiffness)".into(),
            });
        }
        let mut system = system;
        system
            .set_wall_bending(&x, self.wall_bending)
            .map_err(|e| match e {
                ShellSystemError::Element { element, source } => {
                    ShellError::Element { element, source }
                }
                e => ShellError::InvalidParameter {
                    name: "wall_bending",
                    value: self.wall_bending.to_string(),
                    reason: e.to_string(),
                },
            })?;
        let integrator =
            BackwardEuler::new(self.integrator).map_err(ShellError::from_integrator_setup)?;
        let mut sim = ShellSimulation::new(
            system,
            x,
            self.density,
            integrator,
            self.projector,
            self.dt,
            self.max_step_halvings,
        )?;
        sim.set_thickness_prediction(self.thickness_prediction);
        Ok(sim)
    }
}
