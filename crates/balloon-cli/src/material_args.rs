//! The material flags of `balloon inflate`: `--material` (a 3D material on three-prism elements,
//! or an incompressible rubber membrane), its parameters and the membrane presets
//! (`docs/membranes.md`); checked together by `balloon_scenario::material::MaterialSpec`.

use balloon::material::membrane::MembranePreset;
use balloon_scenario::material::{MaterialChoice, MaterialSpec};
use balloon_scenario::range::parse_real;

/// The material flags of `balloon inflate`.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct MaterialArgs {
    /// Constitutive model [default: stvk]. On three-prism elements (Wang et al. 2015): `stvk`
    /// (St. Venant-Kirchhoff, the paper's) or `neo-hookean`, with --young and --poisson.
    /// Incompressible rubber membranes (thickness H / (l1 l2), a pressure maximum like a real
    /// balloon; docs/membranes.md): `membrane-neo-hookean` (--mu), `membrane-mooney-rivlin`
    /// (--c1, --c2), `membrane-gent` (--mu, --jm), `membrane-ogden` (--ogden-mu, --ogden-alpha)
    /// or `membrane-yeoh` (--yeoh), or a --material-preset.
    #[arg(long)]
    pub material: Option<MaterialChoice>,
    /// Young's modulus E, Pa, of `stvk` / `neo-hookean` (latex: about 1 MPa) [default: 1e6];
    /// > 0 and at most 1e12 (stiffer than diamond).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_real)]
    pub young: Option<f64>,
    /// Poisson's ratio nu of `stvk` / `neo-hookean`, -1 < nu < 0.5 [default: 0.45].
    #[arg(long, allow_hyphen_values = true, value_parser = parse_real)]
    pub poisson: Option<f64>,
    /// Shear modulus mu, Pa, of `membrane-neo-hookean` and `membrane-gent` (> 0; latex about
    /// 0.4 MPa), at most 1e12.
    #[arg(long, allow_hyphen_values = true, value_parser = parse_real)]
    pub mu: Option<f64>,
    /// Mooney-Rivlin c1, Pa (> 0, at most 1e12): W = c1 (I1 - 3) + c2 (I2 - 3).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_real)]
    pub c1: Option<f64>,
    /// Mooney-Rivlin c2, Pa (>= 0, at most 1e12) [default: 0].
    #[arg(long, allow_hyphen_values = true, value_parser = parse_real)]
    pub c2: Option<f64>,
    /// Gent's limit Jm of I1 - 3, in [1e-6, 1e6] (rubber about 30-100).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_real)]
    pub jm: Option<f64>,
    /// Ogden moduli mu_p, Pa, comma-separated (one per --ogden-alpha; sum mu_p alpha_p / 2 > 0;
    /// each in [-1e12, 1e12]).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1, value_parser = parse_real)]
    pub ogden_mu: Option<Vec<f64>>,
    /// Ogden exponents alpha_p, comma-separated (non-zero, in [-100, 100], one per --ogden-mu).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1,
          value_parser = parse_real)]
    pub ogden_alpha: Option<Vec<f64>>,
    /// Yeoh constants `c1[,c2[,c3]]`, Pa (c1 > 0; missing ones are 0):
    /// W = c1 (I1 - 3) + c2 (I1 - 3)^2 + c3 (I1 - 3)^3; each in [-1e12, 1e12].
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, num_args = 1, value_parser = parse_real)]
    pub yeoh: Option<Vec<f64>>,
    /// A published membrane fit (sources in docs/membranes.md): `natural-rubber` (Ogden, Treloar's
    /// data, Ogden 1972) or `elastosil-m4601` (Yeoh, Polygerinos et al. 2015). Implies its
    /// membrane model; sets every parameter, so no parameter flag may be given with it.
    #[arg(long)]
    pub material_preset: Option<MembranePreset>,
}

impl MaterialArgs {
    /// The material keys of the scenario.
    pub fn spec(&self) -> MaterialSpec {
        MaterialSpec {
            material: self.material,
            material_preset: self.material_preset,
            young: self.young,
            poisson: self.poisson,
            mu: self.mu,
            c1: self.c1,
            c2: self.c2,
            jm: self.jm,
            ogden_mu: self.ogden_mu.clone(),
            ogden_alpha: self.ogden_alpha.clone(),
            yeoh: self.yeoh.clone(),
        }
    }
}
