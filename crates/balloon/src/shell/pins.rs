//! Hard pins of the shell: vertices removed from the backward Euler solve (Eq. 18-23).
//!
//! A pinned vertex keeps its position exactly. [`WithPins`] wraps the force system handed to
//! the integrator so that every pinned degree of freedom `i` is decoupled from the others: its
//! row and column of the stiffness `K` (element blocks, triplets, diagonal, low-rank terms and
//! the matrix-free differential) are zero, and its force is the one that cancels the external
//! load (gravity and the external forces). With `v_i^n = 0` the Newton residual of Eq. 23 at `i`
//! is then exactly zero and the Newton matrix `(1 + dt alpha) M + (dt^2 + dt beta) K` has the
//! identity row `(1 + dt alpha) m_i e_i`, so every linear solver returns `dv_i = 0` exactly and
//! the position `x_i = x_i^n + dt v_i` never changes. The shell-volume projection (Algorithm 2)
//! gives pinned vertices a zero inverse mass, so it does not move them either, and the velocity
//! of Algorithm 1 (line 12) stays zero. The static solve (Newton with the shift `K + mu M`)
//! sees the same decoupled rows, with no gravity to cancel, and leaves pinned vertices where
//! they are too.

use balloon_integrate::statics::LoadScaling;
use balloon_integrate::{ForceSystem, LowRankTerm, StiffnessBlocks, SystemError, TangentKind};
use std::sync::Mutex;

/// The pinned vertices of a shell and the buffers of their masked stiffness.
#[derive(Debug, Default)]
pub(crate) struct Pins {
    /// Pinned vertices, sorted, without duplicates.
    pub(crate) vertices: Vec<usize>,
    /// Per degree of freedom: pinned (empty when nothing is pinned).
    pub(crate) fixed: Vec<bool>,
    /// Projection inverse masses with zeros at the pinned vertices.
    pub(crate) vertex_inverse_mass: Vec<f64>,
    /// The external forces of the step with zeros at the pinned degrees of freedom.
    pub(crate) external: Vec<f64>,
    /// Gravity of the integrator (m/s^2), cancelled at the pinned degrees of freedom.
    pub(crate) gravity: [f64; 3],
    /// The inner system's element blocks with the pinned rows and columns zeroed.
    blocks: Vec<f64>,
    /// Whether `blocks` holds the blocks of the last linearisation point.
    has_blocks: bool,
    /// The inner system's low-rank terms with the pinned entries zeroed.
    low_rank: Vec<LowRankTerm>,
    /// Scratch for the matrix-free differential.
    scratch: Mutex<(Vec<f64>, Vec<f64>)>,
}

impl Pins {
    /// Pins `vertices` (each `< nv`) of a shell with `nv` vertices and projection inverse masses
    /// `inverse_mass`.
    pub(crate) fn new(mut vertices: Vec<usize>, inverse_mass: &[f64]) -> Self {
        vertices.sort_unstable();
        vertices.dedup();
        let mut fixed = vec![false; 3 * inverse_mass.len()];
        let mut vertex_inverse_mass = inverse_mass.to_vec();
        for &v in &vertices {
            fixed[3 * v..3 * v + 3].fill(true);
            vertex_inverse_mass[v] = 0.0;
        }
        if vertices.is_empty() {
            fixed.clear();
        }
        Self {
            vertices,
            fixed,
            vertex_inverse_mass,
            ..Default::default()
        }
    }

    /// Whether any vertex is pinned.
    pub(crate) fn active(&self) -> bool {
        !self.vertices.is_empty()
    }

    /// Prepares a step: zero velocity at the pinned degrees of freedom, the masked external
    /// forces (`external` empty = none) and the integrator's gravity.
    pub(crate) fn prepare(&mut self, v: &mut [f64], external: &[f64], gravity: [f64; 3]) {
        for (vi, &f) in v.iter_mut().zip(&self.fixed) {
            if f {
                *vi = 0.0;
            }
        }
        self.external.clear();
        if !external.is_empty() {
            self.external.extend(
                external
                    .iter()
                    .zip(&self.fixed)
                    .map(|(&e, &f)| if f { 0.0 } else { e }),
            );
        }
        self.gravity = gravity;
    }

    /// Zeroes the pinned rows and columns of triplets (kept, so the sparsity pattern stays).
    fn mask_triplets(&self, triplets: &mut [(usize, usize, f64)], from: usize) {
        for t in &mut triplets[from..] {
            if self.fixed[t.0] || self.fixed[t.1] {
                t.2 = 0.0;
            }
        }
    }
}

/// The static solve (`ShellSimulation::solve_static`) scales the inner system's load.
impl<S: LoadScaling> LoadScaling for WithPins<'_, S> {
    fn set_load_factor(&mut self, factor: f64) {
        self.inner.set_load_factor(factor);
    }
}

