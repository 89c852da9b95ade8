//! The static rest shape of a shell balloon: [`ShellSimulation::solve_static`], and the shell
//! as the static solver sees it, [`StaticShell`].
//!
//! # The static energy
//!
//! [`StaticShell`] is the static energy
//! `W_elastic(x) + W_gas(x)` (Wang et al. 2015, elastic energy Eq. 6-8, gas Eq. 12-17) with a
//! load factor for continuation ([`LoadScaling`]) and one of two gas terms ([`GasTerm`]):
//!
//! * **the shell's own gas** ([`GasTerm::Own`]): a given amount (`W_gas = -p0 V0 ln V +
//!   p_ambient V`, Eq. 14 integrated) or a given pressure (`W_gas = -(p - p_ambient) V`),
//!   scaled by the load factor;
//! * **a given volume** ([`GasTerm::Volume`]): one inner solve of an augmented Lagrangian for
//!   the constraint `V(x) = V_t`, the energy `W_elastic - lambda V + rho/2 (V - V_t)^2` of a
//!   gas with `p_gauge(V) = lambda - rho (V - V_t)` and `dp/dV = -rho` (the rank-1 tangent of
//!   Eq. 16-17, solved by Sherman-Morrison like any gas); `V_t` moves from the start volume to
//!   the target with the load factor. The multiplier update and the choice of `rho` are the
//!   outer loop's (below).
//!
//! The pressure tangent includes the follower term `-(p - p_ambient) d^2V/dx^2` when asked
//! (the exact Hessian), added to each element's stiffness block by the inner element pass, so
//! the Newton matrix is assembled from blocks only.
//!
//! ```
//! use balloon_gas::{IdealGas, PressureLoad};
//! use balloon_integrate::statics::{StaticParams, StaticSolver};
//! use balloon_material::{Lame, StVenantKirchhoff};
//! use balloon_shell::statics::{GasTerm, StaticShell};
//! use balloon_shell::ShellSystem;
//!
//! let mesh = balloon_mesh::generate::icosphere(0.1, 2)?;
//! let mut x = mesh.positions_flat();
//! let v0 = balloon_gas::enclosed_volume(&x, &mesh.triangles)?;
//! let material = StVenantKirchhoff::new(Lame::try_from_young_poisson(1e6, 0.45)?);
//! // An isothermal ideal gas at 3 kPa gauge in the rest shape (no ambient pressure).
//! let gas = PressureLoad::new(IdealGas::try_new(3000.0, v0)?)
//!     .with_ambient_pressure(0.0)?
//!     .with_follower_term(true);
//! let thickness = vec![3e-4; mesh.num_triangles()];
//! let mut shell =
//!     ShellSystem::from_rest_shape(&x, mesh.triangles.clone(), thickness, 950.0, material, gas)?;
//! let mut statics = StaticShell::new(&mut shell, GasTerm::Own, true);
//! let info = StaticSolver::new(StaticParams::default())?.solve_with_continuation(
//!     &mut statics,
//!     0.0,
//!     &mut x,
//!     None,
//! )?;
//! assert!(info.converged);
//! // At rest the gas has expanded until the wall holds it: a larger volume, a lower pressure.
//! assert!(statics.volume() > v0 && statics.gauge_pressure() < 3000.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # The rest shape
//!
//! [`ShellSimulation::solve_static`] finds the equilibrium that minimises the static energy
//! `W_elastic(x) + W_gas(x) - f_ext . x` (Wang et al. 2015, elastic energy Eq. 6-8, gas
//! Eq. 12-17) with the generic
//! [`balloon_integrate::statics::StaticSolver`] (Newton, Levenberg-Marquardt mass shift, Armijo
//! line search, load continuation). Three ways to hold the gas ([`StaticControl`]):
//!
//! * **given amount** (the simulation's ideal gas or pump, the amount at the current time):
//!   `W_gas = -p0 V0 ln V + p_ambient V` (Eq. 14 integrated);
//! * **given pressure** (the simulation's constant-pressure gas): `W_gas = -(p - p_ambient) V`;
//! * **given volume** ([`StaticControl::Volume`]): the constraint `V(x) = V_target` with the
//!   gauge pressure as its Lagrange multiplier `lambda`, by an augmented Lagrangian
//!   `W_elastic - lambda (V - V_t) + rho/2 (V - V_t)^2`: each inner solve is the energy of a
//!   gas with `p_gauge(V) = lambda - rho (V - V_t)` and `dp/dV = -rho` (the rank-1 tangent of
//!   Eq. 16-17, solved by Sherman-Morrison like any gas), followed by the multiplier update
//!   `lambda <- lambda - rho (V - V_t)`. `rho` starts at 100 times the shell's own volume
//!   stiffness along `dV/dx` (`g^T K g / |g|^4` at the start shape), so the multiplier gains
//!   about two digits per update; it grows tenfold when an update gains less than one.
//!   `lambda` starts at the gauge pressure that balances the elastic forces of the start shape
//!   (`-f_e . g / |g|^2`): along a continuation the previous point's pressure, so the first
//!   inner solve starts on the branch (the target volume is then reached by load continuation
//!   from the start volume). The reported pressure is `lambda` at the converged volume. Past a
//!   pressure maximum (a limit point of the membrane) this control stays on the branch, where
//!   pressure control snaps (`docs/membranes.md` section 9).
//!
//! The pressure tangent includes the follower term `-(p - p_ambient) d^2V/dx^2` by default, so
//! the Hessian is exact and Newton converges quadratically (the shift absorbs its
//! indefiniteness).
//!
//! # Thickness at rest
//!
//! The rule that holds at the returned equilibrium: **the shape is a static equilibrium at the
//! thickness `h*`, and `h*` is what the simulation's shell-volume projection (Algorithm 2,
//! Eq. 24-28, or the simulation's own projector) gives for that shape**, i.e. projecting the
//! result again changes the thickness by less than [`StaticOptions::thickness_tolerance`]
//! (relative). It is reached by a fixed-point iteration on `h = G(h)`, `G` = solve at `h`,
//! project the solution (keeping the projection's thickness and discarding its small position
//! correction, so the shape stays an exact equilibrium). The multiplier update of the volume
//! control shares this loop. Without a projector the thickness stays the current one.
//!
//! The loop is made cheap three ways, none of which weakens the rule above:
//!
//! * **Inexact outer iterations.** A solve at a thickness that is still moving need not be exact:
//!   the first solve is asked for a relative residual of `1e-3` (or the final tolerance if looser),
//!   each later one for `0.1` times the relative thickness change of the previous projection,
//!   clamped to `[0.1 thickness_tolerance, 1e-3]` (under volume control never looser than the final
//!   tolerance). The loop stops only after a solve at least as tight as
//!   [`StaticParams::tolerance`](balloon_integrate::statics::StaticParams::tolerance) whose
//!   projection changes the thickness by at most `thickness_tolerance`: the returned shape is that
//!   solve's equilibrium, the returned thickness that projection's.
//! * **Anderson acceleration** (type II, depth 3) of the thickness fixed point, in the
//!   thickness relative to its first value, with safeguards (the plain update `G(h)` when the
//!   fixed-point residual grew, the least-squares problem is singular, or the extrapolation
//!   would move a thickness by more than half its plain update's value): the map is nearly
//!   one-dimensional (the global projection moves every thickness along one pattern), so it
//!   converges in a few iterations where the plain iteration contracts by about 3 per
//!   iteration (15 iterations on the peer sphere).
//! * **Warm starts.** Each solve starts from the previous equilibrium with the previous solve's
//!   final Levenberg-Marquardt shift
//!   ([`StaticSolver::set_warm_start`](balloon_integrate::statics::StaticSolver::set_warm_start))
//!   and keeps the linear solver's factorisation (`balloon_integrate::statics`, "Reused
//!   factorisations"). After an extrapolated thickness it starts instead from the kept equilibria
//!   combined with the extrapolation's own weights (to first order the equilibrium at that
//!   thickness; the last equilibrium if the combination inverts an element): on the peer sphere the
//!   solves of outer iterations 3-5 then end 100-6000 times below their residuals without it after
//!   their one Newton iteration each, and the last solve needs none (7 outer iterations and 11
//!   Newton iterations instead of 8 and 14; `OUTER_LOG=1 cargo run --release -p balloon-benches
//!   --example static_profile`).
//!
//! With the follower term the Newton matrix is assembled from blocks only: each triangle's
//! block of `-(p - p_ambient) d^2V/dx^2` is added to its element stiffness block (no triplet
//! list).
//!
//! Anchor springs are not part of the static energy: a simulation with anchor springs set is
//! refused. External forces ([`ShellSimulation::set_external_forces`]) are included, scaled
//! with the gas load during continuation.
//!
//! [`ShellSimulation::inflate_to_volume`] inflates to a volume this way and leaves the balloon
//! holding its own ideal gas at that volume. Files: `statics/options.rs` (options, report),
//! `statics/rest_shape.rs` (the outer loop), `statics/inflate.rs`; the thickness acceleration
//! is [`balloon_integrate::statics::Anderson`].

