//! Time stepping of a two-layer object: integrate (Song 2009, Ch. 5), collide (Song 2009, Sec.
//! 4.6), check for blow-up, report.

use crate::error::{BlowUpReason, TwoLayerError};
use crate::forces::{AnchorSpring, DragTarget, EnergyBreakdown, TwoLayerForces};
use crate::model::{Dimension, TwoLayerModel};
use crate::params::TwoLayerParams;
use balloon_constraint::two_layer::{
    AxisBox, LayerContainment, collide_box, polygon_winding_number, winding_number,
};
use balloon_integrate::explicit::{ExplicitIntegrator, ExplicitMethod};
use balloon_mesh::TriMesh;
use nalgebra::Point3;
use serde::{Deserialize, Serialize};

/// Statistics of one step (or of the initial state, step 0).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TwoLayerStats {
    /// Steps taken.
    pub step: usize,
    /// Simulated time (s).
    pub time: f64,
    /// Kinetic energy (J).
    pub kinetic: f64,
    /// Potential energy: springs + gas + gravity + drag (J).
    pub potential: f64,
    /// Total energy (J).
    pub total: f64,
    /// Volume enclosed by the outer layer (m^3; area in 2D; 0 in 1D).
    pub volume_outer: f64,
    /// Volume enclosed by the inner layer.
    pub volume_inner: f64,
    /// Gas pressure of the outer layer (Pa).
    pub pressure_outer: f64,
    /// Gas pressure of the inner layer (Pa).
    pub pressure_inner: f64,
    /// Lowest particle coordinate along the up axis (m).
    pub min_height: f64,
    /// Particle-wall contacts resolved in this step.
    pub collisions: usize,
    /// Inner particles put back inside the outer layer in this step.
    pub contained: usize,
}

/// A running two-layer simulation: state `[x; v]`, an explicit integrator with its buffers,
/// collision box, energy bookkeeping for blow-up detection.
#[derive(Clone, Debug)]
pub struct TwoLayerSimulation {
    forces: TwoLayerForces,
    integrator: ExplicitIntegrator,
    state: Vec<f64>,
    time: f64,
    steps: usize,
    dt: f64,
    collision_box: Option<AxisBox>,
    restitution: f64,
    energy_initial: f64,
    work: f64,
    scale: f64,
    tolerance: f64,
    /// Keeps the inner layer inside the outer one (2D and 3D).
    containment: Option<LayerContainment>,
    last_collisions: usize,
    last_contained: usize,
}