/// A force system whose pinned degrees of freedom are decoupled (see the module docs).
pub(crate) struct WithPins<'a, S> {
    pub(crate) inner: &'a mut S,
    pub(crate) pins: &'a mut Pins,
}

impl<S: ForceSystem> ForceSystem for WithPins<'_, S> {
    fn num_dofs(&self) -> usize {
        self.inner.num_dofs()
    }

    fn masses(&self) -> &[f64] {
        self.inner.masses()
    }

    fn forces(&mut self, time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.inner.forces(time, x, f)?;
        let pins = &mut *self.pins;
        let m = self.inner.masses();
        // The force that cancels the integrator's external load `m g + 0` (the external forces
        // are zero there): the same expression, so the sum is exactly zero.
        for (i, fi) in f.iter_mut().enumerate() {
            if pins.fixed[i] {
                *fi = -(m[i] * pins.gravity[i % 3] + 0.0);
            }
        }
        pins.has_blocks = false;
        if let Some(b) = self.inner.stiffness_blocks() {
            let k = b.nodes_per_block;
            let size = 3 * k;
            pins.blocks.clear();
            pins.blocks.extend_from_slice(b.values);
            for (nodes, block) in b
                .nodes
                .chunks_exact(k)
                .zip(pins.blocks.chunks_exact_mut(size * size))
            {
                for (a, &na) in nodes.iter().enumerate() {
                    for d in 0..3 {
                        if !pins.fixed[3 * na + d] {
                            continue;
                        }
                        let r = 3 * a + d;
                        // Column-major: row r and column r of the block.
                        for c in 0..size {
                            block[c * size + r] = 0.0;
                            block[r * size + c] = 0.0;
                        }
                    }
                }
            }
            pins.has_blocks = true;
        }
        pins.low_rank.clear();
        for t in self.inner.low_rank_terms() {
            let mut t = t.clone();
            for (u, &fx) in t.vector.iter_mut().zip(&pins.fixed) {
                if fx {
                    *u = 0.0;
                }
            }
            pins.low_rank.push(t);
        }
        Ok(())
    }

    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        let fixed = &self.pins.fixed;
        let mut guard = self
            .pins
            .scratch
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let (masked, out) = &mut *guard;
        masked.clear();
        masked.extend(dx.iter().zip(fixed).map(|(&d, &f)| if f { 0.0 } else { d }));
        out.clear();
        out.resize(df.len(), 0.0);
        self.inner.add_force_differential(masked, out);
        for ((d, &o), &f) in df.iter_mut().zip(out.iter()).zip(fixed) {
            if !f {
                *d += o;
            }
        }
    }

    fn add_stiffness_triplets(
        &self,
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), SystemError> {
        let from = triplets.len();
        self.inner.add_stiffness_triplets(triplets)?;
        self.pins.mask_triplets(triplets, from);
        Ok(())
    }

    fn stiffness_blocks(&self) -> Option<StiffnessBlocks<'_>> {
        let b = self.inner.stiffness_blocks()?;
        self.pins.has_blocks.then_some(StiffnessBlocks {
            nodes_per_block: b.nodes_per_block,
            nodes: b.nodes,
            values: &self.pins.blocks,
        })
    }

    fn add_remaining_stiffness_triplets(
        &self,
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), SystemError> {
        let from = triplets.len();
        self.inner.add_remaining_stiffness_triplets(triplets)?;
        self.pins.mask_triplets(triplets, from);
        Ok(())
    }

    fn add_stiffness_diagonal(&self, diagonal: &mut [f64]) -> Result<(), SystemError> {
        let mut own = vec![0.0; diagonal.len()];
        self.inner.add_stiffness_diagonal(&mut own)?;
        for ((d, o), &f) in diagonal.iter_mut().zip(own).zip(&self.pins.fixed) {
            if !f {
                *d += o;
            }
        }
        Ok(())
    }

    fn set_tangent(&mut self, kind: TangentKind) -> Result<(), SystemError> {
        self.inner.set_tangent(kind)
    }

    fn low_rank_terms(&self) -> &[LowRankTerm] {
        &self.pins.low_rank
    }

    /// The inner system's energy: the pinned coordinates never move along a Newton direction,
    /// so their (cancelled) forces play no part in the line search.
    fn potential_energy(&mut self, time: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        self.inner.potential_energy(time, x)
    }

    fn force_scale(&self) -> Option<f64> {
        self.inner.force_scale()
    }
}

#[cfg(test)]
mod tests {
    use crate::shell::{AnchorSpring, ShellBalloon, ShellMaterialModel};
    use balloon_gas::GasKind;
    use balloon_integrate::linear::LinearSolverKind;
    use balloon_material::membrane::{MembraneModel, MembraneNeoHookean};

