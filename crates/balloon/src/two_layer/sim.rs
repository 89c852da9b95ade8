//! Time stepping of a two-layer object: integrate (seed Ch. 5), collide (seed Sec. 4.6), check
//! for blow-up, report.

use super::containment::LayerContainment;
use super::forces::{AnchorSpring, DragTarget, EnergyBreakdown, TwoLayerForces};
use super::model::{Dimension, TwoLayerBody, TwoLayerModel};
use super::{BlowUpReason, TwoLayerError, non_negative, positive};
use balloon_constraint::two_layer::{AxisBox, collide_box, polygon_winding_number, winding_number};
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

impl TwoLayerBody {
    /// Builds the body and a simulation of it at rest with `method` and time step `dt` (s).
    pub fn simulate(
        &self,
        method: ExplicitMethod,
        dt: f64,
    ) -> Result<TwoLayerSimulation, TwoLayerError> {
        TwoLayerSimulation::new(self, method, dt)
    }
}

impl TwoLayerSimulation {
    /// A simulation of `body` starting at rest in its rest shape.
    pub fn new(
        body: &TwoLayerBody,
        method: ExplicitMethod,
        dt: f64,
    ) -> Result<Self, TwoLayerError> {
        positive("dt", dt)?;
        let model = body.build()?;
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
    /// (seed Sec. 4.4). The pulled particle is the outer particle nearest to the target now.
    /// The energy the drag spring stores at this moment counts as work done on the body.
    /// Returns the pulled particle.
    pub fn set_drag(&mut self, target: Option<DragTarget>) -> Result<Option<usize>, TwoLayerError> {
        if let Some(t) = &target {
            positive("drag stiffness", t.stiffness)?;
            non_negative("drag damping", t.damping)?;
            non_negative("drag rest length", t.rest_length)?;
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
    /// use balloon::two_layer::{AnchorSpring, ExplicitMethod, TwoLayerBody};
    /// // A 2D ring without gravity, its particle 0 held by a spring 1 m below where it is.
    /// let mut sim = TwoLayerBody::circle(12).with_gravity(0.0).simulate(ExplicitMethod::Rk4, 1e-3)?;
    /// let y0 = sim.positions()[1];
    /// let anchor = AnchorSpring { particle: 0, point: [sim.positions()[0], y0 - 1.0, 0.0], stiffness: 5.0 };
    /// sim.set_loads(vec![anchor], None)?;
    /// sim.run(50)?;
    /// assert!(sim.positions()[1] < y0); // pulled down
    /// assert!(sim.work_done() > 0.0); // the spring's 1/2 K (1 m)^2 counts as work
    /// # Ok::<(), balloon::two_layer::TwoLayerError>(())
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
            positive("anchor stiffness", a.stiffness)?;
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

    /// Advances one step: integrate all forces over `dt` (seed Sec. 4.7, Step 11), resolve box
    /// collisions and inner-layer containment (Step 12), then check for blow-up.
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
    /// of the 1D spring, seed Sec. 3.3), with zero inverse mass and zero velocity, so every
    /// explicit method leaves their positions exactly as they are. Their springs still pull on
    /// their neighbours. Every particle must exist.
    ///
    /// ```
    /// use balloon::two_layer::{ExplicitMethod, TwoLayerBody};
    /// let mut sim = TwoLayerBody::uv_sphere(8, 6).simulate(ExplicitMethod::Rk4, 1e-3)?;
    /// let before = sim.positions()[..3].to_vec();
    /// sim.fix_particles(&[0])?;
    /// sim.run(50)?;
    /// assert_eq!(&sim.positions()[..3], &before[..]);
    /// # Ok::<(), balloon::two_layer::TwoLayerError>(())
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
    /// Sets the drag spring (seed Sec. 4.4, Eq. 4.7) on a chosen particle instead of the one
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
        positive("drag stiffness", target.stiffness)?;
        non_negative("drag damping", target.damping)?;
        non_negative("drag rest length", target.rest_length)?;
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

    /// Changes the integration method for the following steps (seed Ch. 5).
    pub fn set_method(&mut self, method: ExplicitMethod) {
        self.integrator.set_method(method);
    }

    /// Changes the time step (s, positive and finite) for the following steps.
    pub fn set_dt(&mut self, dt: f64) -> Result<(), TwoLayerError> {
        self.dt = positive("dt", dt)?;
        Ok(())
    }
}

#[cfg(test)]
mod viewer_api_tests {
    use super::*;
    use nalgebra::Vector3;

    fn sphere() -> TwoLayerSimulation {
        TwoLayerBody::octahedron_sphere(1)
            .with_radii(0.8, 1.0)
            .with_pressure(200.0, 200.0)
            .with_gravity(0.0)
            .simulate(ExplicitMethod::Rk4, 1e-3)
            .unwrap()
    }

    fn pos(sim: &TwoLayerSimulation, i: usize) -> Vector3<f64> {
        let x = sim.positions();
        Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
    }

    #[test]
    fn drag_on_a_chosen_particle_pulls_it_towards_the_target() {
        let mut sim = sphere();
        let n = sim.model().layer_size;
        let particle = n + 3;
        let start = pos(&sim, particle);
        // A target beyond the particle, farther from it than from several other particles'
        // positions would not matter: the chosen particle is the one pulled.
        let target = Point3::from(start * 1.6);
        let drag = DragTarget {
            point: target,
            stiffness: 50.0,
            damping: 0.5,
            rest_length: 0.0,
        };
        assert_eq!(sim.set_drag_particle(particle, drag).unwrap(), particle);
        assert_eq!(sim.forces().drag().map(|(_, i)| i), Some(particle));
        assert!(sim.work_done() > 0.0);
        let d0 = (target.coords - start).norm();
        sim.run(200).unwrap();
        let d1 = (target.coords - pos(&sim, particle)).norm();
        assert!(d1 < 0.8 * d0, "distance to the target {d0} -> {d1}");
        // Moving the target keeps the same particle even when another one is nearer to it.
        let other = pos(&sim, n + 10);
        let moved = DragTarget {
            point: Point3::from(other + Vector3::new(1e-3, 0.0, 0.0)),
            ..drag
        };
        sim.set_drag_particle(particle, moved).unwrap();
        assert_eq!(sim.forces().drag().map(|(_, i)| i), Some(particle));
    }

    #[test]
    fn bad_drag_particles_and_dt_are_rejected() {
        let mut sim = sphere();
        let n = sim.model().layer_size;
        let drag = DragTarget {
            point: Point3::new(0.0, 0.0, 2.0),
            stiffness: 50.0,
            damping: 0.0,
            rest_length: 0.0,
        };
        let e = sim.set_drag_particle(0, drag).unwrap_err().to_string();
        assert!(e.contains("outer layer"), "{e}");
        assert!(sim.set_drag_particle(2 * n, drag).is_err());
        let bad = DragTarget {
            stiffness: -1.0,
            ..drag
        };
        assert!(sim.set_drag_particle(n, bad).is_err());
        // A particle already on the target of another: the target is at particle n + 1.
        let on = DragTarget {
            point: Point3::from(pos(&sim, n + 1)),
            ..drag
        };
        assert!(sim.set_drag_particle(n + 2, on).is_err());
        assert!(sim.forces().drag().is_none());
        assert!(sim.set_dt(0.0).is_err());
        sim.set_dt(5e-4).unwrap();
        assert_eq!(sim.dt(), 5e-4);
        sim.set_method(ExplicitMethod::Symplectic);
        assert_eq!(sim.method(), ExplicitMethod::Symplectic);
        sim.step().unwrap();
    }
}

#[cfg(test)]
mod tests {
    use super::super::model::SpringKind;
    use super::*;
    use balloon_mesh::generate::octahedron_sphere;
    use nalgebra::Vector3;

    fn centroid(x: &[f64], range: std::ops::Range<usize>) -> Vector3<f64> {
        let n = range.len() as f64;
        range
            .map(|i| Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]))
            .sum::<Vector3<f64>>()
            / n
    }

    fn mean_radius(x: &[f64], range: std::ops::Range<usize>) -> f64 {
        let c = centroid(x, range.clone());
        let n = range.len() as f64;
        range
            .map(|i| (Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]) - c).norm())
            .sum::<f64>()
            / n
    }

    /// The 1D hanging spring (seed Sec. 3.3) released from its rest length is a harmonic
    /// oscillator about `L + m g / k`: `x(t) = -L - (m g / k)(1 - cos(omega t))`. The global
    /// error at t = 1 s must fall with the method's order (Euler and symplectic 1, midpoint 2,
    /// RK4 4), fitted over four time steps within +-0.3.
    #[test]
    fn hanging_spring_converges_with_the_order_of_each_method() {
        let (mass, k, g, length): (f64, f64, f64, f64) = (1.0, 100.0, 9.81, 0.5);
        let omega = (k / mass).sqrt();
        for method in ExplicitMethod::ALL {
            let mut pts = Vec::new();
            for dt in [0.004f64, 0.002, 0.001, 0.0005] {
                let body = TwoLayerBody::line(length)
                    .with_masses(mass, mass)
                    .with_spring(SpringKind::Structural, k, 0.0)
                    .with_gravity(g);
                let mut sim = body.simulate(method, dt).unwrap();
                let steps = (1.0 / dt).round() as usize;
                sim.run(steps).unwrap();
                let t = sim.time();
                let exact = -length - mass * g / k * (1.0 - (omega * t).cos());
                let exact_v = -mass * g / k * omega * (omega * t).sin();
                let err = ((sim.positions()[3] - exact).powi(2)
                    + ((sim.velocities()[3] - exact_v) / omega).powi(2))
                .sqrt();
                // The fixed end never moves and nothing leaves the x axis.
                assert_eq!(&sim.positions()[0..3], &[0.0, 0.0, 0.0]);
                assert_eq!(&sim.positions()[4..6], &[0.0, 0.0]);
                pts.push((dt, err));
            }
            let n = pts.len() as f64;
            let mx = pts.iter().map(|p| p.0.ln()).sum::<f64>() / n;
            let my = pts.iter().map(|p| p.1.ln()).sum::<f64>() / n;
            let slope = pts
                .iter()
                .map(|p| (p.0.ln() - mx) * (p.1.ln() - my))
                .sum::<f64>()
                / pts.iter().map(|p| (p.0.ln() - mx).powi(2)).sum::<f64>();
            assert!(
                (slope - method.order() as f64).abs() < 0.3,
                "{method}: fitted order {slope:.3} (errors {pts:?})"
            );
        }
    }

    fn free_sphere() -> TwoLayerBody {
        TwoLayerBody::octahedron_sphere(1)
            .with_radii(0.7, 1.0)
            .with_pressure(40.0, 20.0)
            .with_damping(0.0)
    }

    /// Largest deviation of the total energy from its initial value over 1.5 s, and the largest
    /// kinetic energy seen.
    fn energy_drift(body: &TwoLayerBody, method: ExplicitMethod, dt: f64) -> (f64, f64) {
        let mut sim = body.simulate(method, dt).unwrap();
        let e0 = sim.energies().total();
        let (mut drift, mut kmax) = (0.0f64, 0.0f64);
        for _ in 0..(1.5 / dt).round() as usize {
            let s = sim.step().unwrap();
            drift = drift.max((s.total - e0).abs());
            kmax = kmax.max(s.kinetic);
        }
        (drift, kmax)
    }

    /// Without damping and collisions all forces are conservative (gravity, springs, gas), so
    /// the total energy is constant up to the integrator's error: RK4's drift is tiny and
    /// falls at least 16x when dt halves; symplectic Euler's stays bounded. Momentum: internal
    /// springs and the pressure of closed layers exert no net force, so with no gravity the
    /// centre of mass stays put.
    #[test]
    fn undamped_energy_is_conserved_and_momentum_without_gravity() {
        let body = free_sphere();
        let (d1, kmax) = energy_drift(&body, ExplicitMethod::Rk4, 1e-3);
        let (d2, _) = energy_drift(&body, ExplicitMethod::Rk4, 5e-4);
        // The gas inflates the body: the motion is not trivial.
        assert!(kmax > 1.0, "kinetic energy peak {kmax}");
        assert!(
            d2 < 1e-4 * kmax,
            "RK4 drift {d2:.3e} J vs kinetic peak {kmax:.3e} J"
        );
        assert!(
            d1 / d2 > 16.0,
            "RK4 drift must fall >= 16x per halving: {d1:.3e} -> {d2:.3e}"
        );
        let (ds, _) = energy_drift(&body, ExplicitMethod::Symplectic, 2.5e-4);
        assert!(ds < 0.05 * kmax, "symplectic Euler drift {ds:.3e} J");
        let mut sim = free_sphere()
            .with_gravity(0.0)
            .simulate(ExplicitMethod::Rk4, 1e-3)
            .unwrap();
        sim.run(500).unwrap();
        let n = sim.model().num_particles();
        let mut p = Vector3::zeros();
        for i in 0..n {
            p += Vector3::new(
                sim.velocities()[3 * i],
                sim.velocities()[3 * i + 1],
                sim.velocities()[3 * i + 2],
            ) * sim.model().masses[i];
        }
        assert!(p.norm() < 1e-10, "momentum {p}");
        assert!(centroid(sim.positions(), 0..n).norm() < 1e-10);
    }

    /// Radial force balance of the 2D two-layer N-gon (derivation in docs/two-layer.md): with
    /// inner radius `a` and outer `b`, structural sides `2 r sin(pi/N)`, radius springs `b - a`,
    /// shear springs `l = sqrt(a^2 + b^2 - 2ab cos(2pi/N))`, and gas energy `-c ln(A)` with
    /// `A ~ r^2`, the equilibrium solves `dU/da = dU/db = 0`. A damped simulation must settle
    /// there.
    #[test]
    fn pressurised_circle_settles_at_analytic_radii() {
        let (nn, a0, b0) = (12usize, 0.6, 1.0);
        let (ks, kr, ksh) = (100.0, 50.0, 40.0);
        let (p_out, p_in) = (150.0, 80.0);
        let body = TwoLayerBody::circle(nn)
            .with_radii(a0, b0)
            .with_spring(SpringKind::Structural, ks, 0.4)
            .with_spring(SpringKind::Radius, kr, 0.4)
            .with_spring(SpringKind::ShearLeft, ksh, 0.4)
            .with_spring(SpringKind::ShearRight, ksh, 0.4)
            .with_pressure(p_out, p_in)
            .with_gravity(0.0);
        let (a, b) = crate::two_layer::analytic::CircleBody {
            particles: nn,
            inner_radius: a0,
            outer_radius: b0,
            structural: ks,
            radius: kr,
            shear: ksh,
            outer_pressure: p_out,
            inner_pressure: p_in,
        }
        .equilibrium_radii()
        .expect("Newton converges");
        assert!(
            b > 1.05 * b0,
            "pressure should inflate the body noticeably (b = {b})"
        );
        let mut sim = body.simulate(ExplicitMethod::Rk4, 1e-3).unwrap();
        sim.run(4000).unwrap();
        let x = sim.positions();
        let (ra, rb) = (mean_radius(x, 0..nn), mean_radius(x, nn..2 * nn));
        assert!(
            (ra - a).abs() < 1e-4 * a,
            "inner radius {ra} vs analytic {a}"
        );
        assert!(
            (rb - b).abs() < 1e-4 * b,
            "outer radius {rb} vs analytic {b}"
        );
        assert!(sim.energies().kinetic < 1e-8);
    }

    /// 3D: the octahedron sphere with gas settles at the radial force balance. The potential
    /// over uniform scalings `(a, b)` of the two layers is computed here independently from the
    /// mesh and minimised by Newton (the 1D radial root find of `docs/two-layer.md`, done for
    /// both layers). The model's energy must agree with it on scaled shapes; the simulated
    /// equilibrium must have a lower energy (it minimises over all shapes) and lie within 2%
    /// of the predicted radii (the valence-4 kernel points bulge a little, seed Sec. 3.5.3).
    #[test]
    fn pressurised_sphere_settles_at_radial_force_balance() {
        let (a0, b0, level) = (0.7, 1.0, 2u32);
        let (ks, kr, ksh, p_out, p_in) = (100.0, 60.0, 40.0, 120.0, 60.0);
        let body = TwoLayerBody::octahedron_sphere(level)
            .with_radii(a0, b0)
            .with_spring(SpringKind::Structural, ks, 0.3)
            .with_spring(SpringKind::Radius, kr, 0.3)
            .with_spring(SpringKind::ShearLeft, ksh, 0.3)
            .with_spring(SpringKind::ShearRight, ksh, 0.3)
            .with_pressure(p_out, p_in)
            .with_gravity(0.0);
        let unit = octahedron_sphere(1.0, level).unwrap();
        let u: Vec<Vector3<f64>> = unit.vertices.iter().map(|p| p.coords).collect();
        let mut edges = std::collections::BTreeSet::new();
        for t in &unit.triangles {
            for k in 0..3 {
                let (i, j) = (t[k], t[(k + 1) % 3]);
                edges.insert((i.min(j), i.max(j)));
            }
        }
        let v_unit: f64 = unit
            .triangles
            .iter()
            .map(|t| u[t[0]].dot(&u[t[1]].cross(&u[t[2]])) / 6.0)
            .sum();
        let (c_out, c_in) = (p_out * v_unit * b0.powi(3), p_in * v_unit * a0.powi(3));
        let energy = |a: f64, b: f64| {
            let mut e = 0.0;
            for &(i, j) in &edges {
                let d = (u[i] - u[j]).norm();
                e += 0.5 * ks * d * d * ((a - a0).powi(2) + (b - b0).powi(2));
                let l = (u[j] * b - u[i] * a).norm();
                let l0 = (u[j] * b0 - u[i] * a0).norm();
                e += 2.0 * 0.5 * ksh * (l - l0).powi(2);
            }
            e += u.len() as f64 * 0.5 * kr * ((b - a) - (b0 - a0)).powi(2);
            e - c_in * 3.0 * (a / a0).ln() - c_out * 3.0 * (b / b0).ln()
        };
        let grad = |a: f64, b: f64| {
            let h = 1e-6;
            [
                (energy(a + h, b) - energy(a - h, b)) / (2.0 * h),
                (energy(a, b + h) - energy(a, b - h)) / (2.0 * h),
            ]
        };
        let (mut a, mut b) = (a0, b0);
        for _ in 0..40 {
            let g = grad(a, b);
            let h = 1e-5;
            let (ga, gb) = (grad(a + h, b), grad(a, b + h));
            let (gam, gbm) = (grad(a - h, b), grad(a, b - h));
            let j = [
                [(ga[0] - gam[0]) / (2.0 * h), (gb[0] - gbm[0]) / (2.0 * h)],
                [(ga[1] - gam[1]) / (2.0 * h), (gb[1] - gbm[1]) / (2.0 * h)],
            ];
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            a -= (j[1][1] * g[0] - j[0][1] * g[1]) / det;
            b -= (-j[1][0] * g[0] + j[0][0] * g[1]) / det;
        }
        assert!(
            b > 1.05 * b0,
            "pressure should inflate the body noticeably (b = {b})"
        );
        let mut sim = body.simulate(ExplicitMethod::Rk4, 1e-3).unwrap();
        let n = sim.model().layer_size;
        let scaled: Vec<f64> = sim
            .model()
            .rest_positions
            .iter()
            .enumerate()
            .map(|(k, x)| x * if k < 3 * n { a / a0 } else { b / b0 })
            .collect();
        let zero = vec![0.0; scaled.len()];
        let u_scaled = sim.forces().energies(&scaled, &zero).potential();
        assert!(
            (u_scaled - energy(a, b)).abs() < 1e-9 * energy(a, b).abs(),
            "model energy {u_scaled} vs independent {}",
            energy(a, b)
        );
        sim.run(3000).unwrap();
        let x = sim.positions();
        let (ra, rb) = (mean_radius(x, 0..n), mean_radius(x, n..2 * n));
        assert!(
            (rb - b).abs() < 0.02 * b,
            "outer radius {rb} vs predicted {b}"
        );
        assert!(
            (ra - a).abs() < 0.02 * a,
            "inner radius {ra} vs predicted {a}"
        );
        assert!(sim.energies().kinetic < 1e-8);
        assert!(sim.energies().potential() <= u_scaled + 1e-9 * u_scaled.abs());
        // A static equilibrium: the net force on every particle vanishes.
        let mut f = vec![0.0; x.len()];
        let mut forces = sim.forces().clone();
        forces.forces_into(x, &zero, &mut f);
        let worst = f.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        assert!(worst < 1e-6, "residual force {worst:.3e} N");
    }

    /// A body dropped in a box with damped collisions comes to rest on the floor: the floor
    /// removes kinetic energy at every bounce and the spring damping the vibrations; no
    /// particle leaves the box and no inner particle leaves the outer layer.
    #[test]
    fn dropped_body_comes_to_rest_on_the_floor() {
        let floor = -1.3;
        let bbox =
            AxisBox::try_new(Point3::new(-2.0, -2.0, floor), Point3::new(2.0, 2.0, 2.0)).unwrap();
        let body = TwoLayerBody::octahedron_sphere(1)
            .with_radii(0.7, 1.0)
            .with_pressure(30.0, 15.0)
            .with_damping(1.0)
            .with_box(Some(bbox))
            .with_restitution(0.3);
        let mut sim = body.simulate(ExplicitMethod::Rk4, 5e-4).unwrap();
        let mut touched = false;
        for _ in 0..6000 {
            let s = sim.step().unwrap();
            touched |= s.collisions > 0;
        }
        let s = sim.stats();
        assert!(touched);
        assert!(
            s.kinetic < 1e-5,
            "still moving: kinetic {:.3e} J",
            s.kinetic
        );
        assert!(
            (s.min_height - floor).abs() < 1e-3,
            "min height {}",
            s.min_height
        );
        assert!(
            s.total < sim.energy_initial(),
            "energy must have been dissipated"
        );
        assert_eq!(sim.escaped_particles(), 0);
        let n = sim.model().layer_size;
        // Resting on the floor, the body is squashed but still holds its gas.
        assert!(s.volume_outer > 0.7 * sim.model().rest_volume_outer);
        // It fell from its start (centre at z = 0) and sits above the floor.
        let cz = centroid(sim.positions(), n..2 * n).z;
        assert!(cz < -0.1 && cz > floor + 0.5, "centre height {cz}");
    }

    /// The drag spring pulls the nearest outer particle, and with it the body, toward the
    /// target; removing it leaves the body free.
    #[test]
    fn drag_moves_the_body_toward_the_target() {
        let body = TwoLayerBody::octahedron_sphere(1)
            .with_pressure(200.0, 100.0)
            .with_damping(0.2)
            .with_gravity(0.0);
        let mut sim = body.simulate(ExplicitMethod::Rk4, 1e-3).unwrap();
        let target = Point3::new(4.0, 0.0, 0.0);
        let pulled = sim
            .set_drag(Some(DragTarget {
                point: target,
                stiffness: 5.0,
                damping: 0.1,
                rest_length: 0.0,
            }))
            .unwrap()
            .unwrap();
        let n = sim.model().layer_size;
        assert_eq!(
            pulled, n,
            "outer particle 0 at (1, 0, 0) is nearest to the target"
        );
        assert!(sim.work_done() > 0.0);
        let c0 = centroid(sim.positions(), 0..2 * n);
        let d0 = (Vector3::new(sim.positions()[3 * pulled], 0.0, 0.0) - target.coords).norm();
        sim.run(1000).unwrap();
        let c1 = centroid(sim.positions(), 0..2 * n);
        let d1 = (Vector3::new(sim.positions()[3 * pulled], 0.0, 0.0) - target.coords).norm();
        assert!(c1.x > c0.x + 0.05, "centre moved {} -> {}", c0.x, c1.x);
        assert!(d1 < d0);
        assert!(
            c1.y.abs() < 1e-6 && c1.z.abs() < 1e-6,
            "pulled straight along x"
        );
        assert_eq!(sim.set_drag(None).unwrap(), None);
        assert!(sim.forces().drag().is_none());
        assert!(
            sim.set_drag(Some(DragTarget {
                point: target,
                stiffness: -1.0,
                damping: 0.0,
                rest_length: 0.0
            }))
            .is_err()
        );
    }

    #[test]
    fn invalid_parameters_are_errors_naming_the_parameter() {
        let check = |body: TwoLayerBody, dt: f64, name: &str| {
            let msg = body
                .simulate(ExplicitMethod::Rk4, dt)
                .expect_err("must fail")
                .to_string();
            assert!(msg.contains(name), "`{msg}` should name `{name}`");
        };
        let b = || TwoLayerBody::octahedron_sphere(1);
        check(b().with_masses(0.0, 1.0), 1e-3, "inner_mass");
        check(b().with_masses(1.0, -1.0), 1e-3, "outer_mass");
        check(b().with_radii(-0.1, 1.0), 1e-3, "inner_radius");
        check(
            b().with_radii(1.0, 1.0),
            1e-3,
            "must be below the outer radius",
        );
        check(b().with_radii(0.5, f64::NAN), 1e-3, "outer_radius");
        check(b(), 0.0, "dt");
        check(b(), -1e-3, "dt");
        check(
            b().with_spring(SpringKind::Radius, 0.0, 0.1),
            1e-3,
            "radius stiffness",
        );
        check(
            b().with_spring(SpringKind::ShearLeft, 1.0, -0.1),
            1e-3,
            "shear-left damping",
        );
        check(b().with_pressure(-1.0, 0.0), 1e-3, "outer_pressure");
        check(b().with_restitution(1.5), 1e-3, "restitution");
        check(TwoLayerBody::circle(2), 1e-3, "particles");
        check(TwoLayerBody::uv_sphere(2, 4), 1e-3, "slices");
        check(TwoLayerBody::octahedron_sphere(9), 1e-3, "level");
        check(TwoLayerBody::line(0.0), 1e-3, "length");
        let small = AxisBox::try_new(Point3::new(-0.5, -0.5, -0.5), Point3::new(0.5, 0.5, 0.5));
        check(b().with_box(Some(small.unwrap())), 1e-3, "collision_box");
    }

    /// Stiff springs at a large step: the explicit integrators leave their stability region,
    /// and the step reports a blow-up that names the step, integrator and dt.
    #[test]
    fn unstable_step_is_detected_as_blow_up() {
        for method in ExplicitMethod::ALL {
            let body = TwoLayerBody::octahedron_sphere(1)
                .with_spring(SpringKind::Structural, 1e5, 0.0)
                .with_pressure(100.0, 0.0);
            let mut sim = body.simulate(method, 5e-3).unwrap();
            let err = sim.run(2000).expect_err("must blow up");
            let msg = err.to_string();
            match err {
                TwoLayerError::BlowUp {
                    step,
                    dt,
                    suggested_dt,
                    reason,
                    ..
                } => {
                    assert!((1..2000).contains(&step));
                    assert_eq!(dt, 5e-3);
                    assert!(suggested_dt < dt);
                    // The reason carries its numbers and the message states them.
                    match reason {
                        BlowUpReason::NonFinite { particle, .. } => {
                            assert!(particle < sim.forces.model().num_particles())
                        }
                        BlowUpReason::InvertedLayer { volume, .. } => assert!(volume <= 0.0),
                        BlowUpReason::EnergyGrowth { total, bound, .. } => {
                            assert!(total > bound || !total.is_finite(), "{total} {bound}")
                        }
                    }
                    assert!(msg.contains(&format!(": {reason}; ")), "{msg}");
                }
                other => panic!("unexpected error {other}"),
            }
            assert!(
                msg.contains(method.name()) && msg.contains("smaller dt"),
                "{msg}"
            );
        }
        // The same body at a small step is fine.
        let body = TwoLayerBody::octahedron_sphere(1)
            .with_spring(SpringKind::Structural, 1e5, 0.0)
            .with_pressure(100.0, 0.0);
        let mut sim = body.simulate(ExplicitMethod::Rk4, 1e-4).unwrap();
        sim.run(200).unwrap();
    }

    /// 2D: the two-layer circle dropped on the floor of a box (gravity along -y) comes to rest
    /// on it with every particle in the box and the inner polygon inside the outer one; the same
    /// with valence normalisation on a 3D sphere stays stable and bounded.
    #[test]
    fn circle_rests_on_the_floor_and_normalised_sphere_is_stable() {
        let floor = -1.5;
        let bbox =
            AxisBox::try_new(Point3::new(-3.0, floor, -1.0), Point3::new(3.0, 3.0, 1.0)).unwrap();
        // 18 particles: the lowest point is a side, not a vertex (a polygon balanced on a
        // vertex is an unstable equilibrium and would roll away on the frictionless floor).
        let body = TwoLayerBody::circle(18)
            .with_radii(0.7, 1.0)
            .with_pressure(30.0, 15.0)
            .with_damping(1.0)
            .with_box(Some(bbox))
            .with_restitution(0.0);
        let mut sim = body.simulate(ExplicitMethod::Rk4, 5e-4).unwrap();
        sim.run(16000).unwrap();
        let s = sim.stats();
        // The inflated 2D body keeps a slow, weakly damped wobble: allow 0.1% of the fall energy.
        let fall = sim.model().masses.iter().sum::<f64>() * 9.81 * 0.5;
        assert!(s.kinetic < 1e-3 * fall, "kinetic {:.3e} J", s.kinetic);
        assert!((s.min_height - floor).abs() < 1e-3);
        assert_eq!(sim.escaped_particles(), 0);
        assert!(sim.positions().iter().skip(2).step_by(3).all(|z| *z == 0.0));
        let body = TwoLayerBody::octahedron_sphere(2)
            .with_valence_normalization(true)
            .with_pressure(50.0, 25.0)
            .with_box(Some(
                AxisBox::try_new(Point3::new(-2.0, -2.0, -1.2), Point3::new(2.0, 2.0, 2.0))
                    .unwrap(),
            ));
        let mut sim = body.simulate(ExplicitMethod::Rk4, 1e-3).unwrap();
        sim.run(1000).unwrap();
        assert_eq!(sim.escaped_particles(), 0);
    }

    #[test]
    fn builders_make_the_seed_spring_layout() {
        // 2D (seed Sec. 3.4.2): N structural springs per layer, N radius, N left and N right
        // shear springs; 2N drawing triangles.
        let m = TwoLayerBody::circle(12).build().unwrap();
        assert_eq!(m.num_particles(), 24);
        assert_eq!(m.spring_counts(), [24, 12, 12, 12]);
        assert_eq!(m.draw_triangles().len(), 24);
        assert!(
            (m.rest_volume_outer - 0.5 * 12.0 * (std::f64::consts::TAU / 12.0).sin()).abs() < 1e-12
        );
        // 3D octahedron level 1: V = 18, E = 48, F = 32 per layer (Euler: V - E + F = 2).
        let m = TwoLayerBody::octahedron_sphere(1).build().unwrap();
        assert_eq!(m.layer_size, 18);
        assert_eq!(m.spring_counts(), [96, 18, 48, 48]);
        assert_eq!(m.draw_triangles().len(), 64);
        // UV sphere: slices * (stacks - 1) + 2 particles per layer.
        let m = TwoLayerBody::uv_sphere(8, 6).build().unwrap();
        assert_eq!(m.layer_size, 8 * 5 + 2);
        // Rest lengths are the rest distances: the body at rest carries no spring force.
        let body = TwoLayerBody::uv_sphere(8, 6).with_gravity(0.0);
        let m = body.build().unwrap();
        let mut f = vec![0.0; m.rest_positions.len()];
        TwoLayerForces::new(m.clone(), &body).forces_into(
            &m.rest_positions,
            &vec![0.0; f.len()],
            &mut f,
        );
        assert!(f.iter().all(|c| c.abs() < 1e-12));
    }
}
