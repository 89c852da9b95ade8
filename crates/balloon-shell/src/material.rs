//! The material seam of the shell: a material together with the element every triangle becomes.
//!
//! [`ShellSystem`](crate::ShellSystem) (and the `balloon` facade's shell simulation) are
//! generic over a [`ShellMaterial`]. Every 3D [`Material`] (St. Venant-Kirchhoff, neo-Hookean,
//! [`MaterialModel`], a user's own) is one through a blanket implementation and runs on the
//! three-prism element of Wang et al. 2015 (Eq. 1-11) with a thickness state that the shell-volume
//! projection (Eq. 24-28) moves; [`Membrane`](crate::Membrane) wraps an incompressible membrane
//! model (`balloon_material::membrane`) and runs on the constant-strain
//! [`HyperMembrane`] triangle, whose thickness follows the stretch (`docs/membranes.md`, M2).
//! [`ShellMaterialModel`] chooses between the two at run time (from a scenario's material).
//!
//! The element kind is chosen with the material, so the force loop, Newton (exact and projected
//! tangents), the gas models, anchors, statistics and the `Simulation` trait are shared and
//! monomorphised per material: the three-prism path is the code it was before the seam existed.

use balloon_element::{ElementError, HyperMembrane, ThreePrism};
use balloon_material::membrane::MembraneMaterial;
use balloon_material::{Material, MaterialModel, MembraneModel};
use nalgebra::{SMatrix, Vector3};
use serde::{Deserialize, Serialize};

use crate::Membrane;

/// A shell material: the constitutive model plus the element kind it is evaluated on.
///
/// Implemented for every [`Material`] (three-prism elements, Wang et al. 2015, Eq. 4-11), for
/// [`Membrane`](crate::Membrane) (incompressible [`HyperMembrane`] triangles,
/// `docs/membranes.md` M22-M25) and for the run-time choice [`ShellMaterialModel`]. The methods
/// are called once per element in the shell's hot loops; they must not allocate.
///
/// Conventions (as for the elements): positions `x` in metres, forces `-dE/dx` in newtons,
/// stiffness `K = d^2E/dx^2` 9x9 vertex-major in N/m; `h` is the element's current thickness (m)
/// as the shell stores it.
pub trait ShellMaterial: Clone + Send + Sync + std::fmt::Debug {
    /// The element every triangle of the shell becomes.
    type Element: Clone + Send + Sync + std::fmt::Debug;

    /// The rest element of a triangle with rest corners `rest` (m) and rest thickness
    /// `thickness` (m).
    ///
    /// # Errors
    /// The element's own validation ([`ElementError`]: non-finite input, `thickness <= 0`,
    /// degenerate triangle).
    fn element(
        &self,
        rest: [Vector3<f64>; 3],
        thickness: f64,
    ) -> Result<Self::Element, ElementError>;

    /// Lumped vertex masses (kg) of `element` for a density `density` (kg/m^3), Wang et al. 2015, Eq. 19.
    fn lumped_masses(&self, element: &Self::Element, density: f64) -> [f64; 3];

    /// Masses of the three vertices and of the virtual thickness vertex used by the
    /// shell-volume projection (Wang et al. 2015, Sec. 7, Eq. 27), kg.
    fn projection_masses(&self, element: &Self::Element, density: f64) -> ([f64; 3], f64);

    /// Elastic energy of `element` at corners `x` and thickness `h` (J); `+infinity` outside
    /// the model's admissible states.
    fn energy(&self, element: &Self::Element, x: &[Vector3<f64>; 3], h: f64) -> f64;

    /// Elastic forces and the stiffness block of `element`: the exact Hessian, or with
    /// `projected` its projection onto the positive semi-definite cone (projected Newton; the
    /// forces are the same).
    fn forces_and_stiffness(
        &self,
        element: &Self::Element,
        x: &[Vector3<f64>; 3],
        h: f64,
        projected: bool,
    ) -> ([Vector3<f64>; 3], SMatrix<f64, 9, 9>);

