//! A closed enum of the membrane models, their names and published presets.

use std::fmt;
use std::str::FromStr;

use nalgebra::{Matrix2, Matrix3};
use serde::{Deserialize, Serialize};

use super::{
    MembraneGent, MembraneMaterial, MembraneMooneyRivlin, MembraneNeoHookean, MembraneOgden,
    MembraneYeoh,
};
use crate::MaterialError;

/// Which membrane model (no parameters), by the names the command line uses.
///
/// Parses case-insensitively from `membrane-neo-hookean`, `membrane-mooney-rivlin`,
/// `membrane-gent`, `membrane-ogden`, `membrane-yeoh` (the `membrane-` prefix is optional, and
/// `neohookean` / `mooneyrivlin` are accepted); displays with the prefix.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MembraneKind {
    /// [`MembraneNeoHookean`].
    NeoHookean,
    /// [`MembraneMooneyRivlin`].
    MooneyRivlin,
    /// [`MembraneGent`].
    Gent,
    /// [`MembraneOgden`].
    Ogden,
    /// [`MembraneYeoh`].
    Yeoh,
}

impl MembraneKind {
    /// Every kind, in documentation order.
    pub const ALL: [MembraneKind; 5] = [
        Self::NeoHookean,
        Self::MooneyRivlin,
        Self::Gent,
        Self::Ogden,
        Self::Yeoh,
    ];

    /// The command-line name, e.g. `membrane-gent`.
    pub fn name(self) -> &'static str {
        match self {
            Self::NeoHookean => "membrane-neo-hookean",
            Self::MooneyRivlin => "membrane-mooney-rivlin",
            Self::Gent => "membrane-gent",
            Self::Ogden => "membrane-ogden",
            Self::Yeoh => "membrane-yeoh",
        }
    }
}

impl FromStr for MembraneKind {
    type Err = MaterialError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let lower = s.trim().to_ascii_lowercase();
        let bare = lower.strip_prefix("membrane-").unwrap_or(&lower);
        match bare {
            "neo-hookean" | "neohookean" => Ok(Self::NeoHookean),
            "mooney-rivlin" | "mooneyrivlin" => Ok(Self::MooneyRivlin),
            "gent" => Ok(Self::Gent),
            "ogden" => Ok(Self::Ogden),
            "yeoh" => Ok(Self::Yeoh),
            _ => Err(MaterialError::UnknownMembraneModel(s.to_owned())),
        }
    }
}

impl fmt::Display for MembraneKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A membrane model chosen at run time; implements [`MembraneMaterial`] by dispatching to the
/// concrete model.
///
/// Serialised with an internal `model` tag next to the parameters, for example
/// `{"model": "membrane-gent", "mu": 4e5, "jm": 60}` or
/// `{"model": "membrane-ogden", "mu": [6.3e5, 1.2e3, -1e4], "alpha": [1.3, 5, -2]}`.
/// Deserialisation validates the parameters (the same checks as the `try_new` constructors).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "kebab-case")]
pub enum MembraneModel {
    /// Incompressible neo-Hookean.
    #[serde(rename = "membrane-neo-hookean")]
    NeoHookean(MembraneNeoHookean),
    /// Incompressible Mooney-Rivlin.
    #[serde(rename = "membrane-mooney-rivlin")]
    MooneyRivlin(MembraneMooneyRivlin),
    /// Incompressible Gent.
    #[serde(rename = "membrane-gent")]
    Gent(MembraneGent),
    /// Incompressible Ogden with N terms.
    #[serde(rename = "membrane-ogden")]
    Ogden(MembraneOgden),
    /// Incompressible Yeoh.
    #[serde(rename = "membrane-yeoh")]
    Yeoh(MembraneYeoh),
}

impl MembraneModel {
    /// Which model this is.
    pub fn kind(&self) -> MembraneKind {
        match self {
            Self::NeoHookean(_) => MembraneKind::NeoHookean,
            Self::MooneyRivlin(_) => MembraneKind::MooneyRivlin,
            Self::Gent(_) => MembraneKind::Gent,
            Self::Ogden(_) => MembraneKind::Ogden,
            Self::Yeoh(_) => MembraneKind::Yeoh,
        }
    }
}

impl From<MembraneNeoHookean> for MembraneModel {
    fn from(m: MembraneNeoHookean) -> Self {
        Self::NeoHookean(m)
    }
}
impl From<MembraneMooneyRivlin> for MembraneModel {
    fn from(m: MembraneMooneyRivlin) -> Self {
        Self::MooneyRivlin(m)
    }
}
impl From<MembraneGent> for MembraneModel {
    fn from(m: MembraneGent) -> Self {
        Self::Gent(m)
    }
}
impl From<MembraneOgden> for MembraneModel {
    fn from(m: MembraneOgden) -> Self {
        Self::Ogden(m)
    }
}
impl From<MembraneYeoh> for MembraneModel {
    fn from(m: MembraneYeoh) -> Self {
        Self::Yeoh(m)
    }
}

