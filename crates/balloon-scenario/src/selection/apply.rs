//! What the runs do with selections: anchors (hard pins or springs to the rest positions) and
//! loads scheduled in time, set on a shell, a volumetric body or a two-layer body, and updated
//! before each step.
//!
//! An anchor holds its vertices where they are at rest: hard (removed from the solve,
//! `ShellSimulation::set_pinned_vertices`) unless a stiffness is given, by the anchor's own
//! `@K` or the scenario's `pin_stiffness` (N/m), which makes it a zero-length spring per vertex
//! to its rest position. A load acts from its `start` until its `end` (s); the loads active in
//! the middle of the coming step are the ones applied.
//!
//! ```
//! use balloon::shell::ShellBalloon;
//! use balloon_scenario::selection::{apply::shell_anchors, parse_load, parse_pin};
//! let mesh = balloon::mesh::generate::icosphere(0.1, 2).unwrap();
//! let mut sim = ShellBalloon::new(mesh).build().unwrap();
//! let pins = [parse_pin("below:z:-0.09").unwrap()];
//! let loads = [parse_load("force=0,0,1;on=above:z:0.09;start=0.5").unwrap()];
//! let mut applied = shell_anchors(&mut sim, &pins, None, &loads).unwrap();
//! assert!(!sim.pinned_vertices().is_empty());
//! applied.before_step(&mut sim).unwrap(); // before every step: the force starts at 0.5 s
//! ```

use super::selector::{SelectionError, Selector};
use super::specs::{Load, LoadKind, Pin};
use balloon::shell::{AnchorSpring, ShellMaterial, ShellSimulation};
use balloon::volumetric::VolumetricSimulation;

/// Sets the anchors `pins` on `sim` (springs of `pin_stiffness` N/m for those without their own
/// stiffness, hard pins when there is none) and returns the `loads` to apply before each step
/// ([`ShellLoads::before_step`]; the loads of time 0 are already applied). A selection that
/// picks no vertex is an error naming the selector.
pub fn shell_anchors<M: ShellMaterial>(
    sim: &mut ShellSimulation<M>,
    pins: &[Pin],
    pin_stiffness: Option<f64>,
    loads: &[Load],
) -> Result<ShellLoads, SelectionError> {
    let rest = sim.rest_positions().to_vec();
    let mut hard = Vec::new();
    let mut springs = Vec::new();
    for pin in pins {
        let vertices = pin.selector.select(&rest)?;
        match pin.stiffness.or(pin_stiffness) {
            None => hard.extend(vertices),
            Some(k) => springs.extend(vertices.into_iter().map(|v| AnchorSpring {
                vertex: v,
                anchor: [rest[3 * v], rest[3 * v + 1], rest[3 * v + 2]],
                stiffness: k,
            })),
        }
    }
    if !hard.is_empty() {
        hard.sort_unstable();
        hard.dedup();
        refuse_all_pinned(
            pins,
            pin_stiffness,
            hard.len(),
            &rest,
            "vertices of the mesh",
        )?;
        sim.set_pinned_vertices(hard)?;
    }
    let loads = select_loads(loads, &rest, Selector::select)?;
    let mut out = ShellLoads {
        springs,
        loads,
        active: None,
    };
    out.before_step(sim)?;
    Ok(out)
}

/// [`SelectionError::AllPinned`] when the `pinned` distinct vertices (or particles) of the hard
/// `pins` are all of the `rest` positions' (`what` they are, for the message).
fn refuse_all_pinned(
    pins: &[Pin],
    pin_stiffness: Option<f64>,
    pinned: usize,
    rest: &[f64],
    what: &'static str,
) -> Result<(), SelectionError> {
    let count = rest.len() / 3;
    if pinned < count {
        return Ok(());
    }
    let selections = pins
        .iter()
        .filter(|p| p.stiffness.or(pin_stiffness).is_none())
        .map(|p| format!("`{p}`"))
        .collect::<Vec<_>>()
        .join(", ");
    Err(SelectionError::AllPinned {
        count,
        what,
        selections,
    })
}

