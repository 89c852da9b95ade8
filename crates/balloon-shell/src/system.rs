//! The shell balloon as a [`ForceSystem`]: elastic forces of the material's elements (the
//! three-prism of Wang et al. 2015, Eq. 8 and 11, or membrane triangles, `docs/membranes.md`
//! M24-M25) plus the uniform gas (Eq. 15-17), seen by the implicit integrator.

use crate::bending::{Pass, WallBending};
use crate::error::ShellSystemError;
use crate::material::ShellMaterial;
use balloon_element::ElementError;
use balloon_gas::{GasModel, PressureLoad};
use balloon_integrate::{ForceSystem, LowRankTerm, StiffnessBlocks, SystemError, TangentKind};
use balloon_mesh::parallel::prelude::*;
use nalgebra::{SMatrix, SMatrixView, Vector3};

/// Below this many elements the per-element loops run serially (thread start-up would dominate);
/// from this many on they run on rayon with the `parallel` feature (the same results).
pub const PARALLEL_THRESHOLD: usize = 2048;

/// One element's inputs (element, triangle, thickness) and outputs (forces, stiffness block).
type ElementWork<'a, E> = (
    ((&'a E, &'a [usize; 3]), &'a f64),
    (&'a mut [Vector3<f64>; 3], &'a mut [f64; 81]),
);
/// One element's inputs and its force slot, for the force-only pass.
type ElementForceWork<'a, E> = (
    ((&'a E, &'a [usize; 3]), &'a f64),
    &'a mut [Vector3<f64>; 3],
);

/// The gauge pressure of the follower blocks as a function of the enclosed volume `V`:
/// `scale p_gas(V) + lambda - rho (V - volume)`, `p_gas` the gas's own gauge pressure (the
/// static solver's gas term: `scale` the load factor for the own gas, or the augmented
/// Lagrangian's `lambda - rho (V - V_t)` of the volume control with `scale = 0`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FollowerGauge {
    /// Factor on the gas's own gauge pressure.
    pub(crate) scale: f64,
    /// Constant part, Pa.
    pub(crate) lambda: f64,
    /// Slope `-dp/dV` of the volume penalty, Pa/m^3.
    pub(crate) rho: f64,
    /// Volume at which the penalty vanishes, m^3.
    pub(crate) volume: f64,
}

impl FollowerGauge {
    /// The gauge pressure at volume `v`, `own` giving the gas's own (called only when
    /// `scale != 0`).
    fn at(&self, v: f64, own: impl Fn(f64) -> f64) -> f64 {
        let gas = if self.scale != 0.0 {
            self.scale * own(v)
        } else {
            0.0
        };
        gas + self.lambda - self.rho * (v - self.volume)
    }
}

/// The largest ratio of the wall's bending to its stretching stiffness at the mesh's scale
/// (`s h^2 w / (12 |E|^2)` averaged over the hinges, about `(h / l)^2 / 3` for edges of length
/// `l`) at which [`ShellSystem`] splits its stiffness for a factorising preconditioner
/// (`ForceSystem::set_stiffness_split`). Measured with `balloon inflate MESH --steps 10
/// --bending 1` (`docs/benchmarks.md`, "The wall's bending stiffness"): the split saved time
/// at the ratios of the shared models at 1 m (3.4e-5 to 2.1e-4) and of the torus at 0.1 m
/// (3.4e-3); it cost time at 4.2e-3 (the bunny at 0.1 m) and more at 1.5e-2 (spot at
/// 0.1 m), where the hinges hold the wall and CG needs their couplings in the factor. The
/// limit sits below the bunny's with a margin.
pub const SPLIT_STIFFNESS_RATIO: f64 = 2e-3;

