//! The shell's material (the `material` keys of `[shell]`): a 3D material on three-prism
//! elements (Wang et al. 2015) or an incompressible rubber membrane, its parameters and the
//! published membrane presets, checked together ([`MaterialSpec::resolve`]).
//!
//! ```
//! use balloon_scenario::material::{MaterialChoice, MaterialSpec};
//! let gent = MaterialSpec {
//!     material: Some("membrane-gent".parse().unwrap()),
//!     mu: Some(4e5),
//!     jm: Some(40.0),
//!     ..MaterialSpec::default()
//! };
//! assert_eq!(gent.resolve().unwrap().name(), "membrane-gent");
//! // A parameter the model does not take is an error naming it and its value.
//! let bad = MaterialSpec { c1: Some(1e5), ..gent };
//! assert_eq!(
//!     bad.resolve().unwrap_err(),
//!     "`c1` = 100000 is not a parameter of membrane-gent, which takes `mu` and `jm`"
//! );
//! ```

use crate::serde_text;
use balloon::material::membrane::{
    MembraneGent, MembraneKind, MembraneMooneyRivlin, MembraneNeoHookean, MembraneOgden,
    MembranePreset, MembraneYeoh,
};
use balloon::material::{MaterialError, MaterialKind, MaterialModel, MembraneModel};
use balloon::shell::{self, ShellMaterialModel};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// A `material` name: a 3D material on three-prism elements or a membrane model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaterialChoice {
    /// `stvk` or `neo-hookean` (three-prism elements with a thickness state).
    Solid(MaterialKind),
    /// `membrane-neo-hookean`, `membrane-mooney-rivlin`, `membrane-gent`, `membrane-ogden` or
    /// `membrane-yeoh` (incompressible membrane triangles, `h = H / (l1 l2)`).
    Membrane(MembraneKind),
}

/// Every accepted `material` name, for messages.
const MATERIAL_NAMES: &str = "stvk, neo-hookean, membrane-neo-hookean, membrane-mooney-rivlin, \
                              membrane-gent, membrane-ogden, membrane-yeoh";

impl FromStr for MaterialChoice {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let lower = s.trim().to_ascii_lowercase();
        let parsed = if lower.starts_with("membrane-") {
            lower.parse().map(Self::Membrane).ok()
        } else {
            lower.parse().map(Self::Solid).ok()
        };
        parsed.ok_or_else(|| format!("unknown material `{s}`: expected one of {MATERIAL_NAMES}"))
    }
}

impl fmt::Display for MaterialChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Solid(k) => k.fmt(f),
            Self::Membrane(k) => k.fmt(f),
        }
    }
}

/// The material keys of `[shell]`: the model, its parameters, or a preset.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MaterialSpec {
    /// Constitutive model [default: stvk].
    #[serde(with = "serde_text::option", skip_serializing_if = "Option::is_none")]
    pub material: Option<MaterialChoice>,
    /// A published membrane fit (`natural-rubber`, `elastosil-m4601`); sets every parameter.
    #[serde(with = "serde_text::option", skip_serializing_if = "Option::is_none")]
    pub material_preset: Option<MembranePreset>,
    /// Young's modulus E, Pa, of `stvk` / `neo-hookean` [default: 1e6].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub young: Option<f64>,
    /// Poisson's ratio of `stvk` / `neo-hookean` [default: 0.45].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub poisson: Option<f64>,
    /// Shear modulus mu, Pa, of `membrane-neo-hookean` and `membrane-gent`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mu: Option<f64>,
    /// Mooney-Rivlin c1, Pa.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub c1: Option<f64>,
    /// Mooney-Rivlin c2, Pa [default: 0].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub c2: Option<f64>,
    /// Gent's limit Jm of I1 - 3.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub jm: Option<f64>,
    /// Ogden moduli mu_p, Pa (one per `ogden_alpha`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ogden_mu: Option<Vec<f64>>,
    /// Ogden exponents alpha_p.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ogden_alpha: Option<Vec<f64>>,
    /// Yeoh constants `c1[, c2[, c3]]`, Pa.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub yeoh: Option<Vec<f64>>,
}