macro_rules! dispatch {
    ($self:ident, $m:ident => $e:expr) => {
        match $self {
            MembraneModel::NeoHookean($m) => $e,
            MembraneModel::MooneyRivlin($m) => $e,
            MembraneModel::Gent($m) => $e,
            MembraneModel::Ogden($m) => $e,
            MembraneModel::Yeoh($m) => $e,
        }
    };
}

impl MembraneMaterial for MembraneModel {
    #[inline]
    fn energy(&self, c: &Matrix2<f64>) -> f64 {
        dispatch!(self, m => m.energy(c))
    }
    #[inline]
    fn stress(&self, c: &Matrix2<f64>) -> Matrix2<f64> {
        dispatch!(self, m => m.stress(c))
    }
    #[inline]
    fn stress_differential(&self, c: &Matrix2<f64>, dc: &Matrix2<f64>) -> Matrix2<f64> {
        dispatch!(self, m => m.stress_differential(c, dc))
    }
    #[inline]
    fn energy_and_stress(&self, c: &Matrix2<f64>) -> (f64, Matrix2<f64>) {
        dispatch!(self, m => m.energy_and_stress(c))
    }
    #[inline]
    fn tangent(&self, c: &Matrix2<f64>) -> Matrix3<f64> {
        dispatch!(self, m => m.tangent(c))
    }
    #[inline]
    fn initial_shear_modulus(&self) -> f64 {
        dispatch!(self, m => m.initial_shear_modulus())
    }
    #[inline]
    fn is_admissible(&self, c: &Matrix2<f64>) -> bool {
        dispatch!(self, m => m.is_admissible(c))
    }
}

/// Published material fits, usable as membrane models. Every number comes from the source
/// returned by [`MembranePreset::source`]; see also the table in `docs/membranes.md`.
///
/// No preset is given for Ecoflex 00-30 or Dragon Skin: no fit whose numbers could be traced to
/// a citable publication was found while writing this (fits circulating in code without a
/// source were not used).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MembranePreset {
    /// Vulcanised natural rubber (Treloar's 8 % sulphur compound), the classical stand-in for
    /// balloon latex: three-term Ogden fit `mu = (0.63, 0.0012, -0.01)` MPa,
    /// `alpha = (1.3, 5.0, -2.0)` (initial shear modulus 0.4225 MPa).
    NaturalRubber,
    /// Wacker Elastosil M4601 silicone (soft-robotics actuators): Yeoh fit `c1 = 0.11` MPa,
    /// `c2 = 0.02` MPa, `c3 = 0` (initial shear modulus 0.22 MPa).
    ElastosilM4601,
}

impl MembranePreset {
    /// Every preset.
    pub const ALL: [MembranePreset; 2] = [Self::NaturalRubber, Self::ElastosilM4601];

    /// The preset's name (`natural-rubber`, `elastosil-m4601`).
    pub fn name(self) -> &'static str {
        match self {
            Self::NaturalRubber => "natural-rubber",
            Self::ElastosilM4601 => "elastosil-m4601",
        }
    }

    /// The membrane model with the published parameters.
    pub fn model(self) -> MembraneModel {
        // The literals satisfy every constructor check (the crate's tests run them through
        // `try_new`), so the structs are built directly and this cannot fail.
        match self {
            Self::NaturalRubber => MembraneModel::Ogden(MembraneOgden::preset_unchecked(
                vec![0.63e6, 0.0012e6, -0.01e6],
                vec![1.3, 5.0, -2.0],
            )),
            Self::ElastosilM4601 => {
                MembraneModel::Yeoh(MembraneYeoh::preset_unchecked(0.11e6, 0.02e6, 0.0))
            }
        }
    }

    /// The source of the numbers: author, year, journal, and which fit.
    pub fn source(self) -> &'static str {
        match self {
            Self::NaturalRubber => {
                "R. W. Ogden (1972), Large deformation isotropic elasticity - on the correlation of \
                 theory and experiment for incompressible rubberlike solids, Proc. R. Soc. Lond. A \
                 326, 565-584: three-term Ogden fit to L. R. G. Treloar's (1944, Trans. Faraday \
                 Soc. 40, 59-70) simple-tension, pure-shear and equibiaxial data for vulcanised \
                 natural rubber"
            }
            Self::ElastosilM4601 => {
                "P. Polygerinos, Z. Wang, J. T. B. Overvelde, K. C. Galloway, R. J. Wood, \
                 K. Bertoldi, C. J. Walsh (2015), Modeling of soft fiber-reinforced bending \
                 actuators, IEEE Trans. Robotics 31(3), 778-789: Yeoh model (two terms) fitted \
                 to uniaxial tensile tests of Elastosil M4601, used in their finite-element model"
            }
        }
    }
}

impl FromStr for MembranePreset {
    type Err = MaterialError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "natural-rubber" => Ok(Self::NaturalRubber),
            "elastosil-m4601" | "elastosil" => Ok(Self::ElastosilM4601),
            _ => Err(MaterialError::UnknownPreset(s.to_owned())),
        }
    }
}

impl fmt::Display for MembranePreset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}
