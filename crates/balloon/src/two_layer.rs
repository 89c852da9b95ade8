//! Two-layer elastic objects (Song 2009, "Dynamic Deformation of Uniform Elastic Two-Layer
//! Objects"): the builder [`TwoLayerBody`] (shape, radii, masses, spring constants per
//! [`SpringKind`], pressures, gravity, collision box, restitution, with documented defaults)
//! composes the stage crate `balloon-two-layer`, which holds the model ([`TwoLayerModel`]), the
//! forces ([`TwoLayerForces`]) and the stepping ([`TwoLayerSimulation`], explicit integrators,
//! box collisions and the inner layer kept inside the outer one); they are re-exported here.
//!
//! ```
//! use balloon::two_layer::{TwoLayerBody, ExplicitMethod};
//! let body = TwoLayerBody::octahedron_sphere(1)
//!     .with_radii(0.8, 1.0)
//!     .with_pressure(200.0, 200.0);
//! let mut sim = body.simulate(ExplicitMethod::Rk4, 1e-3).unwrap();
//! let stats = sim.step().unwrap();
//! assert!(stats.volume_outer > stats.volume_inner);
//! ```
//!
//! The particle layout and the gas are described in the `balloon-two-layer` crate docs.

pub use balloon_constraint::two_layer::AxisBox;
pub use balloon_two_layer::{
    AnchorSpring, BlowUpReason, Dimension, DragTarget, EnergyBreakdown, ExplicitMethod, Spring,
    SpringKind, SpringParams, TwoLayerError, TwoLayerForces, TwoLayerModel, TwoLayerParams,
    TwoLayerSimulation, TwoLayerStats, analytic,
};
use nalgebra::Point3;
use serde::{Deserialize, Serialize};

#[cfg(test)]
mod tests;

/// Shape of a two-layer object.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Shape {
    /// 1D: particle 0 fixed at the centre, particle 1 hanging `length` (m) below it along `-x`.
    Line {
        /// Rest length of the spring (m).
        length: f64,
    },
    /// 2D circle with `particles` per layer (>= 3), counter-clockwise in the `xy` plane.
    Circle {
        /// Particles per layer.
        particles: usize,
    },
    /// 3D UV sphere (Song 2009, Sec. 3.5.1) with `slices` meridians and `stacks` bands, poles on
    /// `z`.
    UvSphere {
        /// Meridians (>= 3).
        slices: usize,
        /// Latitude bands (>= 2).
        stacks: usize,
    },
    /// 3D octahedron subdivided `level` times (Song 2009, Sec. 3.5.2), `4^(level+1) + 2` particles
    /// per layer.
    OctahedronSphere {
        /// Subdivision level (<= 7 here).
        level: u32,
    },
}

impl Shape {
    /// The dimension of the shape.
    pub fn dimension(&self) -> Dimension {
        match self {
            Shape::Line { .. } => Dimension::One,
            Shape::Circle { .. } => Dimension::Two,
            Shape::UvSphere { .. } | Shape::OctahedronSphere { .. } => Dimension::Three,
        }
    }
}

/// Builder of a two-layer object: geometry and all physical parameters, with documented
/// defaults (SI units). `build` validates and returns a [`TwoLayerModel`]; `simulate` also
/// creates a [`TwoLayerSimulation`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TwoLayerBody {
    /// Shape.
    pub shape: Shape,
    /// Inner layer radius (m), default 0.8. Ignored in 1D.
    pub inner_radius: f64,
    /// Outer layer radius (m), default 1.0. Ignored in 1D.
    pub outer_radius: f64,
    /// Mass of each inner particle (kg), default 0.01.
    pub inner_mass: f64,
    /// Mass of each outer particle (kg), default 0.01 (the 1D free particle has this mass).
    pub outer_mass: f64,
    /// Constants per [`SpringKind`] (indexed by `kind as usize`). Defaults: structural
    /// 100 N/m, radius 50 N/m, shear 50 N/m, damping 0.05 N s/m each.
    pub springs: [SpringParams; 4],
    /// Initial gas pressure in the outer layer at its rest volume (Pa; N/m per unit depth in
    /// 2D), default 0. Sets `(nRT)_outer = P V0`.
    pub outer_pressure: f64,
    /// Initial gas pressure in the inner layer at its rest volume, default 0.
    pub inner_pressure: f64,
    /// Gravitational acceleration (m/s^2) along minus the up axis, default 9.81.
    pub gravity: f64,
    /// Centre of the body at rest (m), default the origin.
    pub center: Point3<f64>,
    /// Collision box, default none.
    pub collision_box: Option<AxisBox>,
    /// Coefficient of restitution in `[0, 1]` for box and inner-layer collisions, default 0.5.
    pub restitution: f64,
    /// Normalise the spring force sum at each particle by `mean valence / valence` (Song
    /// 2009, Sec. 3.5.3), default off. Breaks action = reaction: momentum and energy are then not
    /// conserved exactly.
    pub valence_normalization: bool,
    /// Blow-up bound: the step fails when the total energy exceeds the initial energy plus the
    /// work done by the drag by more than `blowup_tolerance` times the body's energy scale
    /// (see [`TwoLayerForces::energy_scale`]). Default 1.
    pub blowup_tolerance: f64,
}

