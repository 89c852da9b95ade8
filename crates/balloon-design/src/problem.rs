//! The inverse-statics equations: the residual `r(X) = f_el(x*; X) + p g(x*)` of the static
//! equilibrium at the fixed target `x*` as a function of the rest positions `X`, and its exact
//! Jacobian `dr/dX` assembled from the elements' rest derivatives (`docs/design.md`, D1-D10).

use balloon_element::{Hinge, HyperMembrane, ThreePrism};
use balloon_mesh::TriMesh;
use balloon_mesh::topology::EdgeHinge;
use balloon_shell::{ShellMaterial, ShellMaterialModel};
use nalgebra::{SMatrix, Vector3};

use crate::DesignError;

/// One inverse-statics problem: the target (deformed) surface `x*`, the rest thickness of
/// every face, the material and the gauge pressure.
///
/// The rest shape `X` shares the target's connectivity. The three-prism's current thickness
/// in the static solve is its stored thickness, which for a shell built from a rest shape is the
/// rest thickness `H` (Wang et al. 2015, Sec. 4; only the shell-volume projection of the
/// dynamic step moves it), so the equations use `h = H`. The membranes' thickness follows the
/// stretch and does not enter their forces.
///
/// **The wall's bending stiffness** ([`DesignProblem::with_wall_bending`], off by default) adds
/// the forces of one discrete-shell hinge per interior edge (Grinspun, Hirani, Desbrun and
/// Schröder 2003, "Discrete Shells", Eq. 3; [`balloon_element::Hinge`]) at `x*` with the rest
/// weight and rest angle of `X`, the same wall as the shell's
/// `balloon_shell::ShellSystem::set_wall_bending`, with its modulus
/// `D = s Y h^3 / (12 (1 - nu^2))` from the same `h = H` (the mean rest thickness of the two
/// triangles; `docs/design.md`, D20).
#[derive(Clone, Debug)]
pub struct DesignProblem {
    target: Vec<f64>,
    triangles: Vec<[usize; 3]>,
    thickness: Vec<f64>,
    material: ShellMaterialModel,
    pressure: f64,
    /// `p dV/dx` at the target (N), the pressure forces (Wang et al. 2015, Eq. 15).
    pressure_forces: Vec<f64>,
    /// The gas when the load is an amount of gas ([`DesignProblem::with_gas_amount`]).
    gas: Option<GasAmount>,
    /// The factor `s` on the wall's plate bending modulus (0: no bending stiffness).
    wall_bending: f64,
    /// The material's plate modulus `Y / (1 - nu^2)` (Pa).
    plate_modulus: f64,
    /// The bending hinges (interior edges) when `wall_bending > 0`, else none.
    hinges: Vec<EdgeHinge>,
    /// Their corners `[x0, x1, x2, x3]`.
    hinge_corners: Vec<[usize; 4]>,
}

/// A load given as an amount of isothermal ideal gas (Wang et al. 2015, Eq. 12 and 14):
/// `p_abs V = nRT`, so the gauge pressure at volume `V` is `nRT / V - p_ambient`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GasAmount {
    /// `nRT = p_abs V`, J.
    pub amount: f64,
    /// The ambient (outside) pressure, Pa.
    pub ambient: f64,
}

impl GasAmount {
    /// The gauge pressure (Pa) of this gas at the volume `volume` (m^3).
    pub fn gauge_pressure(&self, volume: f64) -> f64 {
        self.amount / volume - self.ambient
    }
}

/// Checks a rest thickness map: one positive, finite value (m) per face of `faces`.
pub(crate) fn check_thickness(thickness: &[f64], faces: usize) -> Result<(), DesignError> {
    if thickness.len() != faces {
        return Err(DesignError::InvalidParameter {
            name: "thickness",
            value: thickness.len() as f64,
            allowed: "one value per face of the target",
        });
    }
    if let Some(&h) = thickness.iter().find(|h| !(h.is_finite() && **h > 0.0)) {
        return Err(DesignError::InvalidParameter {
            name: "thickness",
            value: h,
            allowed: "positive and finite, in m",
        });
    }
    Ok(())
}

