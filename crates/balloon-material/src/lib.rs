//! Hyperelastic materials for the `balloon` workspace: energy density `psi(F)`, first
//! Piola-Kirchhoff stress `P(F) = dpsi/dF` and its differential `dP(F; dF)`; and, in
//! [`membrane`], incompressible rubber membranes `W(C)` with their stress `S = 2 dW/dC` and
//! tangent.
//!
//! **What it is for.** Constitutive laws evaluated on one 3x3 deformation gradient at a time, in
//! `f64` and SI units (`psi` in J/m^3 per unit *rest* volume, `P` in Pa). Elements
//! (`balloon-element`) are generic over the [`Material`] trait and monomorphised, so a material is
//! a small `Copy` value with no allocation. The equations follow Wang et al. 2015 ("Cute Balloons with
//! Thickness"), Sec. 4, Eq. 6, 7, 9 and the differential used by Eq. 11.
//!
//! **What it is not for.** Meshes, elements, quadrature and assembly live elsewhere; this crate
//! knows nothing of them.
//!
//! | type | model | notes |
//! |---|---|---|
//! | [`StVenantKirchhoff`] (alias StVK) | `mu E:E + lambda/2 tr(E)^2`, Eq. 6 | defined for all `F`, no inversion resistance |
//! | [`NeoHookean`] | `mu/2 (I1 - 3) - mu ln J + lambda/2 (ln J)^2` | infinite energy as `J -> 0`, undefined for `J <= 0` |
//! | [`MaterialModel`] | closed serde enum over the above | run-time choice from a scenario file |
//! | [`Lame`] | validated `(mu, lambda)`, from `(E, nu)` | |
//! | [`membrane`] module | incompressible membranes `W(C)` on the 2x2 in-plane `C`: neo-Hookean, Mooney-Rivlin, Gent, Ogden (N terms), Yeoh; [`MembraneModel`] enum, published presets, the analytic thin sphere | plane stress, `h = H / sqrt(det C)`; see `docs/membranes.md` |
//!
//! ```
//! use balloon_material::{Lame, Material, StVenantKirchhoff};
//! use nalgebra::Matrix3;
//!
//! let lame = Lame::try_from_young_poisson(1.0e6, 0.45)?;
//! let stvk = StVenantKirchhoff::new(lame);
//! // No energy and no stress in the rest state.
//! assert_eq!(stvk.energy_density(&Matrix3::identity()), 0.0);
//! assert_eq!(stvk.first_piola(&Matrix3::identity()), Matrix3::zeros());
//! // A 1% uniaxial stretch stores energy.
//! let f = Matrix3::new(1.01, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
//! assert!(stvk.energy_density(&f) > 0.0);
//! # Ok::<(), balloon_material::MaterialError>(())
//! ```
//!
//! Features: none; `serde` support is always on (the scenario files need it).

mod error;
mod lame;
pub mod membrane;
mod model;
mod neo_hookean;
mod stvk;

pub use error::MaterialError;
pub use lame::Lame;
pub use membrane::{MembraneMaterial, MembraneModel};
pub use model::{MaterialKind, MaterialModel};
pub use neo_hookean::NeoHookean;
pub use stvk::StVenantKirchhoff;

use nalgebra::{Matrix3, SMatrix};

/// A hyperelastic material: energy density `psi(F)` per unit rest volume and its derivatives.
///
/// Implementors must keep `first_piola` the exact derivative of `energy_density` and
/// `first_piola_differential` the exact directional derivative of `first_piola`: elements and the
/// Newton solver (Wang et al. 2015, Eq. 8, 11, 23) rely on it, and the crate's finite-difference tests check
/// it for every model.
pub trait Material: Clone + Send + Sync + std::fmt::Debug {
    /// Energy density `psi(F)` in J/m^3 (per unit rest volume), Wang et al. 2015, Eq. 5-6.
    fn energy_density(&self, f: &Matrix3<f64>) -> f64;

    /// First Piola-Kirchhoff stress `P = dpsi/dF` in Pa, Wang et al. 2015, Eq. 9.
    fn first_piola(&self, f: &Matrix3<f64>) -> Matrix3<f64>;