use balloon_gas::GasModel;
use balloon_integrate::statics::LoadScaling;
use balloon_integrate::{ForceSystem, LowRankTerm, StiffnessBlocks, SystemError, TangentKind};

use crate::material::ShellMaterial;
use crate::system::{FollowerGauge, ShellSystem};

#[cfg(doc)]
use crate::ShellSimulation;

mod inflate;
mod options;
mod rest_shape;
#[cfg(test)]
mod tests;

pub use options::{OuterRecord, StabilityReport, StaticControl, StaticOptions, StaticReport};

/// How the gas acts in the static energy (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GasTerm {
    /// The shell's own gas model, scaled by the load factor.
    Own,
    /// A volume control: `p_gauge(V) = lambda - rho (V - V_t(s))` with the target
    /// `V_t(s) = V_start + s (V_target - V_start)` at load factor `s`.
    Volume {
        /// The multiplier (the gauge pressure at `V = V_t`), Pa.
        lambda: f64,
        /// The penalty `-dp/dV`, Pa/m^3 (positive).
        rho: f64,
        /// `V_start`, m^3: the target at load factor 0.
        start: f64,
        /// `V_target`, m^3: the target at load factor 1.
        target: f64,
    },
}

/// The shell as seen by the static solver: its elastic part plus a [`GasTerm`] with a load
/// factor, and optionally the follower term of the pressure tangent (module docs). It borrows
/// the shell for the solve and restores the shell's own follower setting when dropped.
pub struct StaticShell<'a, M: ShellMaterial, G: GasModel> {
    inner: &'a mut ShellSystem<M, G>,
    gas: GasTerm,
    factor: f64,
    follower: bool,
    /// Positions, gauge pressure and volume of the last evaluation.
    x: Vec<f64>,
    gauge: f64,
    volume: f64,
    rank1: LowRankTerm,
    scale: f64,
    /// The inner system's [`ShellSystem::follower_blocks`] before this wrapper set it (to
    /// `follower`: the inner element pass adds this gas term's follower blocks, at the gauge
    /// pressure of [`StaticShell::follower_gauge`]), restored on drop with the override cleared.
    inner_follower_blocks: bool,
}