/// Each load with the vertices (or particles) its `on` selector picks from the rest positions
/// `rest` by `select` (the system's selection, with its own message for an empty one); an
/// empty list for a load without `on` (gravity, on everything).
fn select_loads(
    loads: &[Load],
    rest: &[f64],
    select: impl Fn(&Selector, &[f64]) -> Result<Vec<usize>, SelectionError>,
) -> Result<Vec<(Load, Vec<usize>)>, SelectionError> {
    loads
        .iter()
        .map(|l| {
            let picked = match &l.on {
                Some(s) => select(s, rest)?,
                None => Vec::new(),
            };
            Ok((l.clone(), picked))
        })
        .collect()
}

/// The part of a force load each selected vertex takes: all of it (`per=vertex`) or its share
/// of the total (`per=total`).
fn force_share(total: bool, picked: usize) -> f64 {
    if total { 1.0 / picked as f64 } else { 1.0 }
}

/// Adds a force load to the flat `forces` (N per dof) of the `picked` vertices.
fn spread_force(forces: &mut [f64], force: &[f64; 3], total: bool, picked: &[usize]) {
    let share = force_share(total, picked.len());
    for &v in picked {
        for d in 0..3 {
            forces[3 * v + d] += share * force[d];
        }
    }
}

/// Pins the hard anchor selections of a two-layer body (those without `@K` when there is no
/// `pin_stiffness`; `balloon::two_layer::TwoLayerSimulation::fix_particles`). Spring anchors
/// are left to [`two_layer_loads`].
pub fn fix_two_layer(
    sim: &mut balloon::two_layer::TwoLayerSimulation,
    pins: &[Pin],
    pin_stiffness: Option<f64>,
) -> Result<(), SelectionError> {
    let rest = sim.positions().to_vec();
    let mut hard = Vec::new();
    for pin in pins {
        if pin.stiffness.or(pin_stiffness).is_none() {
            hard.extend(pin.selector.select(&rest)?);
        }
    }
    hard.sort_unstable();
    hard.dedup();
    refuse_all_pinned(
        pins,
        pin_stiffness,
        hard.len(),
        &rest,
        "particles of the body",
    )?;
    sim.fix_particles(&hard)?;
    Ok(())
}

/// The spring anchors and scheduled loads of a two-layer run
/// (`balloon::two_layer::TwoLayerSimulation::set_loads`), updated before each step
/// ([`TwoLayerLoads::before_step`]).
#[derive(Debug)]
pub struct TwoLayerLoads {
    /// The `@K` springs to the rest positions (always on).
    springs: Vec<balloon::two_layer::AnchorSpring>,
    /// The loads with their selected particles.
    loads: Vec<(Load, Vec<usize>)>,
    /// Which loads were active at the last update (`None` before the first).
    active: Option<Vec<bool>>,
}

/// Selects the spring anchors (`@K`, or every pin with `pin_stiffness`) and the loads of a
/// two-layer run on the particles' positions at the start and applies those of time 0.
pub fn two_layer_loads(
    sim: &mut balloon::two_layer::TwoLayerSimulation,
    pins: &[Pin],
    pin_stiffness: Option<f64>,
    loads: &[Load],
) -> Result<TwoLayerLoads, SelectionError> {
    let rest = sim.positions().to_vec();
    let mut springs = Vec::new();
    for pin in pins {
        if let Some(k) = pin.stiffness.or(pin_stiffness) {
            springs.extend(pin.selector.select(&rest)?.into_iter().map(|i| {
                balloon::two_layer::AnchorSpring {
                    particle: i,
                    point: [rest[3 * i], rest[3 * i + 1], rest[3 * i + 2]],
                    stiffness: k,
                }
            }));
        }
    }
    let loads = select_loads(loads, &rest, Selector::select)?;
    let mut out = TwoLayerLoads {
        springs,
        loads,
        active: None,
    };
    out.before_step(sim)?;
    Ok(out)
}

