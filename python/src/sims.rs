//! The step-wise simulations: `Shell`, `Volumetric`, `TwoLayer`.

use crate::args;
use crate::convert::{detached, flat_points, points_array, stats_dict, triangles_array};
use crate::errors::{BalloonError, InvalidOption, setter_err, to_py_err};
use crate::options::{Use, scenario_of};
use crate::shared::Shared;
use balloon::Simulation;
use balloon::gas::GasModel;
use balloon::shell::AnchorSpring;
use balloon::two_layer::{DragTarget, TwoLayerSimulation};
use balloon::volumetric::VolumetricSimulation;
use balloon_scenario::selection::ShellLoads;
use balloon_scenario::shell::ShellSim;
use balloon_scenario::{Scenario, SystemKind};
use nalgebra::{Point3, Vector3};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::{Mutex, MutexGuard};

/// Locks the anchor springs and loads of a shell (only `step()` uses them, holding the
/// simulation's turn, so the lock is free).
fn lock_loads(m: &Mutex<ShellLoads>) -> PyResult<MutexGuard<'_, ShellLoads>> {
    m.lock()
        .map_err(|_| BalloonError::new_err("the simulation is unusable after an internal error"))
}

/// The volume the shell's surface encloses now, m^3.
fn current_volume(sim: &ShellSim) -> PyResult<f64> {
    balloon::gas::enclosed_volume(sim.positions(), sim.triangles())
        .map_err(|e| BalloonError::new_err(e.to_string()))
}

/// Shell(mesh="builtin", **options)
/// --
///
/// A shell balloon (Wang et al. 2015) built exactly as `balloon inflate` builds it from the same
/// options, driven step by step from Python: `step()` returns the step's statistics;
/// `positions`, `velocities`, `thickness`, `time`, `gauge_pressure`, `gas_volume` read the
/// state; `set_pressure`, `set_pump_rate`, `set_external_forces`, `set_anchor_springs`,
/// `set_dt` steer it. Output options (`out`, `render`, ...) are accepted and ignored.
#[pyclass(module = "balloon._balloon", subclass)]
pub(crate) struct Shell {
    sim: Shared<ShellSim>,
    /// The anchor springs and scheduled loads of the options (`pin`, `load`), applied before
    /// every step as the CLI applies them.
    loads: Mutex<ShellLoads>,
}

#[pymethods]
impl Shell {
    #[new]
    #[pyo3(signature = (mesh = None, **options))]
    fn new(
        py: Python<'_>,
        mesh: Option<&Bound<'_, PyAny>>,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let (scenario, arrays, _) = scenario_of(SystemKind::Shell, mesh, options, Use::Stepwise)?;
        let Scenario::Shell(s) = scenario else {
            return Err(BalloonError::new_err("not a shell scenario"));
        };
        let (sim, loads) = detached(py, move || Ok(s.build(arrays)?))?;
        Ok(Self {
            sim: Shared::new(sim),
            loads: Mutex::new(loads),
        })
    }