    /// Directional derivative `dP = (dP/dF) : dF` of the first Piola stress at `F` along `dF`
    /// (the `P(F; dF)` of Wang et al. 2015, Eq. 11), in Pa per unit of `dF`.
    fn first_piola_differential(&self, f: &Matrix3<f64>, df: &Matrix3<f64>) -> Matrix3<f64>;

    /// `dP(F; dF_k)` for several directions `dF_k` at the same `F`. Override when the
    /// directions can share the work that depends on `F` only (both built-in models do): the
    /// elements' stiffness blocks call this with 6 or 9 directions.
    fn first_piola_differentials<const N: usize>(
        &self,
        f: &Matrix3<f64>,
        dfs: &[Matrix3<f64>; N],
    ) -> [Matrix3<f64>; N] {
        std::array::from_fn(|k| self.first_piola_differential(f, &dfs[k]))
    }

    /// `(psi(F), P(F))` together; override when the two share work (both built-in models do).
    fn energy_and_piola(&self, f: &Matrix3<f64>) -> (f64, Matrix3<f64>) {
        (self.energy_density(f), self.first_piola(f))
    }

    /// The fourth-order tangent `dP/dF` as a 9x9 matrix in **column-major `vec` ordering**:
    /// `vec(F) = [F11 F21 F31 F12 F22 F32 F13 F23 F33]` (nalgebra's storage order, so
    /// `F.as_slice()[k]` is entry `k`), and `tangent[(i, k)] = d vec(P)_i / d vec(F)_k`.
    /// Hence `vec(dP) = tangent * vec(dF)`. For a hyperelastic material the matrix is symmetric
    /// (major symmetry, it is the Hessian of `psi`).
    ///
    /// The provided implementation evaluates [`Material::first_piola_differential`] along the 9
    /// unit directions.
    fn tangent(&self, f: &Matrix3<f64>) -> SMatrix<f64, 9, 9> {
        let mut t = SMatrix::<f64, 9, 9>::zeros();
        for k in 0..9 {
            let mut df = Matrix3::zeros();
            df.as_mut_slice()[k] = 1.0;
            let dp = self.first_piola_differential(f, &df);
            t.column_mut(k).copy_from_slice(dp.as_slice());
        }
        t
    }

    /// Whether the model is defined at `F` (for example `det F > 0` for [`NeoHookean`]).
    /// Outside the admissible set the energy is `+infinity` and the stress is not meaningful; see
    /// each model's documentation. Defaults to `true`.
    fn is_admissible(&self, _f: &Matrix3<f64>) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use balloon_test_support::{
        Rng, assert_second_order, check_gradient, check_jacobian, taylor_remainder_orders,
    };
    use nalgebra::{Rotation3, Vector3};

    fn lame() -> Lame {
        Lame::try_new(1.3, 2.1).unwrap()
    }

    fn models() -> Vec<MaterialModel> {
        vec![
            MaterialModel::from_lame(MaterialKind::StVenantKirchhoff, lame()),
            MaterialModel::from_lame(MaterialKind::NeoHookean, lame()),
        ]
    }

    /// A random, well-conditioned deformation gradient `I + a G` with `det > 0.3`, stretching and
    /// compressing.
    fn random_f(rng: &mut Rng, a: f64) -> Matrix3<f64> {
        loop {
            let g = Matrix3::from_iterator((0..9).map(|_| rng.next_f64()));
            let f = Matrix3::identity() + g * a;
            if f.determinant() > 0.3 {
                return f;
            }
        }
    }

    fn random_rotation(rng: &mut Rng) -> Rotation3<f64> {
        let axis = Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
        Rotation3::new(axis * 3.0)
    }

    fn mat(x: &[f64]) -> Matrix3<f64> {
        Matrix3::from_column_slice(x)
    }

