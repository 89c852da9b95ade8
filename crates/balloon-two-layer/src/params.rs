//! The physical parameters of a two-layer body beyond its geometry ([`TwoLayerParams`]): spring
//! constants per kind, gravity, valence normalisation, the collision box, restitution and the
//! blow-up bound.

use balloon_constraint::two_layer::{AxisBox, check_restitution};
use serde::{Deserialize, Serialize};

use crate::error::TwoLayerError;
use crate::model::SpringParams;

/// What [`crate::TwoLayerForces`] and [`crate::TwoLayerSimulation`] need besides the
/// [`crate::TwoLayerModel`], with documented defaults (SI units).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TwoLayerParams {
    /// Constants per [`crate::SpringKind`] (indexed by `kind as usize`). Defaults: structural
    /// 100 N/m, radius 50 N/m, shear 50 N/m, damping 0.05 N s/m each.
    pub springs: [SpringParams; 4],
    /// Gravitational acceleration (m/s^2) along minus the up axis, default 9.81.
    pub gravity: f64,
    /// Normalise the spring force sum at each particle by `mean valence / valence` (Song
    /// 2009, Sec. 3.5.3), default off. Breaks action = reaction: momentum and energy are then not
    /// conserved exactly.
    pub valence_normalization: bool,
    /// Collision box, default none.
    pub collision_box: Option<AxisBox>,
    /// Coefficient of restitution in `[0, 1]` for box and inner-layer collisions, default 0.5.
    pub restitution: f64,
    /// Blow-up bound: the step fails when the total energy exceeds the initial energy plus the
    /// work done by the drag by more than `blowup_tolerance` times the body's energy scale
    /// (see [`crate::TwoLayerForces::energy_scale`]). Default 1.
    pub blowup_tolerance: f64,
}

impl Default for TwoLayerParams {
    fn default() -> Self {
        let s = |k: f64| SpringParams {
            stiffness: k,
            damping: 0.05,
        };
        Self {
            springs: [s(100.0), s(50.0), s(50.0), s(50.0)],
            gravity: 9.81,
            valence_normalization: false,
            collision_box: None,
            restitution: 0.5,
            blowup_tolerance: 1.0,
        }
    }
}

impl TwoLayerParams {
    /// Checks every parameter; the error names the first invalid one (`structural stiffness`,
    /// `radius damping`, ..., `gravity`, `restitution`, `blowup_tolerance`, the box).
    pub fn validate(&self) -> Result<(), TwoLayerError> {
        const STIFF: [&str; 4] = [
            "structural stiffness",
            "radius stiffness",
            "shear-left stiffness",
            "shear-right stiffness",
        ];
        const DAMP: [&str; 4] = [
            "structural damping",
            "radius damping",
            "shear-left damping",
            "shear-right damping",
        ];
        for (k, s) in self.springs.iter().enumerate() {
            TwoLayerError::check_positive(STIFF[k], s.stiffness)?;
            TwoLayerError::check_non_negative(DAMP[k], s.damping)?;
        }
        if !self.gravity.is_finite() {
            return Err(TwoLayerError::InvalidParameter {
                name: "gravity",
                value: self.gravity.to_string(),
                reason: "must be finite (m/s^2)".into(),
            });
        }
        check_restitution(self.restitution)?;
        TwoLayerError::check_positive("blowup_tolerance", self.blowup_tolerance)?;
        if let Some(b) = &self.collision_box {
            AxisBox::try_new(b.min, b.max)?;
        }
        Ok(())
    }
}