    /// Advances one time step (GIL released) and returns its statistics as a dict (the keys of
    /// a `stats.jsonl` line plus `steps`, `time`, `dt`, `kinetic_energy`). Raises SolverError
    /// when the step fails (the state is rolled back to the start of the step).
    fn step<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut guard = self.sim.lock(py)?;
        let sim = &mut *guard;
        lock_loads(&self.loads)?
            .before_step(sim)
            .map_err(|e| to_py_err(e.into()))?;
        let stats = crate::cancel::solve(py, || Simulation::step(sim), |e| to_py_err(e.into()))?;
        stats_dict(py, &stats)
    }

    /// Vertex positions, m: an (n, 3) float64 array (a copy of the current state).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_array(py, self.sim.lock(py)?.positions())
    }

    /// Vertex velocities, m/s: an (n, 3) float64 array.
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_array(py, self.sim.lock(py)?.velocities())
    }

    /// The triangles: an (m, 3) int64 array.
    #[getter]
    fn triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        triangles_array(py, self.sim.lock(py)?.triangles())
    }

    /// Current shell thickness per triangle, m: an (m,) float64 array.
    #[getter]
    fn thickness<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        Ok(PyArray1::from_slice(py, self.sim.lock(py)?.thickness()))
    }

    /// Simulated time, s.
    #[getter]
    fn time(&self, py: Python<'_>) -> PyResult<f64> {
        Ok(self.sim.lock(py)?.time())
    }

    /// Steps taken.
    #[getter]
    fn steps(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(Simulation::steps(&*self.sim.lock(py)?))
    }

    /// The time step of the following steps, s.
    #[getter]
    fn dt(&self, py: Python<'_>) -> PyResult<f64> {
        Ok(self.sim.lock(py)?.dt())
    }

    /// Gauge pressure of the gas, Pa: the gas law's at the current enclosed volume and time
    /// (so it is the true pressure before the first step, and after a failed step that was
    /// rolled back).
    #[getter]
    fn gauge_pressure(&self, py: Python<'_>) -> PyResult<f64> {
        let sim = self.sim.lock(py)?;
        let volume = current_volume(&sim)?;
        Ok(GasModel::absolute_pressure(sim.gas(), volume, sim.time()) - sim.ambient_pressure())
    }

    /// Enclosed gas volume, m^3, of the current positions (after a failed step that was
    /// rolled back, the volume of the restored state).
    #[getter]
    fn gas_volume(&self, py: Python<'_>) -> PyResult<f64> {
        current_volume(&*self.sim.lock(py)?)
    }

    /// Changes the time step (s) of the following steps (the range of `dt=`).
    fn set_dt(&self, py: Python<'_>, dt: &Bound<'_, PyAny>) -> PyResult<()> {
        let dt = args::ranged(SystemKind::Shell, dt, "dt")?;
        self.sim.lock(py)?.set_dt(dt).map_err(setter_err)
    }

    /// Sets the gauge pressure, Pa (held pressure of `gas="constant"`, the amount of the
    /// ideal gas at the rest volume, ...; an error for the pump).
    /// The range is that of `pressure=`.
    fn set_pressure(&self, py: Python<'_>, pressure: &Bound<'_, PyAny>) -> PyResult<()> {
        let pressure = args::ranged(SystemKind::Shell, pressure, "pressure")?;
        self.sim
            .lock(py)?
            .set_gauge_pressure(pressure)
            .map_err(setter_err)
    }

    /// Sets the pump rate, m^3/s of ambient air, of `gas="pump"` from now on (the range of
    /// `pump_rate=`).
    fn set_pump_rate(&self, py: Python<'_>, rate: &Bound<'_, PyAny>) -> PyResult<()> {
        let rate = args::ranged(SystemKind::Shell, rate, "pump_rate")?;
        self.sim.lock(py)?.set_pump_rate(rate).map_err(setter_err)
    }

    /// Sets external forces, N: an (n, 3) array, one per vertex, applied in every following
    /// step; None removes them.
    #[pyo3(signature = (forces = None))]
    fn set_external_forces(
        &self,
        py: Python<'_>,
        forces: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let mut sim = self.sim.lock(py)?;
        let f = match forces {
            Some(f) => Some(flat_points(f, sim.positions().len() / 3, "forces")?),
            None => None,
        };
        sim.set_external_forces(f.as_deref()).map_err(setter_err)
    }

    /// Replaces the anchor springs: a list of (vertex, (x, y, z), stiffness N/m), zero-length
    /// springs pulling the vertex to the fixed point (integrated implicitly); [] removes them.
    /// Each entry is checked: a vertex that is not a whole number (a float is refused, not
    /// truncated), a point that is not three numbers or a stiffness that is not a number is an
    /// `InvalidOption` naming the entry.
    fn set_anchor_springs(&self, py: Python<'_>, springs: &Bound<'_, PyAny>) -> PyResult<()> {
        let entries: Vec<Bound<'_, PyAny>> = springs
            .try_iter()
            .and_then(|it| it.collect::<PyResult<_>>())
            .map_err(|_| {
                InvalidOption::new_err(
                    "anchor springs must be a list of (vertex, (x, y, z), stiffness)",
                )
            })?;
        let springs = entries
            .iter()
            .enumerate()
            .map(|(i, e)| {
                let parts: Vec<Bound<'_, PyAny>> = e
                    .try_iter()
                    .and_then(|it| it.collect::<PyResult<_>>())
                    .ok()
                    .filter(|p: &Vec<_>| p.len() == 3)
                    .ok_or_else(|| {
                        InvalidOption::new_err(format!(
                            "anchor spring {i} must be (vertex, (x, y, z), stiffness)"
                        ))
                    })?;
                Ok(AnchorSpring {
                    vertex: args::index(&parts[0], &format!("the vertex of anchor spring {i}"))?,
                    anchor: args::point(&parts[1], &format!("the point of anchor spring {i}"))?,
                    stiffness: args::real(&parts[2], "stiffness")?,
                })
            })
            .collect::<PyResult<Vec<_>>>()?;
        self.sim
            .lock(py)?
            .set_anchor_springs(springs)
            .map_err(setter_err)
    }
}

