//! The volume-conserving impulse-based body's scenario (`balloon volumetric`, Diziol, Bender
//! and Bayer 2011): the triangle soup (`[mesh]`), the lattice generator (`[lattice]`), the
//! body's springs and masses (`[body]`), the scene, time step and cell-volume solver
//! (`[run]`), the outputs, anchors and loads; and [`VolumetricScenario::build`].
//!
//! ```
//! use balloon_scenario::volumetric::{SceneChoice, VolumetricScenario};
//! let mut s = VolumetricScenario::default();
//! s.mesh.path = "builtin:icosphere".into();
//! s.lattice.resolution = Some(10);
//! s.lattice.voxels_per_cell = 2;
//! s.run.scene = SceneChoice::Free;
//! s.validate().unwrap();
//! let built = s.build(None).unwrap();
//! assert!(built.sim.lattice().cells.len() > 50);
//! ```

use crate::error::ScenarioError;
use crate::keys::{
    Key, Kind, Recorded, anchor_keys, flag, output_keys, real, real_opt, whole, whole_opt,
};
use crate::keys::{PIN_STIFFNESS, SCALE, STEPS, mesh_path, mesh_transform};
use crate::mesh::MeshSpec;
use crate::output::{ColorField, Output, choices};
use crate::range::End::{Closed, Open};
use crate::range::{MAX_STEPS, Real, ValueError, Whole, real_text};
use crate::selection::apply::fix_volumetric;
use crate::selection::{Load, Pin, SelectionError};
use crate::value::{SetError, Value};
use balloon::constraint::cell_volume::{
    CellCentre, CellCorrection, CellVolumeParams, SpringParams,
};
use balloon::mesh::TriMesh;
use balloon::mesh::lattice::{
    DEFAULT_TARGET_CELLS, LatticeError, LatticeParams, SizingParams, size_lattice,
};
use balloon::volumetric::{
    MassModel, VolumetricBody, VolumetricError, VolumetricParams, VolumetricScene,
    VolumetricSimulation,
};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;
use std::time::Instant;

/// The scene (`scene`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SceneChoice {
    /// The body alone (falls freely under gravity).
    Free,
    /// Fig. 4 of the paper: a rigid sphere falls on the body resting on a floor plane.
    DropSphere,
    /// The body on a floor plane perpendicular to `up`, at `floor_height` (default: just under
    /// the body), no sphere: the live viewer's built-in volumetric set-up.
    Floor,
}

choices!(
    SceneChoice,
    "a scene",
    [
        (SceneChoice::Free, "free"),
        (SceneChoice::DropSphere, "drop-sphere"),
        (SceneChoice::Floor, "floor")
    ]
);

/// The up axis of a volumetric scene (`up`): gravity acts along it (`gravity` < 0 pulls
/// down), the floor is perpendicular to it, and pictures stand on it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Up {
    /// +y up (mesh files and the built-in meshes as modelled, the live viewer's body).
    Y,
    /// +z up (the drop-sphere scene of Diziol, Bender and Bayer 2011, Fig. 4).
    #[default]
    Z,
}

choices!(Up, "an up axis", [(Up::Y, "y"), (Up::Z, "z")]);

impl Up {
    /// The coordinate index of the axis (1 for y, 2 for z).
    pub fn index(self) -> usize {
        match self {
            Self::Y => 1,
            Self::Z => 2,
        }
    }

    /// The unit vector along the axis.
    pub fn vector(self) -> nalgebra::Vector3<f64> {
        let mut v = nalgebra::Vector3::zeros();
        v[self.index()] = 1.0;
        v
    }
}

/// Gap between the lowest particle and the default floor of the `floor` scene, relative to
/// the diagonal of the particles' bounding box: just under the body, so that it starts at
/// rest on the floor without touching it (a drop would invert coarse cells on impact).
pub const FLOOR_GAP: f64 = 1e-3;

/// The default floor height (m, along `up`) of the `floor` scene for the particles `x`:
/// [`FLOOR_GAP`] times their bounding-box diagonal below the lowest one.
pub fn default_floor_height(x: &[nalgebra::Point3<f64>], up: Up) -> f64 {
    let (mut lo, mut hi) = (
        nalgebra::Vector3::repeat(f64::INFINITY),
        nalgebra::Vector3::repeat(f64::NEG_INFINITY),
    );
    for p in x {
        lo = lo.inf(&p.coords);
        hi = hi.sup(&p.coords);
    }
    lo[up.index()] - FLOOR_GAP * (hi - lo).norm()
}