/// A list's values as given (`a,b,c`).
fn list(v: &[f64]) -> String {
    v.iter().map(f64::to_string).collect::<Vec<_>>().join(",")
}

impl MaterialSpec {
    /// The membrane parameters that were given, as `(name, value)`.
    fn membrane_params(&self) -> Vec<(&'static str, String)> {
        let mut out = Vec::new();
        let scalars = [
            ("mu", self.mu),
            ("c1", self.c1),
            ("c2", self.c2),
            ("jm", self.jm),
        ];
        for (name, v) in scalars {
            if let Some(v) = v {
                out.push((name, v.to_string()));
            }
        }
        let lists = [
            ("ogden_mu", &self.ogden_mu),
            ("ogden_alpha", &self.ogden_alpha),
            ("yeoh", &self.yeoh),
        ];
        for (name, v) in lists {
            if let Some(v) = v {
                out.push((name, list(v)));
            }
        }
        out
    }

    /// The model chosen: `material`, the preset's model, or StVK.
    pub fn choice(&self) -> MaterialChoice {
        match (self.material, self.material_preset) {
            (Some(m), _) => m,
            (None, Some(p)) => MaterialChoice::Membrane(p.model().kind()),
            (None, None) => MaterialChoice::Solid(MaterialKind::StVenantKirchhoff),
        }
    }

    /// Checks the keys together and builds the material. Errors name the parameter and its
    /// value: a membrane parameter with a 3D material, `young` / `poisson` with a membrane, a
    /// parameter that the chosen membrane model does not take, a missing required parameter, a
    /// preset that disagrees with `material` or comes with parameters, and every parameter out
    /// of range (Gent's `jm > 0`, Ogden's list lengths and positive initial shear modulus, ...).
    pub fn resolve(&self) -> Result<ShellMaterialModel, String> {
        let given = self.membrane_params();
        if let Some(preset) = self.material_preset {
            let model = preset.model();
            if let Some(MaterialChoice::Solid(kind)) = self.material {
                return Err(format!(
                    "`material_preset` = {preset} is a membrane ({}), but `material` is {kind}",
                    model.kind()
                ));
            }
            if let Some(MaterialChoice::Membrane(kind)) = self.material
                && kind != model.kind()
            {
                return Err(format!(
                    "`material_preset` = {preset} is a {} fit, but `material` is {kind}",
                    model.kind()
                ));
            }
            if let Some((name, value)) = given.first() {
                return Err(format!(
                    "`{name}` = {value} cannot be combined with `material_preset` = {preset}, which sets every parameter"
                ));
            }
            self.no_solid_params(model.kind())?;
            return Ok(model.into());
        }
        match self.choice() {
            MaterialChoice::Solid(kind) => {
                if let Some((name, value)) = given.first() {
                    return Err(format!(
                        "`{name}` = {value} is a membrane parameter, but `material` is {kind}; \
                         use a membrane-* material or drop `{name}`"
                    ));
                }
                let young = self.young.unwrap_or(shell::DEFAULT_YOUNG);
                let poisson = self.poisson.unwrap_or(shell::DEFAULT_POISSON);
                let model =
                    MaterialModel::from_young_poisson(kind, young, poisson).map_err(|e| {
                        format!("invalid `young` = {young} / `poisson` = {poisson}: {e}")
                    })?;
                Ok(model.into())
            }
            MaterialChoice::Membrane(kind) => {
                self.no_solid_params(kind)?;
                Ok(self.membrane(kind)?.into())
            }
        }
    }

    /// `young` / `poisson` belong to the three-prism materials only.
    fn no_solid_params(&self, kind: MembraneKind) -> Result<(), String> {
        for (name, v) in [("young", self.young), ("poisson", self.poisson)] {
            if let Some(v) = v {
                return Err(format!(
                    "`{name}` = {v} applies to stvk and neo-hookean, not to the membrane {kind}; \
                     give its own parameters"
                ));
            }
        }
        Ok(())
    }