/// Elastic shell + gas, with per-element force and stiffness caches filled at each linearisation.
///
/// One element per triangle of a closed mesh (the kind is the material's,
/// [`ShellMaterial::Element`]), lumped vertex masses, and the gas enclosed by the triangles
/// ([`PressureLoad`]: pressure forces, their rank-1 tangent and optionally the follower term,
/// Eq. 15-17). Degrees of freedom are the vertex positions, flat `[x0, y0, z0, x1, ...]` (m).
///
/// ```
/// use balloon_gas::{ConstantPressure, PressureLoad};
/// use balloon_integrate::ForceSystem;
/// use balloon_material::{Lame, StVenantKirchhoff};
/// use balloon_shell::ShellSystem;
///
/// let mesh = balloon_mesh::generate::icosphere(0.1, 1)?;
/// let material = StVenantKirchhoff::new(Lame::try_from_young_poisson(1e6, 0.45)?);
/// // 1 kPa over an ambient of 0: the gas pushes the sphere out.
/// let gas = PressureLoad::new(ConstantPressure::try_new(1000.0)?).with_ambient_pressure(0.0)?;
/// let x = mesh.positions_flat();
/// let thickness = vec![3e-4; mesh.num_triangles()];
/// let mut shell =
///     ShellSystem::from_rest_shape(&x, mesh.triangles.clone(), thickness, 950.0, material, gas)?;
/// let mut f = vec![0.0; x.len()];
/// shell.forces(0.0, &x, &mut f)?;
/// // At rest the elastic forces vanish: only the pressure acts, outwards.
/// let outward: f64 = f.iter().zip(&x).map(|(f, x)| f * x).sum();
/// assert!(outward > 0.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug)]
pub struct ShellSystem<M: ShellMaterial, G: GasModel> {
    pub(crate) triangles: Vec<[usize; 3]>,
    elements: Vec<M::Element>,
    /// Current thickness per element, m, one per triangle and positive (moved by a shell-volume
    /// projection; for a membrane, `H / (l1 l2)` refreshed by
    /// [`ShellSystem::refresh_thickness`]).
    pub thickness: Vec<f64>,
    material: M,
    /// The enclosed gas and its pressure load (state and model, replaceable as a whole).
    pub gas: PressureLoad<G>,
    masses: Vec<f64>,
    /// Vertex -> incident (element, local corner) pairs, CSR layout.
    incident_offsets: Vec<usize>,
    incident: Vec<(u32, u8)>,
    elem_forces: Vec<[Vector3<f64>; 3]>,
    /// Element stiffness blocks, 9x9 column-major (vertex-major dofs), contiguous so that they
    /// can be handed to the assembler as they are ([`ForceSystem::stiffness_blocks`]).
    elem_stiffness: Vec<[f64; 81]>,
    /// Positions of the last linearisation (the gas differential needs them).
    x_lin: Vec<f64>,
    /// Exact element Hessians, or projected onto the PSD cone (projected Newton).
    tangent: TangentKind,
    /// `|f_elastic| + |f_gas|` at the last evaluation, N ([`ForceSystem::force_scale`]).
    force_scale: f64,
    /// When the gas includes the pressure follower term, it goes into `elem_stiffness` (each
    /// triangle's block of `-(p - p_ambient) d^2V/dx^2`), so that the Newton matrix is assembled
    /// from blocks alone (default `true`).
    pub(crate) follower_blocks: bool,
    /// The gauge pressure of the follower blocks in place of the gas's own (then they are in
    /// the blocks whether or not the gas's follower term is on): the static solver's gas term
    /// while it runs (`None` otherwise).
    pub(crate) follower_gauge_override: Option<FollowerGauge>,
    /// The last evaluation was [`ForceSystem::residual_forces`]: `elem_stiffness` is still that
    /// of an earlier point until [`ForceSystem::refresh_stiffness`] recomputes it at `x_lin`.
    stiffness_stale: bool,
    /// The optional bending stiffness of the wall ([`ShellSystem::set_wall_bending`]).
    bending: Option<WallBending>,
}

impl<M: ShellMaterial, G: GasModel> ShellSystem<M, G> {
    /// Builds the system from its parts: `num_vertices` vertices, the `triangles` (outward
    /// oriented, indices below `num_vertices`), one element and one thickness (m) per triangle,
    /// the material the elements are evaluated with, the gas load, and the lumped mass of each
    /// vertex (kg; expanded to degrees of freedom).
    ///
    /// # Errors
    /// [`ShellSystemError::LengthMismatch`] when `elements`, `thickness` or `vertex_masses`
    /// do not have one entry per triangle (vertex), [`ShellSystemError::VertexOutOfRange`] when
    /// a triangle names a vertex that does not exist.
    pub fn try_new(
        num_vertices: usize,
        triangles: Vec<[usize; 3]>,
        elements: Vec<M::Element>,
        thickness: Vec<f64>,
        material: M,
        gas: PressureLoad<G>,
        vertex_masses: &[f64],
    ) -> Result<Self, ShellSystemError> {
        for (what, len, expected) in [
            ("elements", elements.len(), triangles.len()),
            ("thickness", thickness.len(), triangles.len()),
            ("vertex_masses", vertex_masses.len(), num_vertices),
        ] {
            if len != expected {
                return Err(ShellSystemError::LengthMismatch {
                    what,
                    len,
                    expected,
                });
            }
        }
        if let Some((triangle, &vertex)) = triangles
            .iter()
            .enumerate()
            .find_map(|(e, t)| t.iter().find(|&&v| v >= num_vertices).map(|v| (e, v)))
        {
            return Err(ShellSystemError::VertexOutOfRange {
                triangle,
                vertex,
                num_vertices,
            });
        }
        let mut counts = vec![0usize; num_vertices + 1];
        for t in &triangles {
            for &v in t {
                counts[v + 1] += 1;
            }
        }
        for i in 0..num_vertices {
            counts[i + 1] += counts[i];
        }
        let mut fill = counts.clone();
        let mut incident = vec![(0u32, 0u8); counts[num_vertices]];
        for (e, t) in triangles.iter().enumerate() {
            for (l, &v) in t.iter().enumerate() {
                incident[fill[v]] = (e as u32, l as u8);
                fill[v] += 1;
            }
        }
        let masses = vertex_masses.iter().flat_map(|&m| [m; 3]).collect();
        let ne = elements.len();
        Ok(Self {
            triangles,
            elements,
            thickness,
            material,
            gas,
            masses,
            incident_offsets: counts,
            incident,
            elem_forces: vec![[Vector3::zeros(); 3]; ne],
            elem_stiffness: vec![[0.0; 81]; ne],
            x_lin: Vec::new(),
            follower_blocks: true,
            follower_gauge_override: None,
            stiffness_stale: false,
            tangent: TangentKind::Exact,
            force_scale: 0.0,
            bending: None,
        })
    }