/// Volumetric(mesh="builtin", **options)
/// --
///
/// A volume-conserving body (Diziol, Bender and Bayer 2011) built exactly as `balloon volumetric` builds it, driven
/// step by step: `step()`, `positions` (lattice particles), `surface_positions` (the embedded
/// surface), `time`, `set_external_forces`, `set_dt`.
#[pyclass(module = "balloon._balloon", subclass)]
pub(crate) struct Volumetric {
    sim: Shared<VolumetricSimulation>,
}

#[pymethods]
impl Volumetric {
    #[new]
    #[pyo3(signature = (mesh = None, **options))]
    fn new(
        py: Python<'_>,
        mesh: Option<&Bound<'_, PyAny>>,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let (scenario, arrays, _) =
            scenario_of(SystemKind::Volumetric, mesh, options, Use::Stepwise)?;
        let Scenario::Volumetric(s) = scenario else {
            return Err(BalloonError::new_err("not a volumetric scenario"));
        };
        let built = detached(py, move || Ok(s.build(arrays)?))?;
        Ok(Self {
            sim: Shared::new(built.sim),
        })
    }

    /// Advances one time step (GIL released) and returns its statistics as a dict.
    fn step<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut guard = self.sim.lock(py)?;
        let sim = &mut *guard;
        let stats = crate::cancel::solve(py, || Simulation::step(sim), |e| to_py_err(e.into()))?;
        stats_dict(py, &stats)
    }

    /// Lattice particle positions, m: an (n, 3) float64 array.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_array(py, Simulation::positions(&*self.sim.lock(py)?))
    }

    /// Lattice particle velocities, m/s: an (n, 3) float64 array.
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_array(py, Simulation::velocities(&*self.sim.lock(py)?))
    }

    /// The embedded surface (the input soup deformed with the lattice), m: (k, 3).
    #[getter]
    fn surface_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let sim = self.sim.lock(py)?;
        let flat: Vec<f64> = sim
            .lattice()
            .embedding
            .positions(sim.positions())
            .iter()
            .flat_map(|p| [p.x, p.y, p.z])
            .collect();
        points_array(py, &flat)
    }

    /// The embedded surface's triangles: (m, 3) int64.
    #[getter]
    fn surface_triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        triangles_array(py, &self.sim.lock(py)?.lattice().embedding.triangles)
    }

    /// Simulated time, s.
    #[getter]
    fn time(&self, py: Python<'_>) -> PyResult<f64> {
        Ok(self.sim.lock(py)?.time())
    }

    /// Steps taken.
    #[getter]
    fn steps(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(Simulation::steps(&*self.sim.lock(py)?))
    }

    /// The time step of the following steps, s.
    #[getter]
    fn dt(&self, py: Python<'_>) -> PyResult<f64> {
        Ok(Simulation::dt(&*self.sim.lock(py)?))
    }

    /// Changes the time step (s) of the following steps.
    fn set_dt(&self, py: Python<'_>, dt: &Bound<'_, PyAny>) -> PyResult<()> {
        let dt = args::ranged(SystemKind::Volumetric, dt, "dt")?;
        Simulation::set_dt(&mut *self.sim.lock(py)?, dt).map_err(setter_err)
    }

    /// Sets external forces, N: an (n, 3) array, one per lattice particle; None removes them.
    #[pyo3(signature = (forces = None))]
    fn set_external_forces(
        &self,
        py: Python<'_>,
        forces: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let mut sim = self.sim.lock(py)?;
        let f = match forces {
            Some(f) => {
                let flat = flat_points(f, sim.positions().len(), "forces")?;
                Some(
                    flat.chunks_exact(3)
                        .map(|c| Vector3::new(c[0], c[1], c[2]))
                        .collect::<Vec<_>>(),
                )
            }
            None => None,
        };
        sim.set_external_forces(f.as_deref()).map_err(setter_err)
    }
}

