//! Connected balloons: several closed shells, each holding its own isothermal ideal gas
//! (Wang et al. 2015, Eq. 12), joined by tubes through which gas flows from the higher pressure
//! to the lower (the two-balloon experiment).
//!
//! Each step advances every shell with its own amount of gas held fixed (the implicit step of Wang
//! et al. 2015, Eq. 18-23, unchanged), then lets gas flow through the tubes at the end-of-step
//! volumes. The flow law of a tube between balloons `i` and `j` with conductance `kappa` (m^3/s)
//! moves gas amount (in `nRT` units, J) at the rate
//!
//! ```text
//! d(nRT)_i/dt = -kappa (p_i - p_j),     p_i = (nRT)_i / V_i,
//! ```
//!
//! integrated by backward Euler over the step (`(I + dt L D) n' = n` with `L` the tubes'
//! weighted graph Laplacian and `D = diag(1/V_i)`), which is stable for any conductance and
//! conserves the total amount exactly. [`Conductance::Instant`] is the limit of an infinite
//! conductance: the gas of the balloons it joins is shared out at one pressure every step.
//! At rest (no flow, no motion) the split is exact: the pressures of connected balloons are
//! equal and the total amount is the one they started with.
//!
//! ```
//! use balloon_gas::{Gas, IdealGas, PressureLoad};
//! use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
//! use balloon_material::{Lame, StVenantKirchhoff};
//! use balloon_shell::connected::{Conductance, ConnectedBalloons, Tube};
//! use balloon_shell::{ShellSimulation, ShellSystem};
//!
//! // A latex sphere holding an ideal gas `gauge` Pa over the atmosphere.
//! let balloon = |gauge: f64| -> Result<ShellSimulation<StVenantKirchhoff>, Box<dyn std::error::Error>> {
//!     let mesh = balloon_mesh::generate::icosphere(0.1, 1)?;
//!     let x = mesh.positions_flat();
//!     let v0 = balloon_gas::enclosed_volume(&x, &mesh.triangles)?;
//!     let gas = Gas::Ideal(IdealGas::try_new(101_325.0 + gauge, v0)?);
//!     let gas = PressureLoad::new(gas).with_ambient_pressure(101_325.0)?;
//!     let material = StVenantKirchhoff::new(Lame::try_from_young_poisson(1e6, 0.45)?);
//!     let h = vec![3e-4; mesh.num_triangles()];
//!     let system = ShellSystem::from_rest_shape(&x, mesh.triangles, h, 950.0, material, gas)?;
//!     let mut params = BackwardEulerParams::default();
//!     params.mass_damping = 10.0;
//!     let integrator = BackwardEuler::new(params)?;
//!     Ok(ShellSimulation::new(system, x, 950.0, integrator, None, 0.01, 10)?)
//! };
//! let tube = Tube { a: 0, b: 1, conductance: Conductance::Finite(1e-3) };
//! let mut pair = ConnectedBalloons::new(vec![balloon(800.0)?, balloon(200.0)?], vec![tube])?;
//! let total = pair.total_amount();
//! pair.step()?;
//! assert!((pair.total_amount() / total - 1.0).abs() < 1e-12);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Files: `mod.rs` the set, its checks and its step; `flow.rs` the flow through the tubes;
//! `error.rs` the error.

mod error;
mod flow;

pub use error::ConnectedError;

use balloon_gas::Gas;
use serde::{Deserialize, Serialize};

use flow::{equalise_instant_groups, find, finite_flow};

use crate::{ShellMaterial, ShellSimulation, ShellSnapshot, ShellStepStats};

/// How freely gas flows through a [`Tube`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Conductance {
    /// Flow `kappa (p_i - p_j)` in `nRT` units (J/s) for `kappa` in m^3/s (positive, finite).
    Finite(f64),
    /// Instant equalisation: the joined balloons share one pressure after every step.
    Instant,
}

/// A tube between balloons `a` and `b` (indices into the balloons of [`ConnectedBalloons`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Tube {
    /// One end.
    pub a: usize,
    /// The other end.
    pub b: usize,
    /// How freely gas flows.
    pub conductance: Conductance,
}

/// The state of [`ConnectedBalloons`] at one moment: each balloon's [`ShellSnapshot`] (its
/// gas amount included) and the step count.
#[derive(Clone, Debug)]
pub struct ConnectedSnapshot {
    balloons: Vec<ShellSnapshot<Gas>>,
    step: usize,
}

impl ConnectedSnapshot {
    /// Steps taken up to the saved state.
    pub fn steps_taken(&self) -> usize {
        self.step
    }
    /// Simulation time of the saved state, s.
    pub fn time(&self) -> f64 {
        self.balloons.first().map_or(0.0, ShellSnapshot::time)
    }
}

