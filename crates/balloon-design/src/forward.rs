//! The forward check: the static equilibrium of a rest shape under the problem's pressure,
//! solved by the shell's own static solver (`balloon_shell::statics`), and its distance to
//! the target.

use balloon_gas::{ConstantPressure, Gas, IdealGas, PressureLoad};
use balloon_integrate::statics::{StaticParams, StaticSolver};
use balloon_shell::statics::{GasTerm, StaticShell};
use balloon_shell::{ShellMaterialModel, ShellSystem};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::DesignError;
use crate::problem::DesignProblem;

/// Density of the wall in the forward check (kg/m^3). Statics does not depend on it; the
/// static solver scales its regularisation with the masses.
const DENSITY: f64 = 1000.0;

/// The distance of a shape to the target, vertex by vertex (same connectivity).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Distance {
    /// Largest vertex distance (m).
    pub max: f64,
    /// Root mean square of the vertex distances (m).
    pub rms: f64,
    /// `max` over the target's bounding-box diagonal.
    pub max_relative: f64,
    /// `rms` over the target's bounding-box diagonal.
    pub rms_relative: f64,
}

/// Bounding-box diagonal of flat positions (m).
pub fn bbox_diagonal(x: &[f64]) -> f64 {
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for p in x.chunks(3) {
        let p = Vector3::new(p[0], p[1], p[2]);
        lo = lo.inf(&p);
        hi = hi.sup(&p);
    }
    (hi - lo).norm()
}

/// Per-vertex distances `|a_v - b_v|` (m).
pub fn vertex_distances(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.chunks(3)
        .zip(b.chunks(3))
        .map(|(p, q)| {
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        })
        .collect()
}

/// The [`Distance`] of `shape` to `target`, relative figures over `target`'s bounding-box
/// diagonal.
pub fn distance(shape: &[f64], target: &[f64]) -> Distance {
    let d = vertex_distances(shape, target);
    let max = d.iter().copied().fold(0.0, f64::max);
    let rms = (d.iter().map(|v| v * v).sum::<f64>() / d.len().max(1) as f64).sqrt();
    let diag = bbox_diagonal(target);
    Distance {
        max,
        rms,
        max_relative: max / diag,
        rms_relative: rms / diag,
    }
}

/// `shape` moved rigidly (rotation and translation, Kabsch's least-squares fit) onto
/// `reference`: a free balloon's equilibrium and rest shape are only defined up to a rigid
/// motion.
pub fn rigidly_aligned(shape: &[f64], reference: &[f64]) -> Vec<f64> {
    let n = (shape.len() / 3).max(1) as f64;
    let centroid = |x: &[f64]| {
        x.chunks(3)
            .map(|p| Vector3::new(p[0], p[1], p[2]))
            .sum::<Vector3<f64>>()
            / n
    };
    let (cs, cr) = (centroid(shape), centroid(reference));
    let mut h = Matrix3::zeros();
    for (p, q) in shape.chunks(3).zip(reference.chunks(3)) {
        let p = Vector3::new(p[0], p[1], p[2]) - cs;
        let q = Vector3::new(q[0], q[1], q[2]) - cr;
        h += p * q.transpose();
    }
    let svd = h.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return shape.to_vec();
    };
    let mut d = Matrix3::identity();
    if (vt.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = vt.transpose() * d * u.transpose();
    shape
        .chunks(3)
        .flat_map(|p| {
            let q = r * (Vector3::new(p[0], p[1], p[2]) - cs) + cr;
            [q.x, q.y, q.z]
        })
        .collect()
}

