//! Connected balloons: several closed shells, each holding its own isothermal ideal gas
//! (seed 000, Eq. 12), joined by tubes through which gas flows from the higher pressure to the
//! lower (issue 14, item 4: the two-balloon experiment).
//!
//! Each step advances every shell with its own amount of gas held fixed (the implicit step of
//! seed 000, Eq. 18-23, unchanged), then lets gas flow through the tubes at the end-of-step
//! volumes. The flow law of a tube between balloons `i` and `j` with conductance `kappa`
//! (m^3/s) moves gas amount (in `nRT` units, J) at the rate
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
//! use balloon::gas::GasKind;
//! use balloon::mesh::generate::icosphere;
//! use balloon::shell::ShellBalloon;
//! use balloon::shell::connected::{Conductance, ConnectedBalloons, Tube};
//!
//! let balloon = |gauge: f64| {
//!     ShellBalloon::new(icosphere(0.1, 1).unwrap())
//!         .with_gas(GasKind::Ideal)
//!         .with_gauge_pressure(gauge)
//!         .build()
//!         .unwrap()
//! };
//! let tube = Tube { a: 0, b: 1, conductance: Conductance::Finite(1e-3) };
//! let mut pair = ConnectedBalloons::new(vec![balloon(800.0), balloon(200.0)], vec![tube]).unwrap();
//! let total = pair.total_amount();
//! pair.step().unwrap();
//! assert!((pair.total_amount() / total - 1.0).abs() < 1e-12);
//! ```

use balloon_gas::Gas;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

pub use super::connected_error::ConnectedError;
use super::statics::{StaticControl, StaticOptions, StaticReport};
use super::{ShellError, ShellMaterial, ShellSimulation, ShellStepStats};
use crate::simulation::{DrawnSurface, Simulation, SimulationError, SimulationStats};
use std::borrow::Cow;

impl<M: ShellMaterial> ShellSimulation<M, Gas> {
    /// Inflates the balloon statically to the enclosed volume `target` (m^3) and leaves it
    /// holding that gas: a static solve under volume control (the gauge pressure is the
    /// volume constraint's multiplier, [`StaticControl::Volume`]), then the isothermal ideal
    /// gas amount is set to `nRT = (p_ambient + p_gauge) V` (seed 000, Eq. 12) so that the
    /// balloon is at rest at that volume with its own gas, ready to be connected. `options`
    /// gives the solver settings; its `control` is replaced by the volume target.
    ///
    /// To pre-inflate to a linear stretch `l` of a sphere, pass
    /// `target = l^3 * rest_gas_volume()`.
    ///
    /// ```
    /// use balloon::gas::GasKind;
    /// use balloon::shell::ShellBalloon;
    /// use balloon::shell::statics::StaticOptions;
    /// let mut sim = ShellBalloon::new(balloon::mesh::generate::icosphere(0.1, 1).unwrap())
    ///     .with_gas(GasKind::Ideal)
    ///     .build()
    ///     .unwrap();
    /// let target = 1.2 * sim.rest_gas_volume();
    /// let report = sim.inflate_to_volume(target, &StaticOptions::default())?;
    /// assert!((sim.gas_volume() / target - 1.0).abs() < 1e-6);
    /// let amount = (sim.ambient_pressure() + report.gauge_pressure) * report.gas_volume;
    /// assert_eq!(sim.gas_amount(), Some(amount));
    /// # Ok::<(), balloon::shell::ShellError>(())
    /// ```
    ///
    /// # Errors
    /// [`ShellError::InvalidParameter`] when the gas is not the isothermal ideal gas or
    /// `target` is not positive and finite; the static solve's error when it fails (the
    /// simulation is then left as it was), [`ShellError::StaticNotConverged`] when it ends
    /// without meeting its tolerances.
    pub fn inflate_to_volume(
        &mut self,
        target: f64,
        options: &StaticOptions,
    ) -> Result<StaticReport, ShellError> {
        if self.gas_amount().is_none() {
            return Err(ShellError::InvalidParameter {
                name: "gas",
                value: format!("{:?}", self.gas().kind()).to_lowercase(),
                reason: "inflating to a volume and holding the gas needs the isothermal ideal \
                         gas (`gas` = ideal)"
                    .into(),
            });
        }
        if !(target.is_finite() && target > 0.0) {
            return Err(ShellError::InvalidParameter {
                name: "volume",
                value: target.to_string(),
                reason: "the target volume must be positive and finite (m^3)".into(),
            });
        }
        let report = self.solve_static(&StaticOptions {
            control: StaticControl::Volume { target },
            ..*options
        })?;
        if !report.converged {
            return Err(ShellError::StaticNotConverged {
                outer_iterations: report.outer_iterations,
                residual: report.relative_residual,
                thickness_change: report.thickness_change,
                volume_error: report.volume_error,
            });
        }
        self.set_gas_amount((self.ambient_pressure() + report.gauge_pressure) * report.gas_volume)?;
        Ok(report)
    }
}

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
    /// vertex blocks in order), refreshed after every step: what [`Simulation`] reads.
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

fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
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

    /// Where each balloon's vertices start in the merged surface ([`Simulation::positions`],
    /// [`Simulation::surface`]): balloon `i` owns vertices `offsets[i]..offsets[i + 1]`; the
    /// last entry is the total vertex count.
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

    /// The tubes.
    pub fn tubes(&self) -> &[Tube] {
        &self.tubes
    }

    /// Simulation time, s.
    pub fn time(&self) -> f64 {
        self.balloons[0].time()
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
        let mut new = self.finite_flow(dt, &volumes, &old);
        self.equalise_instant_groups(&volumes, &mut new);
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

    /// Backward Euler on the finite tubes at fixed volumes: `(I + dt L D) n' = n`.
    fn finite_flow(&self, dt: f64, volumes: &[f64], amounts: &[f64]) -> Vec<f64> {
        let n = amounts.len();
        let mut a = DMatrix::<f64>::identity(n, n);
        let mut any = false;
        for t in &self.tubes {
            if let Conductance::Finite(kappa) = t.conductance {
                any = true;
                let c = dt * kappa;
                // Row i: + c (n_i / V_i - n_j / V_j); row j the opposite.
                a[(t.a, t.a)] += c / volumes[t.a];
                a[(t.a, t.b)] -= c / volumes[t.b];
                a[(t.b, t.b)] += c / volumes[t.b];
                a[(t.b, t.a)] -= c / volumes[t.a];
            }
        }
        if !any {
            return amounts.to_vec();
        }
        // A column-diagonally dominant M-matrix: LU with partial pivoting always succeeds.
        a.lu()
            .solve(&DVector::from_column_slice(amounts))
            .map_or_else(|| vec![f64::NAN; n], |x| x.as_slice().to_vec())
    }

    /// Shares the gas of every group of balloons joined by instant tubes at one pressure.
    fn equalise_instant_groups(&self, volumes: &[f64], amounts: &mut [f64]) {
        let n = amounts.len();
        for root in 0..n {
            let members: Vec<usize> = (0..n).filter(|&i| self.groups[i] == root).collect();
            if members.len() < 2 {
                continue;
            }
            let total: f64 = members.iter().map(|&i| amounts[i]).sum();
            let volume: f64 = members.iter().map(|&i| volumes[i]).sum();
            for &i in &members {
                amounts[i] = total * volumes[i] / volume;
            }
        }
    }
}

impl<M: ShellMaterial> Simulation for ConnectedBalloons<M> {
    type Detail = ConnectedStepStats;

    fn name(&self) -> &'static str {
        "connected"
    }
    fn step(&mut self) -> Result<SimulationStats<ConnectedStepStats>, SimulationError> {
        let dt = ConnectedBalloons::dt(self);
        let detail = ConnectedBalloons::step(self)?;
        Ok(SimulationStats {
            steps: self.step,
            time: detail.time,
            dt,
            kinetic_energy: Simulation::kinetic_energy(self),
            detail,
        })
    }
    fn time(&self) -> f64 {
        ConnectedBalloons::time(self)
    }
    fn dt(&self) -> f64 {
        ConnectedBalloons::dt(self)
    }
    /// Sets the time step of every balloon. They all check the same range, so a refusal comes
    /// from balloon 0, before any balloon changed.
    fn set_dt(&mut self, dt: f64) -> Result<(), SimulationError> {
        for (i, b) in self.balloons.iter_mut().enumerate() {
            b.set_dt(dt)
                .map_err(|source| ConnectedError::Shell { balloon: i, source })?;
        }
        Ok(())
    }
    fn steps(&self) -> usize {
        self.step
    }
    fn positions(&self) -> &[f64] {
        &self.merged.positions
    }
    fn velocities(&self) -> &[f64] {
        &self.merged.velocities
    }
    fn kinetic_energy(&self) -> f64 {
        self.balloons.iter().map(Simulation::kinetic_energy).sum()
    }
    fn surface(&self) -> DrawnSurface<'_> {
        DrawnSurface {
            positions: Cow::Borrowed(&self.merged.positions),
            triangles: Cow::Borrowed(&self.merged.triangles),
        }
    }
}
