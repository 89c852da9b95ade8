//! The material flags of `balloon inflate`: `--material` (a 3D material on three-prism elements,
//! or an incompressible rubber membrane), its parameters and the membrane presets, checked
//! together before any work (`docs/membranes.md`).

use crate::params::{End::Closed, real};
use anyhow::{Result, bail};
use balloon::material::membrane::{
    MembraneGent, MembraneKind, MembraneMooneyRivlin, MembraneNeoHookean, MembraneOgden,
    MembranePreset, MembraneYeoh,
};
use balloon::material::{MaterialError, MaterialKind, MaterialModel, MembraneModel};
use balloon::shell::{self, ShellMaterialModel};
use std::fmt;
use std::str::FromStr;

/// A `--material` name: a 3D material on three-prism elements (seed 000) or a membrane model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaterialChoice {
    /// `stvk` or `neo-hookean` (three-prism elements with a thickness state).
    Solid(MaterialKind),
    /// `membrane-neo-hookean`, `membrane-mooney-rivlin`, `membrane-gent`, `membrane-ogden` or
    /// `membrane-yeoh` (incompressible membrane triangles, `h = H / (l1 l2)`).
    Membrane(MembraneKind),
}

/// Every accepted `--material` name, for messages.
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

/// The material flags of `balloon inflate`.
#[derive(Debug, Default, clap::Args)]
pub struct MaterialArgs {
    /// Constitutive model [default: stvk]. On three-prism elements (seed 000): `stvk`
    /// (St. Venant-Kirchhoff, the paper's) or `neo-hookean`, with --young and --poisson.
    /// Incompressible rubber membranes (thickness H / (l1 l2), a pressure maximum like a real
    /// balloon; docs/membranes.md): `membrane-neo-hookean` (--mu), `membrane-mooney-rivlin`
    /// (--c1, --c2), `membrane-gent` (--mu, --jm), `membrane-ogden` (--ogden-mu, --ogden-alpha)
    /// or `membrane-yeoh` (--yeoh), or a --material-preset.
    #[arg(long)]
    pub material: Option<MaterialChoice>,
    /// Young's modulus E, Pa, of `stvk` / `neo-hookean` (latex: about 1 MPa) [default: 1e6];
    /// > 0 and at most 1e12 (stiffer than diamond).
    #[arg(long, allow_hyphen_values = true, value_parser = real(Closed(-1e12), Closed(1e12)))]
    pub young: Option<f64>,
    /// Poisson's ratio nu of `stvk` / `neo-hookean`, -1 < nu < 0.5 [default: 0.45].
    #[arg(long, allow_hyphen_values = true, value_parser = real(Closed(-1e3), Closed(1e3)))]
    pub poisson: Option<f64>,
    /// Shear modulus mu, Pa, of `membrane-neo-hookean` and `membrane-gent` (> 0; latex about
    /// 0.4 MPa), at most 1e12.
    #[arg(long, allow_hyphen_values = true, value_parser = real(Closed(-1e12), Closed(1e12)))]
    pub mu: Option<f64>,
    /// Mooney-Rivlin c1, Pa (> 0, at most 1e12): W = c1 (I1 - 3) + c2 (I2 - 3).
    #[arg(long, allow_hyphen_values = true, value_parser = real(Closed(-1e12), Closed(1e12)))]
    pub c1: Option<f64>,
    /// Mooney-Rivlin c2, Pa (>= 0, at most 1e12) [default: 0].
    #[arg(long, allow_hyphen_values = true, value_parser = real(Closed(-1e12), Closed(1e12)))]
    pub c2: Option<f64>,
    /// Gent's limit Jm of I1 - 3 (> 0, at most 1e6; rubber about 30-100).
    #[arg(long, allow_hyphen_values = true, value_parser = real(Closed(-1e6), Closed(1e6)))]
    pub jm: Option<f64>,
    /// Ogden moduli mu_p, Pa, comma-separated (one per --ogden-alpha; sum mu_p alpha_p / 2 > 0;
    /// each in [-1e12, 1e12]).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1, value_parser = real(Closed(-1e12), Closed(1e12)))]
    pub ogden_mu: Option<Vec<f64>>,
    /// Ogden exponents alpha_p, comma-separated (non-zero, in [-100, 100], one per --ogden-mu).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1,
          value_parser = real(Closed(-100.0), Closed(100.0)))]
    pub ogden_alpha: Option<Vec<f64>>,
    /// Yeoh constants `c1[,c2[,c3]]`, Pa (c1 > 0; missing ones are 0):
    /// W = c1 (I1 - 3) + c2 (I1 - 3)^2 + c3 (I1 - 3)^3; each in [-1e12, 1e12].
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1, value_parser = real(Closed(-1e12), Closed(1e12)))]
    pub yeoh: Option<Vec<f64>>,
    /// A published membrane fit (sources in docs/membranes.md): `natural-rubber` (Ogden, Treloar's
    /// data, Ogden 1972) or `elastosil-m4601` (Yeoh, Polygerinos et al. 2015). Implies its
    /// membrane model; sets every parameter, so no parameter flag may be given with it.
    #[arg(long)]
    pub material_preset: Option<MembranePreset>,
}

