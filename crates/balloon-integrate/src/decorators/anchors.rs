//! Zero-length springs from vertices to fixed anchor points: [`Anchored`].
//!
//! A spring of stiffness `k` from vertex `v` (position `x_v`) to the anchor `a` has the energy
//! `k/2 |x_v - a|^2`, the force `k (a - x_v)` on the vertex and the stiffness `k I` on its
//! 3x3 diagonal block. [`Anchored`] adds them to the inner system's (forces, energy, force
//! differential, stiffness triplets and diagonal), so an integrator steps the springs
//! implicitly with the system: stiff springs stay stable where an explicit spring force would
//! blow up.

use serde::{Deserialize, Serialize};

use super::DecoratorError;
use crate::{ForceSystem, LowRankTerm, StiffnessBlocks, SystemError, TangentKind};

/// A zero-length spring from a vertex to a fixed anchor point: force `k (anchor - x_v)`,
/// stiffness `k I` on the vertex.
///
/// ```
/// use balloon_integrate::decorators::AnchorSpring;
/// let spring = AnchorSpring { vertex: 3, anchor: [0.0, 0.0, 1.0], stiffness: 50.0 };
/// assert!(spring.check(4).is_ok());
/// assert!(spring.check(3).is_err()); // vertex 3 of a system of 3 vertices
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AnchorSpring {
    /// The pulled vertex.
    pub vertex: usize,
    /// Anchor position, m.
    pub anchor: [f64; 3],
    /// Stiffness, N/m (>= 0).
    pub stiffness: f64,
}

impl AnchorSpring {
    /// Checks the spring for a system of `num_vertices` vertices.
    ///
    /// # Errors
    /// [`DecoratorError::VertexOutOfRange`] when the vertex does not exist,
    /// [`DecoratorError::InvalidSpring`] when the anchor is not finite or the stiffness is not
    /// finite and `>= 0`.
    pub fn check(&self, num_vertices: usize) -> Result<(), DecoratorError> {
        if self.vertex >= num_vertices {
            return Err(DecoratorError::VertexOutOfRange {
                what: "anchor spring vertex",
                vertex: self.vertex,
                num_vertices,
            });
        }
        let ok = self.stiffness.is_finite()
            && self.stiffness >= 0.0
            && self.anchor.iter().all(|c| c.is_finite());
        if !ok {
            return Err(DecoratorError::InvalidSpring { spring: *self });
        }
        Ok(())
    }
}

/// Anchor springs checked once for a system of a given number of vertices (what [`Anchored`]
/// adds to a system).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Anchors {
    springs: Vec<AnchorSpring>,
    num_vertices: usize,
}

impl Anchors {
    /// The springs `springs` on a system of `num_vertices` vertices (an empty list is no
    /// springs).
    ///
    /// # Errors
    /// The first spring's error of [`AnchorSpring::check`].
    pub fn new(num_vertices: usize, springs: Vec<AnchorSpring>) -> Result<Self, DecoratorError> {
        for s in &springs {
            s.check(num_vertices)?;
        }
        Ok(Self {
            springs,
            num_vertices,
        })
    }

    /// The springs, in the order given.
    pub fn springs(&self) -> &[AnchorSpring] {
        &self.springs
    }

    /// Number of springs.
    pub fn len(&self) -> usize {
        self.springs.len()
    }

    /// Whether there are no springs.
    pub fn is_empty(&self) -> bool {
        self.springs.is_empty()
    }

    /// The number of vertices of the system the springs were checked for.
    pub fn num_vertices(&self) -> usize {
        self.num_vertices
    }
}

/// A force system plus anchor springs: their force, energy, differential and stiffness entries
/// added to the inner system's (module docs). Everything else (masses, element blocks,
/// low-rank terms, tangent kind, force scale) is the inner system's. The forces and the energy
/// of a line-search trial are evaluated one after the other (the trait's default
/// [`ForceSystem::residual_forces_and_energy`]), not in a fused pass of the inner system.
///
/// ```
/// use balloon_integrate::decorators::{AnchorSpring, Anchored, Anchors};
/// use balloon_integrate::{ForceSystem, SystemError};
///
/// /// One free particle of 2 kg.
/// struct Particle([f64; 3]);
/// impl ForceSystem for Particle {
///     fn num_dofs(&self) -> usize { 3 }
///     fn masses(&self) -> &[f64] { &self.0 }
///     fn forces(&mut self, _t: f64, _x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
///         f.fill(0.0);
///         Ok(())
///     }
///     fn add_force_differential(&self, _dx: &[f64], _df: &mut [f64]) {}
///     fn potential_energy(&mut self, _t: f64, _x: &[f64]) -> Result<Option<f64>, SystemError> {
///         Ok(Some(0.0))
///     }
/// }
///
/// let spring = AnchorSpring { vertex: 0, anchor: [1.0, 2.0, 3.0], stiffness: 10.0 };
/// let anchors = Anchors::new(1, vec![spring])?;
/// let mut particle = Particle([2.0; 3]);
/// let mut anchored = Anchored::new(&mut particle, &anchors)?;
/// let x = [1.0, 2.0, 2.5];
/// let mut f = [0.0; 3];
/// anchored.forces(0.0, &x, &mut f)?;
/// assert_eq!(f, [0.0, 0.0, 5.0]); // k (a - x)
/// assert_eq!(anchored.potential_energy(0.0, &x)?, Some(1.25)); // k/2 |x - a|^2
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Anchored<'a, S> {
    inner: &'a mut S,
    springs: &'a [AnchorSpring],
}

