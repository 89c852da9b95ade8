//! The volumetric body (Diziol, Bender and Bayer 2011) in the viewer.

use super::view::*;
use crate::ViewerError;
use crate::protocol::{ControlSpec, ControlValue};
use balloon::Simulation;
use balloon::constraint::cell_volume::{CellCorrection, CellSolver};
use balloon::fields;
use balloon::mesh::TriMesh;
use balloon::volumetric::{VolumetricBody, VolumetricSimulation};
use balloon_scenario::volumetric::{
    Correction, Up, VolumeSolver, VolumetricScenario, default_floor_height, floor_plane,
};
use nalgebra::Vector3;
use serde_json::{Map, Value, json};

#[derive(Clone, Debug)]
pub(super) struct VolumetricSettings {
    pub(super) stiffness: f64,
    pub(super) correction: CellCorrection,
    pub(super) solver: CellSolver,
    pub(super) gravity: f64,
    pub(super) dt: f64,
}

/// One control of the volumetric view, parsed from the protocol once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum VolumetricControl {
    /// `stiffness`, `k dt^2 / m` (rebuilds).
    Stiffness(f64),
    /// `correction` (rebuilds).
    Correction(CellCorrection),
    /// `solver` (rebuilds).
    Solver(CellSolver),
    /// `gravity`, m/s^2 (live).
    Gravity(f64),
    /// `dt`, s (live).
    Dt(f64),
}

/// The protocol's names of the cell-volume corrections.
const CORRECTIONS: [(&str, CellCorrection); 2] = [
    ("scaling", CellCorrection::Scaling),
    ("gradient", CellCorrection::Gradient),
];
/// The protocol's names of the cell-volume solvers.
const CELL_SOLVERS: [(&str, CellSolver); 2] = [
    ("gauss-seidel", CellSolver::GaussSeidel),
    ("global", CellSolver::Global),
];

/// The protocol name of `value` in `table`.
impl VolumetricControl {
    pub(super) fn parse(name: &str, value: &ControlValue) -> Result<Self, ViewerError> {
        Ok(match name {
            "stiffness" => Self::Stiffness(number(name, value)?),
            "correction" => Self::Correction(lookup(&CORRECTIONS, name, choice(name, value)?)?),
            "solver" => Self::Solver(lookup(&CELL_SOLVERS, name, choice(name, value)?)?),
            "gravity" => Self::Gravity(number(name, value)?),
            "dt" => Self::Dt(number(name, value)?),
            other => return Err(ViewerError::UnknownControl(other.to_string())),
        })
    }
}

/// A volume-conserving lattice body (Diziol, Bender and Bayer 2011) on a floor in the viewer.
pub struct VolumetricView {
    pub(super) soup: TriMesh,
    /// The mesh as given on the command line (`--mesh`); `None`: the built-in lying teddy
    /// ([`crate::default_mesh`]).
    pub(super) mesh_spec: Option<String>,
    pub(super) settings: VolumetricSettings,
    pub(super) sim: VolumetricSimulation,
}

/// Volumetric drag spring: `k = VOLUMETRIC_DRAG_GAIN m / dt^2` with `m` the effective mass of the
/// picked surface point (see `apply_drag`; explicit, so far below the stability limit 4).
const VOLUMETRIC_DRAG_GAIN: f64 = 0.05;

/// Lattice resolution of the volumetric view (voxels along the longest side: a coarse body that
/// steps interactively); everything else of the lattice is `balloon volumetric`'s default.
pub(super) const LATTICE_RESOLUTION: usize = 36;

/// The defaults of `balloon volumetric` (`VolumetricScenario::default()`), where the view takes
/// its settings from.
fn cli_defaults() -> VolumetricScenario {
    VolumetricScenario::default()
}

impl VolumetricView {
    /// A volumetric view of the soup `soup` (m) with the default controls: the correction,
    /// the cell-volume solver and its tolerance, gravity, density, restitution, the lattice
    /// generator and the spring stiffness and damping are those of `balloon volumetric`
    /// (`VolumetricScenario::default()`); only the lattice resolution and the time step are the
    /// viewer's own (an interactive size).
    pub fn new(soup: TriMesh) -> Result<Self, ViewerError> {
        let cli = cli_defaults();
        let volume = cli.volume_params();
        let settings = VolumetricSettings {
            stiffness: balloon::volumetric::DEFAULT_SPRING_STIFFNESS,
            correction: volume.correction,
            solver: volume.solver,
            gravity: cli.run.gravity.abs(),
            dt: 5e-4,
        };
        let sim = Self::build(&soup, &settings)?;
        Ok(Self {
            soup,
            mesh_spec: None,
            settings,
            sim,
        })
    }