impl TwoLayerLoads {
    /// Sets the anchor springs and the forces of the loads active in the middle of the coming
    /// step (`start <= t < end`), when that set changed. Gravity loads add each particle's mass
    /// times g to its force.
    pub fn before_step(
        &mut self,
        sim: &mut balloon::two_layer::TwoLayerSimulation,
    ) -> Result<(), SelectionError> {
        if self.springs.is_empty() && self.loads.is_empty() {
            return Ok(());
        }
        let active = active_loads(&self.loads, sim.time(), sim.dt());
        if self.active.as_ref() == Some(&active) {
            return Ok(());
        }
        let masses = sim.model().masses.clone();
        let mut forces = vec![0.0; 3 * masses.len()];
        let mut springs = self.springs.clone();
        let mut any_force = false;
        for ((load, particles), _) in self.loads.iter().zip(&active).filter(|(_, a)| **a) {
            match &load.kind {
                LoadKind::Gravity(g) => {
                    any_force = true;
                    for (i, m) in masses.iter().enumerate() {
                        for d in 0..3 {
                            forces[3 * i + d] += m * g[d];
                        }
                    }
                }
                LoadKind::Force { force, total } => {
                    any_force = true;
                    spread_force(&mut forces, force, *total, particles);
                }
                LoadKind::Grab { target, stiffness } => {
                    springs.extend(particles.iter().map(|&i| balloon::two_layer::AnchorSpring {
                        particle: i,
                        point: *target,
                        stiffness: *stiffness,
                    }));
                }
            }
        }
        sim.set_loads(springs, any_force.then_some(&forces[..]))?;
        self.active = Some(active);
        Ok(())
    }
}

/// The anchor springs and scheduled loads of a shell run.
#[derive(Debug, Default)]
pub struct ShellLoads {
    /// The anchor springs (always on).
    springs: Vec<AnchorSpring>,
    /// The loads with their selected vertices.
    loads: Vec<(Load, Vec<usize>)>,
    /// Which loads were active at the last update (`None` before the first).
    active: Option<Vec<bool>>,
}

impl ShellLoads {
    /// Sets the external forces and anchor springs of the loads active at the simulation's
    /// current time (`start <= t < end`), when that set changed.
    pub fn before_step<M: ShellMaterial>(
        &mut self,
        sim: &mut ShellSimulation<M>,
    ) -> Result<(), SelectionError> {
        let active = active_loads(&self.loads, sim.time(), sim.dt());
        if self.active.as_ref() == Some(&active) {
            return Ok(());
        }
        let n = sim.positions().len();
        let mut forces = vec![0.0; n];
        let mut any_force = false;
        for ((load, vertices), _) in self.loads.iter().zip(&active).filter(|(_, a)| **a) {
            match &load.kind {
                LoadKind::Gravity(g) => {
                    any_force = true;
                    for (i, (f, m)) in forces.iter_mut().zip(sim.masses()).enumerate() {
                        *f += m * g[i % 3];
                    }
                }
                LoadKind::Force { force, total } => {
                    any_force = true;
                    spread_force(&mut forces, force, *total, vertices);
                }
                LoadKind::Grab { .. } => {}
            }
        }
        let springs = self.springs_of(&active);
        sim.set_external_forces(any_force.then_some(&forces[..]))?;
        sim.set_anchor_springs(springs)?;
        self.active = Some(active);
        Ok(())
    }

    /// The anchor springs the last [`ShellLoads::before_step`] set: the anchors' springs
    /// followed by the springs of the grabs active then (empty before the first update).
    /// Whoever adds springs of its own (the live viewer's drag) sets these plus its own with
    /// `ShellSimulation::set_anchor_springs` after `before_step`, since `before_step` replaces
    /// every anchor spring when the active loads change and leaves them alone otherwise.
    pub fn anchor_springs(&self) -> Vec<AnchorSpring> {
        match &self.active {
            Some(active) => self.springs_of(active),
            None => Vec::new(),
        }
    }