impl<M: ShellMaterial, G: GasModel> Drop for StaticShell<'_, M, G> {
    fn drop(&mut self) {
        self.inner.follower_blocks = self.inner_follower_blocks;
        self.inner.follower_gauge_override = None;
    }
}

impl<'a, M: ShellMaterial, G: GasModel> StaticShell<'a, M, G> {
    /// The static energy of `inner` with the gas term `gas` at load factor 1, with the
    /// pressure follower term in the tangent when `follower` (the exact Hessian).
    pub fn new(inner: &'a mut ShellSystem<M, G>, gas: GasTerm, follower: bool) -> Self {
        let inner_follower_blocks = std::mem::replace(&mut inner.follower_blocks, follower);
        Self {
            inner_follower_blocks,
            inner,
            gas,
            factor: 1.0,
            follower,
            x: Vec::new(),
            gauge: 0.0,
            volume: 0.0,
            rank1: LowRankTerm::default(),
            scale: 0.0,
        }
    }

    /// The gauge pressure of this gas term as the inner element pass needs it for the follower
    /// blocks ([`StaticShell::pressure`] as a function of the volume).
    fn follower_gauge(&self) -> FollowerGauge {
        match self.gas {
            GasTerm::Own => FollowerGauge {
                scale: self.factor,
                lambda: 0.0,
                rho: 0.0,
                volume: 0.0,
            },
            GasTerm::Volume {
                lambda,
                rho,
                start,
                target,
            } => FollowerGauge {
                scale: 0.0,
                lambda,
                rho,
                volume: start + self.factor * (target - start),
            },
        }
    }

