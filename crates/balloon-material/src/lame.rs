//! Lame parameters and their conversion from engineering constants.

use serde::{Deserialize, Serialize};

use crate::MaterialError;

/// The two Lame parameters of an isotropic material, in pascals.
///
/// Invariants (checked by every constructor, including deserialisation): `mu > 0`, both finite,
/// and a positive bulk modulus `K = lambda + 2 mu / 3 > 0`, which is equivalent to a Poisson ratio
/// in `(-1, 0.5)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawLame")]
pub struct Lame {
    mu: f64,
    lambda: f64,
}

#[derive(Deserialize)]
struct RawLame {
    mu: f64,
    lambda: f64,
}

impl TryFrom<RawLame> for Lame {
    type Error = MaterialError;
    fn try_from(raw: RawLame) -> Result<Self, Self::Error> {
        Lame::try_new(raw.mu, raw.lambda)
    }
}

impl Lame {
    /// Lame parameters from the shear modulus `mu` (Pa) and the first Lame parameter `lambda`
    /// (Pa).
    ///
    /// # Errors
    /// [`MaterialError::InvalidParameter`] naming `mu` if `mu` is not finite and positive, or
    /// naming `lambda` if `lambda` is not finite or `3 lambda + 2 mu <= 0` (non-positive bulk
    /// modulus).
    pub fn try_new(mu: f64, lambda: f64) -> Result<Self, MaterialError> {
        if !(mu.is_finite() && mu > 0.0) {
            return Err(MaterialError::InvalidParameter {
                name: "mu",
                value: mu,
                allowed: "finite and > 0 Pa",
            });
        }
        if !(lambda.is_finite() && 3.0 * lambda + 2.0 * mu > 0.0) {
            return Err(MaterialError::InvalidParameter {
                name: "lambda",
                value: lambda,
                allowed: "finite and > -2 mu / 3 (positive bulk modulus)",
            });
        }
        Ok(Self { mu, lambda })
    }

    /// Lame parameters from Young's modulus `young` (Pa) and Poisson's ratio `poisson`
    /// (dimensionless), with the textbook formulas
    /// `mu = E / (2 (1 + nu))` and `lambda = E nu / ((1 + nu)(1 - 2 nu))`.
    ///
    /// # Errors
    /// [`MaterialError::InvalidParameter`] naming `young` unless `E` is finite and `> 0`, or naming
    /// `poisson` unless `-1 < nu < 0.5` (the incompressible limit `nu = 0.5` has infinite
    /// `lambda`).
    pub fn try_from_young_poisson(young: f64, poisson: f64) -> Result<Self, MaterialError> {
        if !(young.is_finite() && young > 0.0) {
            return Err(MaterialError::InvalidParameter {
                name: "young",
                value: young,
                allowed: "finite and > 0 Pa",
            });
        }
        if !(poisson.is_finite() && poisson > -1.0 && poisson < 0.5) {
            return Err(MaterialError::InvalidParameter {
                name: "poisson",
                value: poisson,
                allowed: "-1 < nu < 0.5",
            });
        }
        let mu = young / (2.0 * (1.0 + poisson));
        let lambda = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
        Self::try_new(mu, lambda)
    }

    /// Shear modulus `mu` (Pa).
    pub fn mu(&self) -> f64 {
        self.mu
    }

    /// First Lame parameter `lambda` (Pa).
    pub fn lambda(&self) -> f64 {
        self.lambda
    }

    /// Young's modulus `E = mu (3 lambda + 2 mu) / (lambda + mu)` (Pa).
    pub fn young(&self) -> f64 {
        self.mu * (3.0 * self.lambda + 2.0 * self.mu) / (self.lambda + self.mu)
    }

    /// Poisson's ratio `nu = lambda / (2 (lambda + mu))`.
    pub fn poisson(&self) -> f64 {
        self.lambda / (2.0 * (self.lambda + self.mu))
    }

    /// Bulk modulus `K = lambda + 2 mu / 3` (Pa).
    pub fn bulk(&self) -> f64 {
        self.lambda + 2.0 * self.mu / 3.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn textbook_conversion_and_inverse() {
        // Rubber-like: E = 1 MPa, nu = 0.45.
        let l = Lame::try_from_young_poisson(1.0e6, 0.45).unwrap();
        let mu = 1.0e6 / 2.9;
        let lambda = 1.0e6 * 0.45 / (1.45 * 0.1);
        assert!((l.mu() - mu).abs() <= 1e-9 * mu);
        assert!((l.lambda() - lambda).abs() <= 1e-9 * lambda);
        assert!((l.young() - 1.0e6).abs() <= 1e-6);
        assert!((l.poisson() - 0.45).abs() <= 1e-12);
        // nu = 0 decouples: lambda = 0, mu = E / 2.
        let l0 = Lame::try_from_young_poisson(2.0, 0.0).unwrap();
        assert_eq!((l0.mu(), l0.lambda()), (1.0, 0.0));
        // Auxetic materials are allowed.
        let la = Lame::try_from_young_poisson(1.0, -0.5).unwrap();
        assert!(la.lambda() < 0.0 && la.bulk() > 0.0);
    }

    #[test]
    fn rejects_bad_parameters_naming_them() {
        for (e, nu, name) in [
            (0.0, 0.3, "young"),
            (-1.0, 0.3, "young"),
            (f64::NAN, 0.3, "young"),
            (f64::INFINITY, 0.3, "young"),
            (1.0, 0.5, "poisson"),
            (1.0, -1.0, "poisson"),
            (1.0, 0.7, "poisson"),
            (1.0, f64::NAN, "poisson"),
        ] {
            match Lame::try_from_young_poisson(e, nu) {
                Err(MaterialError::InvalidParameter { name: n, .. }) => assert_eq!(n, name),
                other => panic!("E = {e}, nu = {nu}: expected error on {name}, got {other:?}"),
            }
        }
        let msg = Lame::try_from_young_poisson(1.0, 0.5)
            .unwrap_err()
            .to_string();
        assert!(msg.contains("poisson") && msg.contains("0.5"), "{msg}");
        assert!(matches!(
            Lame::try_new(0.0, 1.0),
            Err(MaterialError::InvalidParameter { name: "mu", .. })
        ));
        assert!(matches!(
            Lame::try_new(1.0, -1.0),
            Err(MaterialError::InvalidParameter { name: "lambda", .. })
        ));
    }

    #[test]
    fn deserialisation_validates() {
        let ok: Lame = serde_json::from_str(r#"{"mu": 2.0, "lambda": 3.0}"#).unwrap();
        assert_eq!((ok.mu(), ok.lambda()), (2.0, 3.0));
        let bad = serde_json::from_str::<Lame>(r#"{"mu": -2.0, "lambda": 3.0}"#);
        assert!(bad.unwrap_err().to_string().contains("mu"));
    }
}
