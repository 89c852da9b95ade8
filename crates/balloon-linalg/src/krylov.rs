//! Krylov solvers: preconditioned conjugate gradients ([`cg`]) on any symmetric positive
//! definite operator given as closures, with its scratch vectors in a reusable [`CgWorkspace`].

use crate::error::SolveError;
use crate::info::{Preconditioner, SolveInfo};
use crate::vector::dot;

/// Scratch vectors of [`cg`], reused across calls.
#[derive(Clone, Debug, Default)]
pub struct CgWorkspace {
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    ap: Vec<f64>,
}

/// Preconditioned conjugate gradients for a symmetric positive definite operator.
///
/// * `apply(p, out)` writes `out = A p` (overwrite),
/// * `precondition(r, z)` writes `z = P^-1 r` (overwrite; the identity is `z.copy_from_slice(r)`),
/// * `x` holds the initial guess on entry and the solution on exit.
///
/// Stops when `||b - A x|| <= relative_tolerance ||b||` or after `max_iterations`; in the latter
/// case `converged` is `false` (not an error). Errors on non-positive curvature or non-finite
/// values.
pub fn cg(
    mut apply: impl FnMut(&[f64], &mut [f64]),
    mut precondition: impl FnMut(&[f64], &mut [f64]),
    b: &[f64],
    x: &mut [f64],
    max_iterations: usize,
    relative_tolerance: f64,
    ws: &mut CgWorkspace,
) -> Result<SolveInfo, SolveError> {
    let n = b.len();
    if x.len() != n {
        return Err(SolveError::Dimension {
            what: "x",
            len: x.len(),
            expected: n,
        });
    }
    for v in [&mut ws.r, &mut ws.z, &mut ws.p, &mut ws.ap] {
        v.resize(n, 0.0);
    }
    let bnorm = dot(b, b).sqrt();
    if !bnorm.is_finite() {
        return Err(SolveError::NonFinite { iteration: 0 });
    }
    if bnorm == 0.0 {
        x.fill(0.0);
        return Ok(SolveInfo {
            preconditioner: Preconditioner::Unreported,
            iterations: 0,
            relative_residual: 0.0,
            converged: true,
        });
    }
    if x.iter().all(|&v| v == 0.0) {
        // A zero start (every Newton solve): r = b, without a product with A (whose result
        // would be exactly zero for a finite A).
        ws.r.copy_from_slice(b);
    } else {
        apply(x, &mut ws.ap);
        for i in 0..n {
            ws.r[i] = b[i] - ws.ap[i];
        }
    }
    let target = relative_tolerance * bnorm;
    let mut rnorm = dot(&ws.r, &ws.r).sqrt();
    if rnorm <= target {
        return Ok(SolveInfo {
            preconditioner: Preconditioner::Unreported,
            iterations: 0,
            relative_residual: rnorm / bnorm,
            converged: true,
        });
    }
    precondition(&ws.r, &mut ws.z);
    ws.p.copy_from_slice(&ws.z);
    let mut rz = dot(&ws.r, &ws.z);
    for it in 0..max_iterations {
        apply(&ws.p, &mut ws.ap);
        let curvature = dot(&ws.p, &ws.ap);
        if !curvature.is_finite() {
            return Err(SolveError::NonFinite { iteration: it });
        }
        if curvature <= 0.0 {
            return Err(SolveError::NonPositiveCurvature {
                iteration: it,
                curvature,
                direction_norm_squared: dot(&ws.p, &ws.p),
            });
        }
        let alpha = rz / curvature;
        for i in 0..n {
            x[i] += alpha * ws.p[i];
            ws.r[i] -= alpha * ws.ap[i];
        }
        rnorm = dot(&ws.r, &ws.r).sqrt();
        if !rnorm.is_finite() {
            return Err(SolveError::NonFinite { iteration: it });
        }
        if rnorm <= target {
            return Ok(SolveInfo {
                preconditioner: Preconditioner::Unreported,
                iterations: it + 1,
                relative_residual: rnorm / bnorm,
                converged: true,
            });
        }
        precondition(&ws.r, &mut ws.z);
        let rz_new = dot(&ws.r, &ws.z);
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..n {
            ws.p[i] = ws.z[i] + beta * ws.p[i];
        }
    }
    Ok(SolveInfo {
        preconditioner: Preconditioner::Unreported,
        iterations: max_iterations,
        relative_residual: rnorm / bnorm,
        converged: false,
    })
}