    /// Records the mesh spec (`--mesh`) the soup was loaded from, for the saved scenario.
    pub fn with_mesh_spec(mut self, spec: Option<String>) -> Self {
        self.mesh_spec = spec;
        self
    }

    fn build(soup: &TriMesh, s: &VolumetricSettings) -> Result<VolumetricSimulation, ViewerError> {
        let cli = cli_defaults();
        // The CLI's cell-volume settings for the correction and solver chosen on the page.
        let mut chosen = cli.clone();
        chosen.run.correction = match s.correction {
            CellCorrection::Scaling => Correction::Scaling,
            CellCorrection::Gradient => Correction::Gradient,
        };
        chosen.run.volume_solver = match s.solver {
            CellSolver::GaussSeidel => VolumeSolver::GaussSeidel,
            CellSolver::Global => VolumeSolver::Global,
        };
        // `balloon volumetric`'s parameters, with the viewer's lattice resolution, scene (gravity
        // along -y) and time step.
        let mut params = chosen.params();
        params.lattice.resolution = LATTICE_RESOLUTION;
        params.gravity = [0.0, -s.gravity, 0.0];
        params.dt = s.dt;
        let body = VolumetricBody::build(soup, params).map_err(ViewerError::from)?;
        // Springs relative to the particle mass and the time step with `balloon volumetric`'s
        // damping: `k = s m / dt^2` (explicit, stable for s well below 1), damping
        // `DEFAULT_SPRING_DAMPING m / dt` (the CLI's `damping` left unset), diagonals as stiff
        // as the edges (the CLI's `soft_diagonals = false`).
        let springs = body.default_springs(s.stiffness);
        let body = body.with_springs(springs).map_err(ViewerError::from)?;
        let sim = VolumetricSimulation::new(body);
        // The floor just below the body (a drop would invert the coarse cells on impact): the
        // `floor` scene of `balloon volumetric` with `up` = y.
        let height = default_floor_height(sim.positions(), Up::Y);
        let floor = floor_plane(height, Up::Y).ok_or(ViewerError::Floor)?;
        Ok(sim.with_plane(floor))
    }

    /// Applies a control; `true` when the simulation must be rebuilt.
    fn apply(&mut self, control: VolumetricControl) -> Result<bool, ViewerError> {
        let s = &mut self.settings;
        match control {
            VolumetricControl::Stiffness(k) => s.stiffness = k,
            VolumetricControl::Correction(c) => s.correction = c,
            VolumetricControl::Solver(solver) => s.solver = solver,
            VolumetricControl::Gravity(g) => {
                self.sim
                    .set_gravity([0.0, -g, 0.0])
                    .map_err(ViewerError::from)?;
                s.gravity = g;
                return Ok(false);
            }
            VolumetricControl::Dt(dt) => {
                VolumetricSimulation::set_dt(&mut self.sim, dt).map_err(ViewerError::from)?;
                s.dt = dt;
                return Ok(false);
            }
        }
        Ok(true)
    }
}