/// What one step of [`ConnectedBalloons`] did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConnectedStepStats {
    /// Step number (1-based).
    pub step: usize,
    /// Time at the end of the step, s.
    pub time: f64,
    /// Each balloon's gas volume at the end of the step, m^3.
    pub volumes: Vec<f64>,
    /// Each balloon's gauge pressure after the flow, Pa.
    pub gauge_pressures: Vec<f64>,
    /// Each balloon's gas amount `nRT` after the flow, J.
    pub amounts: Vec<f64>,
    /// Each balloon's linear stretch `(V / V0)^(1/3)` against its rest gas volume `V0` (the
    /// stretch of a sphere inflated uniformly to that volume).
    pub stretches: Vec<f64>,
    /// The total gas amount `sum nRT` after the flow, J (conserved).
    pub total_amount: f64,
    /// The largest amount moved into or out of one balloon in this step, J.
    pub max_transfer: f64,
    /// Each balloon's own step statistics.
    pub balloons: Vec<ShellStepStats>,
}

/// Several shells, each with its own ideal gas, joined by tubes (see the module docs).
#[derive(Debug)]
pub struct ConnectedBalloons<M: ShellMaterial> {
    balloons: Vec<ShellSimulation<M, Gas>>,
    tubes: Vec<Tube>,
    /// Balloons joined by instant tubes: the group representative of each balloon.
    groups: Vec<usize>,
    step: usize,
    /// All balloons' positions, velocities and triangles one after the other (the balloons'
    /// vertex blocks in order), refreshed after every step: the set as one surface.
    merged: Merged,
}

/// The balloons as one surface (see [`ConnectedBalloons::vertex_offsets`]).
#[derive(Debug, Default)]
struct Merged {
    positions: Vec<f64>,
    velocities: Vec<f64>,
    triangles: Vec<[usize; 3]>,
}

impl Merged {
    fn of<M: ShellMaterial>(balloons: &[ShellSimulation<M, Gas>]) -> Self {
        let mut m = Self::default();
        for b in balloons {
            let base = m.positions.len() / 3;
            m.triangles.extend(
                b.triangles()
                    .iter()
                    .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
            );
            m.positions.extend_from_slice(b.positions());
            m.velocities.extend_from_slice(b.velocities());
        }
        m
    }

    fn refresh<M: ShellMaterial>(&mut self, balloons: &[ShellSimulation<M, Gas>]) {
        self.positions.clear();
        self.velocities.clear();
        for b in balloons {
            self.positions.extend_from_slice(b.positions());
            self.velocities.extend_from_slice(b.velocities());
        }
    }
}

impl<M: ShellMaterial> ConnectedBalloons<M> {
    /// Joins `balloons` (each built with the isothermal ideal gas, all with the same time step
    /// and ambient pressure) by `tubes`.
    ///
    /// # Errors
    /// [`ConnectedError`] naming the balloon or tube that is not valid.
    pub fn new(
        balloons: Vec<ShellSimulation<M, Gas>>,
        tubes: Vec<Tube>,
    ) -> Result<Self, ConnectedError> {
        let first = balloons.first().ok_or(ConnectedError::Empty)?;
        let (dt, ambient) = (first.dt(), first.ambient_pressure());
        for (i, b) in balloons.iter().enumerate() {
            if b.gas_amount().is_none() {
                return Err(ConnectedError::NotIdealGas { balloon: i });
            }
            for (what, value, expected) in [
                ("dt", b.dt(), dt),
                ("ambient_pressure", b.ambient_pressure(), ambient),
            ] {
                if value != expected {
                    return Err(ConnectedError::Mismatch {
                        balloon: i,
                        what,
                        value,
                        expected,
                    });
                }
            }
        }
        let n = balloons.len();
        let mut parent: Vec<usize> = (0..n).collect();
        for (k, t) in tubes.iter().enumerate() {
            let bad = |reason: String| ConnectedError::InvalidTube { tube: k, reason };
            if t.a >= n || t.b >= n {
                return Err(bad(format!(
                    "joins balloons {} and {}, but there are {n}",
                    t.a, t.b
                )));
            }
            if t.a == t.b {
                return Err(bad(format!("joins balloon {} to itself", t.a)));
            }
            match t.conductance {
                Conductance::Finite(kappa) if !(kappa.is_finite() && kappa > 0.0) => {
                    return Err(bad(format!(
                        "conductance {kappa} must be positive and finite (m^3/s)"
                    )));
                }
                Conductance::Finite(_) => {}
                Conductance::Instant => {
                    let (ra, rb) = (find(&mut parent, t.a), find(&mut parent, t.b));
                    parent[ra] = rb;
                }
            }
        }
        let groups = (0..n).map(|i| find(&mut parent, i)).collect();
        let merged = Merged::of(&balloons);
        Ok(Self {
            balloons,
            tubes,
            groups,
            step: 0,
            merged,
        })
    }