    /// Builds the system of a rest shape: `rest` positions (flat, m), its `triangles`, one
    /// rest thickness per triangle (m) and the `density` (kg/m^3): each triangle becomes the
    /// material's rest element ([`ShellMaterial::element`]) and the vertex masses are its
    /// lumped masses ([`ShellMaterial::lumped_masses`], Eq. 19) summed per vertex.
    ///
    /// # Errors
    /// Those of [`ShellSystem::try_new`], a `rest` whose length is not a multiple of 3
    /// ([`ShellSystemError::LengthMismatch`]), and the first rest element the material refuses
    /// ([`ShellSystemError::Element`]: degenerate triangle, thickness not positive).
    pub fn from_rest_shape(
        rest: &[f64],
        triangles: Vec<[usize; 3]>,
        thickness: Vec<f64>,
        density: f64,
        material: M,
        gas: PressureLoad<G>,
    ) -> Result<Self, ShellSystemError> {
        let nv = rest.len() / 3;
        if rest.len() != 3 * nv {
            return Err(ShellSystemError::LengthMismatch {
                what: "rest",
                len: rest.len(),
                expected: 3 * nv,
            });
        }
        if thickness.len() != triangles.len() {
            return Err(ShellSystemError::LengthMismatch {
                what: "thickness",
                len: thickness.len(),
                expected: triangles.len(),
            });
        }
        let mut elements = Vec::with_capacity(triangles.len());
        let mut vertex_mass = vec![0.0; nv];
        for (e, (t, &h)) in triangles.iter().zip(&thickness).enumerate() {
            if let Some(&vertex) = t.iter().find(|&&v| v >= nv) {
                return Err(ShellSystemError::VertexOutOfRange {
                    triangle: e,
                    vertex,
                    num_vertices: nv,
                });
            }
            let corners = t.map(|v| Vector3::new(rest[3 * v], rest[3 * v + 1], rest[3 * v + 2]));
            let el = material
                .element(corners, h)
                .map_err(|source| ShellSystemError::Element { element: e, source })?;
            let m = material.lumped_masses(&el, density);
            for c in 0..3 {
                vertex_mass[t[c]] += m[c];
            }
            elements.push(el);
        }
        Self::try_new(
            nv,
            triangles,
            elements,
            thickness,
            material,
            gas,
            &vertex_mass,
        )
    }

    /// Gives the wall the bending stiffness of a plate of its material and thickness,
    /// `D = factor Y h^3 / (12 (1 - nu^2))` per interior edge (a discrete-shell hinge, Grinspun
    /// et al. 2003, Eq. 3, with the dihedral angles of `rest` as the rest angles; `h` the mean
    /// current thickness of the edge's two triangles, `Y / (1 - nu^2)` the material's
    /// [`ShellMaterial::plate_modulus`]); `factor = 0` removes it. The three-prism wall of
    /// Wang et al. 2015 has none (each prism is extruded along its own triangle's normal), so
    /// the default is 0.
    ///
    /// # Errors
    /// [`ShellSystemError::InvalidParameter`] (`bending`) for a negative or non-finite factor,
    /// [`ShellSystemError::LengthMismatch`] for a `rest` without three coordinates per vertex,
    /// [`ShellSystemError::Element`] for a degenerate rest hinge.
    pub fn set_wall_bending(&mut self, rest: &[f64], factor: f64) -> Result<(), ShellSystemError> {
        if factor == 0.0 {
            self.bending = None;
            return Ok(());
        }
        let expected = self.masses.len();
        if rest.len() != expected {
            return Err(ShellSystemError::LengthMismatch {
                what: "rest",
                len: rest.len(),
                expected,
            });
        }
        self.bending = Some(WallBending::new(
            rest,
            &self.triangles,
            &self.material,
            factor,
        )?);
        self.stiffness_stale = true;
        Ok(())
    }

