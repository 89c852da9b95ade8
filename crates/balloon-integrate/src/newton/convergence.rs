//! The convergence test of the Newton core: a residual force relative to a force scale, the
//! inexact-Newton forcing term and the stall test.
//!
//! Newton stops when the residual force `|r|` (N) is at most the tolerance times the force
//! scale `F`, the sum of the norms of the terms of the residual at the current iterate (for a
//! backward Euler step `|M (v - v^n)| / dt + F_int + |f_ext| + |C v|`, for a static solve
//! `F_int + |f_ext|`; `F_int` from [`crate::ForceSystem::force_scale`], the elastic and the
//! pressure forces counted separately, or `|f|`). Every term is a force norm over the same
//! degrees of freedom, so the ratio does not depend on units, model size or resolution. `F` has
//! a floor: for a dynamic step the force that moves the body by `1e-3` of its bounding-box
//! diagonal in one step, for a static solve the force that moves it by `1e-10` of it against
//! its own stiffness (the module docs of [`crate::implicit`] and [`crate::statics`]).

/// The Newton residual at one iterate: `|r|` and the force scale (N) it is relative to. For a
/// backward Euler step `r` is the velocity-form right-hand side `b` (N s) and `dt` its time
/// step; for a static solve `r` is a force and `dt = 1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Residual {
    /// `|r|` (N s for a dynamic step, N for a static solve).
    pub norm: f64,
    /// The force scale `F`, N.
    pub scale: f64,
    /// The time step `r` is scaled by (1 for a static solve), s.
    pub dt: f64,
}

impl Residual {
    /// `|r| / (dt F)`: the residual force relative to the force scale `F`.
    pub fn relative(&self) -> f64 {
        let force = self.norm / self.dt;
        if force == 0.0 {
            0.0
        } else if self.scale > 0.0 {
            force / self.scale
        } else {
            f64::INFINITY
        }
    }
}

/// Newton iterations over which the relative residual must at least halve. When it does not
/// (and is still above the tolerance) the solve has stalled, typically because the time step
/// is far longer than the time scale of the motion, so that the incremental potential is
/// strongly non-convex along the way: the step stops at once as
/// [`crate::newton::NewtonError::NotConverged`], and the caller's step halving takes over
/// instead of spending the remaining iterations. Applied to dynamic steps (not in the paper's
/// fixed-iteration mode).
pub const NEWTON_STALL_WINDOW: usize = 8;

/// Upper bound on the Newton iterations of a step or load stage.
pub const MAX_NEWTON_ITERATIONS: usize = 1000;

/// Whether the relative residuals `history` (oldest first, the last one current) show a stall
/// above `tolerance` ([`NEWTON_STALL_WINDOW`]).
pub(crate) fn stalled(history: &[f64], tolerance: f64) -> bool {
    let Some(&current) = history.last() else {
        return false;
    };
    history.len() > NEWTON_STALL_WINDOW
        && current > tolerance
        && current > 0.5 * history[history.len() - 1 - NEWTON_STALL_WINDOW]
}

/// The relative tolerance an inexact Newton step asks of its linear solve: `forcing * tol /
/// relative_residual`, clamped to `[floor, 0.1]` (`floor`: the solver's own tolerance; a
/// `forcing` of 0 gives `floor`).
pub(crate) fn forcing_tolerance(forcing: f64, tol: f64, relative_residual: f64, floor: f64) -> f64 {
    const LOOSEST: f64 = 0.1;
    let floor = floor.min(LOOSEST);
    let eta = forcing * tol / relative_residual;
    if eta.is_finite() {
        eta.clamp(floor, LOOSEST)
    } else {
        floor
    }
}

/// The Euclidean norm.
pub(crate) fn norm(v: &[f64]) -> f64 {
    v.iter().map(|a| a * a).sum::<f64>().sqrt()
}

/// The diagonal of the bounding box of `x` read as 3D points (the range of the values when the
/// length is not a multiple of 3), m.
pub(crate) fn extent(x: &[f64]) -> f64 {
    if !x.len().is_multiple_of(3) {
        let (lo, hi) = x
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        return if hi >= lo { hi - lo } else { 0.0 };
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in x.chunks_exact(3) {
        for c in 0..3 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    (0..3)
        .map(|c| (hi[c] - lo[c]).max(0.0).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// The first entry of `v` that is NaN or infinite.
pub(crate) fn first_non_finite(v: &[f64]) -> Option<usize> {
    v.iter().position(|a| !a.is_finite())
}