/// The floor plane of the `floor` scene: perpendicular to `up` at `height` (m), its normal
/// pointing up; `None` for a height that is not finite.
pub fn floor_plane(height: f64, up: Up) -> Option<balloon::constraint::rigid::Plane> {
    let mut point = nalgebra::Point3::origin();
    point[up.index()] = height;
    height
        .is_finite()
        .then(|| balloon::constraint::rigid::Plane::new(point, up.vector()))
        .flatten()
}

/// The cell-volume correction (`correction`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Correction {
    /// Scale the cell about its centre (the paper, Sec. 4).
    Scaling,
    /// Move along the mass-weighted volume gradient.
    Gradient,
}

choices!(
    Correction,
    "a correction",
    [
        (Correction::Scaling, "scaling"),
        (Correction::Gradient, "gradient")
    ]
);

/// How the cell constraints are solved (`volume_solver`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum VolumeSolver {
    /// The paper's Gauss-Seidel sweeps, one cell at a time.
    GaussSeidel,
    /// Newton iterations on all cells at once (sparse Cholesky); gradient correction.
    Global,
}

choices!(
    VolumeSolver,
    "a volume solver",
    [
        (VolumeSolver::GaussSeidel, "gauss-seidel"),
        (VolumeSolver::Global, "global")
    ]
);

/// Over-relaxation of the Gauss-Seidel volume sweeps (`over_relaxation`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Relaxation {
    /// Chosen from the measured convergence rate (`CellVolumeParams::adaptive_relaxation`).
    #[default]
    Adaptive,
    /// A fixed factor `omega` in (0, 2) (1 = the paper).
    Fixed(f64),
}

impl FromStr for Relaxation {
    type Err = String;
    /// `adaptive` or a number (its range is checked with the others).
    fn from_str(s: &str) -> Result<Self, String> {
        if s.trim() == "adaptive" {
            return Ok(Self::Adaptive);
        }
        crate::range::parse_real(s)
            .map(Self::Fixed)
            .map_err(|e| format!("{e}, or `adaptive`"))
    }
}

impl fmt::Display for Relaxation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Adaptive => f.write_str("adaptive"),
            Self::Fixed(omega) => write!(f, "{omega:?}"),
        }
    }
}

/// The `[lattice]` table: the soup -> lattice generator (the paper, Sec. 3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LatticeTable {
    /// Voxels along the longest side of the bounding box; `None`: sized for `cells`.
    pub resolution: Option<usize>,
    /// Size the lattice for about this many cells [default 1000 without `resolution`].
    pub cells: Option<usize>,
    /// Voxels along one side of a lattice cell.
    pub voxels_per_cell: usize,
    /// Ray directions in the inside/outside vote.
    pub rays: usize,
    /// Distance band in voxels.
    pub band_voxels: f64,
    /// P_in of the ray vote.
    pub p_in: f64,
    /// P_subs of the ray vote.
    pub p_subs: f64,
    /// Pseudo-density threshold for keeping a cell.
    pub density_threshold: f64,
    /// Hole-filling rounds.
    pub fill_iterations: usize,
    /// Axis-aligned Laplacian smoothing iterations.
    pub smoothing_iterations: usize,
    /// Weight of one smoothing iteration.
    pub smoothing_weight: f64,
}

impl Default for LatticeTable {
    fn default() -> Self {
        Self {
            resolution: None,
            cells: None,
            voxels_per_cell: 3,
            rays: 14,
            band_voxels: 4.0,
            p_in: 0.8,
            p_subs: 0.6,
            density_threshold: 0.5,
            fill_iterations: 2,
            smoothing_iterations: 2,
            smoothing_weight: 0.25,
        }
    }
}