/// TwoLayer(**options)
/// --
///
/// A two-layer mass-spring body (Song 2009) built exactly as `balloon two-layer` builds it,
/// driven step by step: `step()`, `positions`, `time`, `set_drag`, `set_dt`.
#[pyclass(module = "balloon._balloon", subclass)]
pub(crate) struct TwoLayer {
    sim: Shared<TwoLayerSimulation>,
}

#[pymethods]
impl TwoLayer {
    #[new]
    #[pyo3(signature = (**options))]
    fn new(py: Python<'_>, options: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let (scenario, _, _) = scenario_of(SystemKind::TwoLayer, None, options, Use::Stepwise)?;
        let Scenario::TwoLayer(s) = scenario else {
            return Err(BalloonError::new_err("not a two-layer scenario"));
        };
        let sim = detached(py, move || Ok(s.build()?))?;
        Ok(Self {
            sim: Shared::new(sim),
        })
    }

    /// Advances one time step (GIL released) and returns its statistics as a dict.
    fn step<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut guard = self.sim.lock(py)?;
        let sim = &mut *guard;
        let stats = crate::cancel::solve(py, || Simulation::step(sim), |e| to_py_err(e.into()))?;
        stats_dict(py, &stats)
    }

    /// Particle positions, m: an (n, 3) float64 array.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_array(py, Simulation::positions(&*self.sim.lock(py)?))
    }

    /// Particle velocities, m/s: an (n, 3) float64 array.
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_array(py, Simulation::velocities(&*self.sim.lock(py)?))
    }

    /// Simulated time, s.
    #[getter]
    fn time(&self, py: Python<'_>) -> PyResult<f64> {
        Ok(self.sim.lock(py)?.time())
    }

    /// Steps taken.
    #[getter]
    fn steps(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(Simulation::steps(&*self.sim.lock(py)?))
    }

    /// The time step of the following steps, s.
    #[getter]
    fn dt(&self, py: Python<'_>) -> PyResult<f64> {
        Ok(Simulation::dt(&*self.sim.lock(py)?))
    }

    /// Changes the time step (s) of the following steps.
    fn set_dt(&self, py: Python<'_>, dt: &Bound<'_, PyAny>) -> PyResult<()> {
        let dt = args::ranged(SystemKind::TwoLayer, dt, "dt")?;
        Simulation::set_dt(&mut *self.sim.lock(py)?, dt).map_err(setter_err)
    }

    /// Drags the body ("mouse"): a spring of `stiffness` N/m and `damping` N s/m from the
    /// nearest particle to `point` (x, y, z), m; None releases it. Returns the dragged particle.
    #[pyo3(signature = (point = None, stiffness = None, damping = None))]
    fn set_drag(
        &self,
        py: Python<'_>,
        point: Option<&Bound<'_, PyAny>>,
        stiffness: Option<&Bound<'_, PyAny>>,
        damping: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Option<usize>> {
        let point = point
            .filter(|p| !p.is_none())
            .map(|p| args::point(p, "the drag point"))
            .transpose()?;
        // Defaults: 10 N/m and 0.1 N s/m.
        let stiffness = stiffness.map_or(Ok(10.0), |k| args::real(k, "stiffness"))?;
        let damping = damping.map_or(Ok(0.1), |c| args::real(c, "damping"))?;
        let target = point.map(|p| DragTarget {
            point: Point3::new(p[0], p[1], p[2]),
            stiffness,
            damping,
            rest_length: 0.0,
        });
        self.sim.lock(py)?.set_drag(target).map_err(setter_err)
    }
}