    #[test]
    fn piola_is_the_gradient_of_energy() {
        let mut rng = Rng::new(11);
        for m in models() {
            for _ in 0..10 {
                let f = random_f(&mut rng, 0.4);
                let x = f.as_slice().to_vec();
                check_gradient(
                    |x| m.energy_density(&mat(x)),
                    |x| m.first_piola(&mat(x)).as_slice().to_vec(),
                    &x,
                    1e-6,
                    1e-7,
                );
                let dx = rng.vector(9);
                let ratios = taylor_remainder_orders(
                    |x| m.energy_density(&mat(x)),
                    |x| m.first_piola(&mat(x)).as_slice().to_vec(),
                    &x,
                    &dx,
                    1e-2,
                );
                assert_second_order(&ratios);
                let (psi, p) = m.energy_and_piola(&f);
                assert!((psi - m.energy_density(&f)).abs() <= 1e-14 * psi.abs().max(1.0));
                assert!((p - m.first_piola(&f)).norm() <= 1e-13 * p.norm().max(1.0));
            }
        }
    }

    #[test]
    fn piola_differential_is_the_derivative_of_piola() {
        let mut rng = Rng::new(12);
        for m in models() {
            for seed in 0..10 {
                let f = random_f(&mut rng, 0.4);
                check_jacobian(
                    |x| m.first_piola(&mat(x)).as_slice().to_vec(),
                    |x, d| {
                        m.first_piola_differential(&mat(x), &mat(d))
                            .as_slice()
                            .to_vec()
                    },
                    f.as_slice(),
                    1e-6,
                    1e-7,
                    seed,
                );
            }
        }
    }

    #[test]
    fn tangent_is_symmetric_and_matches_differential() {
        let mut rng = Rng::new(13);
        for m in models() {
            for _ in 0..10 {
                let f = random_f(&mut rng, 0.4);
                let t = m.tangent(&f);
                // Major symmetry: the tangent is the Hessian of psi with respect to F.
                assert!((t - t.transpose()).norm() <= 1e-12 * t.norm());
                let df = random_f(&mut rng, 1.0) - Matrix3::identity();
                let dp = m.first_piola_differential(&f, &df);
                let tv = t * nalgebra::SVector::<f64, 9>::from_column_slice(df.as_slice());
                assert!(
                    (tv - nalgebra::SVector::<f64, 9>::from_column_slice(dp.as_slice())).norm()
                        <= 1e-12 * dp.norm().max(1.0)
                );
                // The batched differentials equal the single ones.
                let dfs = [df, df.transpose(), Matrix3::identity()];
                let batch = m.first_piola_differentials(&f, &dfs);
                for (b, d) in batch.iter().zip(&dfs) {
                    assert!(
                        (b - m.first_piola_differential(&f, d)).norm() <= 1e-13 * b.norm().max(1.0)
                    );
                }
                // Ordering: entry (i, k) is d vec(P)_i / d vec(F)_k with vec column-major.
                let mut e = Matrix3::zeros();
                e[(1, 2)] = 1.0; // F23 -> vec index 3 * 2 + 1 = 7
                let col = m.first_piola_differential(&f, &e);
                assert!((t[(3, 7)] - col[(0, 1)]).abs() <= 1e-13 * t.norm());
            }
        }
    }

    #[test]
    fn rest_and_rigid_rotations_are_stress_free() {
        let mut rng = Rng::new(14);
        for m in models() {
            assert_eq!(m.energy_density(&Matrix3::identity()), 0.0);
            assert!(m.first_piola(&Matrix3::identity()).norm() <= 1e-15);
            for _ in 0..10 {
                // A rigid rotation stores no energy and carries no stress.
                let r = random_rotation(&mut rng).into_inner();
                assert!(m.energy_density(&r).abs() <= 1e-13, "{m:?}");
                assert!(m.first_piola(&r).norm() <= 1e-13, "{m:?}");
            }
        }
    }

    #[test]
    fn frame_indifference() {
        let mut rng = Rng::new(15);
        for m in models() {
            for _ in 0..10 {
                // Rotating the deformed body after deforming it changes no stretch: psi(RF) =
                // psi(F), and the stress rotates with the body: P(RF) = R P(F).
                let f = random_f(&mut rng, 0.4);
                let r = random_rotation(&mut rng).into_inner();
                let (psi, p) = m.energy_and_piola(&f);
                let (psi_r, p_r) = m.energy_and_piola(&(r * f));
                assert!((psi - psi_r).abs() <= 1e-12 * psi.abs().max(1.0));
                assert!((r * p - p_r).norm() <= 1e-12 * p.norm().max(1.0));
            }
        }
    }