    /// The membrane model `kind` from its parameters; any other membrane parameter is an error.
    fn membrane(&self, kind: MembraneKind) -> Result<MembraneModel, String> {
        let takes: &[&str] = match kind {
            MembraneKind::NeoHookean => &["mu"],
            MembraneKind::MooneyRivlin => &["c1", "c2"],
            MembraneKind::Gent => &["mu", "jm"],
            MembraneKind::Ogden => &["ogden_mu", "ogden_alpha"],
            MembraneKind::Yeoh => &["yeoh"],
        };
        if let Some((name, value)) = self
            .membrane_params()
            .into_iter()
            .find(|(n, _)| !takes.contains(n))
        {
            let takes: Vec<String> = takes.iter().map(|t| format!("`{t}`")).collect();
            return Err(format!(
                "`{name}` = {value} is not a parameter of {kind}, which takes {}",
                takes.join(" and ")
            ));
        }
        let need = |name: &str, v: Option<f64>, what: &str| -> Result<f64, String> {
            v.ok_or_else(|| format!("{kind} needs `{name}` ({what})"))
        };
        let checked = |r: Result<MembraneModel, MaterialError>| {
            r.map_err(|e| format!("invalid {} for {kind}: {e}", self.param_of(kind, &e)))
        };
        match kind {
            MembraneKind::NeoHookean => {
                let mu = need("mu", self.mu, "shear modulus, Pa")?;
                checked(MembraneNeoHookean::try_new(mu).map(Into::into))
            }
            MembraneKind::MooneyRivlin => {
                let c1 = need("c1", self.c1, "Pa, > 0")?;
                let c2 = self.c2.unwrap_or(0.0);
                checked(MembraneMooneyRivlin::try_new(c1, c2).map(Into::into))
            }
            MembraneKind::Gent => {
                let mu = need("mu", self.mu, "shear modulus, Pa")?;
                let jm = need("jm", self.jm, "limit of I1 - 3, > 0")?;
                checked(MembraneGent::try_new(mu, jm).map(Into::into))
            }
            MembraneKind::Ogden => {
                let (Some(mu), Some(alpha)) = (&self.ogden_mu, &self.ogden_alpha) else {
                    return Err(format!(
                        "{kind} needs `ogden_mu` and `ogden_alpha` (lists, one alpha per mu)"
                    ));
                };
                checked(MembraneOgden::try_new(mu.clone(), alpha.clone()).map(Into::into))
            }
            MembraneKind::Yeoh => {
                let Some(c) = &self.yeoh else {
                    return Err(format!("{kind} needs `yeoh` = c1[,c2[,c3]] (Pa)"));
                };
                if c.is_empty() || c.len() > 3 {
                    return Err(format!(
                        "invalid `yeoh` = {}: give 1 to 3 constants c1[,c2[,c3]], got {}",
                        list(c),
                        c.len()
                    ));
                }
                let at = |i: usize| c.get(i).copied().unwrap_or(0.0);
                checked(MembraneYeoh::try_new(at(0), at(1), at(2)).map(Into::into))
            }
        }
    }