impl TwoLayerSimulation {
    /// A simulation of `model` with `params` (a [`TwoLayerParams`], or anything that converts
    /// into one, such as the facade's body builder), starting at rest in its rest shape, stepped
    /// by `method` with time step `dt` (s).
    ///
    /// # Errors
    /// [`TwoLayerError::InvalidParameter`] for a non-positive `dt`, an invalid parameter, a
    /// model whose arrays do not fit together or a body that starts outside its collision box;
    /// [`TwoLayerError::Collision`] for an invalid box or restitution, or an outer layer that is
    /// not a closed oriented surface.
    pub fn new(
        model: TwoLayerModel,
        params: impl Into<TwoLayerParams>,
        method: ExplicitMethod,
        dt: f64,
    ) -> Result<Self, TwoLayerError> {
        TwoLayerError::check_positive("dt", dt)?;
        let body = params.into();
        body.validate()?;
        model.check()?;
        let n3 = 3 * model.num_particles();
        let mut state = model.rest_positions.clone();
        state.resize(2 * n3, 0.0);
        let n = model.layer_size;
        let containment = match model.dimension {
            Dimension::One => None,
            Dimension::Two => Some(LayerContainment::polygon(0, n, n)),
            Dimension::Three => Some(LayerContainment::surface(0, n, n, &model.surface)?),
        };
        let forces = TwoLayerForces::new(model, body);
        let mut sim = Self {
            integrator: ExplicitIntegrator::new(method),
            state,
            time: 0.0,
            steps: 0,
            dt,
            collision_box: body.collision_box,
            restitution: body.restitution,
            energy_initial: 0.0,
            work: 0.0,
            scale: forces.energy_scale(),
            tolerance: body.blowup_tolerance,
            containment,
            last_collisions: 0,
            last_contained: 0,
            forces,
        };
        if let Some(b) = sim.collision_box {
            let x = &sim.state[..n3];
            let outside = (0..x.len() / 3)
                .filter(|&i| !b.contains(&Point3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]), 0.0))
                .count();
            if outside > 0 {
                // Starting outside the box would mean a violent first projection; refuse.
                return Err(TwoLayerError::InvalidParameter {
                    name: "collision_box",
                    value: format!("{:?} .. {:?}", b.min, b.max),
                    reason: format!(
                        "{outside} particles of the body at rest lie outside the box; enlarge the box or move the centre"
                    ),
                });
            }
        }
        sim.energy_initial = sim.energies().total();
        sim.scale = sim.scale.max(sim.energy_initial.abs());
        Ok(sim)
    }

    /// The model.
    pub fn model(&self) -> &TwoLayerModel {
        self.forces.model()
    }

    /// The force system.
    pub fn forces(&self) -> &TwoLayerForces {
        &self.forces
    }

    /// Positions, flat `[x0, y0, z0, ...]` (m).
    pub fn positions(&self) -> &[f64] {
        &self.state[..self.state.len() / 2]
    }

    /// Velocities, flat (m/s).
    pub fn velocities(&self) -> &[f64] {
        &self.state[self.state.len() / 2..]
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps taken.
    pub fn step_count(&self) -> usize {
        self.steps
    }

    /// The time step (s).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// The integrator.
    pub fn method(&self) -> ExplicitMethod {
        self.integrator.method()
    }

    /// Total energy at the start (J).
    pub fn energy_initial(&self) -> f64 {
        self.energy_initial
    }

    /// Energy put in by setting or removing drag targets (J).
    pub fn work_done(&self) -> f64 {
        self.work
    }

    /// Energies of the current state.
    pub fn energies(&self) -> EnergyBreakdown {
        let (x, v) = self.state.split_at(self.state.len() / 2);
        self.forces.energies(x, v)
    }

    /// Sets the drag ("mouse") target while the simulation runs, or removes it with `None`
    /// (Song 2009, Sec. 4.4). The pulled particle is the outer particle nearest to the target now.
    /// The energy the drag spring stores at this moment counts as work done on the body.
    /// Returns the pulled particle.
    pub fn set_drag(&mut self, target: Option<DragTarget>) -> Result<Option<usize>, TwoLayerError> {
        if let Some(t) = &target {
            TwoLayerError::check_positive("drag stiffness", t.stiffness)?;
            TwoLayerError::check_non_negative("drag damping", t.damping)?;
            TwoLayerError::check_non_negative("drag rest length", t.rest_length)?;
            if !t.point.coords.iter().all(|c| c.is_finite()) {
                return Err(TwoLayerError::InvalidParameter {
                    name: "drag point",
                    value: format!("{:?}", t.point),
                    reason: "must be finite".into(),
                });
            }
        }
        let before = self.energies().drag;
        let n3 = self.state.len() / 2;
        let particle = self.forces.set_drag(target, &self.state[..n3]);
        self.work += self.energies().drag - before;
        Ok(particle)
    }

    /// Sets the loads of the following steps, replacing earlier ones: zero-length anchor
    /// springs `F = K (a - x)` (spring anchors and grabs) and constant external forces (N, flat,
    /// one triple per particle; `None` for none), added to the forces of every evaluation of
    /// the integrator. Their energy (`EnergyBreakdown::loads`: `1/2 K |x - a|^2 - F . x`) is
    /// part of the total, and the change it makes at this moment counts as work done on the
    /// body, as for the drag. Every particle must exist, every stiffness be positive and
    /// finite, every coordinate and force finite.
    ///
    /// ```
    /// use balloon_two_layer::{AnchorSpring, ExplicitMethod, TwoLayerModel, TwoLayerParams};
    /// use balloon_two_layer::TwoLayerSimulation;
    /// use nalgebra::Point3;
    /// // A 2D ring without gravity, its particle 0 held by a spring 1 m below where it is.
    /// let ring = TwoLayerModel::circle(12, Point3::origin(), [0.8, 1.0], [0.01, 0.01]);
    /// let params = TwoLayerParams { gravity: 0.0, ..TwoLayerParams::default() };
    /// let mut sim = TwoLayerSimulation::new(ring, params, ExplicitMethod::Rk4, 1e-3)?;
    /// let y0 = sim.positions()[1];
    /// let anchor = AnchorSpring { particle: 0, point: [sim.positions()[0], y0 - 1.0, 0.0], stiffness: 5.0 };
    /// sim.set_loads(vec![anchor], None)?;
    /// sim.run(50)?;
    /// assert!(sim.positions()[1] < y0); // pulled down
    /// assert!(sim.work_done() > 0.0); // the spring's 1/2 K (1 m)^2 counts as work
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn set_loads(
        &mut self,
        anchors: Vec<AnchorSpring>,
        external: Option<&[f64]>,
    ) -> Result<(), TwoLayerError> {
        let n3 = self.state.len() / 2;
        let n = n3 / 3;
        for a in &anchors {
            if a.particle >= n {
                return Err(TwoLayerError::InvalidParameter {
                    name: "anchor particle",
                    value: a.particle.to_string(),
                    reason: format!("the body has {n} particles"),
                });
            }
            TwoLayerError::check_positive("anchor stiffness", a.stiffness)?;
            if !a.point.iter().all(|c| c.is_finite()) {
                return Err(TwoLayerError::InvalidParameter {
                    name: "anchor point",
                    value: format!("{:?}", a.point),
                    reason: "must be finite".into(),
                });
            }
        }
        let external = external.map(<[f64]>::to_vec).unwrap_or_default();
        if !external.is_empty() && external.len() != n3 {
            return Err(TwoLayerError::InvalidParameter {
                name: "external forces",
                value: external.len().to_string(),
                reason: format!("expected {n3} components (3 per particle)"),
            });
        }
        if let Some(i) = external.iter().position(|f| !f.is_finite()) {
            return Err(TwoLayerError::InvalidParameter {
                name: "external forces",
                value: external[i].to_string(),
                reason: format!("the force on particle {} must be finite", i / 3),
            });
        }
        let before = self.energies().loads;
        self.forces.set_loads(anchors, external);
        self.work += self.energies().loads - before;
        Ok(())
    }

    /// Statistics of the current state.
    pub fn stats(&self) -> TwoLayerStats {
        let (x, v) = self.state.split_at(self.state.len() / 2);
        let m = self.model();
        let up = m.dimension.up_axis();
        let (volume_outer, volume_inner) = (m.layer_volume(x, true), m.layer_volume(x, false));
        let e = self
            .forces
            .energies_with_volumes(x, v, volume_outer, volume_inner);
        let pressure = |gas: f64, v: f64| if gas == 0.0 { 0.0 } else { gas / v };
        TwoLayerStats {
            step: self.steps,
            time: self.time,
            kinetic: e.kinetic,
            potential: e.potential(),
            total: e.total(),
            volume_outer,
            volume_inner,
            pressure_outer: pressure(m.gas_outer, volume_outer),
            pressure_inner: pressure(m.gas_inner, volume_inner),
            min_height: x
                .iter()
                .skip(up)
                .step_by(3)
                .copied()
                .fold(f64::INFINITY, f64::min),
            collisions: self.last_collisions,
            contained: self.last_contained,
        }
    }

    fn blow_up(&self, reason: BlowUpReason) -> TwoLayerError {
        let omega = self.forces.max_frequency_estimate();
        let limit = if omega > 0.0 { 1.0 / omega } else { self.dt };
        TwoLayerError::BlowUp {
            step: self.steps,
            time: self.time,
            method: self.method(),
            dt: self.dt,
            suggested_dt: (0.25 * self.dt).min(limit),
            reason,
        }
    }

    /// Advances one step: integrate all forces over `dt` (Song 2009, Sec. 4.7, Step 11), resolve
    /// box collisions and inner-layer containment (Step 12), then check for blow-up.
    ///
    /// Errors with [`TwoLayerError::BlowUp`] (naming the step, method and dt) when a coordinate
    /// becomes non-finite, a gas-filled layer inverts, or the total energy exceeds
    /// `initial + work + tolerance * scale`. The state is then left as it was after the failed
    /// step; earlier output stays valid.
    pub fn step(&mut self) -> Result<TwoLayerStats, TwoLayerError> {
        let n3 = self.state.len() / 2;
        self.integrator
            .step_second_order(&mut self.forces, self.time, self.dt, &mut self.state)?;
        self.time += self.dt;
        self.steps += 1;
        if let Some(i) = self.state.iter().position(|c| !c.is_finite()) {
            return Err(self.blow_up(BlowUpReason::NonFinite {
                particle: (i % n3) / 3,
                velocity: i >= n3,
            }));
        }
        let (x, v) = self.state.split_at_mut(n3);
        let m = self.forces.model();
        self.last_collisions = 0;
        self.last_contained = 0;
        if let Some(b) = &self.collision_box {
            self.last_collisions = collide_box(x, v, 0..m.num_particles(), b, self.restitution);
        }
        if let Some(c) = &mut self.containment {
            self.last_contained = c.contain(x, v, &m.masses, &m.fixed, self.restitution);
        }
        let stats = self.stats();
        let m = self.forces.model();
        for (vol, gas, name) in [
            (stats.volume_outer, m.gas_outer, "outer"),
            (stats.volume_inner, m.gas_inner, "inner"),
        ] {
            if gas > 0.0 && vol <= 0.0 {
                return Err(self.blow_up(BlowUpReason::InvertedLayer {
                    layer: name,
                    volume: vol,
                }));
            }
        }
        let bound = self.energy_initial + self.work + self.tolerance * self.scale;
        if !stats.total.is_finite() || stats.total > bound {
            return Err(self.blow_up(BlowUpReason::EnergyGrowth {
                total: stats.total,
                bound,
                initial: self.energy_initial,
                work: self.work,
                tolerance: self.tolerance,
                scale: self.scale,
            }));
        }
        Ok(stats)
    }

    /// Pins `particles` hard from now on: they become fixed particles of the model (as the top
    /// of the 1D spring, Song 2009, Sec. 3.3), with zero inverse mass and zero velocity, so every
    /// explicit method leaves their positions exactly as they are. Their springs still pull on
    /// their neighbours. Every particle must exist.
    ///
    /// ```
    /// use balloon_two_layer::{ExplicitMethod, TwoLayerModel, TwoLayerParams, TwoLayerSimulation};
    /// use nalgebra::Point3;
    /// let sphere = balloon_mesh::generate::uv_sphere(1.0, 8, 6)?;
    /// let model = TwoLayerModel::from_unit_sphere(sphere, Point3::origin(), [0.8, 1.0], [0.01, 0.01]);
    /// let mut sim = TwoLayerSimulation::new(model, TwoLayerParams::default(), ExplicitMethod::Rk4, 1e-3)?;
    /// let before = sim.positions()[..3].to_vec();
    /// sim.fix_particles(&[0])?;
    /// sim.run(50)?;
    /// assert_eq!(&sim.positions()[..3], &before[..]);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn fix_particles(&mut self, particles: &[usize]) -> Result<(), TwoLayerError> {
        let n = self.forces.model().num_particles();
        if let Some(&bad) = particles.iter().find(|&&i| i >= n) {
            return Err(TwoLayerError::InvalidParameter {
                name: "fixed particle",
                value: bad.to_string(),
                reason: format!("the body has {n} particles"),
            });
        }
        self.forces.fix(particles);
        let n3 = 3 * n;
        for &i in particles {
            self.state[n3 + 3 * i..n3 + 3 * i + 3].fill(0.0);
        }
        Ok(())
    }

    /// Takes `steps` steps and returns the last statistics.
    pub fn run(&mut self, steps: usize) -> Result<TwoLayerStats, TwoLayerError> {
        let mut last = self.stats();
        for _ in 0..steps {
            last = self.step()?;
        }
        Ok(last)
    }

    /// A mesh of the current shape for drawing (see [`TwoLayerModel::draw_triangles`]).
    pub fn draw_mesh(&self) -> TriMesh {
        let x = self.positions();
        let vertices = x
            .chunks_exact(3)
            .map(|c| Point3::new(c[0], c[1], c[2]))
            .collect();
        TriMesh::new(vertices, self.model().draw_triangles())
    }

    /// The closed outer (`outer = true`) or inner layer as its own mesh (3D only).
    pub fn layer_mesh(&self, outer: bool) -> Option<TriMesh> {
        let m = self.model();
        if m.dimension != Dimension::Three {
            return None;
        }
        let off = if outer { m.layer_size } else { 0 };
        let x = self.positions();
        let vertices = (off..off + m.layer_size)
            .map(|i| Point3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]))
            .collect();
        Some(TriMesh::new(vertices, m.surface.clone()))
    }

    /// Particles that escaped: any particle outside the collision box (by more than 1e-9 m)
    /// plus inner particles outside the outer layer by the exact winding-number test
    /// ([`winding_number`] < 1/2; cost `O(n^2)`, meant for summaries, not every step).
    pub fn escaped_particles(&self) -> usize {
        let x = self.positions();
        let m = self.model();
        let p = |i: usize| Point3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
        let mut count = 0;
        if let Some(b) = &self.collision_box {
            count += (0..m.num_particles())
                .filter(|&i| !b.contains(&p(i), 1e-9))
                .count();
        }
        let n = m.layer_size;
        count += (0..n)
            .filter(|&i| {
                let w = match m.dimension {
                    Dimension::Three => winding_number(&p(i), x, n, &m.surface),
                    _ => polygon_winding_number(&p(i), x, n, n),
                };
                w < 0.5
            })
            .count();
        count
    }
}