    /// The elastic forces of `element` alone, bit for bit those of
    /// [`ShellMaterial::forces_and_stiffness`] (the line-search trials of the Newton solve need
    /// no stiffness: [`balloon_integrate::ForceSystem::residual_forces`]). The default takes
    /// them from `forces_and_stiffness`.
    fn forces(&self, element: &Self::Element, x: &[Vector3<f64>; 3], h: f64) -> [Vector3<f64>; 3] {
        self.forces_and_stiffness(element, x, h, false).0
    }

    /// The elastic forces and energy of `element` together, `(forces, energy)`: the forces bit
    /// for bit those of [`ShellMaterial::forces`], the energy that of
    /// [`ShellMaterial::energy`] (to round-off), for line-search trials that need both
    /// ([`balloon_integrate::ForceSystem::residual_forces_and_energy`]). The default calls
    /// the two; the built-in elements share the kinematics and the strain.
    fn forces_and_energy(
        &self,
        element: &Self::Element,
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> ([Vector3<f64>; 3], f64) {
        (self.forces(element, x, h), self.energy(element, x, h))
    }

    /// Checks the state of `element` (finite, not degenerate, inside the model's admissible
    /// set). Used to explain a non-finite force or energy.
    ///
    /// # Errors
    /// The element's [`ElementError`] naming what is wrong.
    fn check_state(
        &self,
        element: &Self::Element,
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> Result<(), ElementError>;

    /// The element kind's name in errors (`three-prism`, `hyper membrane`).
    fn element_name(&self) -> &'static str;

    /// The plate modulus `Y / (1 - nu^2)` (Pa) of the material at small strain, for the bending
    /// stiffness `D = Y h^3 / (12 (1 - nu^2))` of an optional wall bending term
    /// ([`crate::ShellSystem::set_wall_bending`]): `4 mu (lambda + mu) / (lambda + 2 mu)` from the
    /// material's own tangent at `F = I` for a 3D material, `4 mu0` for an incompressible
    /// membrane (its limit `lambda -> infinity`).
    fn plate_modulus(&self) -> f64;

    /// Whether the thickness is a function of the stretch (an incompressible membrane, `h = H /
    /// (l1 l2)`) rather than a state of its own that the shell-volume projection moves. When
    /// `true` the shell refreshes its thickness from
    /// [`ShellMaterial::current_thickness`] after every solve, every element keeps its material
    /// volume `A h = A0 H` exactly and the projection of Wang et al. 2015 (Alg. 1, line 10) has nothing
    /// to correct.
    fn thickness_follows_stretch(&self) -> bool {
        false
    }

    /// The thickness (m) of `element` at corners `x`, given the stored thickness `h`: `h` itself
    /// for the three-prism (the default), `H / sqrt(det C)` for a membrane.
    fn current_thickness(&self, _element: &Self::Element, _x: &[Vector3<f64>; 3], h: f64) -> f64 {
        h
    }
}

/// Every 3D material runs on the three-prism element of Wang et al. 2015, with the thickness a state of
/// the shell (Eq. 4) moved by the volume projection (Eq. 24-28).
impl<M: Material> ShellMaterial for M {
    type Element = ThreePrism;

    #[inline]
    fn element(&self, rest: [Vector3<f64>; 3], thickness: f64) -> Result<ThreePrism, ElementError> {
        ThreePrism::try_new(rest, thickness)
    }

    #[inline]
    fn lumped_masses(&self, element: &ThreePrism, density: f64) -> [f64; 3] {
        element.lumped_masses(density)
    }

    #[inline]
    fn projection_masses(&self, element: &ThreePrism, density: f64) -> ([f64; 3], f64) {
        element.projection_masses(density)
    }

    #[inline]
    fn energy(&self, element: &ThreePrism, x: &[Vector3<f64>; 3], h: f64) -> f64 {
        element.energy(self, x, h)
    }

    #[inline]
    fn forces(&self, element: &ThreePrism, x: &[Vector3<f64>; 3], h: f64) -> [Vector3<f64>; 3] {
        element.forces(self, x, h)
    }

    #[inline]
    fn forces_and_energy(
        &self,
        element: &ThreePrism,
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> ([Vector3<f64>; 3], f64) {
        element.forces_and_energy(self, x, h)
    }

    #[inline]
    fn forces_and_stiffness(
        &self,
        element: &ThreePrism,
        x: &[Vector3<f64>; 3],
        h: f64,
        projected: bool,
    ) -> ([Vector3<f64>; 3], SMatrix<f64, 9, 9>) {
        if projected {
            element.forces_and_projected_stiffness(self, x, h)
        } else {
            element.forces_and_stiffness(self, x, h)
        }
    }

    fn check_state(
        &self,
        element: &ThreePrism,
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> Result<(), ElementError> {
        element.check_state(x, h)
    }

    fn element_name(&self) -> &'static str {
        PRISM
    }

    fn plate_modulus(&self) -> f64 {
        solid_plate_modulus(self)
    }
}

/// An incompressible membrane runs on [`HyperMembrane`] triangles: energy `A0 H W(C)` (M23),
/// forces and stiffness from the model's stress and stress differential (M24-M25), thickness
/// `H / sqrt(det C)` (M2).
impl<W: MembraneMaterial> ShellMaterial for Membrane<W> {
    type Element = HyperMembrane;

    #[inline]
    fn element(
        &self,
        rest: [Vector3<f64>; 3],
        thickness: f64,
    ) -> Result<HyperMembrane, ElementError> {
        HyperMembrane::try_new(rest, thickness)
    }

    #[inline]
    fn lumped_masses(&self, element: &HyperMembrane, density: f64) -> [f64; 3] {
        element.lumped_masses(density)
    }

    /// The same split as the three-prism (1/6 of `rho A0 H` per vertex, 1/2 on the virtual
    /// vertex), so a projector the user switches on sees the masses of Wang et al. 2015, Eq. 27.
    #[inline]
    fn projection_masses(&self, element: &HyperMembrane, density: f64) -> ([f64; 3], f64) {
        let m = density * element.rest_volume();
        ([m / 6.0; 3], m / 2.0)
    }

    #[inline]
    fn energy(&self, element: &HyperMembrane, x: &[Vector3<f64>; 3], _h: f64) -> f64 {
        element.energy(&self.0, x)
    }

    #[inline]
    fn forces(&self, element: &HyperMembrane, x: &[Vector3<f64>; 3], _h: f64) -> [Vector3<f64>; 3] {
        element.forces(&self.0, x)
    }

    #[inline]
    fn forces_and_energy(
        &self,
        element: &HyperMembrane,
        x: &[Vector3<f64>; 3],
        _h: f64,
    ) -> ([Vector3<f64>; 3], f64) {
        let (w, f) = element.energy_and_forces(&self.0, x);
        (f, w)
    }

    #[inline]
    fn forces_and_stiffness(
        &self,
        element: &HyperMembrane,
        x: &[Vector3<f64>; 3],
        _h: f64,
        projected: bool,
    ) -> ([Vector3<f64>; 3], SMatrix<f64, 9, 9>) {
        if projected {
            element.forces_and_projected_stiffness(&self.0, x)
        } else {
            element.forces_and_stiffness(&self.0, x)
        }
    }

    fn check_state(
        &self,
        element: &HyperMembrane,
        x: &[Vector3<f64>; 3],
        _h: f64,
    ) -> Result<(), ElementError> {
        membrane_check_state(&self.0, element, x)
    }

    fn element_name(&self) -> &'static str {
        MEMBRANE
    }

    fn plate_modulus(&self) -> f64 {
        4.0 * self.0.initial_shear_modulus()
    }

    fn thickness_follows_stretch(&self) -> bool {
        true
    }

    #[inline]
    fn current_thickness(&self, element: &HyperMembrane, x: &[Vector3<f64>; 3], _h: f64) -> f64 {
        element.thickness(x)
    }
}

/// The plate modulus `Y / (1 - nu^2) = 4 mu (lambda + mu) / (lambda + 2 mu)` of an isotropic 3D
/// material, read from its tangent at `F = I` (`dP = mu (dF + dF^T) + lambda tr(dF) I` there:
/// `dP11/dF11 = lambda + 2 mu`, `dP22/dF11 = lambda`).
fn solid_plate_modulus<M: Material>(material: &M) -> f64 {
    let t = material.tangent(&nalgebra::Matrix3::identity());
    let lambda = t[(4, 0)];
    let mu = 0.5 * (t[(0, 0)] - lambda);
    4.0 * mu * (lambda + mu) / (lambda + 2.0 * mu)
}

/// Element names in errors (as the elements name themselves).
const PRISM: &str = "three-prism";
const MEMBRANE: &str = "hyper membrane";

/// Checks a membrane triangle: finite and not degenerate ([`HyperMembrane::check_state`]), and
/// inside the model's admissible set (for example below Gent's limit), reported as the area
/// stretch `sqrt(det C)` that is out of range.
fn membrane_check_state<W: MembraneMaterial>(
    material: &W,
    element: &HyperMembrane,
    x: &[Vector3<f64>; 3],
) -> Result<(), ElementError> {
    element.check_state(x)?;
    if !element.is_admissible(material, x) {
        return Err(ElementError::InvalidParameter {
            element: MEMBRANE,
            name: "area stretch",
            value: element.right_cauchy_green(x).determinant().max(0.0).sqrt(),
            allowed: "a stretch where the membrane model is defined (Gent: I1 - 3 < jm)",
        });
    }
    Ok(())
}

/// A shell material chosen at run time (a scenario's material): a 3D material on
/// three-prism elements, or an incompressible membrane on [`HyperMembrane`] triangles.
///
/// Serialises as the inner model, with its `model` tag (`"st-venant-kirchhoff"`,
/// `"neo-hookean"`, `"membrane-gent"`, ...), e.g.
/// `{"model": "membrane-gent", "mu": 400000.0, "jm": 60.0}`; deserialisation tries the 3D
/// models first, then the membranes, validating the parameters either way. Code that knows the
/// material at compile time should use it directly (a [`Material`] or a [`Membrane`] as the
/// shell material): the `match` here is one branch per element call.
///
/// ```
/// use balloon_material::membrane::{MembraneNeoHookean, MembraneModel};
/// use balloon_shell::{ShellMaterial, ShellMaterialModel};
///
/// let rubber = ShellMaterialModel::from(MembraneModel::from(MembraneNeoHookean::try_new(4e5)?));
/// assert!(rubber.thickness_follows_stretch());
/// let json = serde_json::to_string(&rubber).unwrap();
/// assert_eq!(json, r#"{"model":"membrane-neo-hookean","mu":400000.0}"#);
/// let back: ShellMaterialModel = serde_json::from_str(&json).unwrap();
/// assert_eq!(back, rubber);
/// # Ok::<(), balloon_material::MaterialError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ShellMaterialModel {
    /// A 3D material on three-prism elements (Wang et al. 2015).
    Solid(MaterialModel),
    /// An incompressible membrane model on [`HyperMembrane`] triangles.
    Membrane(MembraneModel),
}

impl From<MaterialModel> for ShellMaterialModel {
    fn from(m: MaterialModel) -> Self {
        Self::Solid(m)
    }
}

impl From<MembraneModel> for ShellMaterialModel {
    fn from(m: MembraneModel) -> Self {
        Self::Membrane(m)
    }
}

impl ShellMaterialModel {
    /// The model's name: `st-venant-kirchhoff`, `neo-hookean`, or `membrane-...`.
    pub fn name(&self) -> String {
        match self {
            Self::Solid(m) => m.kind().to_string(),
            Self::Membrane(m) => m.kind().to_string(),
        }
    }
}

/// The element of a [`ShellMaterialModel`]: the kind follows the material's variant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShellElement {
    /// A three-prism element (Wang et al. 2015, Eq. 1-4).
    Prism(ThreePrism),
    /// A membrane triangle (`docs/membranes.md` M22).
    Membrane(HyperMembrane),
}

