//! The seam between integrators and physics: a [`ForceSystem`].
//!
//! Degrees of freedom are flat: `x = [x0, y0, z0, x1, y1, z1, ...]` (metres), forces in newtons,
//! masses in kilograms per degree of freedom (a lumped, diagonal mass matrix).

use std::sync::Arc;

pub use balloon_linalg::{LowRankTerm, StiffnessBlocks};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Which stiffness matrix `K` a [`ForceSystem`] hands to Newton (through
/// [`ForceSystem::add_force_differential`], [`ForceSystem::add_stiffness_triplets`] and
/// [`ForceSystem::add_stiffness_diagonal`]). The forces are always the exact ones, so the
/// backward Euler solution Newton converges to does not depend on this choice; only the path
/// (and the speed) does.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TangentKind {
    /// The exact Hessian of the energy (`"exact"`, default): quadratic Newton convergence, but
    /// indefinite where elements are compressed, so the solvers may need a mass-shift retry
    /// (`BackwardEulerParams::regularize_indefinite`).
    #[default]
    Exact,
    /// Per-element Hessians projected onto the positive semi-definite cone (`"projected"`,
    /// projected Newton): the Newton matrix `M + dt^2 K` is then symmetric positive definite at
    /// every iterate (up to non-symmetric or indefinite terms a system adds outside its
    /// elements, such as a pressure follower term) and no regularisation retry is needed.
    Projected,
}

impl std::str::FromStr for TangentKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "exact" => Ok(Self::Exact),
            "projected" => Ok(Self::Projected),
            _ => Err(format!(
                "unknown tangent `{s}`; expected \"exact\" or \"projected\""
            )),
        }
    }
}

impl std::fmt::Display for TangentKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Exact => "exact",
            Self::Projected => "projected",
        })
    }
}

/// Error raised by a force system while evaluating itself (e.g. an inverted element).
#[derive(Debug, Error, Clone)]
pub enum SystemError {
    /// A quantity became NaN or infinite.
    #[error("non-finite {quantity} at dof {dof} (vertex {})", dof / 3)]
    NonFinite {
        /// What became non-finite (e.g. "force").
        quantity: &'static str,
        /// The degree of freedom where it was found.
        dof: usize,
    },
    /// An element inverted or degenerated (zero or negative area / volume, or a non-finite
    /// elastic force or energy), with the element's own error.
    #[error("element {element} is inverted or degenerate: {source}")]
    InvertedElement {
        /// Element index.
        element: usize,
        /// What the element reported, with its numbers.
        #[source]
        source: balloon_element::ElementError,
    },
    /// A failure of a component the integrator knows nothing about (e.g. the gas model), with
    /// its typed error: `source.downcast_ref::<TheComponentsError>()` recovers it. Made by
    /// [`SystemError::component`].
    #[error("{component}: {source}")]
    Component {
        /// Which component failed (e.g. "gas").
        component: &'static str,
        /// The component's own error.
        #[source]
        source: Arc<dyn std::error::Error + Send + Sync + 'static>,
    },
    /// The system cannot provide the requested kind of tangent stiffness.
    #[error("this force system does not support the `{0}` tangent; use the exact tangent")]
    TangentUnsupported(TangentKind),
    /// The system does not provide an assembled stiffness matrix; choose the matrix-free solver.
    #[error(
        "this force system cannot assemble its stiffness matrix; use the matrix-free CG solver"
    )]
    AssemblyUnsupported,
}

impl SystemError {
    /// Wraps the typed error of a component (e.g. `"gas"` and a gas model's error) so that it
    /// survives the integrator: see [`SystemError::Component`].
    pub fn component(
        component: &'static str,
        source: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        Self::Component {
            component,
            source: Arc::new(source),
        }
    }

    /// The component's error as a `T`, if this is a [`SystemError::Component`] holding one.
    pub fn component_error<T: std::error::Error + 'static>(&self) -> Option<&T> {
        match self {
            Self::Component { source, .. } => source.downcast_ref::<T>(),
            _ => None,
        }
    }
}

impl PartialEq for SystemError {
    /// Field-wise; two [`SystemError::Component`]s are equal when they name the same component
    /// and their errors print the same.
    fn eq(&self, other: &Self) -> bool {
        use SystemError::*;
        match (self, other) {
            (
                NonFinite {
                    quantity: a,
                    dof: b,
                },
                NonFinite {
                    quantity: c,
                    dof: d,
                },
            ) => a == c && b == d,
            (
                InvertedElement {
                    element: a,
                    source: b,
                },
                InvertedElement {
                    element: c,
                    source: d,
                },
            ) => a == c && b == d,
            (
                Component {
                    component: a,
                    source: b,
                },
                Component {
                    component: c,
                    source: d,
                },
            ) => a == c && (Arc::ptr_eq(b, d) || b.to_string() == d.to_string()),
            (TangentUnsupported(a), TangentUnsupported(b)) => a == b,
            (AssemblyUnsupported, AssemblyUnsupported) => true,
            _ => false,
        }
    }
}

