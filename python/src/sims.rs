//! The step-wise simulations: `Shell`, `Volumetric`, `TwoLayer`.

use crate::convert::{detached, flat_points, points_array, stats_dict, triangles_array};
use crate::errors::{BalloonError, setter_err, to_py_err};
use crate::options::{Use, scenario_of};
use crate::shared::Shared;
use balloon::Simulation;
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
        let stats = py
            .detach(|| Simulation::step(sim))
            .map_err(|e| to_py_err(e.into()))?;
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

    /// Gauge pressure of the gas, Pa.
    #[getter]
    fn gauge_pressure(&self, py: Python<'_>) -> PyResult<f64> {
        Ok(self.sim.lock(py)?.gauge_pressure())
    }

    /// Enclosed gas volume, m^3.
    #[getter]
    fn gas_volume(&self, py: Python<'_>) -> PyResult<f64> {
        Ok(self.sim.lock(py)?.gas_volume())
    }

    /// Changes the time step (s) of the following steps.
    fn set_dt(&self, py: Python<'_>, dt: f64) -> PyResult<()> {
        self.sim.lock(py)?.set_dt(dt).map_err(setter_err)
    }

    /// Sets the gauge pressure, Pa (held pressure of `gas="constant"`, the amount of the
    /// ideal gas at the rest volume, ...; an error for the pump).
    fn set_pressure(&self, py: Python<'_>, pressure: f64) -> PyResult<()> {
        self.sim
            .lock(py)?
            .set_gauge_pressure(pressure)
            .map_err(setter_err)
    }

    /// Sets the pump rate, m^3/s of ambient air, of `gas="pump"` from now on.
    fn set_pump_rate(&self, py: Python<'_>, rate: f64) -> PyResult<()> {
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
    fn set_anchor_springs(
        &self,
        py: Python<'_>,
        springs: Vec<(usize, [f64; 3], f64)>,
    ) -> PyResult<()> {
        let springs = springs
            .into_iter()
            .map(|(vertex, anchor, stiffness)| AnchorSpring {
                vertex,
                anchor,
                stiffness,
            })
            .collect();
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
        let stats = py
            .detach(|| Simulation::step(sim))
            .map_err(|e| to_py_err(e.into()))?;
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
    fn set_dt(&self, py: Python<'_>, dt: f64) -> PyResult<()> {
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
        let stats = py
            .detach(|| Simulation::step(sim))
            .map_err(|e| to_py_err(e.into()))?;
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
    fn set_dt(&self, py: Python<'_>, dt: f64) -> PyResult<()> {
        Simulation::set_dt(&mut *self.sim.lock(py)?, dt).map_err(setter_err)
    }

    /// Drags the body ("mouse"): a spring of `stiffness` N/m and `damping` N s/m from the
    /// nearest particle to `point` (x, y, z), m; None releases it. Returns the dragged particle.
    #[pyo3(signature = (point = None, stiffness = 10.0, damping = 0.1))]
    fn set_drag(
        &self,
        py: Python<'_>,
        point: Option<[f64; 3]>,
        stiffness: f64,
        damping: f64,
    ) -> PyResult<Option<usize>> {
        let target = point.map(|p| DragTarget {
            point: Point3::new(p[0], p[1], p[2]),
            stiffness,
            damping,
            rest_length: 0.0,
        });
        self.sim.lock(py)?.set_drag(target).map_err(setter_err)
    }
}