/// The shell of the rest shape `rest` under the problem's load (follower term on): a constant
/// gauge pressure (ambient 0), or the problem's amount of isothermal ideal gas against its
/// ambient pressure, with the problem's wall bending stiffness
/// ([`DesignProblem::with_wall_bending`]): the forward problem of the design.
pub(crate) fn shell_from_rest(
    problem: &DesignProblem,
    rest: &[f64],
) -> Result<ShellSystem<ShellMaterialModel, Gas>, DesignError> {
    let forward = |e: &dyn std::fmt::Display| DesignError::Forward(e.to_string());
    let (model, ambient) = match problem.gas_amount() {
        None => (
            Gas::Constant(ConstantPressure::try_new(problem.pressure()).map_err(|e| forward(&e))?),
            0.0,
        ),
        Some(g) => {
            // The shell takes the rest volume as the gas's reference volume (keeping its
            // pressure there), so give the pressure the amount has at that volume.
            let v = crate::problem::enclosed_volume(rest, problem.triangles());
            (
                Gas::Ideal(IdealGas::try_new(g.amount / v, v).map_err(|e| forward(&e))?),
                g.ambient,
            )
        }
    };
    let gas = PressureLoad::new(model)
        .with_ambient_pressure(ambient)
        .map_err(|e| forward(&e))?
        .with_follower_term(true);
    let mut shell = ShellSystem::from_rest_shape(
        rest,
        problem.triangles().to_vec(),
        problem.thickness().to_vec(),
        DENSITY,
        problem.material().clone(),
        gas,
    )
    .map_err(|e| forward(&e))?;
    // The same bending wall as the design's equations (the shell's thickness stays at its
    // rest value in these static solves, as the design's `h = H`).
    if problem.wall_bending() > 0.0 {
        shell
            .set_wall_bending(rest, problem.wall_bending())
            .map_err(|e| forward(&e))?;
    }
    Ok(shell)
}

/// The result of [`forward_check`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ForwardCheck {
    /// The equilibrium positions (flat, m), rigidly aligned onto the target.
    pub positions: Vec<f64>,
    /// Whether the static solve converged.
    pub converged: bool,
    /// Its relative residual.
    pub relative_residual: f64,
    /// Newton iterations of the static solve.
    pub iterations: usize,
    /// Distance of the (aligned) equilibrium to the target.
    pub distance: Distance,
    /// Enclosed volume of the equilibrium (m^3).
    pub volume: f64,
    /// Wall-clock seconds of the static solve.
    pub seconds: f64,
}

/// The static equilibrium of the rest shape `rest` under the problem's pressure (the shell's
/// static solver with load continuation, started from the rest shape, pressure follower term
/// in the tangent), rigidly aligned onto the target, and its distance to the target.
///
/// The wall keeps its rest thickness (no shell-volume projection), as in the design's
/// equations: the same static problem as `balloon inflate REST --static --gas constant
/// --pressure P --volume-projection off` with the design's wall (and `--bending s` with the
/// wall's bending stiffness), not as the default `inflate --static`, whose projection thins a
/// three-prism wall (`docs/design.md`).
///
/// # Errors
/// [`DesignError::Forward`] when the shell cannot be built from `rest` or the solver fails
/// outright. A solve that stops unconverged returns its last shape with `converged = false`.
pub fn forward_check(
    problem: &DesignProblem,
    rest: &[f64],
    params: &StaticParams,
) -> Result<ForwardCheck, DesignError> {
    let started = std::time::Instant::now();
    let forward = |e: &dyn std::fmt::Display| DesignError::Forward(e.to_string());
    let mut shell = shell_from_rest(problem, rest)?;
    let mut x = rest.to_vec();
    // A free body: its rigid motions are kept out of the Newton directions.
    let mut solver = StaticSolver::new(StaticParams {
        remove_rigid_motions: true,
        ..*params
    })
    .map_err(|e| forward(&e))?;
    let (converged, relative_residual, iterations) = {
        let mut statics = StaticShell::new(&mut shell, GasTerm::Own, true);
        match solver.solve_with_continuation(&mut statics, 0.0, &mut x, None) {
            Ok(info) => (info.converged, info.relative_residual, info.iterations),
            Err(_) => (false, f64::INFINITY, 0),
        }
    };
    let positions = rigidly_aligned(&x, problem.target());
    let distance = distance(&positions, problem.target());
    Ok(ForwardCheck {
        volume: crate::problem::enclosed_volume(&positions, problem.triangles()),
        positions,
        converged,
        relative_residual,
        iterations,
        distance,
        seconds: started.elapsed().as_secs_f64(),
    })
}