/// A mechanical system as seen by the implicit integrators.
///
/// The integrator calls [`ForceSystem::forces`] at a linearisation point `x`; the later calls to
/// [`ForceSystem::add_force_differential`], [`ForceSystem::add_stiffness_triplets`] and
/// [`ForceSystem::low_rank_terms`] refer to that same point. `K = -df/dx` is the tangent stiffness.
pub trait ForceSystem {
    /// Number of degrees of freedom (3 x vertices).
    fn num_dofs(&self) -> usize;

    /// Lumped mass per degree of freedom, kg (length [`ForceSystem::num_dofs`]). Entries must be
    /// positive.
    fn masses(&self) -> &[f64];

    /// Evaluates all position-dependent forces at `x` into `f` (overwritten), and stores whatever
    /// is needed to linearise about `x`. `time` is the simulation time at which `x` is evaluated
    /// (for time-dependent loads such as a pump).
    fn forces(&mut self, time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError>;

    /// The forces at `x` as [`ForceSystem::forces`] gives them (bit for bit), for a caller that
    /// may not need the linearisation about `x`: a system whose stiffness costs much more than
    /// its forces can skip it here and compute it in [`ForceSystem::refresh_stiffness`]. The
    /// integrators use it for line-search trials, whose stiffness is needed only when Newton
    /// goes on from them (measured on the three-prism: forces alone 38 ns per element, with
    /// the 9x9 stiffness 306 ns). The default calls [`ForceSystem::forces`].
    fn residual_forces(&mut self, time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.forces(time, x, f)
    }

    /// [`ForceSystem::residual_forces`] and [`ForceSystem::potential_energy`] at the same `x`
    /// and `time` in one call: the forces into `f`, the energy returned (`Ok(None)` for a
    /// system without a potential). The default calls the two; a system that computes both in
    /// one pass over its elements overrides it and says so with
    /// [`ForceSystem::fuses_forces_and_energy`]. The energy must be that of
    /// `potential_energy` up to round-off, the forces bit for bit those of `residual_forces`.
    fn residual_forces_and_energy(
        &mut self,
        time: f64,
        x: &[f64],
        f: &mut [f64],
    ) -> Result<Option<f64>, SystemError> {
        self.residual_forces(time, x, f)?;
        self.potential_energy(time, x)
    }

    /// Whether [`ForceSystem::residual_forces_and_energy`] costs about as much as the forces
    /// alone (default `false`). When it does, the line search of
    /// [`crate::implicit::BackwardEuler`] evaluates each trial's energy and forces together
    /// (one pass instead of two when the trial is accepted, as most are); otherwise it
    /// evaluates the energy first and the forces only for an accepted trial.
    fn fuses_forces_and_energy(&self) -> bool {
        false
    }

    /// Makes the linearisation (differential, stiffness, low-rank terms) refer to the positions
    /// of the last force evaluation when that was [`ForceSystem::residual_forces`]: callers
    /// call it before any of those after `residual_forces`. A no-op after
    /// [`ForceSystem::forces`], and by default.
    fn refresh_stiffness(&mut self) -> Result<(), SystemError> {
        Ok(())
    }

    /// Adds the force differential `df = -K dx` at the last linearisation point to `df`.
    /// Includes any low-rank terms.
    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]);

    /// Appends the sparse part of `K` (everything but [`ForceSystem::low_rank_terms`]) as
    /// `(row, col, value)` triplets; duplicates are summed. Systems that cannot assemble return
    /// [`SystemError::AssemblyUnsupported`] (the default).
    fn add_stiffness_triplets(
        &self,
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), SystemError> {
        let _ = triplets;
        Err(SystemError::AssemblyUnsupported)
    }

    /// Optional faster form of [`ForceSystem::add_stiffness_triplets`] for the assembled
    /// solvers: the element part of the sparse `K` at the last linearisation point as dense
    /// blocks ([`StiffnessBlocks`], borrowed, no copy). Used only together with
    /// [`ForceSystem::add_remaining_stiffness_triplets`]; the blocks plus those triplets must
    /// equal what `add_stiffness_triplets` returns. Default `None` (use the triplets).
    fn stiffness_blocks(&self) -> Option<StiffnessBlocks<'_>> {
        None
    }

    /// Appends the entries of the sparse `K` that are not in [`ForceSystem::stiffness_blocks`]
    /// (e.g. a pressure follower term) as triplets. Default
    /// [`SystemError::AssemblyUnsupported`]: the integrator then uses
    /// [`ForceSystem::add_stiffness_triplets`] even if blocks are offered.
    fn add_remaining_stiffness_triplets(
        &self,
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), SystemError> {
        let _ = triplets;
        Err(SystemError::AssemblyUnsupported)
    }

    /// Asks the system to give, from its next linearisation on, an assembled stiffness that
    /// is a better preconditioner than its exact sparse `K` (`on`), together with the
    /// correction to the exact one ([`ForceSystem::add_stiffness_correction`]), or its exact
    /// sparse `K` (`!on`). Returns whether the split is in effect. The element blocks and the
    /// remaining triplets then hold `K_sparse`, `K = K_sparse + E`; the force differential,
    /// [`ForceSystem::add_stiffness_triplets`] and [`ForceSystem::add_stiffness_diagonal`]
    /// stay exact. Called by the Newton solver before each linearisation, with `on` only for a
    /// linear solver that applies the whole problem and factorises only the matrix
    /// ([`balloon_linalg::LinearSolver::accepts_correction`]). Default: no split (`false`).
    fn set_stiffness_split(&mut self, on: bool) -> bool {
        let _ = on;
        false
    }

    /// `out += scale E p`, the correction `E = K - K_sparse` of a split stiffness
    /// ([`ForceSystem::set_stiffness_split`]) at the last linearisation. Default: nothing
    /// (no split).
    fn add_stiffness_correction(&self, scale: f64, p: &[f64], out: &mut [f64]) {
        let _ = (scale, p, out);
    }

    /// Adds the diagonal of the sparse part of `K` (everything but
    /// [`ForceSystem::low_rank_terms`]) at the last linearisation point to `diagonal` (length
    /// [`ForceSystem::num_dofs`]). Optional: when provided, the matrix-free CG uses it for a
    /// Jacobi preconditioner `diag(A)` instead of the mass diagonal alone, without assembling
    /// `K`. Systems that cannot return [`SystemError::AssemblyUnsupported`] (the default).
    fn add_stiffness_diagonal(&self, diagonal: &mut [f64]) -> Result<(), SystemError> {
        let _ = diagonal;
        Err(SystemError::AssemblyUnsupported)
    }

    /// Selects the tangent stiffness used from the next [`ForceSystem::forces`] call on. The
    /// default implementation supports only [`TangentKind::Exact`] and returns
    /// [`SystemError::TangentUnsupported`] for anything else.
    fn set_tangent(&mut self, kind: TangentKind) -> Result<(), SystemError> {
        match kind {
            TangentKind::Exact => Ok(()),
            other => Err(SystemError::TangentUnsupported(other)),
        }
    }

    /// The dense low-rank part of `K` at the last linearisation point (default: none).
    fn low_rank_terms(&self) -> &[LowRankTerm] {
        &[]
    }

    /// The potential energy `W(x)` (J) whose negative gradient is [`ForceSystem::forces`] at the
    /// same `time` (`f = -dW/dx`), or `Ok(None)` (the default) for a system that has none.
    ///
    /// With a potential, [`crate::implicit::BackwardEuler`] minimises the incremental potential
    /// of the step with an Armijo line search on it; without one it falls back to a line search
    /// on the residual norm. The value may carry any constant offset, but the offset must not
    /// change between calls within a step. Must not change what the last
    /// [`ForceSystem::forces`] call linearised about (no side effects on the tangent).
    /// A state where the energy is undefined (an inverted element, a non-positive gas volume)
    /// is an error, which the line search treats as an infinite energy.
    fn potential_energy(&mut self, time: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        let _ = (time, x);
        Ok(None)
    }

    /// A typical magnitude (N, a Euclidean norm over the degrees of freedom) of the internal
    /// forces at the last [`ForceSystem::forces`] call, summed over parts that may cancel each
    /// other (e.g. the elastic and the pressure forces of an inflated balloon at rest, which
    /// balance). Used only to scale Newton's relative residual; the default `None` uses the norm
    /// of the total force. A system whose forces include loads that its elastic forces balance
    /// at equilibrium (gravity, a pressure) must give it: with the default the static solve's
    /// residual is measured against the (vanishing) total force itself and never falls below
    /// the tolerance.
    fn force_scale(&self) -> Option<f64> {
        None
    }
}

/// Fills `triplets` with what the assembler needs from `system`'s stiffness: only the part
/// beyond its element blocks when it offers blocks ([`ForceSystem::stiffness_blocks`], returns
/// `true`), otherwise every triplet (returns `false`). Shared by the dynamic and the static
/// Newton.
pub(crate) fn collect_stiffness<S: ForceSystem + ?Sized>(
    system: &S,
    triplets: &mut Vec<(usize, usize, f64)>,
) -> Result<bool, SystemError> {
    triplets.clear();
    if system.stiffness_blocks().is_some()
        && system.add_remaining_stiffness_triplets(triplets).is_ok()
    {
        return Ok(true);
    }
    triplets.clear();
    system.add_stiffness_triplets(triplets)?;
    Ok(false)
}
