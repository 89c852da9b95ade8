//! When a step's first Newton iteration may reuse the last step's Newton matrix (a chord, or
//! Shamanskii, step; module docs of [`crate::implicit`], "Reused tangent").

use super::BackwardEulerParams;

/// The tangent-reuse state of a [`super::BackwardEuler`] across steps.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct TangentReuse {
    /// `(m_coef, k_coef)` of the matrix in the assembler when the next step's first Newton
    /// iteration may reuse it; `None` when not.
    reusable: Option<(f64, f64)>,
    /// Steps in a row whose first iteration reused the matrix.
    reused_steps: usize,
}

impl TangentReuse {
    /// Whether the first iteration of a step with `params` and Newton matrix coefficients
    /// `coefficients` reuses the last matrix (`assembled`: the assembler holds the matrix of
    /// the last solve, for an assembled solver). Consumes the offer: a step that fails leaves
    /// none for the next.
    pub(crate) fn first_iteration_may_reuse(
        &mut self,
        params: &BackwardEulerParams,
        coefficients: (f64, f64),
        assembled: bool,
    ) -> bool {
        let reusable = self.reusable.take();
        // (At least two iterations allowed: a dropped chord step uses one up.)
        params.newton_tolerance != 0.0
            && params.newton_iterations >= 2
            && params.stiffness_damping == 0.0
            && self.reused_steps < params.tangent_reuse_steps
            && assembled
            && reusable == Some(coefficients)
    }

    /// Records a successful step: whether its last solve reused the matrix, whether the
    /// assembler holds its last matrix unshifted (`clean`), its Newton iterations and its
    /// matrix coefficients.
    pub(crate) fn after_step(
        &mut self,
        last_solve_reused: bool,
        clean: bool,
        newton_iterations: usize,
        coefficients: (f64, f64),
    ) {
        self.reused_steps = if last_solve_reused {
            self.reused_steps + 1
        } else {
            0
        };
        // Only after a step that one Newton iteration settled: where steps need more, a chord
        // step would add iterations rather than save linearisations.
        if clean && newton_iterations == 1 {
            self.reusable = Some(coefficients);
        }
    }
}