/// The `[body]` table: springs, damping and masses.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BodyTable {
    /// Soft diagonal springs (a twentieth of the edge stiffness, half its damping).
    pub soft_diagonals: bool,
    /// Edge spring stiffness, N/m; `None`: from the particle mass and the time step.
    pub edge_stiffness: Option<f64>,
    /// Diagonal spring stiffness, N/m; `None`: the edge stiffness.
    pub diagonal_stiffness: Option<f64>,
    /// Edge spring damping, N s/m; `None`: from the particle mass and the time step.
    pub damping: Option<f64>,
    /// Diagonal spring damping, N s/m; `None`: the edge damping.
    pub diagonal_damping: Option<f64>,
    /// Mass density, kg/m^3.
    pub density: f64,
    /// Lumped masses and mass-weighted cell centres instead of equal masses.
    pub lumped_masses: bool,
    /// Stiffness of the anchors without their own, N/m; `None`: hard pins.
    pub pin_stiffness: Option<f64>,
}

impl Default for BodyTable {
    fn default() -> Self {
        Self {
            soft_diagonals: false,
            edge_stiffness: None,
            diagonal_stiffness: None,
            damping: None,
            diagonal_damping: None,
            density: 100.0,
            lumped_masses: false,
            pin_stiffness: None,
        }
    }
}

/// The `[run]` table of a volumetric body.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VolumetricRun {
    /// The scene.
    #[serde(with = "crate::serde_text")]
    pub scene: SceneChoice,
    /// Gravity along `up`, m/s^2 (negative: down).
    pub gravity: f64,
    /// The up axis.
    #[serde(with = "crate::serde_text")]
    pub up: Up,
    /// Height of the `floor` scene's floor along `up`, m; `None`: just under the body
    /// ([`default_floor_height`]).
    pub floor_height: Option<f64>,
    /// Contact restitution.
    pub restitution: f64,
    /// Time step, s; `None`: sized to the body (the sag under its weight).
    pub dt: Option<f64>,
    /// Number of steps.
    pub steps: usize,
    /// Relative cell-volume tolerance of the impulse iteration.
    pub tolerance: f64,
    /// Over-relaxation of the Gauss-Seidel sweeps.
    #[serde(with = "crate::serde_text")]
    pub over_relaxation: Relaxation,
    /// The volume correction.
    #[serde(with = "crate::serde_text")]
    pub correction: Correction,
    /// The cell-volume solver.
    #[serde(with = "crate::serde_text")]
    pub volume_solver: VolumeSolver,
}

impl Default for VolumetricRun {
    fn default() -> Self {
        Self {
            scene: SceneChoice::DropSphere,
            gravity: -9.81,
            up: Up::Z,
            floor_height: None,
            restitution: 0.2,
            dt: None,
            steps: 600,
            tolerance: 1e-10,
            over_relaxation: Relaxation::Adaptive,
            correction: Correction::Gradient,
            volume_solver: VolumeSolver::Global,
        }
    }
}

/// A volumetric body's scenario: the keys of a `kind = "volumetric"` scenario file, typed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VolumetricScenario {
    /// `[mesh]`: the triangle soup.
    pub mesh: MeshSpec,
    /// `[lattice]`.
    pub lattice: LatticeTable,
    /// `[body]`.
    pub body: BodyTable,
    /// `[run]`.
    pub run: VolumetricRun,
    /// `[output]`.
    pub output: Output,
    /// `[[anchors]]` (on the lattice particles, by their rest positions).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub anchors: Vec<Pin>,
    /// `[[loads]]`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub loads: Vec<Load>,
}

impl Default for VolumetricScenario {
    fn default() -> Self {
        Self {
            mesh: MeshSpec::default(),
            lattice: LatticeTable::default(),
            body: BodyTable::default(),
            run: VolumetricRun::default(),
            output: Output::every(20),
            anchors: Vec::new(),
            loads: Vec::new(),
        }
    }
}

/// Largest `resolution` (and `voxels_per_cell`): bounds the voxel grid (resolution^3 voxels
/// at most) before anything is built.
const MAX_RESOLUTION: usize = 200;