    /// The factor on the wall's plate bending modulus (0: no bending term; see
    /// [`ShellSystem::set_wall_bending`]).
    pub fn wall_bending(&self) -> f64 {
        self.bending.as_ref().map_or(0.0, WallBending::factor)
    }

    /// The bending energy of the wall at `x` (J; 0 without the term).
    pub fn bending_energy(&self, x: &[f64]) -> f64 {
        self.bending
            .as_ref()
            .map_or(0.0, |b| b.energy(x, &self.thickness))
    }

    /// Appends the part of the bending Hessians that the triangle blocks do not hold, the
    /// coupling of each hinge's two opposite corners, as triplets (nothing without the term).
    pub(crate) fn add_bending_triplets(&self, triplets: &mut Vec<(usize, usize, f64)>) {
        if let Some(b) = &self.bending {
            b.add_triplets(triplets);
        }
    }

    /// The pressure follower term's triplets when it is not in the element blocks.
    fn add_follower_triplets(
        &self,
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), SystemError> {
        if self.follower_in_blocks() {
            return Ok(());
        }
        self.gas
            .add_follower_triplets(&self.x_lin, &self.triangles, triplets)
            .map_err(|e| SystemError::component("gas", e))
    }

    /// What the assembled matrix holds of the bending Hessians beyond the triangle blocks:
    /// the opposite corners' couplings ([`ShellSystem::add_bending_triplets`]), or with a
    /// split stiffness the diagonal blocks that replace them in the preconditioning matrix
    /// (`ForceSystem::set_stiffness_split`).
    pub(crate) fn add_bending_matrix_triplets(&self, triplets: &mut Vec<(usize, usize, f64)>) {
        match &self.bending {
            Some(b) if b.compensated() => b.add_compensation_triplets(triplets),
            Some(b) => b.add_triplets(triplets),
            None => {}
        }
    }

    /// Splits the stiffness for a solver that factorises only a preconditioning matrix
    /// (`on`), or not: with the wall's bending hinges, whose opposite-corner couplings add
    /// fill to a Cholesky factor, the matrix then holds diagonal blocks that bound them
    /// instead (the bending module's `compensate`) and the correction
    /// ([`ShellSystem::add_bending_correction`]) makes up the difference. Only where the
    /// hinges are soft against the wall's stretching at the mesh's scale
    /// ([`SPLIT_STIFFNESS_RATIO`]). Returns whether the split is in effect (never without the
    /// term).
    pub(crate) fn split_bending_stiffness(&mut self, on: bool) -> bool {
        let Some(b) = &mut self.bending else {
            return false;
        };
        // Where the hinges are stiff against stretching (a thin mesh of a small model) they
        // hold the wall, and the factor needs their couplings: split only below the limit.
        let on = on && b.stiffness_ratio(&self.thickness) < SPLIT_STIFFNESS_RATIO;
        if !on {
            b.uncompensate();
        } else if !b.compensated() && b.len() > 0 {
            // The blocks of the current Hessians (recomputed with them from now on).
            b.compensate();
        }
        b.compensated()
    }

    /// `out += scale E p`, the part of the bending Hessians that a split stiffness's matrix
    /// does not hold ([`ShellSystem::split_bending_stiffness`]; nothing without a split).
    pub(crate) fn add_bending_correction(&self, scale: f64, p: &[f64], out: &mut [f64]) {
        if let Some(b) = self.bending.as_ref().filter(|b| b.compensated()) {
            b.add_correction(scale, p, out);
        }
    }

    /// The triangles, one per element.
    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    /// The triangles and the thickness together, for a projection that moves the thickness
    /// of the triangles (Wang et al. 2015, Eq. 24-28).
    pub fn triangles_and_thickness_mut(&mut self) -> (&[[usize; 3]], &mut Vec<f64>) {
        (&self.triangles, &mut self.thickness)
    }

    /// The rest elements, one per triangle.
    pub fn elements(&self) -> &[M::Element] {
        &self.elements
    }

