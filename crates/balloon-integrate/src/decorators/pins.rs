//! Hard pins: vertices removed from the solve, [`Pinned`].
//!
//! A pinned vertex keeps its position exactly. [`Pinned`] wraps the force system handed to an
//! integrator so that every pinned degree of freedom `i` is decoupled from the others: its row
//! and column of the stiffness `K` (element blocks, triplets, diagonal, low-rank terms and the
//! matrix-free differential) are zero, and its force is the one that cancels the integrator's
//! external load `m_i g_i` (the caller zeroes the external forces there,
//! [`Pins::prepare_step`]). With `v_i = 0` at the start of the step the backward Euler residual
//! (Wang et al. 2015, Eq. 23) at `i` is then exactly zero and the Newton matrix
//! `(1 + dt alpha) M + (dt^2 + dt beta) K` has the identity row `(1 + dt alpha) m_i e_i`, so
//! every linear solver returns `dv_i = 0` exactly and the position `x_i = x_i^n + dt v_i` never
//! changes. The static solve (Newton with the shift `K + mu M`) sees the same decoupled rows,
//! with no gravity to cancel, and leaves pinned vertices where they are too.

use std::sync::Mutex;

use super::DecoratorError;
use crate::statics::LoadScaling;
use crate::{ForceSystem, LowRankTerm, StiffnessBlocks, SystemError, TangentKind};

/// The pinned vertices of a system and the buffers of its masked stiffness (what [`Pinned`]
/// holds fixed).
///
/// ```
/// use balloon_integrate::decorators::Pins;
/// let mut pins = Pins::new(4, vec![2, 0, 2])?;
/// assert_eq!(pins.vertices(), [0, 2]); // sorted, without duplicates
/// assert!(pins.is_pinned(2) && !pins.is_pinned(1));
/// // Before a step: zero velocity and external force at the pinned vertices.
/// let mut v = vec![1.0; 12];
/// let mut external = Vec::new();
/// pins.prepare_step(&mut v, &[0.5; 12], [0.0, 0.0, -9.81], &mut external);
/// assert_eq!((v[0], v[3], external[6], external[9]), (0.0, 1.0, 0.0, 0.5));
/// assert!(Pins::new(4, vec![4]).is_err());
/// # Ok::<(), balloon_integrate::decorators::DecoratorError>(())
/// ```
#[derive(Debug, Default)]
pub struct Pins {
    /// Pinned vertices, sorted, without duplicates.
    vertices: Vec<usize>,
    /// Per degree of freedom: pinned (`3 num_vertices` entries).
    fixed: Vec<bool>,
    /// Gravity of the integrator (m/s^2), cancelled at the pinned degrees of freedom.
    gravity: [f64; 3],
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
    /// Pins `vertices` (in any order, duplicates ignored) of a system of `num_vertices`
    /// vertices; an empty list pins nothing.
    ///
    /// # Errors
    /// [`DecoratorError::VertexOutOfRange`] for the first vertex that is not below
    /// `num_vertices`.
    pub fn new(num_vertices: usize, mut vertices: Vec<usize>) -> Result<Self, DecoratorError> {
        if let Some(&bad) = vertices.iter().find(|&&v| v >= num_vertices) {
            return Err(DecoratorError::VertexOutOfRange {
                what: "pinned vertex",
                vertex: bad,
                num_vertices,
            });
        }
        vertices.sort_unstable();
        vertices.dedup();
        let mut fixed = vec![false; 3 * num_vertices];
        for &v in &vertices {
            fixed[3 * v..3 * v + 3].fill(true);
        }
        Ok(Self {
            vertices,
            fixed,
            ..Default::default()
        })
    }

    /// The pinned vertices, sorted.
    pub fn vertices(&self) -> &[usize] {
        &self.vertices
    }