impl TwoLayerBody {
    fn with_shape(shape: Shape) -> Self {
        let p = TwoLayerParams::default();
        Self {
            shape,
            inner_radius: 0.8,
            outer_radius: 1.0,
            inner_mass: 0.01,
            outer_mass: 0.01,
            springs: p.springs,
            outer_pressure: 0.0,
            inner_pressure: 0.0,
            gravity: p.gravity,
            center: Point3::origin(),
            collision_box: p.collision_box,
            restitution: p.restitution,
            valence_normalization: p.valence_normalization,
            blowup_tolerance: p.blowup_tolerance,
        }
    }

    /// 1D object: one spring of rest `length` (m), top end fixed (Song 2009, Sec. 3.3).
    pub fn line(length: f64) -> Self {
        Self::with_shape(Shape::Line { length })
    }

    /// 2D two-layer circle with `particles` per layer (Song 2009, Sec. 3.4).
    pub fn circle(particles: usize) -> Self {
        Self::with_shape(Shape::Circle { particles })
    }

    /// 3D two-layer UV sphere (Song 2009, Sec. 3.5.1).
    pub fn uv_sphere(slices: usize, stacks: usize) -> Self {
        Self::with_shape(Shape::UvSphere { slices, stacks })
    }

    /// 3D two-layer subdivided-octahedron sphere (Song 2009, Sec. 3.5.2).
    pub fn octahedron_sphere(level: u32) -> Self {
        Self::with_shape(Shape::OctahedronSphere { level })
    }

    /// Sets the inner and outer radii (m).
    pub fn with_radii(mut self, inner: f64, outer: f64) -> Self {
        self.inner_radius = inner;
        self.outer_radius = outer;
        self
    }

    /// Sets the per-particle masses of the inner and outer layers (kg).
    pub fn with_masses(mut self, inner: f64, outer: f64) -> Self {
        self.inner_mass = inner;
        self.outer_mass = outer;
        self
    }

    /// Sets stiffness (N/m) and damping (N s/m) of one spring type.
    pub fn with_spring(mut self, kind: SpringKind, stiffness: f64, damping: f64) -> Self {
        self.springs[kind as usize] = SpringParams { stiffness, damping };
        self
    }

    /// Sets the damping of every spring type (N s/m).
    pub fn with_damping(mut self, damping: f64) -> Self {
        for s in &mut self.springs {
            s.damping = damping;
        }
        self
    }

    /// Sets the initial pressures (Pa) of the outer and inner gas at the rest volumes.
    pub fn with_pressure(mut self, outer: f64, inner: f64) -> Self {
        self.outer_pressure = outer;
        self.inner_pressure = inner;
        self
    }

    /// Sets gravity (m/s^2, along minus the up axis; 0 for none).
    pub fn with_gravity(mut self, gravity: f64) -> Self {
        self.gravity = gravity;
        self
    }

    /// Sets the rest centre (m).
    pub fn with_center(mut self, center: Point3<f64>) -> Self {
        self.center = center;
        self
    }

    /// Sets (or removes) the collision box.
    pub fn with_box(mut self, collision_box: Option<AxisBox>) -> Self {
        self.collision_box = collision_box;
        self
    }

    /// Sets the coefficient of restitution in `[0, 1]`.
    pub fn with_restitution(mut self, restitution: f64) -> Self {
        self.restitution = restitution;
        self
    }

    /// Turns valence normalisation of spring forces on or off (Song 2009, Sec. 3.5.3).
    pub fn with_valence_normalization(mut self, on: bool) -> Self {
        self.valence_normalization = on;
        self
    }

