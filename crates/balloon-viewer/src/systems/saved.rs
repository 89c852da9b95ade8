//! The viewer's built-in set-ups as scenarios: what the page's "save scenario" link downloads
//! for a run that was not opened from a file, so that `balloon run` repeats it.

use super::shell::{HELD_FRACTION, ShellView, ViewMaterial};
use super::two_layer::{
    TWO_LAYER_BOX, TWO_LAYER_DAMPING, TWO_LAYER_LEVEL, TWO_LAYER_RADII, TWO_LAYER_STRUCTURAL,
    TwoLayerView,
};
use super::volumetric::VolumetricView;
use crate::ViewerError;
use balloon::constraint::cell_volume::{CellCorrection, CellSolver};
use balloon::gas::GasKind;
use balloon::material::membrane::MembraneKind;
use balloon_scenario::gas::GasControl;
use balloon_scenario::material::MaterialChoice;
use balloon_scenario::selection::parse_pin;
use balloon_scenario::shell::ShellScenario;
use balloon_scenario::two_layer::TwoLayerScenario;
use balloon_scenario::volumetric::{Correction, SceneChoice, Up, VolumeSolver, VolumetricScenario};

/// The built-in mesh the shell view starts with ([`crate::default_mesh`]): the teddy at
/// resolution 14 (1304 vertices).
pub const DEFAULT_SHELL_MESH: &str = "builtin:teddy-coarse";

/// The built-in mesh the volumetric view starts with ([`crate::default_mesh`]): the teddy at
/// resolution 14, laid on its back by [`LYING_ON_ITS_BACK`].
pub const DEFAULT_VOLUMETRIC_MESH: &str = "builtin:teddy-coarse";

/// The map (a scenario's `transform`, `x -> A x + t` row by row) that lays the built-in teddy
/// on its back, face up (+y): `(x, y, z) -> (x, z, -y)`, a quarter turn about x. A soft teddy
/// cannot stand on its round feet: standing, it topples onto its back within a quarter of a
/// second. Every product is by 0 or 1, so the map is exact.
pub const LYING_ON_ITS_BACK: [f64; 12] = [
    1.0, 0.0, 0.0, 0.0, //
    0.0, 0.0, 1.0, 0.0, //
    0.0, -1.0, 0.0, 0.0,
];

/// A mesh spec as a scenario file elsewhere can read it: built-in names as they are, a file by
/// its absolute path (the saved file lands in another folder).
fn portable_mesh_path(spec: &str) -> String {
    if spec.trim().to_ascii_lowercase().starts_with("builtin") {
        return spec.to_string();
    }
    std::fs::canonicalize(spec).map_or_else(|_| spec.to_string(), |p| p.display().to_string())
}

impl ShellView {
    /// The shell scenario of the current set-up: mesh, material (a membrane with the view's
    /// parameters, `mu = E / 3` split as the page's material choice does), thickness, gas, time
    /// step, linear solver, tangent, the live view's fixed three Newton iterations and, with
    /// `hold`, the held vertices as a spring anchor (`below:y:VALUE@K`, `K = 10 E h`).
    pub fn scenario(&self) -> Result<ShellScenario, ViewerError> {
        let st = &self.settings;
        let mut s = ShellScenario::default();
        s.mesh.path = self
            .mesh_spec
            .as_deref()
            .map_or_else(|| DEFAULT_SHELL_MESH.to_string(), portable_mesh_path);
        s.shell.thickness = st.thickness_mm * 1e-3;
        let young = st.young_mpa * 1e6;
        let mu = young / 3.0;
        let m = &mut s.shell.material;
        match st.material {
            ViewMaterial::Solid(kind) => {
                m.material = Some(MaterialChoice::Solid(kind));
                m.young = Some(young);
            }
            ViewMaterial::Membrane(kind) => {
                m.material = Some(MaterialChoice::Membrane(kind));
                match kind {
                    MembraneKind::NeoHookean => m.mu = Some(mu),
                    MembraneKind::MooneyRivlin => {
                        m.c1 = Some(0.4 * mu);
                        m.c2 = Some(0.1 * mu);
                    }
                    MembraneKind::Gent => {
                        m.mu = Some(mu);
                        m.jm = Some(super::shell::GENT_JM);
                    }
                    MembraneKind::Ogden => {
                        let alpha = super::shell::OGDEN_ALPHA;
                        m.ogden_mu = Some(vec![2.0 * mu / alpha]);
                        m.ogden_alpha = Some(vec![alpha]);
                    }
                    MembraneKind::Yeoh => m.yeoh = Some(vec![0.5 * mu, 0.0, 1e-3 * mu]),
                }
            }
        }
        let g = &mut s.gas;
        g.model = match st.gas {
            GasKind::Ideal => GasControl::Ideal,
            GasKind::Constant => GasControl::Constant,
            GasKind::Pump => GasControl::Pump,
            GasKind::Polytropic => GasControl::Polytropic,
            GasKind::Leak => GasControl::Leak,
            GasKind::SupplyPump => GasControl::SupplyPump,
        };
        g.pressure = st.pressure;
        if matches!(st.gas, GasKind::Pump | GasKind::SupplyPump) {
            g.pump_rate = Some(st.pump_rate);
        }
        match st.gas {
            GasKind::Polytropic => {
                g.laws.gamma = Some(balloon::gas::GasLawParams::default().gamma);
            }
            GasKind::Leak => g.laws.leak_conductance = Some(st.leak_conductance),
            GasKind::SupplyPump => g.laws.supply_pressure = Some(st.pressure.max(1.0)),
            _ => {}
        }
        let r = &mut s.run;
        r.dt = st.dt;
        r.linear_solver = st.solver;
        r.tangent = st.tangent;
        r.newton_iters = super::shell::VIEWER_NEWTON_ITERATIONS;
        r.newton_tol = 0.0;
        // Decided when the view's simulation was built (on: it was built converging Newton,
        // then set to the fixed iterations); unset, the scenario's fixed iterations turn it off.
        r.follower_term = Some(self.sim.follower_term());
        if st.hold {
            // The view holds the vertices at or below the threshold; the selector takes those
            // strictly below, so the next float up selects the same ones.
            let spec = format!(
                "below:y:{}@{}",
                self.hold_height().next_up(),
                self.spring_stiffness()
            );
            s.anchors.push(
                parse_pin(&spec).map_err(|e| ViewerError::Scenario(format!("`{spec}`: {e}")))?,
            );
        }
        Ok(s)
    }