impl TwoLayerSimulation {
    /// Sets the drag spring (Song 2009, Sec. 4.4, Eq. 4.7) on a chosen particle instead of the one
    /// nearest to the target (what the live viewer needs: the user picks a vertex, then moves the
    /// target). The particle must be an outer-layer particle (a free particle in 1D) that is not
    /// fixed. The work bookkeeping is that of [`TwoLayerSimulation::set_drag`]. Returns the
    /// particle.
    pub fn set_drag_particle(
        &mut self,
        particle: usize,
        target: DragTarget,
    ) -> Result<usize, TwoLayerError> {
        let m = self.forces.model();
        let allowed = if m.has_layers() {
            m.layer_size..2 * m.layer_size
        } else {
            0..m.num_particles()
        };
        if !allowed.contains(&particle) || m.fixed[particle] {
            return Err(TwoLayerError::InvalidParameter {
                name: "drag particle",
                value: particle.to_string(),
                reason: format!(
                    "must be a free particle of the outer layer ({}..{})",
                    allowed.start, allowed.end
                ),
            });
        }
        TwoLayerError::check_positive("drag stiffness", target.stiffness)?;
        TwoLayerError::check_non_negative("drag damping", target.damping)?;
        TwoLayerError::check_non_negative("drag rest length", target.rest_length)?;
        if !target.point.coords.iter().all(|c| c.is_finite()) {
            return Err(TwoLayerError::InvalidParameter {
                name: "drag point",
                value: format!("{:?}", target.point),
                reason: "must be finite".into(),
            });
        }
        // `TwoLayerForces::set_drag` picks the particle nearest to the target: hand it a copy
        // of the positions with the chosen particle on the target, so that particle is picked.
        let n3 = self.state.len() / 2;
        let mut probe = self.state[..n3].to_vec();
        for (c, p) in probe[3 * particle..3 * particle + 3]
            .iter_mut()
            .zip(target.point.iter())
        {
            *c = *p;
        }
        let before = self.energies().drag;
        let previous = self.forces.drag();
        let picked = self.forces.set_drag(Some(target), &probe);
        if picked != Some(particle) {
            // Another particle sits exactly on the target: keep the previous drag.
            let restore = previous.map(|(t, i)| {
                let mut x = self.state[..n3].to_vec();
                x[3 * i..3 * i + 3].copy_from_slice(t.point.coords.as_slice());
                (t, x)
            });
            match restore {
                Some((t, x)) => self.forces.set_drag(Some(t), &x),
                None => self.forces.set_drag(None, &probe),
            };
            return Err(TwoLayerError::InvalidParameter {
                name: "drag particle",
                value: particle.to_string(),
                reason: "another particle lies exactly on the target".into(),
            });
        }
        // The energy the spring stores now (real positions) is work done on the body.
        self.work += self.energies().drag - before;
        Ok(particle)
    }

    /// Changes the integration method for the following steps (Song 2009, Ch. 5).
    pub fn set_method(&mut self, method: ExplicitMethod) {
        self.integrator.set_method(method);
    }

    /// Changes the time step (s, positive and finite) for the following steps.
    pub fn set_dt(&mut self, dt: f64) -> Result<(), TwoLayerError> {
        self.dt = TwoLayerError::check_positive("dt", dt)?;
        Ok(())
    }
}