    /// The anchors' springs followed by the springs of the `active` grabs.
    fn springs_of(&self, active: &[bool]) -> Vec<AnchorSpring> {
        let mut springs = self.springs.clone();
        for ((load, vertices), _) in self.loads.iter().zip(active).filter(|(_, a)| **a) {
            if let LoadKind::Grab { target, stiffness } = &load.kind {
                springs.extend(vertices.iter().map(|&v| AnchorSpring {
                    vertex: v,
                    anchor: *target,
                    stiffness: *stiffness,
                }));
            }
        }
        springs
    }
}

/// The flat rest positions (m) of the volumetric body's lattice particles, which the
/// selectors pick from.
fn particle_rest(sim: &VolumetricSimulation) -> Vec<f64> {
    sim.lattice()
        .tet_mesh
        .vertices
        .iter()
        .flat_map(|p| [p.x, p.y, p.z])
        .collect()
}

/// The particles `selector` picks from the flat rest positions `rest`; an empty selection is
/// an error naming the selector and the particles.
fn select_particles(selector: &Selector, rest: &[f64]) -> Result<Vec<usize>, SelectionError> {
    selector.select(rest).map_err(|e| match e {
        SelectionError::Empty(s) => SelectionError::Unsupported(format!(
            "`{s}` selects no particle of the body ({} particles)",
            rest.len() / 3
        )),
        other => other,
    })
}

/// Pins the hard anchor selections of a volumetric body (those without `@K` when there is no
/// `pin_stiffness`): the selected lattice particles, picked by their rest positions, never
/// move (`VolumetricSimulation::set_fixed_particles`). Spring anchors are left to
/// [`volumetric_loads`].
pub fn fix_volumetric(
    sim: &mut VolumetricSimulation,
    pins: &[Pin],
    pin_stiffness: Option<f64>,
) -> Result<(), SelectionError> {
    let rest = particle_rest(sim);
    let mut hard = Vec::new();
    for pin in pins {
        if pin.stiffness.or(pin_stiffness).is_none() {
            hard.extend(select_particles(&pin.selector, &rest)?);
        }
    }
    hard.sort_unstable();
    hard.dedup();
    refuse_all_pinned(
        pins,
        pin_stiffness,
        hard.len(),
        &rest,
        "particles of the lattice",
    )?;
    sim.set_fixed_particles(&hard)?;
    Ok(())
}

/// A zero-length spring pulling one particle toward a point.
#[derive(Clone, Copy, Debug)]
struct PointSpring {
    particle: usize,
    anchor: [f64; 3],
    stiffness: f64,
}

/// The spring anchors and scheduled loads of a volumetric run, applied through
/// `VolumetricSimulation::set_external_forces` (and `set_gravity`) before each step
/// ([`VolumetricLoads::before_step`]).
#[derive(Debug)]
pub struct VolumetricLoads {
    /// The `@K` springs to the rest positions (always on).
    springs: Vec<PointSpring>,
    /// The loads with their selected particles.
    loads: Vec<(Load, Vec<usize>)>,
    /// Gravity when no gravity load is active (the scenario's `gravity`), m/s^2.
    gravity: [f64; 3],
    /// The constant forces of the active loads (N, one per particle) and the springs of the
    /// active grabs, as of the last change of the active set.
    constant: Vec<nalgebra::Vector3<f64>>,
    /// Whether any constant force is active.
    any_constant: bool,
    /// Anchor springs plus the springs of the active grabs.
    active_springs: Vec<PointSpring>,
    /// Which loads were active at the last update (`None` before the first).
    active: Option<Vec<bool>>,
}

/// Selects the spring anchors (`@K`, or every pin with `pin_stiffness`) and the loads of a
/// volumetric run on its lattice particles (by their rest positions) and applies those of time
/// 0. A selection that picks no particle is an error naming the selector.
pub fn volumetric_loads(
    sim: &mut VolumetricSimulation,
    pins: &[Pin],
    pin_stiffness: Option<f64>,
    loads: &[Load],
) -> Result<VolumetricLoads, SelectionError> {
    let rest = particle_rest(sim);
    let mut springs = Vec::new();
    for pin in pins {
        if let Some(k) = pin.stiffness.or(pin_stiffness) {
            springs.extend(
                select_particles(&pin.selector, &rest)?
                    .into_iter()
                    .map(|v| PointSpring {
                        particle: v,
                        anchor: [rest[3 * v], rest[3 * v + 1], rest[3 * v + 2]],
                        stiffness: k,
                    }),
            );
        }
    }
    let loads = select_loads(loads, &rest, select_particles)?;
    let mut out = VolumetricLoads {
        springs,
        loads,
        gravity: sim.body().params.gravity,
        constant: Vec::new(),
        any_constant: false,
        active_springs: Vec::new(),
        active: None,
    };
    out.before_step(sim)?;
    Ok(out)
}