    /// Hands the current gas term and load factor to the inner element pass (with the
    /// follower term).
    fn sync_follower(&mut self) {
        self.inner.follower_gauge_override = self.follower.then(|| self.follower_gauge());
    }

    /// The gauge pressure (Pa) and `dp/dV` (Pa/m^3) of the gas term at volume `v`, from the
    /// inner gas state of the same evaluation for [`GasTerm::Own`].
    fn pressure(&self, v: f64) -> (f64, f64) {
        match self.gas {
            GasTerm::Own => (
                self.factor * self.inner.gas.state().gauge_pressure,
                self.factor * self.inner.gas.dpressure_dvolume(),
            ),
            GasTerm::Volume {
                lambda,
                rho,
                start,
                target,
            } => {
                let vt = start + self.factor * (target - start);
                (lambda - rho * (v - vt), -rho)
            }
        }
    }

    /// Replaces the inner gas force in `f` (elastic plus inner gas, at `x`) by this solve's gas
    /// term (Eq. 15 with [`StaticShell::pressure`]), and keeps what its linearisation needs.
    fn gas_forces(&mut self, x: &[f64], f: &mut [f64]) {
        // Remove the inner gas force (gauge * dV/dx, Eq. 15): `f` is then elastic only.
        let inner_gauge = self.inner.gas.state().gauge_pressure;
        let g = &self.inner.gas.low_rank_term().vector;
        for (fi, gi) in f.iter_mut().zip(g) {
            *fi -= inner_gauge * gi;
        }
        let elastic = f.iter().map(|v| v * v).sum::<f64>().sqrt();
        let volume = self.inner.gas.state().volume;
        let (gauge, dpdv) = self.pressure(volume);
        for (fi, gi) in f.iter_mut().zip(g) {
            *fi += gauge * gi;
        }
        let gnorm = g.iter().map(|v| v * v).sum::<f64>().sqrt();
        self.scale = elastic + gauge.abs() * gnorm;
        self.rank1.coefficient = -dpdv;
        self.rank1.vector.clear();
        self.rank1.vector.extend_from_slice(g);
        self.gauge = gauge;
        self.volume = volume;
        self.x.clear();
        self.x.extend_from_slice(x);
    }

    /// The gauge pressure of the gas term at the last evaluation, Pa.
    pub fn gauge_pressure(&self) -> f64 {
        self.gauge
    }

    /// The enclosed volume at the last evaluation, m^3.
    pub fn volume(&self) -> f64 {
        self.volume
    }

    /// The gas term.
    pub fn gas_term(&self) -> GasTerm {
        self.gas
    }

    /// The load factor (1 = the full load; set by the static solver's continuation through
    /// [`LoadScaling::set_load_factor`]).
    pub fn load_factor(&self) -> f64 {
        self.factor
    }
}