/// Every key of a volumetric scenario, in the order the recorded scenario writes them.
pub static VOLUMETRIC_KEYS: &[Key<VolumetricScenario>] = &{
    let [
        out,
        overwrite,
        json,
        format,
        frame_every,
        render,
        color,
        gif,
        pov,
        image_size,
        color_range,
    ] = output_keys!(VolumetricScenario, Whole::new(1, MAX_STEPS));
    let [anchors, loads] = anchor_keys!(VolumetricScenario);
    [
        mesh_path!(VolumetricScenario, mesh.path),
        real!("mesh", "scale", "scale", SCALE, mesh.scale),
        mesh_transform!(mesh.transform),
        whole_opt!(
            "lattice",
            "resolution",
            "resolution",
            Whole::new(4, MAX_RESOLUTION),
            lattice.resolution
        ),
        whole_opt!(
            "lattice",
            "cells",
            "cells",
            Whole::new(1, 100_000),
            lattice.cells
        ),
        whole!(
            "lattice",
            "voxels_per_cell",
            "voxels_per_cell",
            Whole::new(1, MAX_RESOLUTION),
            lattice.voxels_per_cell
        ),
        whole!("lattice", "rays", "rays", Whole::new(1, 26), lattice.rays),
        real!(
            "lattice",
            "band_voxels",
            "band_voxels",
            Real::new(Closed(1.5), Closed(64.0)),
            lattice.band_voxels
        ),
        real!(
            "lattice",
            "p_in",
            "p_in",
            Real::new(Open(0.0), Open(1.0)),
            lattice.p_in
        ),
        real!(
            "lattice",
            "p_subs",
            "p_subs",
            Real::new(Open(0.0), Open(1.0)),
            lattice.p_subs
        ),
        real!(
            "lattice",
            "density_threshold",
            "density_threshold",
            Real::new(Closed(0.0), Open(1.0)),
            lattice.density_threshold
        ),
        whole!(
            "lattice",
            "fill_iterations",
            "fill_iterations",
            Whole::new(0, 1000),
            lattice.fill_iterations
        ),
        whole!(
            "lattice",
            "smoothing_iterations",
            "smoothing_iterations",
            Whole::new(0, 1000),
            lattice.smoothing_iterations
        ),
        real!(
            "lattice",
            "smoothing_weight",
            "smoothing_weight",
            Real::new(Open(0.0), Closed(0.5)),
            lattice.smoothing_weight
        ),
        flag!(
            "body",
            "soft_diagonals",
            "soft_diagonals",
            body.soft_diagonals
        ),
        real_opt!(
            "body",
            "edge_stiffness",
            "edge_stiffness",
            Real::new(Open(0.0), Closed(1e12)),
            body.edge_stiffness
        ),
        real_opt!(
            "body",
            "diagonal_stiffness",
            "diagonal_stiffness",
            Real::new(Closed(0.0), Closed(1e12)),
            body.diagonal_stiffness
        ),
        real_opt!(
            "body",
            "damping",
            "damping",
            Real::new(Closed(0.0), Closed(1e9)),
            body.damping
        ),
        real_opt!(
            "body",
            "diagonal_damping",
            "diagonal_damping",
            Real::new(Closed(0.0), Closed(1e9)),
            body.diagonal_damping
        ),
        real!(
            "body",
            "density",
            "density",
            Real::new(Open(0.0), Closed(1e5)),
            body.density
        ),
        flag!("body", "lumped_masses", "lumped_masses", body.lumped_masses),
        real_opt!(
            "body",
            "pin_stiffness",
            "pin_stiffness",
            PIN_STIFFNESS,
            body.pin_stiffness
        ),
        crate::keys::choice!("run", "scene", "scene", false, run.scene),
        real!(
            "run",
            "gravity",
            "gravity",
            Real::new(Closed(-1e3), Closed(1e3)),
            run.gravity
        ),
        crate::keys::choice!("run", "up", "up", false, run.up),
        real_opt!(
            "run",
            "floor_height",
            "floor_height",
            Real::new(Closed(-1e6), Closed(1e6)),
            run.floor_height
        ),
        real!(
            "run",
            "restitution",
            "restitution",
            Real::new(Closed(0.0), Closed(1.0)),
            run.restitution
        ),
        real_opt!("run", "dt", "dt", Real::new(Open(0.0), Closed(0.1)), run.dt),
        whole!("run", "steps", "steps", STEPS, run.steps),
        real!(
            "run",
            "tolerance",
            "tolerance",
            Real::new(Open(0.0), Closed(0.1)),
            run.tolerance
        ),
        Key {
            table: "run",
            key: "over_relaxation",
            name: "over_relaxation",
            kind: Kind::NumberOrText,
            recorded: true,
            set: |s, v| {
                s.run.over_relaxation = match v {
                    Value::Text(t) => crate::value::parse_choice("over_relaxation", t, true)?,
                    Value::Int(_) | Value::Float(_) => Relaxation::Fixed(v.real()?),
                    _ => return Err(SetError::Type(v.expected("a number or a string"))),
                };
                Ok(())
            },
            check: |s| match s.run.over_relaxation {
                Relaxation::Fixed(w) if !OMEGA.contains(w) => Err(ValueError::new(
                    "over_relaxation",
                    real_text(w),
                    Some(format!("{}, or `adaptive`", OMEGA.reason())),
                )),
                _ => Ok(()),
            },
            get: |s| Recorded::one(s.run.over_relaxation),
            copy: |d, s| d.run.over_relaxation = s.run.over_relaxation,
        },
        crate::keys::choice!("run", "correction", "correction", false, run.correction),
        crate::keys::choice!(
            "run",
            "volume_solver",
            "volume_solver",
            false,
            run.volume_solver
        ),
        out,
        overwrite,
        json,
        format,
        frame_every,
        flag!(
            "output",
            "lattice_frames",
            "lattice_frames",
            output.lattice_frames
        ),
        render,
        color,
        gif,
        pov,
        image_size,
        color_range,
        anchors,
        loads,
    ]
};

