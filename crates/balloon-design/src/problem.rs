//! The inverse-statics equations: the residual `r(X) = f_el(x*; X) + p g(x*)` of the static
//! equilibrium at the fixed target `x*` as a function of the rest positions `X`, and its exact
//! Jacobian `dr/dX` assembled from the elements' rest derivatives (`docs/design.md`, D1-D10).

use balloon_element::{HyperMembrane, ThreePrism};
use balloon_mesh::TriMesh;
use balloon_shell::ShellMaterialModel;
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
        Ok(Self {
            target: x,
            triangles: target.triangles.clone(),
            thickness,
            material,
            pressure,
            pressure_forces,
            gas: None,
        })
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
        let mut tri =
            jacobian.then(|| sprs::TriMat::with_capacity((n, n), 81 * self.triangles.len()));
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
        if r.iter().any(|v| !v.is_finite()) {
            return Err(DesignError::NonFinite("the equilibrium residual"));
        }
        Ok((r, tri.map(|t| t.to_csr())))
    }
}