    /// The balloons.
    pub fn balloons(&self) -> &[ShellSimulation<M, Gas>] {
        &self.balloons
    }

    /// Replaces balloon `balloon`'s anchor springs ([`ShellSimulation::set_anchor_springs`],
    /// vertices numbered within that balloon), acting from the next step: a live viewer's drag.
    ///
    /// # Errors
    /// [`ConnectedError::NoBalloon`] for an index beyond the balloons, [`ConnectedError::Shell`]
    /// when a spring is invalid for that balloon.
    pub fn set_anchor_springs(
        &mut self,
        balloon: usize,
        springs: Vec<balloon_integrate::decorators::AnchorSpring>,
    ) -> Result<(), ConnectedError> {
        self.balloon_mut(balloon)?
            .set_anchor_springs(springs)
            .map_err(|source| ConnectedError::Shell { balloon, source })
    }

    /// Balloon `balloon`, or [`ConnectedError::NoBalloon`] naming the count.
    fn balloon_mut(
        &mut self,
        balloon: usize,
    ) -> Result<&mut ShellSimulation<M, Gas>, ConnectedError> {
        let count = self.balloons.len();
        self.balloons
            .get_mut(balloon)
            .ok_or(ConnectedError::NoBalloon { balloon, count })
    }

    /// Edits balloon `balloon`'s integrator parameters
    /// ([`ShellSimulation::configure_integrator`]), from the next step on: a live viewer's
    /// fixed Newton iterations while it drags.
    ///
    /// # Errors
    /// [`ConnectedError::NoBalloon`] for an index beyond the balloons, [`ConnectedError::Shell`]
    /// when the edited parameters are invalid.
    pub fn configure_integrator(
        &mut self,
        balloon: usize,
        edit: impl FnOnce(&mut balloon_integrate::implicit::BackwardEulerParams),
    ) -> Result<(), ConnectedError> {
        self.balloon_mut(balloon)?
            .configure_integrator(edit)
            .map_err(|source| ConnectedError::Shell { balloon, source })
    }

    /// Where each balloon's vertices start in the merged surface
    /// ([`ConnectedBalloons::merged_positions`], [`ConnectedBalloons::merged_triangles`]):
    /// balloon `i` owns vertices `offsets[i]..offsets[i + 1]`; the last entry is the total
    /// vertex count.
    pub fn vertex_offsets(&self) -> Vec<usize> {
        let mut offsets = vec![0];
        for b in &self.balloons {
            offsets.push(offsets[offsets.len() - 1] + b.positions().len() / 3);
        }
        offsets
    }

    /// Each balloon's linear stretch `(V / V0)^(1/3)`: its gas volume against its rest gas
    /// volume.
    pub fn stretches(&self) -> Vec<f64> {
        self.balloons
            .iter()
            .map(|b| (b.gas_volume() / b.rest_gas_volume()).cbrt())
            .collect()
    }

    /// All balloons' positions one after the other (flat, m; balloon `i` at
    /// [`ConnectedBalloons::vertex_offsets`] `[i]`), as of the end of the last step.
    pub fn merged_positions(&self) -> &[f64] {
        &self.merged.positions
    }

    /// All balloons' velocities one after the other (flat, m/s), laid out as
    /// [`ConnectedBalloons::merged_positions`].
    pub fn merged_velocities(&self) -> &[f64] {
        &self.merged.velocities
    }

    /// All balloons' triangles, indexing [`ConnectedBalloons::merged_positions`].
    pub fn merged_triangles(&self) -> &[[usize; 3]] {
        &self.merged.triangles
    }

    /// Sets the time step of every balloon. They all check the same range, so a refusal comes
    /// from balloon 0, before any balloon changed.
    ///
    /// # Errors
    /// [`ConnectedError::Shell`] naming the balloon that refused `dt`.
    pub fn set_dt(&mut self, dt: f64) -> Result<(), ConnectedError> {
        for (i, b) in self.balloons.iter_mut().enumerate() {
            b.set_dt(dt)
                .map_err(|source| ConnectedError::Shell { balloon: i, source })?;
        }
        Ok(())
    }

    /// The tubes.
    pub fn tubes(&self) -> &[Tube] {
        &self.tubes
    }

    /// Simulation time, s.
    pub fn time(&self) -> f64 {
        self.balloons[0].time()
    }