    /// Sets the blow-up tolerance (relative to the energy scale).
    pub fn with_blowup_tolerance(mut self, tolerance: f64) -> Self {
        self.blowup_tolerance = tolerance;
        self
    }

    /// Validates the parameters and builds particles, springs and layers
    /// ([`TwoLayerModel::line`], [`TwoLayerModel::circle`],
    /// [`TwoLayerModel::from_unit_sphere`]), filled with gas at the initial pressures.
    pub fn build(&self) -> Result<TwoLayerModel, TwoLayerError> {
        self.validate()?;
        let (c, radii) = (self.center, [self.inner_radius, self.outer_radius]);
        let masses = [self.inner_mass, self.outer_mass];
        let invalid = |name: &'static str, value: String, reason: &str| {
            Err(TwoLayerError::InvalidParameter {
                name,
                value,
                reason: reason.into(),
            })
        };
        let model = match self.shape {
            Shape::Line { length } => {
                let length = TwoLayerError::check_positive("length", length)?;
                TwoLayerModel::line(c, length, self.outer_mass)
            }
            Shape::Circle { particles } => {
                if !(3..=1_000_000).contains(&particles) {
                    let reason = "a 2D circle needs between 3 and 1000000 particles per layer";
                    return invalid("particles", particles.to_string(), reason);
                }
                TwoLayerModel::circle(particles, c, radii, masses)
            }
            Shape::UvSphere { slices, stacks } => {
                if slices > 2000 || stacks > 2000 {
                    let value = format!("{slices}/{stacks}");
                    return invalid("slices/stacks", value, "at most 2000 each");
                }
                let mesh = balloon_mesh::generate::uv_sphere(1.0, slices, stacks)?;
                TwoLayerModel::from_unit_sphere(mesh, c, radii, masses)
            }
            Shape::OctahedronSphere { level } => {
                if level > 7 {
                    let reason = "at most 7 (65538 particles per layer)";
                    return invalid("level", level.to_string(), reason);
                }
                let mesh = balloon_mesh::generate::octahedron_sphere(1.0, level)?;
                TwoLayerModel::from_unit_sphere(mesh, c, radii, masses)
            }
        };
        Ok(model.with_pressures(self.outer_pressure, self.inner_pressure))
    }

    /// Builds the body and a simulation of it at rest with `method` and time step `dt` (s).
    pub fn simulate(
        &self,
        method: ExplicitMethod,
        dt: f64,
    ) -> Result<TwoLayerSimulation, TwoLayerError> {
        TwoLayerError::check_positive("dt", dt)?;
        TwoLayerSimulation::new(self.build()?, self, method, dt)
    }

    /// The physical parameters beyond the geometry (springs, gravity, valence normalisation,
    /// box, restitution, blow-up bound).
    pub fn params(&self) -> TwoLayerParams {
        TwoLayerParams {
            springs: self.springs,
            gravity: self.gravity,
            valence_normalization: self.valence_normalization,
            collision_box: self.collision_box,
            restitution: self.restitution,
            blowup_tolerance: self.blowup_tolerance,
        }
    }

    fn validate(&self) -> Result<(), TwoLayerError> {
        let positive = TwoLayerError::check_positive;
        positive("inner_mass", self.inner_mass)?;
        positive("outer_mass", self.outer_mass)?;
        if self.shape.dimension() != Dimension::One {
            positive("inner_radius", self.inner_radius)?;
            positive("outer_radius", self.outer_radius)?;
            if self.inner_radius >= self.outer_radius {
                return Err(TwoLayerError::InvalidParameter {
                    name: "inner_radius",
                    value: self.inner_radius.to_string(),
                    reason: format!("must be below the outer radius {} m", self.outer_radius),
                });
            }
        }
        TwoLayerError::check_non_negative("outer_pressure", self.outer_pressure)?;
        TwoLayerError::check_non_negative("inner_pressure", self.inner_pressure)?;
        if !(self.center.coords.iter().all(|c| c.is_finite())) {
            return Err(TwoLayerError::InvalidParameter {
                name: "center",
                value: format!("{:?}", self.center),
                reason: "must be finite".into(),
            });
        }
        self.params().validate()
    }
}

impl From<&TwoLayerBody> for TwoLayerParams {
    fn from(body: &TwoLayerBody) -> Self {
        body.params()
    }
}