/// Position of vertex `v` in the flat array `x`.
pub(crate) fn point(x: &[f64], v: usize) -> Vector3<f64> {
    Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2])
}

/// Corner positions of triangle `t` in the flat array `x`.
pub(crate) fn corners(x: &[f64], t: &[usize; 3]) -> [Vector3<f64>; 3] {
    t.map(|v| point(x, v))
}

/// `dV/dx` of the enclosed volume `V = sum_t x1 . (x2 x x3) / 6` of an outward-oriented closed
/// mesh (m^2 per coordinate).
pub fn volume_gradient(x: &[f64], triangles: &[[usize; 3]]) -> Vec<f64> {
    let mut g = vec![0.0; x.len()];
    for t in triangles {
        let [a, b, c] = corners(x, t);
        for (v, d) in t.iter().zip([b.cross(&c), c.cross(&a), a.cross(&b)]) {
            for k in 0..3 {
                g[3 * v + k] += d[k] / 6.0;
            }
        }
    }
    g
}

/// Enclosed volume (m^3) of an outward-oriented closed mesh.
pub fn enclosed_volume(x: &[f64], triangles: &[[usize; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = corners(x, t);
            a.dot(&b.cross(&c)) / 6.0
        })
        .sum()
}

impl DesignProblem {
    /// The problem of the target `target` (a closed, outward-oriented mesh, positions in m),
    /// one rest thickness per face `thickness` (m, positive), the `material` and the gauge
    /// pressure `pressure` (Pa, positive: the gas pushes outwards).
    ///
    /// # Errors
    /// [`DesignError::InvalidParameter`] naming `thickness` or `pressure`, and
    /// [`DesignError::Target`] for a target whose enclosed volume is not positive or whose
    /// triangles are degenerate.
    pub fn try_new(
        target: &TriMesh,
        thickness: Vec<f64>,
        material: ShellMaterialModel,
        pressure: f64,
    ) -> Result<Self, DesignError> {
        if !(pressure.is_finite() && pressure > 0.0) {
            return Err(DesignError::InvalidParameter {
                name: "pressure",
                value: pressure,
                allowed: "a positive gauge pressure in Pa",
            });
        }
        check_thickness(&thickness, target.num_triangles())?;
        let x = target.positions_flat();
        if x.iter().any(|v| !v.is_finite()) {
            return Err(DesignError::Target(
                "a vertex position is not finite".into(),
            ));
        }
        let volume = enclosed_volume(&x, &target.triangles);
        if volume.is_nan() || volume <= 0.0 {
            return Err(DesignError::Target(format!(
                "the enclosed volume is {volume:e} m^3; the target must be a closed mesh with \
                 outward-oriented triangles"
            )));
        }
        for (e, t) in target.triangles.iter().enumerate() {
            // The target is also the start of the rest shape: its triangles must be valid
            // rest triangles.
            ThreePrism::try_new(corners(&x, t), thickness[e])
                .map_err(|err| DesignError::Target(format!("triangle {e}: {err}")))?;
        }
        let pressure_forces = volume_gradient(&x, &target.triangles)
            .into_iter()
            .map(|g| pressure * g)
            .collect();
        let plate_modulus = material.plate_modulus();
        Ok(Self {
            target: x,
            triangles: target.triangles.clone(),
            thickness,
            material,
            pressure,
            pressure_forces,
            gas: None,
            wall_bending: 0.0,
            plate_modulus,
            hinges: Vec::new(),
            hinge_corners: Vec::new(),
        })
    }