    /// The error for a non-finite elastic energy at `x`: the first element whose energy is not
    /// finite, with its own check of the state (or a non-finite energy when the state passes).
    pub(crate) fn non_finite_energy_error(&self, x: &[f64]) -> SystemError {
        let found = self
            .elements
            .iter()
            .zip(&self.triangles)
            .zip(&self.thickness)
            .enumerate()
            .find(|(_, ((el, t), h))| {
                !self
                    .material
                    .energy(el, &Self::corner_positions(x, t), **h)
                    .is_finite()
            });
        let (element, source) = match found {
            Some((e, ((el, t), &h))) => (
                e,
                self.material
                    .check_state(el, &Self::corner_positions(x, t), h)
                    .err()
                    .unwrap_or(ElementError::NonFinite {
                        element: self.material.element_name(),
                        quantity: "elastic energy",
                    }),
            ),
            None => (
                0,
                ElementError::NonFinite {
                    element: self.material.element_name(),
                    quantity: "elastic energy",
                },
            ),
        };
        SystemError::InvertedElement { element, source }
    }

    fn corner_positions(x: &[f64], t: &[usize; 3]) -> [Vector3<f64>; 3] {
        t.map(|v| Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]))
    }

    /// Total elastic energy at positions `x` (J): `sum_e V_e Psi(F_e)` (Wang et al. 2015, Eq. 6-7; for a
    /// membrane `sum_e A0_e H_e W(C_e)`, `docs/membranes.md` M23), the energy whose negative
    /// gradient are the elastic forces (Eq. 8).
    pub fn elastic_energy(&self, x: &[f64]) -> f64 {
        self.element_energy(x) + self.bending_energy(x)
    }

    /// The elements' part of [`ShellSystem::elastic_energy`].
    fn element_energy(&self, x: &[f64]) -> f64 {
        let energy = |((el, t), &h): ((&M::Element, &[usize; 3]), &f64)| {
            self.material.energy(el, &Self::corner_positions(x, t), h)
        };
        if self.elements.len() >= PARALLEL_THRESHOLD {
            self.elements
                .par_iter()
                .zip(self.triangles.par_iter())
                .zip(self.thickness.par_iter())
                .map(energy)
                .sum()
        } else {
            self.elements
                .iter()
                .zip(&self.triangles)
                .zip(&self.thickness)
                .map(energy)
                .sum()
        }
    }

    /// Potential energy of the gas at `x` and `time`, J: `Phi(V, t) + p_ambient V` (the
    /// isothermal gas `-p0 V0 ln V`, the constant pressure `-p V`, the pump `-nRT(t) ln V`,
    /// see `balloon_gas::GasModel::potential`), whose negative gradient are the pressure forces
    /// (Eq. 15); `None` for a gas model without a potential.
    pub fn gas_energy(&self, time: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        self.gas
            .potential_at(time, x, &self.triangles)
            .map_err(|e| SystemError::component("gas", e))
    }

    /// Gathers per-element corner values into per-vertex sums: `out[3v..3v+3] = sum value(e, l)`.
    fn gather(&self, out: &mut [f64], value: impl Fn(usize, usize) -> Vector3<f64> + Sync) {
        let body = |(v, o): (usize, &mut [f64])| {
            let mut acc = Vector3::zeros();
            for &(e, l) in &self.incident[self.incident_offsets[v]..self.incident_offsets[v + 1]] {
                acc += value(e as usize, l as usize);
            }
            o[0] += acc.x;
            o[1] += acc.y;
            o[2] += acc.z;
        };
        if self.elements.len() >= PARALLEL_THRESHOLD {
            out.par_chunks_mut(3).enumerate().for_each(body);
        } else {
            out.chunks_mut(3).enumerate().for_each(body);
        }
    }

    /// For a material whose thickness follows the stretch ([`ShellMaterial::thickness_follows_stretch`],
    /// the incompressible membranes) sets every element's thickness to its value at `x`,
    /// `h = H / (l1 l2)` (`docs/membranes.md` M2); otherwise does nothing (the three-prism
    /// thickness is a state moved only by the projection).
    pub fn refresh_thickness(&mut self, x: &[f64]) {
        if !self.material.thickness_follows_stretch() {
            return;
        }
        let material = &self.material;
        let update = |((el, t), h): ((&M::Element, &[usize; 3]), &mut f64)| {
            *h = material.current_thickness(el, &Self::corner_positions(x, t), *h);
        };
        if self.elements.len() >= PARALLEL_THRESHOLD {
            self.elements
                .par_iter()
                .zip(self.triangles.par_iter())
                .zip(self.thickness.par_iter_mut())
                .for_each(update);
        } else {
            self.elements
                .iter()
                .zip(&self.triangles)
                .zip(self.thickness.iter_mut())
                .for_each(update);
        }
    }

    /// The material the elements are evaluated with.
    pub fn material(&self) -> &M {
        &self.material
    }

    /// Whether the element blocks carry a follower term (the `follower_blocks` switch, and
    /// the gas's follower term or an override of its gauge pressure).
    pub(crate) fn follower_in_blocks(&self) -> bool {
        self.follower_blocks && (self.follower_gauge_override.is_some() || self.gas.follower_term())
    }

    /// The gauge pressure at `x` and `time` for the follower blocks (`None` when they are not
    /// wanted, or the volume is not positive: the gas evaluation reports that).
    fn follower_gauge(&self, time: f64, x: &[f64]) -> Option<f64> {
        if !self.follower_in_blocks() {
            return None;
        }
        let volume = balloon_gas::enclosed_volume(x, &self.triangles).ok()?;
        if !(volume.is_finite() && volume > 0.0) {
            return None;
        }
        let own = |v: f64| self.gas.gas().absolute_pressure(v, time) - self.gas.ambient_pressure();
        Some(match self.follower_gauge_override {
            Some(o) => o.at(volume, own),
            None => own(volume),
        })
    }

    /// Element forces and stiffness blocks at `x` into the caches (Wang et al. 2015, Eq. 8 and 11),
    /// with the pressure follower term at gauge pressure `follower` added to each block when
    /// given (`balloon_gas::add_volume_hessian_block`).
    fn element_forces_and_stiffness(&mut self, x: &[f64], follower: Option<f64>) {
        let material = &self.material;
        let triangles = &self.triangles;
        let projected = self.tangent == TangentKind::Projected;
        let work = |(((el, t), &h), (fe, ke)): ElementWork<'_, M::Element>| {
            let xs = Self::corner_positions(x, t);
            let (forces, stiffness) = material.forces_and_stiffness(el, &xs, h, projected);
            *fe = forces;
            ke.copy_from_slice(stiffness.as_slice());
            if let Some(gauge) = follower {
                balloon_gas::add_volume_hessian_block(&xs, -gauge, ke);
            }
        };
        let it = self
            .elements
            .iter()
            .zip(triangles.iter())
            .zip(self.thickness.iter());
        if self.elements.len() >= PARALLEL_THRESHOLD {
            self.elements
                .par_iter()
                .zip(triangles.par_iter())
                .zip(self.thickness.par_iter())
                .zip(
                    self.elem_forces
                        .par_iter_mut()
                        .zip(self.elem_stiffness.par_iter_mut()),
                )
                .for_each(work);
        } else {
            it.zip(
                self.elem_forces
                    .iter_mut()
                    .zip(self.elem_stiffness.iter_mut()),
            )
            .for_each(work);
        }
        if let Some(b) = &mut self.bending {
            b.evaluate(x, &self.thickness, Pass::Stiffness);
            b.fold_into_blocks(&mut self.elem_stiffness);
            if b.compensated() {
                b.compensate();
            }
        }
    }

    /// The element forces at `x` alone into the cache (the stiffness left stale for
    /// [`ForceSystem::refresh_stiffness`]); with `energy` also the elastic energy of the same
    /// pass ([`ShellMaterial::forces_and_energy`]), returned summed (0 without).
    fn element_forces(&mut self, x: &[f64], energy: bool) -> f64 {
        let material = &self.material;
        let triangles = &self.triangles;
        let work = |(((el, t), &h), fe): ElementForceWork<'_, M::Element>| {
            let xs = Self::corner_positions(x, t);
            if energy {
                let (forces, e) = material.forces_and_energy(el, &xs, h);
                *fe = forces;
                e
            } else {
                *fe = material.forces(el, &xs, h);
                0.0
            }
        };
        self.stiffness_stale = true;
        let elements: f64 = if self.elements.len() >= PARALLEL_THRESHOLD {
            self.elements
                .par_iter()
                .zip(triangles.par_iter())
                .zip(self.thickness.par_iter())
                .zip(self.elem_forces.par_iter_mut())
                .map(work)
                .sum()
        } else {
            self.elements
                .iter()
                .zip(triangles.iter())
                .zip(self.thickness.iter())
                .zip(self.elem_forces.iter_mut())
                .map(work)
                .sum()
        };
        let bending = match &mut self.bending {
            Some(b) => b.evaluate(
                x,
                &self.thickness,
                if energy {
                    Pass::ForcesAndEnergy
                } else {
                    Pass::Forces
                },
            ),
            None => 0.0,
        };
        elements + bending
    }

    /// The rest of a force evaluation once the element forces are cached: their check, the
    /// gather into `f`, the gas forces (Eq. 15) and the force scale; keeps `x` as the
    /// linearisation point.
    fn finish_forces(&mut self, time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        if let Some(e) = self
            .elem_forces
            .iter()
            .position(|fe| fe.iter().any(|c| !c.iter().all(|v| v.is_finite())))
        {
            let xs = Self::corner_positions(x, &self.triangles[e]);
            let source = match self
                .material
                .check_state(&self.elements[e], &xs, self.thickness[e])
            {
                Err(err) => err,
                Ok(()) => ElementError::NonFinite {
                    element: self.material.element_name(),
                    quantity: "elastic force",
                },
            };
            return Err(SystemError::InvertedElement { element: e, source });
        }
        if let Some(b) = &self.bending
            && let Some(k) = b.non_finite()
        {
            return Err(SystemError::InvertedElement {
                element: b.face(k),
                source: ElementError::NonFinite {
                    element: "hinge",
                    quantity: "bending force",
                },
            });
        }
        f.iter_mut().for_each(|v| *v = 0.0);
        let forces = &self.elem_forces;
        self.gather(f, |e, l| forces[e][l]);
        if let Some(b) = &self.bending {
            b.add_forces(f);
        }
        let elastic = f.iter().map(|v| v * v).sum::<f64>().sqrt();
        self.gas
            .evaluate(time, x, &self.triangles, f)
            .map_err(|e| SystemError::component("gas", e))?;
        // The pressure force is gauge * dV/dx (Eq. 15).
        let gas = self.gas.state().gauge_pressure.abs()
            * self
                .gas
                .low_rank_term()
                .vector
                .iter()
                .map(|v| v * v)
                .sum::<f64>()
                .sqrt();
        self.force_scale = elastic + gas;
        self.x_lin.clear();
        self.x_lin.extend_from_slice(x);
        Ok(())
    }

    /// Elastic part of the force differential, `df += -K_elastic dx`.
    pub fn add_elastic_differential(&self, dx: &[f64], df: &mut [f64]) {
        let tris = &self.triangles;
        let ks = &self.elem_stiffness;
        self.gather(df, |e, l| {
            let t = &tris[e];
            let mut dxe = SMatrix::<f64, 9, 1>::zeros();
            for (c, &v) in t.iter().enumerate() {
                dxe[3 * c] = dx[3 * v];
                dxe[3 * c + 1] = dx[3 * v + 1];
                dxe[3 * c + 2] = dx[3 * v + 2];
            }
            -(SMatrixView::<f64, 9, 9>::from_slice(&ks[e]).fixed_view::<3, 9>(3 * l, 0) * dxe)
        });
        if let Some(b) = &self.bending {
            b.add_differential(dx, df);
        }
    }
}