impl<M: ShellMaterial, G: GasModel> ForceSystem for StaticShell<'_, M, G> {
    fn num_dofs(&self) -> usize {
        self.inner.num_dofs()
    }

    fn masses(&self) -> &[f64] {
        self.inner.masses()
    }

    /// The forces, and the element blocks with this gas term's follower blocks (computed in
    /// the inner element pass).
    fn forces(&mut self, time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.sync_follower();
        self.inner.forces(time, x, f)?;
        self.gas_forces(x, f);
        Ok(())
    }

    /// The forces alone (the inner shell's [`ForceSystem::residual_forces`]); the element and
    /// follower blocks wait for [`ForceSystem::refresh_stiffness`].
    fn residual_forces(&mut self, time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.sync_follower();
        self.inner.residual_forces(time, x, f)?;
        self.gas_forces(x, f);
        Ok(())
    }

    fn refresh_stiffness(&mut self) -> Result<(), SystemError> {
        self.inner.refresh_stiffness()
    }

    /// The elastic differential (with the follower term, which is in the element blocks) plus
    /// this gas term's rank-1 part.
    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        self.inner.add_elastic_differential(dx, df);
        let g = &self.rank1.vector;
        let gdx: f64 = g.iter().zip(dx).map(|(a, b)| a * b).sum();
        let s = -self.rank1.coefficient * gdx;
        for (d, gi) in df.iter_mut().zip(g) {
            *d += s * gi;
        }
    }

    fn add_stiffness_triplets(
        &self,
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), SystemError> {
        let blocks = self
            .stiffness_blocks()
            .ok_or(SystemError::AssemblyUnsupported)?;
        let k = blocks.nodes_per_block;
        let size = 3 * k;
        for (nodes, values) in blocks
            .nodes
            .chunks_exact(k)
            .zip(blocks.values.chunks_exact(size * size))
        {
            for a in 0..k {
                for b in 0..k {
                    for i in 0..3 {
                        for j in 0..3 {
                            // Column-major: entry (row, col) at col * size + row.
                            let v = values[(3 * b + j) * size + 3 * a + i];
                            triplets.push((3 * nodes[a] + i, 3 * nodes[b] + j, v));
                        }
                    }
                }
            }
        }
        // The exact couplings, also with a split stiffness.
        self.inner.add_bending_triplets(triplets);
        Ok(())
    }

    /// The element blocks, with the follower term `-(p - p_ambient) d^2V/dx^2` added per
    /// triangle when enabled (by the inner element pass).
    fn stiffness_blocks(&self) -> Option<StiffnessBlocks<'_>> {
        self.inner.stiffness_blocks()
    }

    /// The wall's bending Hessians, if any (the follower term is in the blocks).
    fn add_remaining_stiffness_triplets(
        &self,
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), SystemError> {
        self.inner.add_bending_matrix_triplets(triplets);
        Ok(())
    }

    /// As the inner shell's (the wall's bending couplings).
    fn set_stiffness_split(&mut self, on: bool) -> bool {
        self.inner.split_bending_stiffness(on)
    }

    fn add_stiffness_correction(&self, scale: f64, p: &[f64], out: &mut [f64]) {
        self.inner.add_bending_correction(scale, p, out);
    }

    fn add_stiffness_diagonal(&self, diagonal: &mut [f64]) -> Result<(), SystemError> {
        self.inner.add_stiffness_diagonal(diagonal)
    }

    fn set_tangent(&mut self, kind: TangentKind) -> Result<(), SystemError> {
        self.inner.set_tangent(kind)
    }

    fn low_rank_terms(&self) -> &[LowRankTerm] {
        std::slice::from_ref(&self.rank1)
    }

    /// `W_elastic + s W_gas` (own gas) or `W_elastic - lambda V + rho/2 (V - V_t(s))^2`.
    fn potential_energy(&mut self, time: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        let elastic = self.inner.elastic_energy(x);
        if !elastic.is_finite() {
            return Err(self.inner.non_finite_energy_error(x));
        }
        let gas = match self.gas {
            GasTerm::Own => match self.inner.gas_energy(time, x)? {
                Some(w) => self.factor * w,
                None => return Ok(None),
            },
            GasTerm::Volume {
                lambda,
                rho,
                start,
                target,
            } => {
                let v = balloon_gas::enclosed_volume(x, &self.inner.triangles)
                    .map_err(|e| SystemError::component("gas", e))?;
                if !(v.is_finite() && v > 0.0) {
                    return Err(SystemError::component(
                        "gas",
                        balloon_gas::GasError::InvalidVolume { volume: v },
                    ));
                }
                let vt = start + self.factor * (target - start);
                -lambda * v + 0.5 * rho * (v - vt) * (v - vt)
            }
        };
        Ok(Some(elastic + gas))
    }

    fn force_scale(&self) -> Option<f64> {
        Some(self.scale)
    }
}

impl<M: ShellMaterial, G: GasModel> LoadScaling for StaticShell<'_, M, G> {
    fn set_load_factor(&mut self, factor: f64) {
        self.factor = factor;
    }
}