    /// The current state of every balloon and the step count ([`ConnectedSnapshot`]), to put
    /// back later with [`ConnectedBalloons::restore`].
    pub fn snapshot(&self) -> ConnectedSnapshot {
        ConnectedSnapshot {
            balloons: self
                .balloons
                .iter()
                .map(ShellSimulation::snapshot)
                .collect(),
            step: self.step,
        }
    }

    /// Puts back the state of `snapshot` (taken from these balloons): every balloon's
    /// ([`ShellSimulation::restore`]) and the step count.
    ///
    /// # Errors
    /// [`ConnectedError::SnapshotMismatch`] when the snapshot has another number of
    /// balloons, a balloon's [`ConnectedError::Shell`] when its snapshot does not fit it
    /// (taken from other balloons); nothing changes then.
    pub fn restore(&mut self, snapshot: &ConnectedSnapshot) -> Result<(), ConnectedError> {
        if snapshot.balloons.len() != self.balloons.len() {
            return Err(ConnectedError::SnapshotMismatch {
                snapshot: snapshot.balloons.len(),
                count: self.balloons.len(),
            });
        }
        // Every balloon's snapshot is checked before any is put back.
        for (i, (b, s)) in self.balloons.iter().zip(&snapshot.balloons).enumerate() {
            b.check_snapshot(s)
                .map_err(|source| ConnectedError::Shell { balloon: i, source })?;
        }
        for (i, (b, s)) in self.balloons.iter_mut().zip(&snapshot.balloons).enumerate() {
            b.restore(s)
                .map_err(|source| ConnectedError::Shell { balloon: i, source })?;
        }
        self.step = snapshot.step;
        self.merged.refresh(&self.balloons);
        Ok(())
    }

    /// The time step all balloons share, s.
    pub fn dt(&self) -> f64 {
        self.balloons[0].dt()
    }

    /// Steps taken.
    pub fn steps(&self) -> usize {
        self.step
    }

    /// Each balloon's gas amount `nRT`, J.
    pub fn amounts(&self) -> Vec<f64> {
        self.balloons
            .iter()
            .map(|b| b.gas_amount().unwrap_or(f64::NAN))
            .collect()
    }

    /// The total gas amount `sum nRT`, J: constant over the run.
    pub fn total_amount(&self) -> f64 {
        self.amounts().iter().sum()
    }

    /// Each balloon's gauge pressure at its current volume and amount, Pa.
    pub fn gauge_pressures(&self) -> Vec<f64> {
        self.balloons
            .iter()
            .map(|b| b.gas_amount().unwrap_or(f64::NAN) / b.gas_volume() - b.ambient_pressure())
            .collect()
    }

    /// Advances every balloon one step with its amount of gas fixed, then lets the gas flow
    /// through the tubes at the end-of-step volumes (see the module docs).
    ///
    /// # Errors
    /// [`ConnectedError::Shell`] when a balloon's step fails, [`ConnectedError::Flow`] when the
    /// flow gives an amount that is not positive and finite.
    pub fn step(&mut self) -> Result<ConnectedStepStats, ConnectedError> {
        let step = self.step + 1;
        let mut stats = Vec::with_capacity(self.balloons.len());
        for (i, b) in self.balloons.iter_mut().enumerate() {
            match b.step() {
                Ok(s) => stats.push(s),
                Err(source) => {
                    self.merged.refresh(&self.balloons);
                    return Err(ConnectedError::Shell { balloon: i, source });
                }
            }
        }
        self.merged.refresh(&self.balloons);
        let dt = self.balloons[0].dt();
        let volumes: Vec<f64> = self.balloons.iter().map(|b| b.gas_volume()).collect();
        let old = self.amounts();
        let mut new = finite_flow(&self.tubes, dt, &volumes, &old);
        equalise_instant_groups(&self.groups, &volumes, &mut new);
        for (i, (b, &n)) in self.balloons.iter_mut().zip(&new).enumerate() {
            if !(n.is_finite() && n > 0.0) {
                return Err(ConnectedError::Flow {
                    step,
                    balloon: i,
                    amount: n,
                });
            }
            b.set_gas_amount(n)
                .map_err(|source| ConnectedError::Shell { balloon: i, source })?;
        }
        self.step = step;
        let max_transfer = old
            .iter()
            .zip(&new)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        Ok(ConnectedStepStats {
            step,
            time: self.time(),
            volumes,
            gauge_pressures: self.gauge_pressures(),
            stretches: self.stretches(),
            total_amount: new.iter().sum(),
            amounts: new,
            max_transfer,
            balloons: stats,
        })
    }
}