/// Forces and stiffness of an element that does not belong to the material (impossible through
/// the builder, which makes the elements from the material): NaN, so the shell reports a
/// non-finite force instead of computing with the wrong model.
fn mismatch() -> ([Vector3<f64>; 3], SMatrix<f64, 9, 9>) {
    ([Vector3::repeat(f64::NAN); 3], SMatrix::repeat(f64::NAN))
}

impl ShellMaterial for ShellMaterialModel {
    type Element = ShellElement;

    fn element(
        &self,
        rest: [Vector3<f64>; 3],
        thickness: f64,
    ) -> Result<ShellElement, ElementError> {
        Ok(match self {
            Self::Solid(m) => ShellElement::Prism(m.element(rest, thickness)?),
            Self::Membrane(_) => ShellElement::Membrane(HyperMembrane::try_new(rest, thickness)?),
        })
    }

    fn lumped_masses(&self, element: &ShellElement, density: f64) -> [f64; 3] {
        match element {
            ShellElement::Prism(e) => e.lumped_masses(density),
            ShellElement::Membrane(e) => e.lumped_masses(density),
        }
    }

    fn projection_masses(&self, element: &ShellElement, density: f64) -> ([f64; 3], f64) {
        let m = match element {
            ShellElement::Prism(e) => return e.projection_masses(density),
            ShellElement::Membrane(e) => density * e.rest_volume(),
        };
        ([m / 6.0; 3], m / 2.0)
    }