    /// The vertices of a 0.1 m sphere below z = -0.08 (its "neck").
    fn neck(x: &[f64]) -> Vec<usize> {
        (0..x.len() / 3).filter(|&v| x[3 * v + 2] < -0.08).collect()
    }

    #[test]
    fn a_pinned_neck_stays_bit_for_bit_while_the_rest_inflates_with_every_solver() {
        for solver in [
            LinearSolverKind::Cholesky,
            LinearSolverKind::Pcg,
            LinearSolverKind::FactorizedPcg,
            LinearSolverKind::MatrixFreeCg,
        ] {
            let mesh = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
            let mut sim = ShellBalloon::new(mesh)
                .with_gas(GasKind::Constant)
                .with_gauge_pressure(3000.0)
                .with_linear_solver(solver)
                .configure_integrator(|p| {
                    p.gravity = [0.0, 0.0, -9.81];
                    p.stiffness_damping = 1e-4;
                })
                .build()
                .unwrap();
            let rest = sim.positions().to_vec();
            let pinned = neck(&rest);
            assert!(pinned.len() > 3, "{pinned:?}");
            sim.set_pinned_vertices(pinned.iter().rev().copied().chain([pinned[0]]).collect())
                .unwrap();
            assert_eq!(sim.pinned_vertices(), &pinned[..]);
            // External forces and a spring on a pinned vertex do not move it either.
            let f = vec![0.01; rest.len()];
            sim.set_external_forces(Some(&f)).unwrap();
            sim.set_anchor_springs(vec![AnchorSpring {
                vertex: pinned[0],
                anchor: [0.0, 0.0, -1.0],
                stiffness: 100.0,
            }])
            .unwrap();
            for _ in 0..10 {
                sim.step().unwrap_or_else(|e| panic!("{solver:?}: {e}"));
            }
            let x = sim.positions();
            for &v in &pinned {
                assert_eq!(x[3 * v..3 * v + 3], rest[3 * v..3 * v + 3], "{solver:?}");
                assert_eq!(sim.velocities()[3 * v..3 * v + 3], [0.0; 3]);
            }
            let top = (0..rest.len() / 3)
                .max_by(|&a, &b| rest[3 * a + 2].total_cmp(&rest[3 * b + 2]))
                .unwrap();
            assert!(
                x[3 * top + 2] > rest[3 * top + 2] + 1e-3,
                "{solver:?}: did not inflate"
            );
            assert!(
                sim.gas_volume() > 1.05 * sim.rest_gas_volume(),
                "{solver:?}"
            );
        }
    }

    #[test]
    fn pins_hold_a_membrane_and_can_be_freed_and_are_checked() {
        let mesh = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
        let mut sim = ShellBalloon::new(mesh)
            .with_material(ShellMaterialModel::from(MembraneModel::from(
                MembraneNeoHookean::try_new(3e5).unwrap(),
            )))
            .with_gas(GasKind::Constant)
            .with_gauge_pressure(500.0)
            .build()
            .unwrap();
        let rest = sim.positions().to_vec();
        let pinned = neck(&rest);
        sim.set_pinned_vertices(pinned.clone()).unwrap();
        for _ in 0..5 {
            sim.step().unwrap();
        }
        for &v in &pinned {
            assert_eq!(sim.positions()[3 * v..3 * v + 3], rest[3 * v..3 * v + 3]);
        }
        sim.set_pinned_vertices(Vec::new()).unwrap();
        assert!(sim.pinned_vertices().is_empty());
        for _ in 0..5 {
            sim.step().unwrap();
        }
        assert!(
            pinned
                .iter()
                .any(|&v| sim.positions()[3 * v + 2] != rest[3 * v + 2])
        );
        let e = sim.set_pinned_vertices(vec![0, 100_000]).unwrap_err();
        assert!(e.to_string().contains("100000"), "{e}");
    }

    #[test]
    fn the_static_solve_keeps_pinned_vertices_in_place() {
        let mesh = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
        let mut sim = ShellBalloon::new(mesh)
            .with_gas(GasKind::Constant)
            .with_gauge_pressure(3000.0)
            .build()
            .unwrap();
        let rest = sim.positions().to_vec();
        let pinned = neck(&rest);
        sim.set_pinned_vertices(pinned.clone()).unwrap();
        let f: Vec<f64> = (0..rest.len())
            .map(|i| if i % 3 == 0 { 0.01 } else { 0.0 })
            .collect();
        sim.set_external_forces(Some(&f)).unwrap();
        let report = sim.solve_static(&Default::default()).unwrap();
        assert!(report.converged, "{report:?}");
        for &v in &pinned {
            assert_eq!(sim.positions()[3 * v..3 * v + 3], rest[3 * v..3 * v + 3]);
        }
        assert!(sim.gas_volume() > 1.05 * sim.rest_gas_volume());
    }
}
