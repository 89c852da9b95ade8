//! Hard pins of the shell: the vertices held by [`Pinned`] in the backward Euler solve
//! (Eq. 18-23) and in the static solve, and removed from the shell-volume projection
//! (Algorithm 2: zero inverse mass, so it does not move them either, and the velocity of
//! Algorithm 1, line 12, stays zero). A pinned vertex keeps its position bit for bit.

#[cfg(doc)]
use balloon_integrate::decorators::Pinned;
use balloon_integrate::decorators::{DecoratorError, Pins as PinnedDofs};

use super::ShellError;

/// The pinned vertices of a shell: the decorator's data, the projection's inverse masses with
/// zeros at the pinned vertices, and the masked external forces of the step.
#[derive(Debug, Default)]
pub(crate) struct Pins {
    /// The pinned degrees of freedom and the buffers of their masked stiffness.
    pub(crate) dofs: PinnedDofs,
    /// Projection inverse masses with zeros at the pinned vertices.
    pub(crate) vertex_inverse_mass: Vec<f64>,
    /// The external forces of the step with zeros at the pinned degrees of freedom.
    pub(crate) external: Vec<f64>,
}

impl Pins {
    /// Pins `vertices` (each below the number of vertices, `inverse_mass.len()`) of a shell
    /// with projection inverse masses `inverse_mass`.
    pub(crate) fn new(vertices: Vec<usize>, inverse_mass: &[f64]) -> Result<Self, ShellError> {
        let dofs = PinnedDofs::new(inverse_mass.len(), vertices)?;
        let mut vertex_inverse_mass = inverse_mass.to_vec();
        for &v in dofs.vertices() {
            vertex_inverse_mass[v] = 0.0;
        }
        Ok(Self {
            dofs,
            vertex_inverse_mass,
            external: Vec::new(),
        })
    }

    /// Whether any vertex is pinned.
    pub(crate) fn active(&self) -> bool {
        !self.dofs.is_empty()
    }

    /// Prepares a step: zero velocity at the pinned degrees of freedom, the masked external
    /// forces (`external` empty = none) and the integrator's gravity.
    pub(crate) fn prepare(&mut self, v: &mut [f64], external: &[f64], gravity: [f64; 3]) {
        self.dofs
            .prepare_step(v, external, gravity, &mut self.external);
    }
}

/// A decorator's refusal as the shell's invalid parameter (the names and reasons the shell's
/// setters have always given).
impl From<DecoratorError> for ShellError {
    fn from(e: DecoratorError) -> Self {
        match e {
            DecoratorError::VertexOutOfRange {
                what,
                vertex,
                num_vertices,
            } => ShellError::InvalidParameter {
                name: what,
                value: vertex.to_string(),
                reason: format!("the shell has {num_vertices} vertices"),
            },
            DecoratorError::InvalidSpring { spring } => ShellError::InvalidParameter {
                name: "anchor spring",
                value: format!("{spring:?}"),
                reason: "the anchor must be finite and the stiffness finite and >= 0".into(),
            },
            DecoratorError::SizeMismatch {
                what,
                expected,
                found,
            } => ShellError::InvalidParameter {
                name: what,
                value: format!("{expected} vertices"),
                reason: format!("the shell has {found} vertices"),
            },
        }
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
