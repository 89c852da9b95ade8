//! The shell balloon as a [`ForceSystem`]: elastic forces of the material's elements (three-prism,
//! seed 000 Eq. 8, 11, or membrane triangles, `docs/membranes.md` M24-M25) plus the uniform gas
//! (Eq. 15-17), seen by the implicit integrator.

use super::ShellMaterial;
use balloon_element::ElementError;
use balloon_gas::{GasModel, PressureLoad};
use balloon_integrate::{ForceSystem, LowRankTerm, StiffnessBlocks, SystemError, TangentKind};
use balloon_mesh::parallel::prelude::*;
use nalgebra::{SMatrix, SMatrixView, Vector3};

/// Below this many elements the per-element loops run serially (thread start-up would dominate).
const PARALLEL_THRESHOLD: usize = 2048;

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

/// Elastic shell + gas, with per-element force and stiffness caches filled at each linearisation.
#[derive(Debug)]
pub struct ShellSystem<M: ShellMaterial, G: GasModel> {
    pub(crate) triangles: Vec<[usize; 3]>,
    pub(crate) elements: Vec<M::Element>,
    /// Current thickness per element, m (changed by the volume projection; for a membrane,
    /// `H / (l1 l2)` refreshed by [`ShellSystem::refresh_thickness`]).
    pub(crate) thickness: Vec<f64>,
    pub(crate) material: M,
    pub(crate) gas: PressureLoad<G>,
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
}

