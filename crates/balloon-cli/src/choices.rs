//! The named choices of the flags as clap value enums (their `--help` lists each value with its
//! description), each the command-line spelling of a `balloon_scenario` type.

use balloon_scenario::gas::GasControl;
use balloon_scenario::output::{ColorField as Color, FrameFormat as Format};
use balloon_scenario::shell::ProjectionMode as Projection;
use balloon_scenario::two_layer::SphereChoice;
use balloon_scenario::volumetric::{
    Correction as ScenarioCorrection, SceneChoice, Up, VolumeSolver as ScenarioSolver,
};

/// Defines `From<$cli> for $lib` variant by variant.
macro_rules! same {
    ($cli:ty => $lib:ty: $($v:ident),+) => {
        impl From<$cli> for $lib {
            fn from(c: $cli) -> Self {
                match c {
                    $(<$cli>::$v => <$lib>::$v,)+
                }
            }
        }
    };
}

/// How the gas is held (`--gas`): the gas laws, or a given volume (static only).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum GasArg {
    /// Ambient air added at --pump-rate from the rest shape (the amount at the current time
    /// for --static).
    Pump,
    /// Isothermal ideal gas, a fixed amount (Eq. 12-14).
    Ideal,
    /// A fixed pressure.
    Constant,
    /// Polytropic (adiabatic) gas, `p V^gamma` constant (--gamma, default 1.4), starting at
    /// --pressure.
    Polytropic,
    /// Ideal gas at --pressure leaking to ambient through --leak-conductance.
    Leak,
    /// A pump at --pump-rate that stops at --supply-pressure.
    SupplyPump,
    /// A given enclosed volume (--static only; --volume-ratio or --volume-ratios): the pressure
    /// is its Lagrange multiplier.
    Volume,
}
same!(GasArg => GasControl: Pump, Ideal, Constant, Polytropic, Leak, SupplyPump, Volume);

/// Volume projection mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ProjectionMode {
    /// The global shell-volume projection of Wang et al. 2015 (Eq. 24-28, Algorithm 2).
    Global,
    /// Every element keeps its own material volume (thickness H A0 / A per element).
    PerElement,
    /// No projection: the thickness stays at its rest value (a membrane's still follows its
    /// stretch).
    Off,
}
same!(ProjectionMode => Projection: Global, PerElement, Off);

/// File format of surface frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum FrameFormat {
    /// Wavefront OBJ.
    #[default]
    Obj,
    /// Binary little-endian PLY.
    Ply,
    /// VTK XML PolyData `.vtp` with the fields (velocity, thickness, stretch, ...) and a
    /// `series.pvd` time series for ParaView.
    Vtk,
    /// One USD stage `run.usda` for the whole run (Blender, Houdini, usdview): a mesh per body,
    /// time-sampled points, the fields as primvars.
    Usd,
}
same!(FrameFormat => Format: Obj, Ply, Vtk, Usd);

/// The field that colours renders, the GIF and the POV scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ColorField {
    /// Shell thickness per face (inflate only), shown in mm.
    Thickness,
    /// Mean in-plane stretch sqrt(A/A0) per face, against the rest (or initial) shape.
    Stretch,
    /// Vertex speed |v|, m/s.
    Speed,
    /// Plain shaded surface, no legend.
    None,
}
same!(ColorField => Color: Thickness, Stretch, Speed, None);

/// Scene choice.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SceneArg {
    /// The body alone (falls freely under gravity).
    Free,
    /// Fig. 4: a rigid sphere falls on the body resting on a floor plane.
    DropSphere,
    /// The body on a floor plane (--floor-height, perpendicular to --up), no sphere: the live
    /// viewer's built-in volumetric set-up.
    Floor,
}
same!(SceneArg => SceneChoice: Free, DropSphere, Floor);

/// The volumetric scene's up axis (`--up`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum UpArg {
    /// +y up.
    Y,
    /// +z up.
    Z,
}
same!(UpArg => Up: Y, Z);

/// Cell-volume correction (`--correction`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Correction {
    /// Scale the cell about its centre (Diziol, Bender and Bayer 2011, Sec. 4).
    Scaling,
    /// Move along the mass-weighted volume gradient.
    Gradient,
}
same!(Correction => ScenarioCorrection: Scaling, Gradient);

/// How the cell constraints are solved (`--volume-solver`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum VolumeSolver {
    /// The paper's Gauss-Seidel sweeps, one cell at a time.
    GaussSeidel,
    /// Newton iterations on all cells at once (sparse Cholesky); gradient correction.
    Global,
}
same!(VolumeSolver => ScenarioSolver: GaussSeidel, Global);

/// Sphere construction in 3D.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SphereArg {
    /// Subdivided octahedron (`--level`), Song 2009, Sec. 3.5.2.
    Octa,
    /// UV sphere (`--slices`, `--stacks`), Song 2009, Sec. 3.5.1.
    Uv,
}
same!(SphereArg => SphereChoice: Octa, Uv);

/// A whole number that fits `T` (`--dim`, `--level`); its range is the scenario's.
pub fn whole<T: TryFrom<usize>>(s: &str) -> Result<T, String> {
    let n = balloon_scenario::range::parse_whole(s)?;
    T::try_from(n).map_err(|_| balloon_scenario::range::NOT_A_WHOLE_NUMBER.to_owned())
}
