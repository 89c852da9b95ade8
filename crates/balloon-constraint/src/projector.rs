//! The projector seam of the shell balloon: [`ShellProjector`], what runs after each implicit step
//! to restore the shell's material volume (Wang et al. 2015, Algorithm 1 line 10 and Algorithm 2).
//!
//! [`ShellVolumeProjection`] (the paper's global projection, Eq. 24-28, or the per-element
//! closed form, by its [`ShellVolumeParams::scope`](crate::shell_volume::ShellVolumeParams)) and
//! [`NoProjection`] implement it; a user's own projector is one more implementation, handed to the
//! shell builder with `with_projector`. Not for the volumetric body's cell constraints (those are
//! `cell_volume`).
//!
//! ```
//! use balloon_constraint::projector::{NoProjection, ShellProjectionInput, ShellProjector};
//! use balloon_constraint::shell_volume::{ShellVolumeParams, ShellVolumeProjection, shell_volume};
//!
//! // One triangle with a thickness of 1 mm, then stretched to twice its size.
//! let tris = [[0, 1, 2]];
//! let rest = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
//! let rest_volume = shell_volume(&tris, &rest, &[1e-3]);
//! let input = ShellProjectionInput {
//!     triangles: &tris,
//!     vertex_inverse_mass: &[1.0; 3],
//!     element_inverse_mass: &[1.0],
//!     rest_shell_volume: rest_volume,
//!     rest_element_volumes: &[rest_volume],
//! };
//! let mut projectors: Vec<Box<dyn ShellProjector>> = vec![
//!     Box::new(ShellVolumeProjection::new(ShellVolumeParams::default())),
//!     Box::new(NoProjection),
//! ];
//! for p in &mut projectors {
//!     let mut x: Vec<f64> = rest.iter().map(|c| 2.0 * c).collect();
//!     let mut h = [1e-3];
//!     let info = p.project(&input, &mut x, &mut h).unwrap();
//!     let ratio = shell_volume(&tris, &x, &h) / rest_volume;
//!     assert!((info.final_ratio - ratio).abs() < 1e-9);
//! }
//! ```

use crate::ConstraintError;
use crate::shell_volume::{ProjectionInfo, ShellVolumeProjection, shell_volume};
use std::fmt::Debug;

/// What a shell projection works on, fixed over a run (the positions and thicknesses it changes
/// are passed separately).
#[derive(Clone, Copy, Debug)]
pub struct ShellProjectionInput<'a> {
    /// Triangles of the mid-surface.
    pub triangles: &'a [[usize; 3]],
    /// Inverse projection mass per vertex, `1/m'` of Algorithm 2 (0 pins a vertex).
    pub vertex_inverse_mass: &'a [f64],
    /// Inverse projection mass per element (its virtual vertex).
    pub element_inverse_mass: &'a [f64],
    /// Rest material volume of the shell, `sum_e A0_e H_e` (Eq. 26), m^3.
    pub rest_shell_volume: f64,
    /// Rest material volume per element, `A0_e H_e`, m^3.
    pub rest_element_volumes: &'a [f64],
}

/// Restores the shell's material volume after a step by changing positions (flat, m) and
/// thicknesses (one per triangle, m). On error both must be left unchanged.
pub trait ShellProjector: Send + Sync + Debug + CloneShellProjector {
    /// Projects `x` and `thickness`; reports iterations and the volume ratios before and after.
    fn project(
        &mut self,
        input: &ShellProjectionInput<'_>,
        x: &mut [f64],
        thickness: &mut [f64],
    ) -> Result<ProjectionInfo, ConstraintError>;
}

/// Cloning of boxed projectors (implemented for every `ShellProjector + Clone`).
pub trait CloneShellProjector {
    /// A boxed copy.
    fn clone_box(&self) -> Box<dyn ShellProjector>;
}

impl<T: ShellProjector + Clone + 'static> CloneShellProjector for T {
    fn clone_box(&self) -> Box<dyn ShellProjector> {
        Box::new(self.clone())
    }
}

impl Clone for Box<dyn ShellProjector> {
    fn clone(&self) -> Self {
        self.clone_box()
    }
}

impl ShellProjector for ShellVolumeProjection {
    /// Algorithm 2 (global scope) or the per-element closed form; the rest element volumes come
    /// from the input unless set with [`ShellVolumeProjection::with_rest_element_volumes`].
    fn project(
        &mut self,
        input: &ShellProjectionInput<'_>,
        x: &mut [f64],
        thickness: &mut [f64],
    ) -> Result<ProjectionInfo, ConstraintError> {
        if !self.has_rest_element_volumes() {
            self.set_rest_element_volumes(input.rest_element_volumes);
        }
        ShellVolumeProjection::project(
            self,
            input.triangles,
            x,
            thickness,
            input.vertex_inverse_mass,
            input.element_inverse_mass,
            input.rest_shell_volume,
        )
    }
}

/// No projection: the thickness stays at its rest value and positions are not moved (the shell
/// loses material volume as it stretches).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NoProjection;

impl ShellProjector for NoProjection {
    fn project(
        &mut self,
        input: &ShellProjectionInput<'_>,
        x: &mut [f64],
        thickness: &mut [f64],
    ) -> Result<ProjectionInfo, ConstraintError> {
        let ratio = shell_volume(input.triangles, x, thickness) / input.rest_shell_volume;
        Ok(ProjectionInfo {
            iterations: 0,
            initial_ratio: ratio,
            final_ratio: ratio,
        })
    }
}