    /// The problem with the wall's bending stiffness: `factor` times the plate bending modulus
    /// `D = Y h^3 / (12 (1 - nu^2))` on one discrete-shell hinge per interior edge (Grinspun et
    /// al. 2003, Eq. 3; `h` the mean rest thickness of the edge's two triangles,
    /// `Y / (1 - nu^2)` the material's `balloon_shell::ShellMaterial::plate_modulus`), the
    /// forward model of `balloon_shell::ShellSystem::set_wall_bending` with the same factor.
    /// The residual gains the hinge forces at the target with the rest weights and angles of
    /// `X`, its Jacobian their exact rest derivatives, and the forward check and the shape
    /// optimisation solve with the same wall. `factor = 0` removes it: the problem is then
    /// the one without, bit for bit.
    ///
    /// # Errors
    /// [`DesignError::InvalidParameter`] naming `bending` for a negative or non-finite
    /// factor; [`DesignError::Target`] for a degenerate hinge of the target (not possible for
    /// a target [`DesignProblem::try_new`] accepted).
    pub fn with_wall_bending(mut self, factor: f64) -> Result<Self, DesignError> {
        if !(factor.is_finite() && factor >= 0.0) {
            return Err(DesignError::InvalidParameter {
                name: "bending",
                value: factor,
                allowed: "a finite factor >= 0 on the wall's plate bending modulus (0: none)",
            });
        }
        self.wall_bending = factor;
        if factor == 0.0 {
            self.hinges.clear();
            self.hinge_corners.clear();
            return Ok(self);
        }
        self.hinges = balloon_mesh::topology::hinges(&self.triangles);
        self.hinge_corners = self.hinges.iter().map(|h| h.corners).collect();
        for (k, c) in self.hinge_corners.iter().enumerate() {
            Hinge::try_new(&c.map(|v| point(&self.target, v)))
                .map_err(|err| DesignError::Target(format!("hinge {k}: {err}")))?;
        }
        Ok(self)
    }

    /// The factor on the wall's plate bending modulus (0: none;
    /// [`DesignProblem::with_wall_bending`]).
    pub fn wall_bending(&self) -> f64 {
        self.wall_bending
    }

    /// The number of bending hinges (interior edges; 0 without the wall's bending stiffness).
    pub fn num_hinges(&self) -> usize {
        self.hinges.len()
    }

    /// The layout of `J` for this problem's mesh and hinges.
    pub(crate) fn pattern(&self) -> crate::normal::NormalPattern {
        crate::normal::NormalPattern::new(self.num_dofs() / 3, &self.triangles, &self.hinge_corners)
    }

    /// The bending modulus `D = s Y h^3 / 12 / (1 - nu^2)` (N m) of hinge `k`, `h` the mean
    /// rest thickness of its two triangles.
    fn hinge_modulus(&self, k: usize) -> f64 {
        let [a, b] = self.hinges[k].faces;
        let h = 0.5 * (self.thickness[a] + self.thickness[b]);
        self.wall_bending * self.plate_modulus * h * h * h / 12.0
    }

    /// The corners `[x0, x1, x2, x3]` of each bending hinge.
    pub(crate) fn hinge_corners(&self) -> &[[usize; 4]] {
        &self.hinge_corners
    }

    /// The two triangles of bending hinge `k`.
    pub(crate) fn hinge_faces(&self, k: usize) -> [usize; 2] {
        self.hinges[k].faces
    }

    /// Forces (N) and rest Jacobian (N/m) of bending hinge `k` at the deformed positions
    /// `deformed` for rest positions `rest` (flat, m).
    pub(crate) fn hinge_at(
        &self,
        k: usize,
        deformed: &[f64],
        rest: &[f64],
    ) -> Result<([Vector3<f64>; 4], SMatrix<f64, 12, 12>), DesignError> {
        let c = &self.hinge_corners[k];
        let xr = c.map(|v| point(rest, v));
        let xs = c.map(|v| point(deformed, v));
        let hinge = Hinge::try_new(&xr).map_err(|source| DesignError::RestElement {
            element: self.hinges[k].faces[0],
            source,
        })?;
        Ok(hinge.forces_and_rest_jacobian(&xr, &xs, self.hinge_modulus(k)))
    }