impl<'a, S: ForceSystem> Anchored<'a, S> {
    /// `inner` with the springs of `anchors`.
    ///
    /// # Errors
    /// [`DecoratorError::SizeMismatch`] when `anchors` hold springs and were made for another
    /// number of vertices than `inner.num_dofs() / 3`.
    pub fn new(inner: &'a mut S, anchors: &'a Anchors) -> Result<Self, DecoratorError> {
        let found = inner.num_dofs() / 3;
        if !anchors.is_empty() && anchors.num_vertices != found {
            return Err(DecoratorError::SizeMismatch {
                what: "anchor springs",
                expected: anchors.num_vertices,
                found,
            });
        }
        Ok(Self {
            inner,
            springs: &anchors.springs,
        })
    }
}

impl<S: ForceSystem> ForceSystem for Anchored<'_, S> {
    fn num_dofs(&self) -> usize {
        self.inner.num_dofs()
    }

    fn masses(&self) -> &[f64] {
        self.inner.masses()
    }

    fn forces(&mut self, time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.inner.forces(time, x, f)?;
        self.add_spring_forces(x, f);
        Ok(())
    }

    fn residual_forces(&mut self, time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.inner.residual_forces(time, x, f)?;
        self.add_spring_forces(x, f);
        Ok(())
    }

    fn refresh_stiffness(&mut self) -> Result<(), SystemError> {
        self.inner.refresh_stiffness()
    }

    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        self.inner.add_force_differential(dx, df);
        for s in self.springs {
            for d in 0..3 {
                df[3 * s.vertex + d] -= s.stiffness * dx[3 * s.vertex + d];
            }
        }
    }

    fn add_stiffness_triplets(
        &self,
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), SystemError> {
        self.inner.add_stiffness_triplets(triplets)?;
        self.add_spring_triplets(triplets);
        Ok(())
    }

    fn stiffness_blocks(&self) -> Option<StiffnessBlocks<'_>> {
        self.inner.stiffness_blocks()
    }

    fn add_remaining_stiffness_triplets(
        &self,
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), SystemError> {
        self.inner.add_remaining_stiffness_triplets(triplets)?;
        self.add_spring_triplets(triplets);
        Ok(())
    }

    /// As the inner system's (the springs are exact in the matrix either way).
    fn set_stiffness_split(&mut self, on: bool) -> bool {
        self.inner.set_stiffness_split(on)
    }

    fn add_stiffness_correction(&self, scale: f64, p: &[f64], out: &mut [f64]) {
        self.inner.add_stiffness_correction(scale, p, out);
    }

    fn add_stiffness_diagonal(&self, diagonal: &mut [f64]) -> Result<(), SystemError> {
        self.inner.add_stiffness_diagonal(diagonal)?;
        for s in self.springs {
            for d in 0..3 {
                diagonal[3 * s.vertex + d] += s.stiffness;
            }
        }
        Ok(())
    }

    fn set_tangent(&mut self, kind: TangentKind) -> Result<(), SystemError> {
        self.inner.set_tangent(kind)
    }

    fn low_rank_terms(&self) -> &[LowRankTerm] {
        self.inner.low_rank_terms()
    }

    /// The inner system's energy plus `k/2 |x_v - anchor|^2` per spring.
    fn potential_energy(&mut self, time: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        Ok(self.inner.potential_energy(time, x)?.map(|inner| {
            inner
                + self
                    .springs
                    .iter()
                    .map(|s| {
                        let d2: f64 = (0..3)
                            .map(|d| (x[3 * s.vertex + d] - s.anchor[d]).powi(2))
                            .sum();
                        0.5 * s.stiffness * d2
                    })
                    .sum::<f64>()
        }))
    }

    fn force_scale(&self) -> Option<f64> {
        self.inner.force_scale()
    }
}

impl<S> Anchored<'_, S> {
    /// The springs' forces `k (anchor - x)` added to `f`.
    fn add_spring_forces(&self, x: &[f64], f: &mut [f64]) {
        for s in self.springs {
            for d in 0..3 {
                f[3 * s.vertex + d] += s.stiffness * (s.anchor[d] - x[3 * s.vertex + d]);
            }
        }
    }

    fn add_spring_triplets(&self, triplets: &mut Vec<(usize, usize, f64)>) {
        for s in self.springs {
            for d in 0..3 {
                triplets.push((3 * s.vertex + d, 3 * s.vertex + d, s.stiffness));
            }
        }
    }
}
