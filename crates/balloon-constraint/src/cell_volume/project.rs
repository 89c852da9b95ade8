//! The projection entry points: [`CellVolumeConstraints::project`] and its variants, which
//! dispatch to the Gauss-Seidel sweeps or the global solve ([`crate::cell_global`]) by
//! [`crate::cell_volume::CellVolumeParams::solver`].

use super::cells::CellVolumeConstraints;
use super::params::{CellSolver, ProjectionInfo};
use crate::ConstraintError;
use crate::cell_global::CellProjectionWorkspace;
use nalgebra::{Point3, Vector3};

impl CellVolumeConstraints {
    /// Applies the volume impulses (Eq. 2-4) in Gauss-Seidel sweeps (or, with
    /// [`CellSolver::Global`], by Newton iterations on all cells at once).
    ///
    /// * `preview`: the positions `x = p + h v` of Eq. 1 (m), moved in place to the corrected
    ///   positions;
    /// * `velocities`: `v(t + h)` (m/s), changed by `Delta v_i = (lambda - 1)(x_i - c) / h` so that
    ///   `p + h v` equals the corrected preview again;
    /// * `masses`: particle masses (kg), used by [`CellCentre::MassWeighted`](super::params::CellCentre::MassWeighted) and the gradient
    ///   correction; `f64::INFINITY` marks a fixed particle, which the projection never moves
    ///   (its cells take the gradient correction);
    /// * `h`: the time step (s).
    ///
    /// Returns [`ConstraintError::Inverted`] when a preview tetrahedron is not positive (before
    /// or during the sweeps), and [`ConstraintError::CellVolumeNotConverged`] after `max_sweeps`.
    pub fn project(
        &self,
        preview: &mut [Point3<f64>],
        velocities: &mut [Vector3<f64>],
        masses: &[f64],
        h: f64,
    ) -> Result<ProjectionInfo, ConstraintError> {
        self.project_to_tolerance(preview, velocities, masses, h, self.params.tolerance)
    }

    /// [`CellVolumeConstraints::project`] with another relative tolerance (e.g. a loose one for
    /// the intermediate rounds of a contact loop). The global solver gets a fresh workspace
    /// each call; use [`CellVolumeConstraints::project_with`] to keep one.
    pub fn project_to_tolerance(
        &self,
        preview: &mut [Point3<f64>],
        velocities: &mut [Vector3<f64>],
        masses: &[f64],
        h: f64,
        tolerance: f64,
    ) -> Result<ProjectionInfo, ConstraintError> {
        self.project_with(
            &mut CellProjectionWorkspace::new(),
            preview,
            velocities,
            masses,
            h,
            tolerance,
        )
    }

    /// [`CellVolumeConstraints::project_to_tolerance`] with a caller-owned workspace, which the
    /// global solver ([`CellSolver::Global`]) reuses across calls (the Gauss-Seidel sweeps need
    /// none and ignore it). For the global solver, [`ProjectionInfo::sweeps`] counts Newton
    /// iterations (one sparse factorisation each).
    pub fn project_with(
        &self,
        workspace: &mut CellProjectionWorkspace,
        preview: &mut [Point3<f64>],
        velocities: &mut [Vector3<f64>],
        masses: &[f64],
        h: f64,
        tolerance: f64,
    ) -> Result<ProjectionInfo, ConstraintError> {
        for (name, len) in [("velocities", velocities.len()), ("masses", masses.len())] {
            if len != preview.len() {
                return Err(ConstraintError::LengthMismatch {
                    name,
                    len,
                    expected: preview.len(),
                });
            }
        }
        match self.params.solver {
            CellSolver::GaussSeidel => {
                self.project_gauss_seidel(preview, velocities, masses, h, tolerance)
            }
            CellSolver::Global => {
                self.project_global(workspace, preview, velocities, masses, h, tolerance)
            }
        }
    }
}