impl VolumetricLoads {
    /// Whether there is nothing to apply (no spring anchor, no load).
    pub fn is_empty(&self) -> bool {
        self.springs.is_empty() && self.loads.is_empty()
    }

    /// Sets the gravity and external forces of the coming step: the loads active at its middle
    /// (`start <= t < end`), and the springs (anchors and grabs) at the current positions,
    /// `F = K (anchor - x)` per particle, evaluated explicitly like the cell springs (Eq. 1).
    /// A gravity load replaces `gravity` while active (several add up).
    pub fn before_step(&mut self, sim: &mut VolumetricSimulation) -> Result<(), SelectionError> {
        if self.is_empty() {
            return Ok(());
        }
        let active = active_loads(&self.loads, sim.time(), sim.body().params.dt);
        if self.active.as_ref() != Some(&active) {
            let n = sim.positions().len();
            let mut forces = vec![nalgebra::Vector3::zeros(); n];
            let mut springs = self.springs.clone();
            let mut gravity: Option<[f64; 3]> = None;
            let mut any = false;
            for ((load, particles), _) in self.loads.iter().zip(&active).filter(|(_, a)| **a) {
                match &load.kind {
                    LoadKind::Gravity(g) => {
                        let sum = gravity.get_or_insert([0.0; 3]);
                        for d in 0..3 {
                            sum[d] += g[d];
                        }
                    }
                    LoadKind::Force { force, total } => {
                        any = true;
                        let share = force_share(*total, particles.len());
                        for &i in particles {
                            forces[i] += nalgebra::Vector3::from(*force) * share;
                        }
                    }
                    LoadKind::Grab { target, stiffness } => {
                        springs.extend(particles.iter().map(|&i| PointSpring {
                            particle: i,
                            anchor: *target,
                            stiffness: *stiffness,
                        }));
                    }
                }
            }
            sim.set_gravity(gravity.unwrap_or(self.gravity))?;
            self.constant = forces;
            self.any_constant = any;
            self.active_springs = springs;
            self.active = Some(active);
        }
        let forces = self.forces(sim);
        sim.set_external_forces(forces.as_deref())?;
        Ok(())
    }

    /// The external forces (N, one per particle) the last [`VolumetricLoads::before_step`]
    /// chose, evaluated at the particles' current positions: the constant forces of the active
    /// loads plus the springs of the anchors and active grabs; `None` when there is none.
    /// Whoever adds forces of its own (the live viewer's drag) adds them to these and sets the
    /// sum with `VolumetricSimulation::set_external_forces` after `before_step`.
    pub fn forces(&self, sim: &VolumetricSimulation) -> Option<Vec<nalgebra::Vector3<f64>>> {
        if self.active_springs.is_empty() {
            return self.any_constant.then(|| self.constant.clone());
        }
        let mut forces = self.constant.clone();
        let x = sim.positions();
        for s in &self.active_springs {
            forces[s.particle] +=
                (nalgebra::Vector3::from(s.anchor) - x[s.particle].coords) * s.stiffness;
        }
        Some(forces)
    }
}

/// Which of `loads` act during the step from `time` of size `dt`: those whose `[start, end)`
/// holds the middle of the step, so that a load scheduled at a step boundary is not missed by
/// round-off in the time (the same rule for the three systems).
fn active_loads<T>(loads: &[(Load, T)], time: f64, dt: f64) -> Vec<bool> {
    let t = time + 0.5 * dt;
    loads
        .iter()
        .map(|(l, _)| l.start <= t && t < l.end)
        .collect()
}