impl<M: ShellMaterial, G: GasModel> ShellSystem<M, G> {
    /// Builds the system. `masses` is per vertex (kg); it is expanded to degrees of freedom.
    pub(crate) fn new(
        num_vertices: usize,
        triangles: Vec<[usize; 3]>,
        elements: Vec<M::Element>,
        thickness: Vec<f64>,
        material: M,
        gas: PressureLoad<G>,
        vertex_masses: &[f64],
    ) -> Self {
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
        Self {
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
        }
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

    /// A copy with the same state (the system is not `Clone` because the material need not
    /// be).
    #[cfg(test)]
    pub(crate) fn clone_for_tests(&self) -> Self
    where
        M: Clone,
        G: Clone,
    {
        Self {
            triangles: self.triangles.clone(),
            elements: self.elements.clone(),
            thickness: self.thickness.clone(),
            material: self.material.clone(),
            gas: self.gas.clone(),
            masses: self.masses.clone(),
            incident_offsets: self.incident_offsets.clone(),
            incident: self.incident.clone(),
            elem_forces: self.elem_forces.clone(),
            elem_stiffness: self.elem_stiffness.clone(),
            x_lin: self.x_lin.clone(),
            follower_blocks: self.follower_blocks,
            follower_gauge_override: self.follower_gauge_override,
            stiffness_stale: self.stiffness_stale,
            tangent: self.tangent,
            force_scale: self.force_scale,
        }
    }

    /// Total elastic energy at positions `x` (J): `sum_e V_e Psi(F_e)` (seed 000, Eq. 6-7; for a
    /// membrane `sum_e A0_e H_e W(C_e)`, `docs/membranes.md` M23), the energy whose negative
    /// gradient are the elastic forces (Eq. 8).
    pub fn elastic_energy(&self, x: &[f64]) -> f64 {
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
    pub(crate) fn refresh_thickness(&mut self, x: &[f64]) {
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
    fn follower_in_blocks(&self) -> bool {
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

    /// Element forces and stiffness blocks at `x` into the caches (seed 000, Eq. 8 and 11),
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
        if self.elements.len() >= PARALLEL_THRESHOLD {
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
        }
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
        f.iter_mut().for_each(|v| *v = 0.0);
        let forces = &self.elem_forces;
        self.gather(f, |e, l| forces[e][l]);
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
    pub(crate) fn add_elastic_differential(&self, dx: &[f64], df: &mut [f64]) {
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
        self.add_remaining_stiffness_triplets(triplets)
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

    /// The pressure follower term when enabled and not in the element blocks
    /// (the `follower_blocks` switch); nothing otherwise.
    fn add_remaining_stiffness_triplets(
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

#[cfg(test)]
mod tests {
    use crate::gas::GasKind;
    use crate::integrate::TangentKind;
    use crate::integrate::linear::LinearSolverKind;
    use crate::material::{Lame, StVenantKirchhoff};
    use crate::mesh::generate::icosphere;
    use crate::mesh::geometry;
    use crate::shell::ShellBalloon;
    use crate::shell::analytic::sphere_stretch;
    use balloon_integrate::ForceSystem;

    /// Projected Newton (per-element PSD stiffness) converges to the same equilibrium as the
    /// exact tangent: the analytic StVK sphere stretch within 0.5 % on the 2562-vertex icosphere
    /// at two pressures, with both assembled solvers that rely on an SPD matrix.
    #[test]
    fn projected_tangent_inflates_the_sphere_to_the_analytic_stretch() {
        let mesh = icosphere(0.1, 4).unwrap();
        let r = 3.0 * geometry::enclosed_volume(&mesh) / geometry::surface_area(&mesh);
        let lame = Lame::try_from_young_poisson(1.0e6, 0.45).unwrap();
        let material = StVenantKirchhoff::new(lame);
        let h0 = 3.0e-4;
        for (p, kind) in [
            (1500.0, LinearSolverKind::Cholesky),
            (3000.0, LinearSolverKind::FactorizedPcg),
        ] {
            let mut sim = ShellBalloon::new(mesh.clone())
                .with_material(material)
                .with_thickness(h0)
                .with_gas(GasKind::Constant)
                .with_gauge_pressure(p)
                .with_linear_solver(kind)
                .with_dt(1.0)
                .build()
                .unwrap();
            sim.configure_integrator(|p| p.tangent = TangentKind::Projected)
                .unwrap();
            let mut last = 0.0;
            let mut settled = false;
            for _ in 0..60 {
                let s = sim.step().unwrap();
                if (s.gas_volume - last).abs() < 1e-9 * s.gas_volume {
                    settled = true;
                    break;
                }
                last = s.gas_volume;
            }
            assert!(settled, "p = {p}, {kind}: did not settle");
            let lambda = (sim.gas_volume() / sim.rest_gas_volume()).cbrt();
            let expected = sphere_stretch(&material, h0, r, p).unwrap();
            assert!(
                (lambda / expected - 1.0).abs() < 5e-3,
                "p = {p}, {kind}: stretch {lambda} vs analytic {expected}"
            );
        }
    }

    /// The forces of a line-search trial (`residual_forces`) are bit for bit those of
    /// `forces`, for the prism (StVK and neo-Hookean), a membrane and the run-time material
    /// enum; the stiffness stays that of the earlier point until `refresh_stiffness`, which
    /// then gives exactly the blocks `forces` computes.
    #[test]
    fn residual_forces_equal_the_forces_and_the_refresh_gives_their_stiffness() {
        use crate::material::{MaterialKind, MaterialModel, NeoHookean};
        use crate::shell::{ShellMaterial, ShellMaterialModel, ShellSimulation};
        use balloon_material::membrane::{MembraneModel, MembraneNeoHookean};

        fn check<M: ShellMaterial>(name: &str, mut sim: ShellSimulation<M>) {
            let rest = sim.positions().to_vec();
            let n = rest.len();
            let mut rng = balloon_test_support::Rng::new(11);
            let x: Vec<f64> = rest
                .iter()
                .map(|v| 1.15 * v + 2e-3 * rng.next_f64())
                .collect();
            let sys = &mut sim.system;
            let (mut f_full, mut f_res) = (vec![0.0; n], vec![0.0; n]);
            sys.forces(0.0, &rest, &mut f_full).unwrap();
            let at_rest = sys.stiffness_blocks().unwrap().values.to_vec();
            sys.residual_forces(0.0, &x, &mut f_res).unwrap();
            assert_eq!(
                sys.stiffness_blocks().unwrap().values,
                &at_rest[..],
                "{name}: stale until refreshed"
            );
            sys.refresh_stiffness().unwrap();
            let refreshed = sys.stiffness_blocks().unwrap().values.to_vec();
            sys.forces(0.0, &x, &mut f_full).unwrap();
            let eager = sys.stiffness_blocks().unwrap().values.to_vec();
            assert!(
                f_res
                    .iter()
                    .zip(&f_full)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{name}: residual forces differ"
            );
            assert!(
                refreshed
                    .iter()
                    .zip(&eager)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{name}: refreshed stiffness differs"
            );
            assert!(refreshed != at_rest, "{name}: the point moved");
            // A second refresh changes nothing (it is a no-op once fresh).
            sys.refresh_stiffness().unwrap();
            assert_eq!(sys.stiffness_blocks().unwrap().values, &eager[..]);
            // The fused evaluation of a line-search trial: the same forces bit for bit, the
            // energy of `potential_energy`, the stiffness left stale as `residual_forces` does.
            assert!(sys.fuses_forces_and_energy());
            sys.forces(0.0, &rest, &mut f_full).unwrap();
            let mut f_fused = vec![0.0; n];
            let fused = sys
                .residual_forces_and_energy(0.0, &x, &mut f_fused)
                .unwrap()
                .unwrap();
            assert_eq!(
                sys.stiffness_blocks().unwrap().values,
                &at_rest[..],
                "{name}: fused evaluation left the stiffness stale"
            );
            assert!(
                f_fused
                    .iter()
                    .zip(&f_res)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{name}: fused forces differ"
            );
            let energy = sys.potential_energy(0.0, &x).unwrap().unwrap();
            assert!(
                (fused - energy).abs() <= 1e-12 * energy.abs().max(1e-30),
                "{name}: fused energy {fused} against {energy}"
            );
            assert!(energy.abs() > 0.0, "{name}");
        }

        let mesh = icosphere(0.1, 2).unwrap();
        let lame = Lame::try_from_young_poisson(1.0e6, 0.45).unwrap();
        let base = || {
            ShellBalloon::new(mesh.clone())
                .with_gas(GasKind::Constant)
                .with_gauge_pressure(800.0)
        };
        check("stvk", base().build().unwrap());
        check(
            "neo-hookean",
            base().with_material(NeoHookean::new(lame)).build().unwrap(),
        );
        let membrane = MembraneNeoHookean::try_new(3e5).unwrap();
        check("membrane", base().with_membrane(membrane).build().unwrap());
        check(
            "enum prism",
            base()
                .with_material(ShellMaterialModel::from(MaterialModel::from_lame(
                    MaterialKind::StVenantKirchhoff,
                    lame,
                )))
                .build()
                .unwrap(),
        );
        check(
            "enum membrane",
            base()
                .with_material(ShellMaterialModel::from(MembraneModel::from(membrane)))
                .build()
                .unwrap(),
        );
        // Above the parallel threshold (5120 elements: the element passes run on rayon).
        let fine = icosphere(0.1, 4).unwrap();
        assert!(fine.num_triangles() >= super::PARALLEL_THRESHOLD);
        check(
            "stvk, parallel",
            ShellBalloon::new(fine)
                .with_gas(GasKind::Ideal)
                .with_gauge_pressure(800.0)
                .build()
                .unwrap(),
        );
    }

    /// The element blocks plus the remaining triplets are the full stiffness; with the follower
    /// term in the blocks (the default) there are no remaining triplets, and the matrix equals
    /// the elastic blocks plus the gas's own follower triplets
    /// (`balloon_gas::add_volume_hessian_triplets`, written independently of the block form).
    #[test]
    fn stiffness_blocks_and_remaining_triplets_equal_the_triplets() {
        use balloon_integrate::linear::SparseAssembler;
        let mesh = icosphere(0.1, 2).unwrap();
        let mut sim = ShellBalloon::new(mesh)
            .with_follower_term(true)
            .with_gauge_pressure(900.0)
            .with_linear_solver(LinearSolverKind::Cholesky)
            .build()
            .unwrap();
        let x: Vec<f64> = sim.positions().iter().map(|v| 1.2 * v).collect();
        let n = x.len();
        let d = vec![1.0; n];
        let sys = &mut sim.system;
        let mut f = vec![0.0; n];
        let mut matrices = Vec::new();
        for in_blocks in [true, false] {
            sys.follower_blocks = in_blocks;
            sys.forces(0.0, &x, &mut f).unwrap();
            let mut all = Vec::new();
            sys.add_stiffness_triplets(&mut all).unwrap();
            let mut rest = Vec::new();
            sys.add_remaining_stiffness_triplets(&mut rest).unwrap();
            assert_eq!(
                rest.is_empty(),
                in_blocks,
                "follower triplets unless in the blocks"
            );
            let blocks = sys.stiffness_blocks().unwrap();
            let (mut a, mut b) = (SparseAssembler::new(), SparseAssembler::new());
            a.assemble(&d, 2.0, &all, 0.5).unwrap();
            b.assemble_blocks(&d, 2.0, &blocks, &rest, 0.5).unwrap();
            assert_eq!(a.matrix().col_idx, b.matrix().col_idx);
            let scale = a.matrix().values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (u, v) in a.matrix().values.iter().zip(&b.matrix().values) {
                assert!((u - v).abs() <= 1e-12 * scale);
            }
            matrices.push(a.matrix().clone());
        }
        // Same matrix either way: the block form of the follower term is the triplet form.
        let (with_blocks, with_triplets) = (&matrices[0], &matrices[1]);
        assert_eq!(with_blocks.col_idx, with_triplets.col_idx);
        let scale = with_triplets
            .values
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        let most = with_blocks
            .values
            .iter()
            .zip(&with_triplets.values)
            .fold(0.0f64, |m, (u, v)| m.max((u - v).abs()));
        assert!(most <= 1e-12 * scale, "{most:e} of {scale:e}");
        // And the follower term is there: the matrix differs from the elastic one.
        sys.follower_blocks = false;
        sys.gas = sys.gas.clone().with_follower_term(false);
        sys.forces(0.0, &x, &mut f).unwrap();
        let mut elastic = Vec::new();
        sys.add_stiffness_triplets(&mut elastic).unwrap();
        let mut e = SparseAssembler::new();
        e.assemble(&d, 2.0, &elastic, 0.5).unwrap();
        let sum = |m: &balloon_integrate::linear::CsrMatrix| {
            m.values.iter().map(|v| v.abs()).sum::<f64>()
        };
        assert!((sum(e.matrix()) - sum(with_blocks)).abs() > 1e-6 * sum(with_blocks));
    }

    /// The projected tangent reaches the element stiffness the integrator sees: on a state with
    /// compressed elements the exact assembled matrix is indefinite and the projected one is not
    /// (checked with the quadratic form along the eigenvector directions of a dense copy). The
    /// pressure follower term, which is not projected, is left out here.
    #[test]
    fn projected_tangent_makes_the_assembled_stiffness_psd() {
        let mesh = icosphere(0.1, 1).unwrap();
        let mut sim = ShellBalloon::new(mesh)
            .with_follower_term(false)
            .with_linear_solver(LinearSolverKind::Cholesky)
            .build()
            .unwrap();
        // Shrink the sphere to 80 %: every element is in compression.
        let x: Vec<f64> = sim.positions().iter().map(|v| 0.8 * v).collect();
        let n = x.len();
        let mut min_eig = Vec::new();
        for kind in [TangentKind::Exact, TangentKind::Projected] {
            let sys = &mut sim.system;
            sys.set_tangent(kind).unwrap();
            let mut f = vec![0.0; n];
            sys.forces(0.0, &x, &mut f).unwrap();
            let mut t = Vec::new();
            sys.add_stiffness_triplets(&mut t).unwrap();
            let mut k = nalgebra::DMatrix::<f64>::zeros(n, n);
            for (r, c, v) in t {
                k[(r, c)] += v;
            }
            // The differential used by matrix-free CG is the same matrix.
            let dx: Vec<f64> = (0..n).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
            let mut df = vec![0.0; n];
            sys.add_elastic_differential(&dx, &mut df);
            let kdx = &k * nalgebra::DVector::from_column_slice(&dx);
            for i in 0..n {
                assert!(
                    (kdx[i] + df[i]).abs() <= 1e-9 * kdx.amax(),
                    "{kind} dof {i}"
                );
            }
            let ev = k.symmetric_eigen().eigenvalues;
            min_eig.push(ev.min() / ev.amax());
        }
        assert!(
            min_eig[0] < -1e-3,
            "exact tangent should be indefinite: {min_eig:?}"
        );
        assert!(min_eig[1] > -1e-9, "projected tangent not PSD: {min_eig:?}");
    }

    /// The potential's gradient is minus the forces (elastic + gas) for every gas model, at
    /// zero and standard ambient pressure, and with anchor springs on top (finite differences
    /// on a deformed state, at the time the pump has pumped for a while).
    /// A collapsed element reaches the caller as the element's own typed error, with its index.
    #[test]
    fn a_collapsed_element_is_a_typed_inverted_element_error() {
        use balloon_element::ElementError;
        use balloon_integrate::SystemError;
        let sim = ShellBalloon::new(icosphere(0.1, 1).unwrap())
            .build()
            .unwrap();
        let mut sys = sim.system.clone_for_tests();
        let mut x = sim.positions().to_vec();
        let [a, b, _] = sys.triangles[5];
        for k in 0..3 {
            x[3 * b + k] = x[3 * a + k];
        }
        let mut f = vec![0.0; x.len()];
        let err = sys.forces(0.0, &x, &mut f).unwrap_err();
        match &err {
            SystemError::InvertedElement {
                element,
                source:
                    ElementError::Degenerate {
                        quantity, value, ..
                    },
            } => {
                assert!(
                    sys.triangles[*element].contains(&a) && sys.triangles[*element].contains(&b)
                );
                assert_eq!((*quantity, *value), ("area", 0.0));
            }
            other => panic!("expected InvertedElement with a degenerate area, got {other:?}"),
        }
        assert!(std::error::Error::source(&err).is_some());
    }

    #[test]
    fn potential_energy_gradient_is_minus_the_forces_for_every_gas() {
        use crate::shell::{AnchorSpring, WithAnchors};
        use balloon_test_support::{Rng, check_gradient};
        let mesh = icosphere(0.1, 1).unwrap();
        let time = 0.3;
        for kind in [GasKind::Ideal, GasKind::Constant, GasKind::Pump] {
            for ambient in [0.0, crate::gas::STANDARD_ATMOSPHERE] {
                if kind == GasKind::Pump && ambient == 0.0 {
                    continue; // the pump starts from the ambient pressure
                }
                let sim = ShellBalloon::new(mesh.clone())
                    .with_gas(kind)
                    .with_ambient_pressure(ambient)
                    .with_gauge_pressure(1500.0)
                    .build()
                    .unwrap();
                let mut rng = Rng::new(7);
                let x: Vec<f64> = sim
                    .positions()
                    .iter()
                    .map(|v| 1.15 * v + 0.004 * rng.next_f64())
                    .collect();
                let springs = [AnchorSpring {
                    vertex: 3,
                    anchor: [0.2, -0.1, 0.05],
                    stiffness: 50.0,
                }];
                for anchored in [false, true] {
                    let energy = |x: &[f64]| {
                        let mut sys = sim.system.clone_for_tests();
                        let mut with = WithAnchors {
                            inner: &mut sys,
                            springs: if anchored { &springs[..] } else { &[] },
                        };
                        with.potential_energy(time, x).unwrap().unwrap()
                    };
                    let grad = |x: &[f64]| {
                        let mut sys = sim.system.clone_for_tests();
                        let mut with = WithAnchors {
                            inner: &mut sys,
                            springs: if anchored { &springs[..] } else { &[] },
                        };
                        let mut f = vec![0.0; x.len()];
                        with.forces(time, x, &mut f).unwrap();
                        f.iter().map(|v| -v).collect::<Vec<_>>()
                    };
                    check_gradient(energy, grad, &x, 1e-7, 1e-6);
                }
            }
        }
    }

    /// With the follower term in the element blocks (the default when it is on), the shell's
    /// force differential is the derivative of its forces (central differences, every gas,
    /// both tangents' exact path), and the assembled Newton matrix applied to a direction is
    /// minus that differential (blocks and differential agree); without the follower term the
    /// differential misses it and the check fails by far more (the test would catch a lost
    /// follower block).
    #[test]
    fn force_differential_with_the_follower_in_the_blocks_matches_finite_differences() {
        use balloon_integrate::linear::SparseAssembler;
        use balloon_test_support::{Rng, check_jacobian};
        let mesh = icosphere(0.1, 1).unwrap();
        for kind in [GasKind::Ideal, GasKind::Constant] {
            let sim = ShellBalloon::new(mesh.clone())
                .with_gas(kind)
                .with_ambient_pressure(0.0)
                .with_gauge_pressure(3000.0)
                .build()
                .unwrap();
            assert!(
                sim.system.follower_in_blocks(),
                "on by default with a residual test"
            );
            let mut rng = Rng::new(11);
            let x: Vec<f64> = sim
                .positions()
                .iter()
                .map(|v| 1.2 * v + 0.003 * rng.next_f64())
                .collect();
            let forces = |x: &[f64]| {
                let mut sys = sim.system.clone_for_tests();
                let mut f = vec![0.0; x.len()];
                sys.forces(0.0, x, &mut f).unwrap();
                f
            };
            let differential = |x: &[f64], dx: &[f64]| {
                let mut sys = sim.system.clone_for_tests();
                let mut f = vec![0.0; x.len()];
                sys.forces(0.0, x, &mut f).unwrap();
                let mut df = vec![0.0; x.len()];
                sys.add_force_differential(dx, &mut df);
                df
            };
            check_jacobian(forces, differential, &x, 1e-7, 1e-5, 3);
            // The assembled sparse part plus the rank-1 term is minus the differential.
            let mut sys = sim.system.clone_for_tests();
            let n = x.len();
            let mut f = vec![0.0; n];
            sys.forces(0.0, &x, &mut f).unwrap();
            let blocks = sys.stiffness_blocks().unwrap();
            let mut rest = Vec::new();
            sys.add_remaining_stiffness_triplets(&mut rest).unwrap();
            assert!(rest.is_empty());
            let mut a = SparseAssembler::new();
            a.assemble_blocks(&vec![0.0; n], 0.0, &blocks, &rest, 1.0)
                .unwrap();
            let dx = rng.vector(n);
            let mut kdx = vec![0.0; n];
            a.matrix().mul_into(&dx, &mut kdx);
            balloon_integrate::linear::add_low_rank_product(
                sys.low_rank_terms(),
                1.0,
                &dx,
                &mut kdx,
            );
            let mut df = vec![0.0; n];
            sys.add_force_differential(&dx, &mut df);
            let scale = df.iter().map(|v| v.abs()).fold(0.0, f64::max);
            for (k, d) in kdx.iter().zip(&df) {
                assert!((k + d).abs() <= 1e-10 * scale, "{k} vs {d}");
            }
            // Without the follower term the differential is off by the follower term.
            let mut without = sim.system.clone_for_tests();
            without.gas = without.gas.clone().with_follower_term(false);
            let mut f = vec![0.0; n];
            without.forces(0.0, &x, &mut f).unwrap();
            let mut df0 = vec![0.0; n];
            without.add_force_differential(&dx, &mut df0);
            let gap = df0
                .iter()
                .zip(&df)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(
                gap > 1e-3 * scale,
                "the follower term matters here: {gap:e}"
            );
        }
    }
}