    /// Whether no vertex is pinned.
    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }

    /// Whether `vertex` is pinned.
    pub fn is_pinned(&self, vertex: usize) -> bool {
        self.vertices.binary_search(&vertex).is_ok()
    }

    /// Per degree of freedom (`3 num_vertices` entries): whether it is pinned.
    pub fn pinned_dofs(&self) -> &[bool] {
        &self.fixed
    }

    /// Prepares a step of an integrator whose external load is `m g + f_ext`: zeroes the
    /// velocity `v` at the pinned degrees of freedom, writes the external forces `external`
    /// with zeros at the pinned degrees of freedom into `masked_external` (left empty when
    /// `external` is empty: none), and keeps `gravity` (m/s^2) for the force that cancels
    /// `m g` there. The static solve passes zero gravity.
    pub fn prepare_step(
        &mut self,
        v: &mut [f64],
        external: &[f64],
        gravity: [f64; 3],
        masked_external: &mut Vec<f64>,
    ) {
        for (vi, &f) in v.iter_mut().zip(&self.fixed) {
            if f {
                *vi = 0.0;
            }
        }
        masked_external.clear();
        if !external.is_empty() {
            masked_external.extend(
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

/// A force system whose pinned degrees of freedom are decoupled (module docs). Call
/// [`Pins::prepare_step`] before each step and hand the integrator the masked external forces.
///
/// Line-search trials evaluate the full forces (with the stiffness) of the inner system
/// ([`ForceSystem::forces`], the trait's default `residual_forces`), whose element blocks the
/// pins mask.
///
/// ```
/// use balloon_integrate::decorators::{Pinned, Pins};
/// use balloon_integrate::{ForceSystem, SystemError};
///
/// /// Two particles of 1 kg joined by a linear spring of stiffness 10 N/m (rest length 0).
/// struct Pair([f64; 6]);
/// impl ForceSystem for Pair {
///     fn num_dofs(&self) -> usize { 6 }
///     fn masses(&self) -> &[f64] { &self.0 }
///     fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
///         for d in 0..3 {
///             f[d] = 10.0 * (x[3 + d] - x[d]);
///             f[3 + d] = -f[d];
///         }
///         Ok(())
///     }
///     fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
///         for d in 0..3 {
///             df[d] += 10.0 * (dx[3 + d] - dx[d]);
///             df[3 + d] -= 10.0 * (dx[3 + d] - dx[d]);
///         }
///     }
/// }
///
/// let mut pins = Pins::new(2, vec![0])?;
/// pins.prepare_step(&mut [0.0; 6], &[], [0.0, 0.0, -9.81], &mut Vec::new());
/// let mut pair = Pair([1.0; 6]);
/// let mut held = Pinned::new(&mut pair, &mut pins)?;
/// let mut f = [0.0; 6];
/// held.forces(0.0, &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0], &mut f)?;
/// // Vertex 0: the force that cancels gravity; vertex 1: the spring's.
/// assert_eq!(f, [0.0, 0.0, 9.81, -10.0, 0.0, 0.0]);
/// // Moving the pinned vertex changes no force: its column is zero.
/// let mut df = [0.0; 6];
/// held.add_force_differential(&[1.0, 0.0, 0.0, 0.0, 0.0, 0.0], &mut df);
/// assert_eq!(df, [0.0; 6]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Pinned<'a, S> {
    inner: &'a mut S,
    pins: &'a mut Pins,
}

impl<'a, S: ForceSystem> Pinned<'a, S> {
    /// `inner` with the vertices of `pins` held.
    ///
    /// # Errors
    /// [`DecoratorError::SizeMismatch`] when `pins` were made for another number of vertices
    /// than `inner.num_dofs() / 3`.
    pub fn new(inner: &'a mut S, pins: &'a mut Pins) -> Result<Self, DecoratorError> {
        if pins.fixed.len() != inner.num_dofs() {
            return Err(DecoratorError::SizeMismatch {
                what: "pins",
                expected: pins.fixed.len() / 3,
                found: inner.num_dofs() / 3,
            });
        }
        Ok(Self { inner, pins })
    }
}

/// The static solve scales the inner system's load.
impl<S: LoadScaling> LoadScaling for Pinned<'_, S> {
    fn set_load_factor(&mut self, factor: f64) {
        self.inner.set_load_factor(factor);
    }
}

impl<S: ForceSystem> ForceSystem for Pinned<'_, S> {
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

    /// Never split: the inner system's correction would also need the pins' masking. The
    /// inner system is asked for its exact stiffness (it may have been split for a solve
    /// without pins).
    fn set_stiffness_split(&mut self, _on: bool) -> bool {
        self.inner.set_stiffness_split(false);
        false
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