/// Formats a list flag's values as given (`a,b,c`).
fn list(v: &[f64]) -> String {
    v.iter().map(f64::to_string).collect::<Vec<_>>().join(",")
}

impl MaterialArgs {
    /// The membrane parameter flags that were given, as `(flag, value)`.
    fn membrane_flags(&self) -> Vec<(&'static str, String)> {
        let mut out = Vec::new();
        let scalars = [
            ("--mu", self.mu),
            ("--c1", self.c1),
            ("--c2", self.c2),
            ("--jm", self.jm),
        ];
        for (flag, v) in scalars {
            if let Some(v) = v {
                out.push((flag, v.to_string()));
            }
        }
        let lists = [
            ("--ogden-mu", &self.ogden_mu),
            ("--ogden-alpha", &self.ogden_alpha),
            ("--yeoh", &self.yeoh),
        ];
        for (flag, v) in lists {
            if let Some(v) = v {
                out.push((flag, list(v)));
            }
        }
        out
    }

    /// The model name that the summary records (`st-venant-kirchhoff`, `membrane-gent`, ...).
    pub fn choice(&self) -> MaterialChoice {
        match (self.material, self.material_preset) {
            (Some(m), _) => m,
            (None, Some(p)) => MaterialChoice::Membrane(p.model().kind()),
            (None, None) => MaterialChoice::Solid(MaterialKind::StVenantKirchhoff),
        }
    }

    /// Checks the flags together and builds the material. Errors name the flag and its value:
    /// a membrane flag with a 3D material, `--young` / `--poisson` with a membrane, a flag that
    /// the chosen membrane model does not take, a missing required parameter, a preset that
    /// disagrees with `--material` or comes with parameter flags, and every parameter out of
    /// range (Gent's `jm > 0`, Ogden's list lengths and positive initial shear modulus, ...).
    pub fn resolve(&self) -> Result<ShellMaterialModel> {
        let given = self.membrane_flags();
        if let Some(preset) = self.material_preset {
            let model = preset.model();
            if let Some(MaterialChoice::Solid(kind)) = self.material {
                bail!(
                    "--material-preset {preset} is a membrane ({}), but --material is {kind}",
                    model.kind()
                );
            }
            if let Some(MaterialChoice::Membrane(kind)) = self.material
                && kind != model.kind()
            {
                bail!(
                    "--material-preset {preset} is a {} fit, but --material is {kind}",
                    model.kind()
                );
            }
            if let Some((flag, value)) = given.first() {
                bail!(
                    "{flag} {value} cannot be combined with --material-preset {preset}, which sets every parameter"
                );
            }
            self.no_solid_flags(model.kind())?;
            return Ok(model.into());
        }
        match self.choice() {
            MaterialChoice::Solid(kind) => {
                if let Some((flag, value)) = given.first() {
                    bail!(
                        "{flag} {value} is a membrane parameter, but --material is {kind}; use a \
                         membrane-* material (see --help) or drop {flag}"
                    );
                }
                let young = self.young.unwrap_or(shell::DEFAULT_YOUNG);
                let poisson = self.poisson.unwrap_or(shell::DEFAULT_POISSON);
                let model =
                    MaterialModel::from_young_poisson(kind, young, poisson).map_err(|e| {
                        anyhow::anyhow!("invalid --young {young} / --poisson {poisson}: {e}")
                    })?;
                Ok(model.into())
            }
            MaterialChoice::Membrane(kind) => {
                self.no_solid_flags(kind)?;
                Ok(self.membrane(kind)?.into())
            }
        }
    }

    /// `--young` / `--poisson` belong to the three-prism materials only.
    fn no_solid_flags(&self, kind: MembraneKind) -> Result<()> {
        for (flag, v) in [("--young", self.young), ("--poisson", self.poisson)] {
            if let Some(v) = v {
                bail!(
                    "{flag} {v} applies to stvk and neo-hookean, not to the membrane {kind}; give \
                     its own parameters (see --help)"
                );
            }
        }
        Ok(())
    }