/// The range of a fixed over-relaxation factor: (0, 2).
const OMEGA: Real = Real::new(Open(0.0), Open(2.0));

/// The colours a volumetric run can draw.
pub const VOLUMETRIC_COLORS: &[ColorField] = &[ColorField::Stretch, ColorField::Speed];

/// Largest default time step (s).
const MAX_DT: f64 = 5e-4;
/// Default edge stiffness relative to `m / dt^2` (the library's, shared with the viewer).
const EDGE_STIFFNESS: f64 = balloon::volumetric::DEFAULT_SPRING_STIFFNESS;
/// Sag under the body's weight that the default time step allows. With 0.02 (and stiffness
/// 1/50, the same time step) the drop-sphere impact strained springs by 40-95 % and inverted
/// cells of the bunny, spot and armadillo within 2000 steps; 0.004 is five times stiffer.
const SAG_STRAIN: f64 = 0.004;

/// Why a volumetric scenario could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum VolumetricBuildError {
    /// The keys do not make a run (the message names them).
    #[error("{0}")]
    Invalid(String),
    /// The mesh cannot be loaded.
    #[error("cannot load {path}")]
    Mesh {
        /// The mesh's path or built-in name.
        path: String,
        /// Why.
        #[source]
        source: balloon::mesh::MeshError,
    },
    /// The lattice or the body cannot be built.
    #[error("{context}")]
    Body {
        /// What was being built (and, for a resolution with no cell, one that works).
        context: String,
        /// Why.
        #[source]
        source: VolumetricError,
    },
    /// A body whose lattice has no cell at the resolution asked for.
    #[error("cannot build the volumetric body")]
    NoInterior {
        /// The resolution that would work.
        #[source]
        hint: NoInteriorHint,
    },
    /// The springs are refused.
    #[error("invalid spring parameters")]
    Springs(#[source] VolumetricError),
    /// The scene cannot be set up.
    #[error(transparent)]
    Scene(VolumetricError),
    /// An anchor cannot be used.
    #[error(transparent)]
    Selection(#[from] SelectionError),
}

/// A resolution that leaves no cell, with the one the sizing would choose.
#[derive(Debug, thiserror::Error)]
#[error("{hint}")]
pub struct NoInteriorHint {
    hint: String,
    #[source]
    source: LatticeError,
}

/// What [`VolumetricScenario::build`] makes: the simulation and what a summary reports about
/// its making.
pub struct VolumetricBuild {
    /// The simulation in its scene, at rest, with its hard anchors.
    pub sim: VolumetricSimulation,
    /// The triangle soup as read, scaled and moved.
    pub soup: TriMesh,
    /// Lattice generation time (ms).
    pub lattice_ms: f64,
    /// Edge and diagonal spring stiffness used (N/m).
    pub stiffness: [f64; 2],
}

impl VolumetricScenario {
    /// Checks every value against its range and the keys together, before anything is read.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        crate::keys::check_all(VOLUMETRIC_KEYS, self)?;
        self.mesh
            .check_transform()
            .and_then(|()| {
                self.output
                    .check_pictures("volumetric", VOLUMETRIC_COLORS)
                    .map(drop)
            })
            .and_then(|()| match (self.lattice.resolution, self.lattice.cells) {
                (Some(_), Some(_)) => {
                    Err("give `resolution` or `cells`, not both (`cells` sizes the lattice)".into())
                }
                _ => Ok(()),
            })
            .and_then(|()| self.check_scene())
            .map_err(ScenarioError::Invalid)
    }

    /// `floor_height` only with the `floor` scene; the drop-sphere scene stands on z.
    fn check_scene(&self) -> Result<(), String> {
        let r = &self.run;
        if r.floor_height.is_some() && r.scene != SceneChoice::Floor {
            return Err(format!(
                "`floor_height` is the height of the `floor` scene's floor; `scene` is \"{}\" \
                 (set `scene` = \"floor\" or leave `floor_height` out)",
                r.scene
            ));
        }
        if r.scene == SceneChoice::DropSphere && r.up != Up::Z {
            return Err(format!(
                "`scene` = \"drop-sphere\" drops its sphere along -z and needs `up` = \"z\", \
                 not \"{}\"",
                r.up
            ));
        }
        Ok(())
    }

    /// The cell-volume solver settings: [`CellVolumeParams::gauss_seidel`] or
    /// [`CellVolumeParams::global`] changed by the keys given.
    pub fn volume_params(&self) -> CellVolumeParams {
        let r = &self.run;
        let base = match r.volume_solver {
            VolumeSolver::GaussSeidel => CellVolumeParams::gauss_seidel(),
            VolumeSolver::Global => CellVolumeParams::global(),
        };
        let (over_relaxation, adaptive_relaxation) = match r.over_relaxation {
            // The global solver has no sweeps to relax.
            Relaxation::Adaptive => (1.0, r.volume_solver == VolumeSolver::GaussSeidel),
            Relaxation::Fixed(omega) => (omega, false),
        };
        CellVolumeParams {
            tolerance: r.tolerance,
            over_relaxation,
            adaptive_relaxation,
            centre: if self.body.lumped_masses {
                CellCentre::MassWeighted
            } else {
                CellCentre::Arithmetic
            },
            correction: match r.correction {
                Correction::Scaling => CellCorrection::Scaling,
                Correction::Gradient => CellCorrection::Gradient,
            },
            ..base
        }
    }

    /// The body's parameters before the lattice is built (the time step is settled after):
    /// the lattice generator's settings (the resolution as given, else the library's default),
    /// the cell-volume solver's, density, masses, gravity along `up`, `dt` (the largest allowed
    /// when unset) and restitution. A front end that builds its own scene (the viewer) starts
    /// from these and changes what it must.
    pub fn params(&self) -> VolumetricParams {
        let l = &self.lattice;
        VolumetricParams {
            lattice: LatticeParams {
                resolution: l.resolution.unwrap_or(LatticeParams::default().resolution),
                voxels_per_cell: l.voxels_per_cell,
                rays: l.rays,
                band_voxels: l.band_voxels,
                p_in: l.p_in,
                p_subs: l.p_subs,
                density_threshold: l.density_threshold,
                fill_iterations: l.fill_iterations,
                smoothing_iterations: l.smoothing_iterations,
                smoothing_weight: l.smoothing_weight,
            },
            volume: self.volume_params(),
            density: self.body.density,
            mass_model: if self.body.lumped_masses {
                MassModel::Lumped
            } else {
                MassModel::Equal
            },
            gravity: (self.run.gravity * self.run.up.vector()).into(),
            dt: self.run.dt.unwrap_or(MAX_DT),
            restitution: self.run.restitution,
            ..VolumetricParams::default()
        }
    }

    /// The body at `resolution`, or sized for `cells` (default [`DEFAULT_TARGET_CELLS`]). A
    /// resolution that leaves no interior is reported with the resolution the sizing would
    /// choose.
    fn body(
        &self,
        soup: &TriMesh,
        params: VolumetricParams,
    ) -> Result<VolumetricBody, VolumetricBuildError> {
        const CONTEXT: &str = "cannot build the volumetric body";
        let Some(resolution) = self.lattice.resolution else {
            let sizing =
                SizingParams::for_cells(self.lattice.cells.unwrap_or(DEFAULT_TARGET_CELLS));
            let (body, _) =
                VolumetricBody::build_sized(soup, params, &sizing).map_err(|source| {
                    VolumetricBuildError::Body {
                        context: CONTEXT.into(),
                        source,
                    }
                })?;
            return Ok(body);
        };
        match VolumetricBody::build(soup, params.clone()) {
            Ok(body) => Ok(body),
            Err(VolumetricError::Lattice(e @ LatticeError::NoInterior { .. })) => {
                let hint = match size_lattice(soup, &params.lattice, &SizingParams::default()) {
                    Ok((_, s)) => format!(
                        "resolution {resolution} leaves no cell; `resolution` = {} gives {} cells \
                         (or leave `resolution` out to size the lattice for `cells`)",
                        s.resolution, s.cells
                    ),
                    Err(e) => format!("no resolution gives a body either: {e}"),
                };
                Err(VolumetricBuildError::NoInterior {
                    hint: NoInteriorHint { hint, source: e },
                })
            }
            Err(source) => Err(VolumetricBuildError::Body {
                context: CONTEXT.into(),
                source,
            }),
        }
    }

    /// Builds the simulation: loads `mesh.path` (or takes `mesh`, an in-memory soup), scales
    /// and moves it, generates the lattice, sets the springs, the time step, the scene and the
    /// hard anchors. The spring anchors and loads are applied by
    /// [`crate::selection::apply::volumetric_loads`]. Writes nothing.
    pub fn build(&self, mesh: Option<TriMesh>) -> Result<VolumetricBuild, VolumetricBuildError> {
        let mut soup = match mesh {
            Some(m) => m,
            None => balloon::mesh::load(&self.mesh.path).map_err(|source| {
                VolumetricBuildError::Mesh {
                    path: self.mesh.path.clone(),
                    source,
                }
            })?,
        };
        soup.scale(self.mesh.scale);
        if let Some(t) = &self.mesh.transform {
            crate::mesh::apply_transform(&mut soup, t).map_err(VolumetricBuildError::Invalid)?;
        }
        let params = self.params();
        let t0 = Instant::now();
        let mut body = self.body(&soup, params)?;
        let lattice_ms = t0.elapsed().as_secs_f64() * 1e3;
        let b = &self.body;
        let dt = self.run.dt.unwrap_or_else(|| {
            body.sag_limited_dt_along(
                &self.run.up.vector(),
                EDGE_STIFFNESS,
                SAG_STRAIN,
                self.run.gravity,
                MAX_DT,
            )
        });
        body.params.dt = dt;
        let defaults = body.default_springs(EDGE_STIFFNESS);
        let edge = b.edge_stiffness.unwrap_or(defaults.edge_stiffness);
        let diagonal =
            b.diagonal_stiffness
                .unwrap_or(if b.soft_diagonals { edge / 20.0 } else { edge });
        let damping = b.damping.unwrap_or(defaults.edge_damping);
        let diagonal_damping = b.diagonal_damping.unwrap_or(if b.soft_diagonals {
            damping / 2.0
        } else {
            damping
        });
        let body = body
            .with_springs(SpringParams {
                edge_stiffness: edge,
                edge_damping: damping,
                diagonal_stiffness: diagonal,
                diagonal_damping,
            })
            .map_err(VolumetricBuildError::Springs)?;
        let scene = match self.run.scene {
            SceneChoice::Free | SceneChoice::Floor => VolumetricScene::Free,
            SceneChoice::DropSphere => VolumetricScene::DropSphere {
                soft_diagonals: b.soft_diagonals,
            },
        };
        let mut sim = scene.setup(body).map_err(VolumetricBuildError::Scene)?;
        if self.run.scene == SceneChoice::Floor {
            let up = self.run.up;
            let height = self
                .run
                .floor_height
                .unwrap_or_else(|| default_floor_height(sim.positions(), up));
            let floor = floor_plane(height, up).ok_or_else(|| {
                VolumetricBuildError::Invalid(format!(
                    "`floor_height`: the floor under the body is at {height:e} m, not a finite \
                     height"
                ))
            })?;
            sim = sim.with_plane(floor);
        }
        fix_volumetric(&mut sim, &self.anchors, b.pin_stiffness)?;
        Ok(VolumetricBuild {
            sim,
            soup,
            lattice_ms,
            stiffness: [edge, diagonal],
        })
    }
}

#[cfg(test)]
#[path = "volumetric_tests.rs"]
mod tests;