    /// The problem of [`DesignProblem::try_new`] with the load given as an amount of
    /// isothermal ideal gas instead of a pressure: `amount = nRT = p_abs V` (J) against the
    /// ambient pressure `ambient` (Pa). At the target its gauge pressure is
    /// `amount / V* - ambient` (`V*` the target's enclosed volume), which must be positive;
    /// the inverse solve is then the one at that pressure, and the forward check and the
    /// shape optimisation solve with the gas, whose pressure follows the volume
    /// (`docs/design.md`, "A gas amount as the load").
    ///
    /// # Errors
    /// [`DesignError::InvalidParameter`] naming `gas_amount` or `ambient` (not positive and
    /// finite, or a gas that would not be above the ambient pressure at the target), and the
    /// errors of [`DesignProblem::try_new`].
    pub fn with_gas_amount(
        target: &TriMesh,
        thickness: Vec<f64>,
        material: ShellMaterialModel,
        amount: f64,
        ambient: f64,
    ) -> Result<Self, DesignError> {
        if !(ambient.is_finite() && ambient > 0.0) {
            return Err(DesignError::InvalidParameter {
                name: "ambient",
                value: ambient,
                allowed: "a positive ambient pressure in Pa",
            });
        }
        let gas = GasAmount { amount, ambient };
        let volume = enclosed_volume(&target.positions_flat(), &target.triangles);
        let pressure = gas.gauge_pressure(volume);
        if !(amount.is_finite() && amount > 0.0 && pressure > 0.0 && pressure.is_finite()) {
            return Err(DesignError::InvalidParameter {
                name: "gas_amount",
                value: amount,
                allowed: "an amount nRT in J above the ambient pressure times the target's \
                          volume (a positive gauge pressure at the target)",
            });
        }
        let mut problem = Self::try_new(target, thickness, material, pressure)?;
        problem.gas = Some(gas);
        Ok(problem)
    }

    /// The gas amount, when the load is one ([`DesignProblem::with_gas_amount`]).
    pub fn gas_amount(&self) -> Option<GasAmount> {
        self.gas
    }

    /// The target positions `x*` (flat, m).
    pub fn target(&self) -> &[f64] {
        &self.target
    }

