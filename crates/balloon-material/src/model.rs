//! A closed enum of the materials, chosen at run time from a scenario file.

use std::fmt;
use std::str::FromStr;

use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

use crate::{Lame, Material, MaterialError, NeoHookean, StVenantKirchhoff};

/// Which constitutive model to use (no parameters).
///
/// Parses (case-insensitively) from `stvk`, `st-venant-kirchhoff`, `neo-hookean` or `neohookean`;
/// serialises as `st-venant-kirchhoff` / `neo-hookean` (the other spellings are accepted as
/// aliases).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MaterialKind {
    /// [`StVenantKirchhoff`], Wang et al. 2015, Eq. 6-9.
    #[serde(alias = "stvk")]
    StVenantKirchhoff,
    /// [`NeoHookean`].
    #[serde(alias = "neohookean")]
    NeoHookean,
}

impl FromStr for MaterialKind {
    type Err = MaterialError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "stvk" | "st-venant-kirchhoff" => Ok(Self::StVenantKirchhoff),
            "neo-hookean" | "neohookean" => Ok(Self::NeoHookean),
            _ => Err(MaterialError::UnknownModel(s.to_owned())),
        }
    }
}

impl fmt::Display for MaterialKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::StVenantKirchhoff => "st-venant-kirchhoff",
            Self::NeoHookean => "neo-hookean",
        })
    }
}

/// A material chosen at run time; implements [`Material`] by dispatching to the concrete model.
///
/// Serialised with an internal `model` tag next to the Lame parameters, e.g.
/// `{"model": "st-venant-kirchhoff", "mu": 3.4e5, "lambda": 3.1e6}`
/// (`"stvk"` and `"neohookean"` are accepted as tag aliases). Deserialisation validates the Lame
/// parameters. Hot loops that know the model at compile time should use the concrete type instead
/// (the `match` here is cheap but prevents some inlining).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "kebab-case")]
pub enum MaterialModel {
    /// St. Venant-Kirchhoff (Wang et al. 2015, Eq. 6-9).
    #[serde(alias = "stvk")]
    StVenantKirchhoff(StVenantKirchhoff),
    /// Compressible neo-Hookean.
    #[serde(alias = "neohookean")]
    NeoHookean(NeoHookean),
}

impl MaterialModel {
    /// The model `kind` with Young's modulus `young` (Pa) and Poisson ratio `poisson`.
    ///
    /// # Errors
    /// See [`Lame::try_from_young_poisson`].
    pub fn from_young_poisson(
        kind: MaterialKind,
        young: f64,
        poisson: f64,
    ) -> Result<Self, MaterialError> {
        let lame = Lame::try_from_young_poisson(young, poisson)?;
        Ok(Self::from_lame(kind, lame))
    }

    /// The model `kind` with the given Lame parameters.
    pub fn from_lame(kind: MaterialKind, lame: Lame) -> Self {
        match kind {
            MaterialKind::StVenantKirchhoff => {
                Self::StVenantKirchhoff(StVenantKirchhoff::new(lame))
            }
            MaterialKind::NeoHookean => Self::NeoHookean(NeoHookean::new(lame)),
        }
    }

    /// Which model this is.
    pub fn kind(&self) -> MaterialKind {
        match self {
            Self::StVenantKirchhoff(_) => MaterialKind::StVenantKirchhoff,
            Self::NeoHookean(_) => MaterialKind::NeoHookean,
        }
    }

    /// The Lame parameters.
    pub fn lame(&self) -> Lame {
        match self {
            Self::StVenantKirchhoff(m) => m.lame(),
            Self::NeoHookean(m) => m.lame(),
        }
    }
}

macro_rules! dispatch {
    ($self:ident, $m:ident => $e:expr) => {
        match $self {
            MaterialModel::StVenantKirchhoff($m) => $e,
            MaterialModel::NeoHookean($m) => $e,
        }
    };
}

impl Material for MaterialModel {
    #[inline]
    fn energy_density(&self, f: &Matrix3<f64>) -> f64 {
        dispatch!(self, m => m.energy_density(f))
    }
    #[inline]
    fn first_piola(&self, f: &Matrix3<f64>) -> Matrix3<f64> {
        dispatch!(self, m => m.first_piola(f))
    }
    #[inline]
    fn first_piola_differential(&self, f: &Matrix3<f64>, df: &Matrix3<f64>) -> Matrix3<f64> {
        dispatch!(self, m => m.first_piola_differential(f, df))
    }
    #[inline]
    fn first_piola_differentials<const N: usize>(
        &self,
        f: &Matrix3<f64>,
        dfs: &[Matrix3<f64>; N],
    ) -> [Matrix3<f64>; N] {
        dispatch!(self, m => m.first_piola_differentials(f, dfs))
    }
    #[inline]
    fn energy_and_piola(&self, f: &Matrix3<f64>) -> (f64, Matrix3<f64>) {
        dispatch!(self, m => m.energy_and_piola(f))
    }
    #[inline]
    fn is_admissible(&self, f: &Matrix3<f64>) -> bool {
        dispatch!(self, m => m.is_admissible(f))
    }
}
