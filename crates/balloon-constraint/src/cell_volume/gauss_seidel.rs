//! The Gauss-Seidel sweeps of the paper (Eq. 2-4): one cell at a time, scaled about its centre
//! or moved along its mass-weighted volume gradient, optionally over-relaxed.

use super::cells::{CellVolumeConstraints, cell_volume, volume_and_gradient};
use super::params::{CellCentre, CellCorrection, ProjectionInfo, adaptive_step};
use crate::ConstraintError;
use nalgebra::{Point3, Vector3};

impl CellVolumeConstraints {
    /// The Gauss-Seidel sweeps of [`CellVolumeConstraints::project`].
    pub(crate) fn project_gauss_seidel(
        &self,
        preview: &mut [Point3<f64>],
        velocities: &mut [Vector3<f64>],
        masses: &[f64],
        h: f64,
        tolerance: f64,
    ) -> Result<ProjectionInfo, ConstraintError> {
        if let Some(e) = self.find_inverted(preview) {
            return Err(e);
        }
        let (initial_error, _) = self.max_relative_error(preview);
        let mut info = ProjectionInfo {
            sweeps: 0,
            initial_error,
            final_error: initial_error,
        };
        if initial_error <= tolerance {
            return Ok(info);
        }
        // Largest errors after each sweep, for the adaptive over-relaxation.
        let mut omega = self.params.over_relaxation;
        let mut history: Vec<f64> = vec![initial_error];
        let mut adapted_at: Option<usize> = None;
        for sweep in 1..=self.params.max_sweeps {
            for (c, cell) in self.cells.iter().enumerate() {
                let v = cell_volume(preview, &self.tets[c]);
                if v.is_nan() || v <= 0.0 {
                    return Err(ConstraintError::Inverted {
                        cell: c,
                        tet: 0,
                        volume: v,
                    });
                }
                // A fixed corner (infinite mass) cannot follow a scaling about the centre: such
                // a cell is corrected along the gradient, where that corner's weight is zero.
                if self.params.correction == CellCorrection::Gradient
                    || cell.iter().any(|&i| masses[i] == f64::INFINITY)
                {
                    self.gradient_correction(c, v, omega, preview, velocities, masses, h);
                    continue;
                }
                let lambda = if omega == 1.0 {
                    (self.rest_volumes[c] / v).cbrt()
                } else {
                    (self.rest_volumes[c] / v).powf(omega / 3.0)
                };
                let centre = self.centre(preview, masses, cell);
                for &i in cell {
                    let dx = (preview[i].coords - centre) * (lambda - 1.0);
                    preview[i] += dx;
                    velocities[i] += dx / h;
                }
            }
            if let Some(e) = self.find_inverted(preview) {
                return Err(e);
            }
            let (err, cell) = self.max_relative_error(preview);
            info.sweeps = sweep;
            info.final_error = err;
            if err <= tolerance {
                return Ok(info);
            }
            if self.params.adaptive_relaxation {
                history.push(err);
                if let Some(next) = adaptive_step(&history, omega, &mut adapted_at) {
                    omega = next;
                }
            }
            if sweep == self.params.max_sweeps {
                return Err(ConstraintError::CellVolumeNotConverged {
                    sweeps: sweep,
                    max_error: err,
                    cell,
                });
            }
        }
        Ok(info)
    }

    /// One mass-weighted gradient step for cell `c` of current volume `v` (see
    /// [`CellCorrection::Gradient`]), scaled by the over-relaxation factor `omega`.
    #[allow(clippy::too_many_arguments)]
    fn gradient_correction(
        &self,
        c: usize,
        v: f64,
        omega: f64,
        preview: &mut [Point3<f64>],
        velocities: &mut [Vector3<f64>],
        masses: &[f64],
        h: f64,
    ) {
        let cell = &self.cells[c];
        let mut grad = [Vector3::zeros(); 8];
        volume_and_gradient(preview, cell, &self.tets[c], &mut grad);
        let denom: f64 = cell
            .iter()
            .zip(&grad)
            .map(|(&i, g)| g.norm_squared() / masses[i])
            .sum();
        if denom.is_nan() || denom <= 0.0 {
            return;
        }
        let s = omega * (v - self.rest_volumes[c]) / denom;
        for (&i, g) in cell.iter().zip(&grad) {
            let dx = -g * (s / masses[i]);
            preview[i] += dx;
            velocities[i] += dx / h;
        }
    }

    fn centre(&self, x: &[Point3<f64>], masses: &[f64], cell: &[usize; 8]) -> Vector3<f64> {
        match self.params.centre {
            CellCentre::Arithmetic => {
                cell.iter().fold(Vector3::zeros(), |a, &i| a + x[i].coords) / 8.0
            }
            CellCentre::MassWeighted => {
                let m: f64 = cell.iter().map(|&i| masses[i]).sum();
                cell.iter()
                    .fold(Vector3::zeros(), |a, &i| a + x[i].coords * masses[i])
                    / m
            }
        }
    }
}