    /// The membrane model `kind` from its flags; any other membrane flag is an error.
    fn membrane(&self, kind: MembraneKind) -> Result<MembraneModel> {
        let takes: &[&str] = match kind {
            MembraneKind::NeoHookean => &["--mu"],
            MembraneKind::MooneyRivlin => &["--c1", "--c2"],
            MembraneKind::Gent => &["--mu", "--jm"],
            MembraneKind::Ogden => &["--ogden-mu", "--ogden-alpha"],
            MembraneKind::Yeoh => &["--yeoh"],
        };
        if let Some((flag, value)) = self
            .membrane_flags()
            .into_iter()
            .find(|(f, _)| !takes.contains(f))
        {
            bail!(
                "{flag} {value} is not a parameter of {kind}, which takes {}",
                takes.join(" and ")
            );
        }
        let need = |flag: &str, v: Option<f64>, what: &str| -> Result<f64> {
            v.ok_or_else(|| anyhow::anyhow!("{kind} needs {flag} ({what})"))
        };
        let checked = |r: Result<MembraneModel, MaterialError>| {
            r.map_err(|e| anyhow::anyhow!("invalid {} for {kind}: {e}", self.flag_of(kind, &e)))
        };
        Ok(match kind {
            MembraneKind::NeoHookean => {
                let mu = need("--mu", self.mu, "shear modulus, Pa")?;
                checked(MembraneNeoHookean::try_new(mu).map(Into::into))?
            }
            MembraneKind::MooneyRivlin => {
                let c1 = need("--c1", self.c1, "Pa, > 0")?;
                let c2 = self.c2.unwrap_or(0.0);
                checked(MembraneMooneyRivlin::try_new(c1, c2).map(Into::into))?
            }
            MembraneKind::Gent => {
                let mu = need("--mu", self.mu, "shear modulus, Pa")?;
                let jm = need("--jm", self.jm, "limit of I1 - 3, > 0")?;
                checked(MembraneGent::try_new(mu, jm).map(Into::into))?
            }
            MembraneKind::Ogden => {
                let (Some(mu), Some(alpha)) = (&self.ogden_mu, &self.ogden_alpha) else {
                    bail!(
                        "{kind} needs --ogden-mu and --ogden-alpha (comma-separated, one alpha per mu)"
                    );
                };
                checked(MembraneOgden::try_new(mu.clone(), alpha.clone()).map(Into::into))?
            }
            MembraneKind::Yeoh => {
                let Some(c) = &self.yeoh else {
                    bail!("{kind} needs --yeoh c1[,c2[,c3]] (Pa)");
                };
                if c.is_empty() || c.len() > 3 {
                    bail!(
                        "invalid --yeoh {}: give 1 to 3 constants c1[,c2[,c3]], got {}",
                        list(c),
                        c.len()
                    );
                }
                let at = |i: usize| c.get(i).copied().unwrap_or(0.0);
                checked(MembraneYeoh::try_new(at(0), at(1), at(2)).map(Into::into))?
            }
        })
    }

    /// The flag (and its value as given) that a model constructor's error is about.
    fn flag_of(&self, kind: MembraneKind, e: &MaterialError) -> String {
        let listed = |v: &Option<Vec<f64>>| v.as_deref().map(list).unwrap_or_default();
        let both = || {
            format!(
                "--ogden-mu {} / --ogden-alpha {}",
                listed(&self.ogden_mu),
                listed(&self.ogden_alpha)
            )
        };
        match e {
            MaterialError::InvalidParameter { name, value, .. } => match (kind, *name) {
                (MembraneKind::Yeoh, _) => {
                    format!("--yeoh {} ({name} = {value})", listed(&self.yeoh))
                }
                (MembraneKind::Ogden, "ogden_mu") => {
                    format!("--ogden-mu {}", listed(&self.ogden_mu))
                }
                (MembraneKind::Ogden, "ogden_alpha") => {
                    format!("--ogden-alpha {}", listed(&self.ogden_alpha))
                }
                (MembraneKind::Ogden, _) => both(),
                (_, name) => format!("--{} {value}", name.replace('_', "-")),
            },
            _ => both(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn membrane(kind: &str) -> MaterialArgs {
        MaterialArgs {
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
        let a = MaterialArgs {
            material_preset: Some(MembranePreset::NaturalRubber),
            ..Default::default()
        };
        assert_eq!(
            a.resolve().unwrap(),
            ShellMaterialModel::Membrane(MembranePreset::NaturalRubber.model())
        );
        assert_eq!(a.choice().to_string(), "membrane-ogden");
        // The default stays the paper's StVK with E = 1 MPa, nu = 0.45.
        let d = MaterialArgs::default().resolve().unwrap();
        assert_eq!(
            d,
            ShellMaterialModel::Solid(
                MaterialModel::from_young_poisson(MaterialKind::StVenantKirchhoff, 1e6, 0.45)
                    .unwrap()
            )
        );
    }
}