    /// The parameter (and its value as given) that a model constructor's error is about.
    fn param_of(&self, kind: MembraneKind, e: &MaterialError) -> String {
        let listed = |v: &Option<Vec<f64>>| v.as_deref().map(list).unwrap_or_default();
        let both = || {
            format!(
                "`ogden_mu` = {} / `ogden_alpha` = {}",
                listed(&self.ogden_mu),
                listed(&self.ogden_alpha)
            )
        };
        match e {
            MaterialError::InvalidParameter { name, value, .. } => match (kind, *name) {
                (MembraneKind::Yeoh, _) => {
                    format!("`yeoh` = {} ({name} = {value})", listed(&self.yeoh))
                }
                (MembraneKind::Ogden, "ogden_mu") => {
                    format!("`ogden_mu` = {}", listed(&self.ogden_mu))
                }
                (MembraneKind::Ogden, "ogden_alpha") => {
                    format!("`ogden_alpha` = {}", listed(&self.ogden_alpha))
                }
                (MembraneKind::Ogden, _) => both(),
                (_, name) => {
                    // Plain unless tiny or huge (no three hundred zeros for 1e-300).
                    let a = value.abs();
                    if a != 0.0 && a.is_finite() && !(1e-4..1e16).contains(&a) {
                        format!("`{name}` = {value:e}")
                    } else {
                        format!("`{name}` = {value}")
                    }
                }
            },
            _ => both(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn membrane(kind: &str) -> MaterialSpec {
        MaterialSpec {
            material: Some(kind.parse().unwrap()),
            ..Default::default()
        }
    }

    #[test]
    fn names_parse_and_display() {
        for name in [
            "stvk",
            "neo-hookean",
            "membrane-neo-hookean",
            "membrane-mooney-rivlin",
            "membrane-gent",
            "membrane-ogden",
            "membrane-yeoh",
        ] {
            let c: MaterialChoice = name.parse().unwrap();
            assert_eq!(c.to_string().parse::<MaterialChoice>().unwrap(), c);
        }
        assert_eq!(
            "neo-hookean".parse::<MaterialChoice>().unwrap(),
            MaterialChoice::Solid(MaterialKind::NeoHookean)
        );
        let e = "rubber".parse::<MaterialChoice>().unwrap_err();
        assert!(e.contains("rubber") && e.contains("membrane-gent"), "{e}");
    }

    #[test]
    fn every_model_resolves_from_its_flags() {
        let mut a = membrane("membrane-neo-hookean");
        a.mu = Some(4e5);
        assert!(
            matches!(a.resolve().unwrap(), ShellMaterialModel::Membrane(MembraneModel::NeoHookean(m)) if m.mu() == 4e5)
        );
        let mut a = membrane("membrane-mooney-rivlin");
        a.c1 = Some(1.8e5);
        assert!(matches!(
            a.resolve().unwrap(),
            ShellMaterialModel::Membrane(MembraneModel::MooneyRivlin(m)) if m.c2() == 0.0
        ));
        let mut a = membrane("membrane-gent");
        (a.mu, a.jm) = (Some(4e5), Some(40.0));
        assert!(
            matches!(a.resolve().unwrap(), ShellMaterialModel::Membrane(MembraneModel::Gent(m)) if m.jm() == 40.0)
        );
        let mut a = membrane("membrane-ogden");
        (a.ogden_mu, a.ogden_alpha) = (Some(vec![6.3e5, -1e4]), Some(vec![1.3, -2.0]));
        assert!(
            matches!(a.resolve().unwrap(), ShellMaterialModel::Membrane(MembraneModel::Ogden(m)) if m.alpha() == [1.3, -2.0])
        );
        let mut a = membrane("membrane-yeoh");
        a.yeoh = Some(vec![1.1e5, 2e4]);
        assert!(matches!(
            a.resolve().unwrap(),
            ShellMaterialModel::Membrane(MembraneModel::Yeoh(m)) if m.coefficients() == [1.1e5, 2e4, 0.0]
        ));
        let a = MaterialSpec {
            material_preset: Some(MembranePreset::NaturalRubber),
            ..Default::default()
        };
        assert_eq!(
            a.resolve().unwrap(),
            ShellMaterialModel::Membrane(MembranePreset::NaturalRubber.model())
        );
        assert_eq!(a.choice().to_string(), "membrane-ogden");
        // The default stays the paper's StVK with E = 1 MPa, nu = 0.45.
        let d = MaterialSpec::default().resolve().unwrap();
        assert_eq!(
            d,
            ShellMaterialModel::Solid(
                MaterialModel::from_young_poisson(MaterialKind::StVenantKirchhoff, 1e6, 0.45)
                    .unwrap()
            )
        );
    }
}