impl<M: ShellMaterial, G: GasModel> ForceSystem for ShellSystem<M, G> {
    fn num_dofs(&self) -> usize {
        self.masses.len()
    }

    fn masses(&self) -> &[f64] {
        &self.masses
    }

    fn forces(&mut self, time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        let follower = self.follower_gauge(time, x);
        self.element_forces_and_stiffness(x, follower);
        self.stiffness_stale = false;
        self.finish_forces(time, x, f)
    }

    /// The forces alone (`ShellMaterial::forces`, bit for bit those of [`ForceSystem::forces`]);
    /// the element stiffness waits for [`ForceSystem::refresh_stiffness`].
    fn residual_forces(&mut self, time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.element_forces(x, false);
        self.finish_forces(time, x, f)
    }

    /// The forces of [`ForceSystem::residual_forces`] and the energy of
    /// [`ForceSystem::potential_energy`] in one pass over the elements
    /// ([`ShellMaterial::forces_and_energy`]); the gas energy from the enclosed volume.
    fn residual_forces_and_energy(
        &mut self,
        time: f64,
        x: &[f64],
        f: &mut [f64],
    ) -> Result<Option<f64>, SystemError> {
        let elastic = self.element_forces(x, true);
        self.finish_forces(time, x, f)?;
        let Some(gas) = self.gas_energy(time, x)? else {
            return Ok(None);
        };
        if !elastic.is_finite() {
            return Err(self.non_finite_energy_error(x));
        }
        Ok(Some(elastic + gas))
    }