    #[test]
    fn small_strain_limit_is_linear_elasticity() {
        let mut rng = Rng::new(16);
        let l = lame();
        for m in models() {
            let g = random_f(&mut rng, 1.0) - Matrix3::identity();
            let mut errs = Vec::new();
            for eps in [1e-3, 1e-4] {
                // For F = I + eps G the stress tends to Hooke's law on the small strain
                // sym(eps G), with an error quadratic in eps.
                let du = g * eps;
                let strain = (du + du.transpose()) * 0.5;
                let hooke =
                    strain * (2.0 * l.mu()) + Matrix3::identity() * (l.lambda() * strain.trace());
                let p = m.first_piola(&(Matrix3::identity() + du));
                errs.push((p - hooke).norm() / hooke.norm());
            }
            assert!(errs[0] < 1e-2, "{errs:?}");
            assert!(errs[1] < errs[0] * 0.2, "error not O(eps): {errs:?}");
        }
    }

    #[test]
    fn neo_hookean_near_and_beyond_inversion() {
        let nh = NeoHookean::new(lame());
        // Squashing to zero volume costs unbounded energy.
        let mut last = 0.0;
        for t in [1e-1, 1e-3, 1e-6, 1e-12] {
            let psi = nh.energy_density(&Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, t)));
            assert!(psi > last);
            last = psi;
        }
        assert!(last > 100.0);
        let inverted = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -0.5));
        assert!(!nh.is_admissible(&inverted));
        assert_eq!(nh.energy_density(&inverted), f64::INFINITY);
        assert!(nh.first_piola(&inverted).iter().all(|v| v.is_nan()));
        assert!(
            nh.first_piola_differential(&inverted, &Matrix3::identity())
                .iter()
                .all(|v| v.is_nan())
        );
        assert!(!nh.is_admissible(&Matrix3::zeros()));
        assert!(nh.is_admissible(&Matrix3::identity()));
        // StVK is defined everywhere (it does not resist inversion).
        let stvk = StVenantKirchhoff::new(lame());
        assert!(stvk.is_admissible(&inverted) && stvk.energy_density(&inverted).is_finite());
    }

    #[test]
    fn kinds_parse_and_models_roundtrip() {
        for (s, k) in [
            ("stvk", MaterialKind::StVenantKirchhoff),
            ("St-Venant-Kirchhoff", MaterialKind::StVenantKirchhoff),
            ("neo-hookean", MaterialKind::NeoHookean),
            ("neohookean", MaterialKind::NeoHookean),
        ] {
            assert_eq!(s.parse::<MaterialKind>().unwrap(), k);
            assert_eq!(k.to_string().parse::<MaterialKind>().unwrap(), k);
        }
        let err = "rubber".parse::<MaterialKind>().unwrap_err();
        assert!(err.to_string().contains("rubber"));
        let k: MaterialKind = serde_json::from_str("\"stvk\"").unwrap();
        assert_eq!(k, MaterialKind::StVenantKirchhoff);

        for m in models() {
            let json = serde_json::to_string(&m).unwrap();
            assert!(
                json.contains("\"model\"") && json.contains("\"mu\""),
                "{json}"
            );
            let back: MaterialModel = serde_json::from_str(&json).unwrap();
            assert_eq!(back, m);
            assert_eq!(back.kind(), m.kind());
        }
        let m: MaterialModel =
            serde_json::from_str(r#"{"model": "stvk", "mu": 1.0, "lambda": 2.0}"#).unwrap();
        assert_eq!(m.kind(), MaterialKind::StVenantKirchhoff);
        assert!(
            serde_json::from_str::<MaterialModel>(
                r#"{"model": "neo-hookean", "mu": 1.0, "lambda": -5.0}"#
            )
            .is_err()
        );
        let m = MaterialModel::from_young_poisson(MaterialKind::NeoHookean, 1.0e6, 0.3).unwrap();
        assert!((m.lame().young() - 1.0e6).abs() < 1e-6);
        assert!(MaterialModel::from_young_poisson(MaterialKind::NeoHookean, 1.0e6, 0.5).is_err());
    }
}
