//! Hard pins of the shell: the vertices held by [`Pinned`] in the backward Euler solve
//! (Eq. 18-23) and in the static solve, and removed from the shell-volume projection
//! (Algorithm 2: zero inverse mass, so it does not move them either, and the velocity of
//! Algorithm 1, line 12, stays zero). A pinned vertex keeps its position bit for bit.

#[cfg(doc)]
use balloon_integrate::decorators::Pinned;
use balloon_integrate::decorators::{DecoratorError, Pins as PinnedDofs};

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
    pub(crate) fn new(vertices: Vec<usize>, inverse_mass: &[f64]) -> Result<Self, DecoratorError> {
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