    /// One pass over the elements gives both (see `residual_forces_and_energy`).
    fn fuses_forces_and_energy(&self) -> bool {
        true
    }

    /// Recomputes the element forces and stiffness at `x_lin` after
    /// [`ForceSystem::residual_forces`] (the forces come out the same; the gas terms were
    /// already evaluated there).
    fn refresh_stiffness(&mut self) -> Result<(), SystemError> {
        if self.stiffness_stale {
            let x = std::mem::take(&mut self.x_lin);
            // The gas was evaluated at `x_lin` by `residual_forces`.
            let state = self.gas.state();
            let follower = self.follower_in_blocks().then(|| {
                let own = |_: f64| state.gauge_pressure;
                match self.follower_gauge_override {
                    Some(o) => o.at(state.volume, own),
                    None => state.gauge_pressure,
                }
            });
            self.element_forces_and_stiffness(&x, follower);
            self.x_lin = x;
            self.stiffness_stale = false;
        }
        Ok(())
    }

    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        self.add_elastic_differential(dx, df);
        if self.follower_in_blocks() {
            // The follower term is in the element blocks (so in the elastic differential).
            self.gas.add_rank1_differential(dx, df);
            return;
        }
        // Lengths and indices were checked by the evaluation at `x_lin`, so this cannot fail.
        let checked = self
            .gas
            .add_differential(&self.x_lin, &self.triangles, dx, df);
        debug_assert!(checked.is_ok(), "gas differential: {checked:?}");
    }

    fn add_stiffness_triplets(
        &self,
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), SystemError> {
        triplets.reserve(81 * self.elements.len());
        for (t, k) in self.triangles.iter().zip(&self.elem_stiffness) {
            let k = SMatrixView::<f64, 9, 9>::from_slice(k);
            for a in 0..3 {
                for b in 0..3 {
                    for i in 0..3 {
                        for j in 0..3 {
                            triplets.push((3 * t[a] + i, 3 * t[b] + j, k[(3 * a + i, 3 * b + j)]));
                        }
                    }
                }
            }
        }
        // The exact couplings, also with a split stiffness.
        self.add_bending_triplets(triplets);
        self.add_follower_triplets(triplets)
    }

    fn add_stiffness_diagonal(&self, diagonal: &mut [f64]) -> Result<(), SystemError> {
        let ks = &self.elem_stiffness;
        self.gather(diagonal, |e, l| {
            // Column-major: entry (i, i) is at 10 i.
            Vector3::new(ks[e][30 * l], ks[e][30 * l + 10], ks[e][30 * l + 20])
        });
        Ok(())
    }

    fn stiffness_blocks(&self) -> Option<StiffnessBlocks<'_>> {
        Some(StiffnessBlocks {
            nodes_per_block: 3,
            nodes: self.triangles.as_flattened(),
            values: self.elem_stiffness.as_flattened(),
        })
    }

    /// The couplings of the wall's bending hinges that no triangle block holds (their two
    /// opposite corners; [`ShellSystem::set_wall_bending`]), and the pressure
    /// follower term when enabled and not in the element blocks (the `follower_blocks`
    /// switch).
    fn add_remaining_stiffness_triplets(
        &self,
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), SystemError> {
        self.add_bending_matrix_triplets(triplets);
        self.add_follower_triplets(triplets)
    }

    /// With the wall's bending term, the matrix then holds diagonal blocks in place of each
    /// hinge's opposite-corner coupling (no fill in a Cholesky factor from them), and
    /// [`ForceSystem::add_stiffness_correction`] the difference (see
    /// `docs/elements.md`, section 8).
    fn set_stiffness_split(&mut self, on: bool) -> bool {
        self.split_bending_stiffness(on)
    }

    fn add_stiffness_correction(&self, scale: f64, p: &[f64], out: &mut [f64]) {
        self.add_bending_correction(scale, p, out);
    }

    /// Both kinds: [`TangentKind::Projected`] projects each element's Hessian onto the PSD cone
    /// (`ThreePrism::forces_and_projected_stiffness`, `HyperMembrane::forces_and_projected_stiffness`,
    /// through [`ShellMaterial::forces_and_stiffness`]); the gas terms are unchanged (the
    /// rank-1 volume coupling is PSD, the optional follower term is not projected).
    fn set_tangent(&mut self, kind: TangentKind) -> Result<(), SystemError> {
        self.tangent = kind;
        Ok(())
    }

    fn low_rank_terms(&self) -> &[LowRankTerm] {
        std::slice::from_ref(self.gas.low_rank_term())
    }

    /// Elastic plus gas energy, [`ShellSystem::elastic_energy`] + [`ShellSystem::gas_energy`]
    /// (`None` when the gas has no potential). An element whose energy is not finite
    /// (inverted or degenerate) is [`SystemError::InvertedElement`].
    fn potential_energy(&mut self, time: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        let Some(gas) = self.gas_energy(time, x)? else {
            return Ok(None);
        };
        let elastic = self.elastic_energy(x);
        if !elastic.is_finite() {
            return Err(self.non_finite_energy_error(x));
        }
        Ok(Some(elastic + gas))
    }

    /// `|f_elastic| + |f_gas|` (N) at the last evaluation: the two balance at an inflated rest
    /// shape, where `|f|` alone is round-off.
    fn force_scale(&self) -> Option<f64> {
        Some(self.force_scale)
    }
}