    /// Mean edge length of the target (m; every triangle's three edges, so interior edges
    /// count twice): the length scale of the rest-mesh terms and of the step limits.
    pub fn mean_edge_length(&self) -> f64 {
        let sum: f64 = self
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = corners(&self.target, t);
                (b - a).norm() + (c - b).norm() + (a - c).norm()
            })
            .sum();
        sum / (3 * self.triangles.len()).max(1) as f64
    }

    /// The triangles (shared by the target and the rest shape).
    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    /// The rest thickness per face (m).
    pub fn thickness(&self) -> &[f64] {
        &self.thickness
    }

    /// Replaces the rest thickness map (checked by the caller with [`check_thickness`]).
    pub(crate) fn set_thickness(&mut self, thickness: &[f64]) {
        self.thickness.copy_from_slice(thickness);
    }

    /// The problem with the rest thickness map `thickness` (one per face, m) instead of its
    /// own: the same target, material and load.
    ///
    /// # Errors
    /// [`DesignError::InvalidParameter`] naming `thickness`.
    pub fn with_thickness(&self, thickness: Vec<f64>) -> Result<Self, DesignError> {
        check_thickness(&thickness, self.triangles.len())?;
        Ok(Self {
            thickness,
            ..self.clone()
        })
    }

    /// The material.
    pub fn material(&self) -> &ShellMaterialModel {
        &self.material
    }

    /// The gauge pressure (Pa) at the target (for a gas amount: its pressure at the target's
    /// volume).
    pub fn pressure(&self) -> f64 {
        self.pressure
    }

    /// The pressure forces `p dV/dx` at the target (N).
    pub fn pressure_forces(&self) -> &[f64] {
        &self.pressure_forces
    }

    /// `Ok` when `v` has three coordinates per target vertex, else
    /// [`DesignError::InvalidParameter`] naming it `name`.
    pub(crate) fn check_length(&self, name: &'static str, v: &[f64]) -> Result<(), DesignError> {
        if v.len() == self.num_dofs() {
            Ok(())
        } else {
            Err(DesignError::InvalidParameter {
                name,
                value: v.len() as f64,
                allowed: "three coordinates per target vertex",
            })
        }
    }

    /// Number of degrees of freedom (3 per vertex).
    pub fn num_dofs(&self) -> usize {
        self.target.len()
    }

    /// Forces and rest Jacobian of element `e` for rest positions `rest` (flat, m) at the
    /// target.
    fn element(
        &self,
        e: usize,
        rest: &[f64],
    ) -> Result<([Vector3<f64>; 3], SMatrix<f64, 9, 9>), DesignError> {
        self.element_at(e, &self.target, rest)
    }

    /// Forces and rest Jacobian of element `e` at the deformed positions `deformed` for rest
    /// positions `rest` (flat, m).
    pub(crate) fn element_at(
        &self,
        e: usize,
        deformed: &[f64],
        rest: &[f64],
    ) -> Result<([Vector3<f64>; 3], SMatrix<f64, 9, 9>), DesignError> {
        let t = &self.triangles[e];
        let xr = corners(rest, t);
        let xs = corners(deformed, t);
        let h = self.thickness[e];
        let bad = |source| DesignError::RestElement { element: e, source };
        Ok(match &self.material {
            ShellMaterialModel::Solid(m) => ThreePrism::try_new(xr, h)
                .map_err(bad)?
                .forces_and_rest_jacobian(m, &xr, &xs, h),
            ShellMaterialModel::Membrane(m) => HyperMembrane::try_new(xr, h)
                .map_err(bad)?
                .forces_and_rest_jacobian(m, &xr, &xs),
        })
    }

    /// The residual `r(X) = f_el(x*; X) + s p g(x*)` (N) at load factor `s` (the pressure
    /// scaled by `s`), for rest positions `rest`.
    ///
    /// # Errors
    /// [`DesignError::RestElement`] when a rest triangle is degenerate or not finite.
    pub fn residual(&self, rest: &[f64], load: f64) -> Result<Vec<f64>, DesignError> {
        self.evaluate(rest, load, false).map(|(r, _)| r)
    }

    /// The residual and its Jacobian `dr/dX` (N/m) as a sparse matrix in CSR form.
    ///
    /// # Errors
    /// As [`DesignProblem::residual`].
    pub fn residual_and_jacobian(
        &self,
        rest: &[f64],
        load: f64,
    ) -> Result<(Vec<f64>, sprs::CsMat<f64>), DesignError> {
        self.evaluate(rest, load, true)
            .map(|(r, j)| (r, j.expect("asked for the Jacobian")))
    }

    /// The residual into `r` and the blocks of `J` into `j` (laid out by `pattern`), for the
    /// inverse solve's fixed-pattern normal equations.
    pub(crate) fn evaluate_blocks(
        &self,
        rest: &[f64],
        load: f64,
        pattern: &crate::normal::NormalPattern,
        r: &mut [f64],
        j: &mut [nalgebra::Matrix3<f64>],
    ) -> Result<(), DesignError> {
        for (ri, f) in r.iter_mut().zip(&self.pressure_forces) {
            *ri = load * f;
        }
        j.fill(nalgebra::Matrix3::zeros());
        for (e, t) in self.triangles.iter().enumerate() {
            let (f, jac) = self.element(e, rest)?;
            for (a, &va) in t.iter().enumerate() {
                for k in 0..3 {
                    r[3 * va + k] += f[a][k];
                }
            }
            pattern.add_element(e, &jac, j);
        }
        for (k, c) in self.hinge_corners.iter().enumerate() {
            let (f, jac) = self.hinge_at(k, &self.target, rest)?;
            for (a, &va) in c.iter().enumerate() {
                for l in 0..3 {
                    r[3 * va + l] += f[a][l];
                }
            }
            pattern.add_hinge(k, &jac, j);
        }
        if r.iter().any(|v| !v.is_finite()) || j.iter().any(|b| !b.iter().all(|v| v.is_finite())) {
            return Err(DesignError::NonFinite("the equilibrium residual"));
        }
        Ok(())
    }

    /// The blocks of the rest Jacobian `df_el/dX` (N/m) of the elastic forces at the deformed
    /// positions `deformed` (not the target) into `j`, laid out by `pattern`: the `df/dX` of
    /// the shape optimisation's adjoint (`docs/design.md`, D12; the pressure forces do not
    /// depend on `X`).
    pub(crate) fn rest_jacobian_at(
        &self,
        deformed: &[f64],
        rest: &[f64],
        pattern: &crate::normal::NormalPattern,
        j: &mut [nalgebra::Matrix3<f64>],
    ) -> Result<(), DesignError> {
        j.fill(nalgebra::Matrix3::zeros());
        for e in 0..self.triangles.len() {
            let (_, jac) = self.element_at(e, deformed, rest)?;
            pattern.add_element(e, &jac, j);
        }
        for k in 0..self.hinge_corners.len() {
            let (_, jac) = self.hinge_at(k, deformed, rest)?;
            pattern.add_hinge(k, &jac, j);
        }
        if j.iter().any(|b| !b.iter().all(|v| v.is_finite())) {
            return Err(DesignError::NonFinite("the rest Jacobian"));
        }
        Ok(())
    }

    fn evaluate(
        &self,
        rest: &[f64],
        load: f64,
        jacobian: bool,
    ) -> Result<(Vec<f64>, Option<sprs::CsMat<f64>>), DesignError> {
        let n = self.num_dofs();
        self.check_length("rest", rest)?;
        let mut r: Vec<f64> = self.pressure_forces.iter().map(|f| load * f).collect();
        let mut tri = jacobian.then(|| {
            sprs::TriMat::with_capacity(
                (n, n),
                81 * self.triangles.len() + 144 * self.hinge_corners.len(),
            )
        });
        for (e, t) in self.triangles.iter().enumerate() {
            let (f, j) = self.element(e, rest)?;
            for (a, &va) in t.iter().enumerate() {
                for k in 0..3 {
                    r[3 * va + k] += f[a][k];
                }
                if let Some(tri) = tri.as_mut() {
                    for (b, &vb) in t.iter().enumerate() {
                        for k in 0..3 {
                            for l in 0..3 {
                                tri.add_triplet(3 * va + k, 3 * vb + l, j[(3 * a + k, 3 * b + l)]);
                            }
                        }
                    }
                }
            }
        }
        for (h, c) in self.hinge_corners.iter().enumerate() {
            let (f, j) = self.hinge_at(h, &self.target, rest)?;
            for (a, &va) in c.iter().enumerate() {
                for l in 0..3 {
                    r[3 * va + l] += f[a][l];
                }
                if let Some(tri) = tri.as_mut() {
                    for (b, &vb) in c.iter().enumerate() {
                        for k in 0..3 {
                            for l in 0..3 {
                                tri.add_triplet(3 * va + k, 3 * vb + l, j[(3 * a + k, 3 * b + l)]);
                            }
                        }
                    }
                }
            }
        }
        if r.iter().any(|v| !v.is_finite()) {
            return Err(DesignError::NonFinite("the equilibrium residual"));
        }
        Ok((r, tri.map(|t| t.to_csr())))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_fixtures::ellipsoid_problem;

    /// A rest shape away from the target, bent (so the hinges' rest angles and weights differ
    /// from the target's) and shrunk: `0.9 x*` plus a smooth bump.
    fn bent_rest(problem: &DesignProblem) -> Vec<f64> {
        problem
            .target()
            .iter()
            .enumerate()
            .map(|(i, x)| 0.9 * x + 2e-3 * ((i * 7) as f64 * 0.37).sin())
            .collect()
    }

    fn norm(v: &[f64]) -> f64 {
        v.iter().map(|a| a * a).sum::<f64>().sqrt()
    }

    fn apply(j: &sprs::CsMat<f64>, v: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; v.len()];
        for (value, (r, c)) in j.iter() {
            out[r] += value * v[c];
        }
        out
    }

    /// The residual's exact rest Jacobian with the wall's bending stiffness against central
    /// differences of the residual, for the whole residual and for the hinges' part alone
    /// (the difference with the problem without bending), with a factor that makes the hinge
    /// forces a sizeable part of the residual (asserted); and the fixed-pattern blocks of the
    /// inverse solve (which hold the hinges' opposite-corner couplings) equal to the sparse
    /// Jacobian.
    #[test]
    fn wall_bending_jacobian_matches_central_differences() {
        let plain = ellipsoid_problem();
        let bent = plain.clone().with_wall_bending(1000.0).unwrap();
        assert_eq!(bent.num_hinges(), 3 * plain.triangles().len() / 2);
        let rest = bent_rest(&plain);
        let (r_plain, j_plain) = plain.residual_and_jacobian(&rest, 1.0).unwrap();
        let (r_bent, j_bent) = bent.residual_and_jacobian(&rest, 1.0).unwrap();
        let hinge_r: Vec<f64> = r_bent.iter().zip(&r_plain).map(|(a, b)| a - b).collect();
        let elastic: Vec<f64> = r_plain
            .iter()
            .zip(plain.pressure_forces())
            .map(|(a, b)| a - b)
            .collect();
        let share = norm(&hinge_r) / norm(&elastic);
        assert!(share > 0.2, "hinge forces {share:.3} of the elastic ones");
        let h = 1e-7;
        for seed in 0..3 {
            let dir: Vec<f64> = (0..rest.len())
                .map(|i| ((i * 5 + seed * 11) as f64 * 0.83).cos())
                .collect();
            let at =
                |s: f64| -> Vec<f64> { rest.iter().zip(&dir).map(|(x, d)| x + s * d).collect() };
            let fd = |p: &DesignProblem| -> Vec<f64> {
                let (rp, rm) = (
                    p.residual(&at(h), 1.0).unwrap(),
                    p.residual(&at(-h), 1.0).unwrap(),
                );
                rp.iter()
                    .zip(&rm)
                    .map(|(a, b)| (a - b) / (2.0 * h))
                    .collect()
            };
            let (fd_bent, fd_plain) = (fd(&bent), fd(&plain));
            let exact_bent = apply(&j_bent, &dir);
            let exact_plain = apply(&j_plain, &dir);
            let err = |a: &[f64], b: &[f64]| {
                norm(&a.iter().zip(b).map(|(x, y)| x - y).collect::<Vec<_>>()) / norm(b)
            };
            let whole = err(&fd_bent, &exact_bent);
            assert!(whole < 1e-6, "seed {seed}: whole Jacobian off by {whole:e}");
            let hinge_fd: Vec<f64> = fd_bent.iter().zip(&fd_plain).map(|(a, b)| a - b).collect();
            let hinge_exact: Vec<f64> = exact_bent
                .iter()
                .zip(&exact_plain)
                .map(|(a, b)| a - b)
                .collect();
            let part = err(&hinge_fd, &hinge_exact);
            assert!(part < 1e-6, "seed {seed}: hinge part off by {part:e}");
            assert!(
                norm(&hinge_exact) > 0.05 * norm(&exact_bent),
                "seed {seed}: the hinge part is too small to test"
            );
        }
        // The inverse solve's fixed-pattern blocks hold the same Jacobian.
        let pattern = bent.pattern();
        let n = rest.len();
        let mut r = vec![0.0; n];
        let mut j = vec![nalgebra::Matrix3::zeros(); pattern.j_blocks()];
        bent.evaluate_blocks(&rest, 1.0, &pattern, &mut r, &mut j)
            .unwrap();
        assert_eq!(r, r_bent);
        let dir: Vec<f64> = (0..n).map(|i| (i as f64 * 0.77).sin()).collect();
        let mut blocks = vec![0.0; n];
        pattern.apply(&j, &dir, &mut blocks);
        let sparse = apply(&j_bent, &dir);
        let diff: Vec<f64> = blocks.iter().zip(&sparse).map(|(a, b)| a - b).collect();
        assert!(norm(&diff) <= 1e-12 * norm(&sparse));
        // The forward model's rest Jacobian at another deformed shape has the hinges too.
        let mut jd = vec![nalgebra::Matrix3::zeros(); pattern.j_blocks()];
        bent.rest_jacobian_at(bent.target(), &rest, &pattern, &mut jd)
            .unwrap();
        assert_eq!(jd, j);
    }

    /// Factor 0 is the problem without bending bit for bit; a rest shape similar to the target
    /// (rotated, scaled, moved) has no hinge forces, and the hinges' rest Jacobian maps the
    /// rest shape's rigid motions and its scaling to zero.
    #[test]
    fn wall_bending_off_and_similar_rest_shapes() {
        let plain = ellipsoid_problem();
        let off = plain.clone().with_wall_bending(0.0).unwrap();
        let rest = bent_rest(&plain);
        assert_eq!(off.num_hinges(), 0);
        let (r0, j0) = plain.residual_and_jacobian(&rest, 1.0).unwrap();
        let (r1, j1) = off.residual_and_jacobian(&rest, 1.0).unwrap();
        assert_eq!(r0, r1);
        assert_eq!(j0, j1);
        let bent = plain.clone().with_wall_bending(30.0).unwrap();
        let rot = nalgebra::Rotation3::from_euler_angles(0.3, -0.7, 1.1);
        let similar: Vec<f64> = plain
            .target()
            .chunks(3)
            .flat_map(|p| {
                let y = rot * Vector3::new(p[0], p[1], p[2]) * 0.8 + Vector3::new(0.1, 0.2, 0.3);
                [y.x, y.y, y.z]
            })
            .collect();
        let (ra, _) = plain.residual_and_jacobian(&similar, 1.0).unwrap();
        let (rb, _) = bent.residual_and_jacobian(&similar, 1.0).unwrap();
        let hinge: Vec<f64> = rb.iter().zip(&ra).map(|(a, b)| a - b).collect();
        assert!(norm(&hinge) <= 1e-12 * norm(&ra), "{:e}", norm(&hinge));
        // At the bent rest shape, the hinge part of J on rigid motions and the scaling of X.
        let (_, jb) = bent.residual_and_jacobian(&rest, 1.0).unwrap();
        let (_, jp) = plain.residual_and_jacobian(&rest, 1.0).unwrap();
        let nv = rest.len() / 3;
        let centre: Vector3<f64> =
            (0..nv).map(|v| point(&rest, v)).sum::<Vector3<f64>>() / nv as f64;
        let fields: Vec<Vec<f64>> = vec![
            (0..3 * nv)
                .map(|i| f64::from(u8::from(i % 3 == 1)))
                .collect(),
            (0..nv)
                .flat_map(|v| {
                    let d = Vector3::new(0.3, -0.5, 0.8).cross(&(point(&rest, v) - centre));
                    [d.x, d.y, d.z]
                })
                .collect(),
            (0..nv)
                .flat_map(|v| {
                    let d = point(&rest, v) - centre;
                    [d.x, d.y, d.z]
                })
                .collect(),
        ];
        // The size of the hinge part of J along a generic direction.
        let scale = {
            let d: Vec<f64> = (0..rest.len()).map(|i| (i as f64 * 0.3).cos()).collect();
            let a = apply(&jb, &d);
            let b = apply(&jp, &d);
            norm(&a.iter().zip(&b).map(|(x, y)| x - y).collect::<Vec<_>>()) / norm(&d)
        };
        assert!(scale > 0.0);
        for (m, u) in fields.iter().enumerate() {
            let a = apply(&jb, u);
            let b = apply(&jp, u);
            let hinge: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x - y).collect();
            assert!(
                norm(&hinge) <= 1e-9 * scale * norm(u),
                "field {m}: {:e}",
                norm(&hinge) / norm(u)
            );
        }
    }

    /// Every bad factor is an error naming `bending`.
    #[test]
    fn bad_wall_bending_factors_are_named() {
        for bad in [-1.0, -1e-300, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            match ellipsoid_problem().with_wall_bending(bad) {
                Err(DesignError::InvalidParameter { name, .. }) => assert_eq!(name, "bending"),
                other => panic!("{bad}: {other:?}"),
            }
            let params = crate::DesignParams {
                wall_bending: bad,
                ..crate::DesignParams::default()
            };
            match crate::design(&ellipsoid_problem(), &params, |_| true) {
                Err(DesignError::InvalidParameter { name, .. }) => assert_eq!(name, "bending"),
                other => panic!("{bad}: {:?}", other.map(|d| d.inverse)),
            }
        }
    }
}