    #[inline]
    fn energy(&self, element: &ShellElement, x: &[Vector3<f64>; 3], h: f64) -> f64 {
        match (self, element) {
            (Self::Solid(m), ShellElement::Prism(e)) => e.energy(m, x, h),
            (Self::Membrane(m), ShellElement::Membrane(e)) => e.energy(m, x),
            _ => f64::NAN,
        }
    }

    #[inline]
    fn forces(&self, element: &ShellElement, x: &[Vector3<f64>; 3], h: f64) -> [Vector3<f64>; 3] {
        match (self, element) {
            (Self::Solid(m), ShellElement::Prism(e)) => ShellMaterial::forces(m, e, x, h),
            (Self::Membrane(m), ShellElement::Membrane(e)) => e.forces(m, x),
            _ => mismatch().0,
        }
    }

    #[inline]
    fn forces_and_energy(
        &self,
        element: &ShellElement,
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> ([Vector3<f64>; 3], f64) {
        match (self, element) {
            (Self::Solid(m), ShellElement::Prism(e)) => e.forces_and_energy(m, x, h),
            (Self::Membrane(m), ShellElement::Membrane(e)) => {
                let (w, f) = e.energy_and_forces(m, x);
                (f, w)
            }
            _ => (mismatch().0, f64::NAN),
        }
    }

    #[inline]
    fn forces_and_stiffness(
        &self,
        element: &ShellElement,
        x: &[Vector3<f64>; 3],
        h: f64,
        projected: bool,
    ) -> ([Vector3<f64>; 3], SMatrix<f64, 9, 9>) {
        match (self, element) {
            (Self::Solid(m), ShellElement::Prism(e)) => {
                ShellMaterial::forces_and_stiffness(m, e, x, h, projected)
            }
            (Self::Membrane(m), ShellElement::Membrane(e)) => {
                if projected {
                    e.forces_and_projected_stiffness(m, x)
                } else {
                    e.forces_and_stiffness(m, x)
                }
            }
            _ => mismatch(),
        }
    }

    fn check_state(
        &self,
        element: &ShellElement,
        x: &[Vector3<f64>; 3],
        h: f64,
    ) -> Result<(), ElementError> {
        match (self, element) {
            (Self::Solid(_), ShellElement::Prism(e)) => e.check_state(x, h),
            (Self::Membrane(m), ShellElement::Membrane(e)) => membrane_check_state(m, e, x),
            _ => Err(ElementError::InvalidParameter {
                element: self.element_name(),
                name: "element kind",
                value: f64::NAN,
                allowed: "the element kind of the material (made by the builder)",
            }),
        }
    }

    fn element_name(&self) -> &'static str {
        match self {
            Self::Solid(_) => PRISM,
            Self::Membrane(_) => MEMBRANE,
        }
    }

    fn plate_modulus(&self) -> f64 {
        match self {
            Self::Solid(m) => solid_plate_modulus(m),
            Self::Membrane(m) => 4.0 * m.initial_shear_modulus(),
        }
    }

    fn thickness_follows_stretch(&self) -> bool {
        matches!(self, Self::Membrane(_))
    }

    #[inline]
    fn current_thickness(&self, element: &ShellElement, x: &[Vector3<f64>; 3], h: f64) -> f64 {
        match element {
            ShellElement::Prism(_) => h,
            ShellElement::Membrane(e) => e.thickness(x),
        }
    }
}