    /// The height (y, m) at or below which the rest vertices are held (`hold`).
    pub(super) fn hold_height(&self) -> f64 {
        let (lo, hi) = self
            .rest
            .chunks_exact(3)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), c| {
                (a.min(c[1]), b.max(c[1]))
            });
        lo + HELD_FRACTION * (hi - lo)
    }
}

impl VolumetricView {
    /// The volumetric scenario of the current set-up: the `floor` scene with `up` = y (the
    /// floor just under the body), the mesh (the built-in teddy laid on its back, or `--mesh`),
    /// the view's lattice resolution, gravity, time step, cell-volume correction and solver,
    /// and the spring stiffness and damping in N/m and N s/m when they are not what `balloon
    /// volumetric` derives from the time step (a stiffness other than the default, or a time
    /// step changed after the body was built). Everything else is `balloon volumetric`'s
    /// default, which the view also uses.
    pub fn scenario(&self) -> VolumetricScenario {
        let st = &self.settings;
        let mut s = VolumetricScenario::default();
        match &self.mesh_spec {
            Some(spec) => s.mesh.path = portable_mesh_path(spec),
            None => {
                s.mesh.path = DEFAULT_VOLUMETRIC_MESH.into();
                s.mesh.transform = Some(LYING_ON_ITS_BACK.to_vec());
            }
        }
        s.lattice.resolution = Some(super::volumetric::LATTICE_RESOLUTION);
        let r = &mut s.run;
        r.scene = SceneChoice::Floor;
        r.up = Up::Y;
        r.gravity = -st.gravity;
        r.dt = Some(st.dt);
        r.correction = match st.correction {
            CellCorrection::Scaling => Correction::Scaling,
            CellCorrection::Gradient => Correction::Gradient,
        };
        r.volume_solver = match st.solver {
            CellSolver::GaussSeidel => VolumeSolver::GaussSeidel,
            CellSolver::Global => VolumeSolver::Global,
        };
        let body = self.sim.body();
        let springs = &body.params.springs;
        let derived = body.default_springs(balloon::volumetric::DEFAULT_SPRING_STIFFNESS);
        if *springs != derived {
            s.body.edge_stiffness = Some(springs.edge_stiffness);
            s.body.damping = Some(springs.edge_damping);
            if springs.diagonal_stiffness != springs.edge_stiffness {
                s.body.diagonal_stiffness = Some(springs.diagonal_stiffness);
            }
            if springs.diagonal_damping != springs.edge_damping {
                s.body.diagonal_damping = Some(springs.diagonal_damping);
            }
        }
        s
    }
}

impl TwoLayerView {
    /// The two-layer scenario of the current set-up: the octahedron sphere of level 3 with the
    /// view's radii, structural springs and damping, gas, gravity, box, integrator and time
    /// step (the other body parameters are `balloon two-layer`'s defaults, which the view's
    /// builder also uses).
    pub fn scenario(&self) -> TwoLayerScenario {
        let st = &self.settings;
        let mut s = TwoLayerScenario::default();
        let (inner, outer) = TWO_LAYER_RADII;
        s.body.dim = 3;
        s.body.level = TWO_LAYER_LEVEL;
        s.body.inner_radius = inner;
        s.body.outer_radius = outer;
        s.body.damping = TWO_LAYER_DAMPING;
        let (k, c) = TWO_LAYER_STRUCTURAL;
        s.body.k_structural = k;
        s.body.damping_structural = Some(c);
        s.gas.pressure = st.pressure;
        s.gas.inner_pressure = 0.5 * st.pressure;
        s.run.gravity = st.gravity;
        s.run.box_size = TWO_LAYER_BOX;
        s.run.no_box = !st.wall_box;
        s.run.integrator = st.integrator;
        s.run.dt = st.dt;
        s
    }
}