impl ViewSystem for VolumetricView {
    fn name(&self) -> &'static str {
        "volumetric"
    }

    fn controls(&self) -> Vec<ControlSpec> {
        let s = &self.settings;
        vec![
            ControlSpec::number(
                "stiffness",
                "Cell spring stiffness k dt^2 / m",
                s.stiffness,
                (0.002, 0.3, 0.002),
                "",
                true,
            ),
            ControlSpec::choice(
                "correction",
                "Volume correction",
                name_of(&CORRECTIONS, &s.correction),
                &["scaling", "gradient"],
                true,
            ),
            ControlSpec::choice(
                "solver",
                "Volume solver (global needs the gradient correction)",
                name_of(&CELL_SOLVERS, &s.solver),
                &["gauss-seidel", "global"],
                true,
            ),
            ControlSpec::number(
                "gravity",
                "Gravity",
                s.gravity,
                (0.0, 30.0, 0.1),
                "m/s^2",
                false,
            ),
            ControlSpec::number("dt", "Time step", s.dt, (1e-4, 1e-3, 1e-4), "s", false),
        ]
    }

    fn set_control(&mut self, name: &str, value: &ControlValue) -> Result<bool, ViewerError> {
        self.apply(VolumetricControl::parse(name, value)?)
    }

    fn rebuild(&mut self) -> Result<(), ViewerError> {
        self.sim = Self::build(&self.soup, &self.settings)?;
        Ok(())
    }

    fn simulation(&self) -> &dyn ViewedSimulation {
        &self.sim
    }

    fn simulation_mut(&mut self) -> &mut dyn ViewedSimulation {
        &mut self.sim
    }

    fn stats(&self) -> Map<String, Value> {
        let m = json!({
            "volume_ratio": self.sim.total_volume() / self.sim.body().rest_volume(),
            "kinetic_energy": self.sim.kinetic_energy(),
            "max_strain": self.sim.max_strain(),
            "particles": self.sim.positions().len(),
            "halvings": self.sim.total_halvings(),
            "dt": Simulation::dt(&self.sim),
        });
        m.as_object().cloned().unwrap_or_default()
    }

    fn scalar_fields(&self) -> Vec<&'static str> {
        vec!["speed", "stretch"]
    }

    fn scalar(&self, name: &str) -> Result<Vec<f64>, ViewerError> {
        let emb = &self.sim.lattice().embedding;
        match name {
            "speed" => {
                let v: Vec<f64> = emb
                    .vertices
                    .iter()
                    .flat_map(|e| {
                        let mut s = Vector3::zeros();
                        for (&i, &w) in e.particles.iter().zip(&e.weights) {
                            s += self.sim.velocities()[i] * w;
                        }
                        [s.x, s.y, s.z]
                    })
                    .collect();
                fields::vertex_speeds(&v).map_err(ViewerError::from)
            }
            "stretch" => {
                let rest = flat(&emb.positions(&self.sim.lattice().tet_mesh.vertices));
                let x = self.positions();
                // A soup may hold zero-area triangles: their stretch is undefined (NaN, drawn
                // in the neutral colour), the rest of the surface is coloured.
                let f = fields::face_area_stretch_or_nan(&rest, &x, &emb.triangles)
                    .map_err(ViewerError::from)?;
                fields::face_to_vertex(&x, &emb.triangles, &f).map_err(ViewerError::from)
            }
            other => Err(ViewerError::UnknownField(other.to_string())),
        }
    }

    fn drag_modes(&self) -> Vec<&'static str> {
        vec!["grab"]
    }

    /// The built-in set-up as a volumetric scenario ([`VolumetricView::scenario`]).
    fn scenario_text(&self) -> Option<String> {
        Some(balloon_scenario::file::record(
            &balloon_scenario::Scenario::Volumetric(self.scenario()),
            &balloon_scenario::keys::Literals::default(),
        ))
    }

    fn apply_drag(&mut self, drag: Option<&DragRequest>) -> Result<(), ViewerError> {
        let f = match drag {
            None => None,
            Some(d) => Some(drag_forces(&self.sim, d)?),
        };
        self.sim
            .set_external_forces(f.as_deref())
            .map_err(ViewerError::from)
    }
}

/// The forces (N, one per lattice particle) of the drag `d` on the volumetric body `sim`: a
/// critically damped spring `k = VOLUMETRIC_DRAG_GAIN m / dt^2` on the embedded surface point
/// of the picked vertex (`m` its effective mass), stretched at most half a lattice cell, spread
/// over the particles of its tetrahedron by their barycentric weights.
pub(super) fn drag_forces(
    sim: &VolumetricSimulation,
    d: &DragRequest,
) -> Result<Vec<Vector3<f64>>, ViewerError> {
    {
        let e = sim
            .lattice()
            .embedding
            .vertices
            .get(d.vertex)
            .ok_or(ViewerError::VertexOutOfRange { vertex: d.vertex })?;
        let (x, v, m) = (sim.positions(), sim.velocities(), sim.masses());
        let mut p = Vector3::zeros();
        let mut vel = Vector3::zeros();
        // A force F on the embedded point spread as w_j F accelerates the point by
        // F sum w_j^2 / m_j: its effective mass is 1 / sum w_j^2 / m_j (weights may be negative
        // or above 1 outside the lattice, so the plain sum of masses would be wrong).
        let mut inv_mass = 0.0;
        for (&i, &w) in e.particles.iter().zip(&e.weights) {
            p += x[i].coords * w;
            vel += v[i] * w;
            inv_mass += w * w / m[i];
        }
        let mass = 1.0 / inv_mass;
        let dt = Simulation::dt(sim);
        let k = VOLUMETRIC_DRAG_GAIN * mass / (dt * dt);
        // Critically damped for the pulled mass.
        let c = 2.0 * (k * mass).sqrt();
        // The spring stretches at most half a lattice cell: a far target pulls the body along
        // instead of tearing the picked cell inside out.
        let reach = 0.5 * sim.lattice().info.cell_size;
        let pull = Vector3::from(d.target) - p;
        let pull = if pull.norm() > reach {
            pull * (reach / pull.norm())
        } else {
            pull
        };
        let force = k * pull - c * vel;
        let mut f = vec![Vector3::zeros(); x.len()];
        for (&i, &w) in e.particles.iter().zip(&e.weights) {
            f[i] += force * w;
        }
        Ok(f)
    }
}
