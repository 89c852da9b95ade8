//! Builders of two-layer objects (seed 004, Ch. 3): the 1D spring, the 2D two-layer circle and
//! the 3D two-layer spheres (UV and subdivided octahedron).

use super::{TwoLayerError, non_negative, positive};
use balloon_constraint::two_layer::{AxisBox, check_restitution};
use balloon_mesh::TriMesh;
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;

/// Spatial dimension of a two-layer object.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Dimension {
    /// Two particles on the `x` axis, one spring, motion along `x` only (seed Sec. 3.3).
    One,
    /// Two concentric polygons in the `xy` plane, motion in the plane (seed Sec. 3.4).
    Two,
    /// Two concentric closed triangle meshes (seed Sec. 3.5).
    Three,
}

impl Dimension {
    /// Index of the "up" axis: gravity pulls along minus this axis (`x` in 1D, so the 1D spring
    /// hangs; `y` in 2D; `z` in 3D).
    pub fn up_axis(self) -> usize {
        match self {
            Dimension::One => 0,
            Dimension::Two => 1,
            Dimension::Three => 2,
        }
    }

    /// Number of coordinates a particle may move along (1, 2 or 3).
    pub fn free_axes(self) -> usize {
        match self {
            Dimension::One => 1,
            Dimension::Two => 2,
            Dimension::Three => 3,
        }
    }
}

/// The type of a spring (seed Sec. 3.4.1, Fig. 3.4); each type has its own constants.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum SpringKind {
    /// Along a layer (mesh edges / polygon sides): keeps the layer's shape.
    Structural = 0,
    /// From an inner particle to its outer partner: resists bending.
    Radius = 1,
    /// From inner particle `a` to the outer partner of its neighbour `b` (`a < b` in 3D, `b` the
    /// next particle in 2D): resists shear / fold-over.
    ShearLeft = 2,
    /// From inner particle `b` to the outer partner of its neighbour `a`.
    ShearRight = 3,
}

impl SpringKind {
    /// All kinds, indexable by `kind as usize`.
    pub const ALL: [SpringKind; 4] = [
        SpringKind::Structural,
        SpringKind::Radius,
        SpringKind::ShearLeft,
        SpringKind::ShearRight,
    ];

    /// Lowercase name.
    pub fn name(self) -> &'static str {
        match self {
            SpringKind::Structural => "structural",
            SpringKind::Radius => "radius",
            SpringKind::ShearLeft => "shear-left",
            SpringKind::ShearRight => "shear-right",
        }
    }
}

/// Constants of one spring type: Hooke stiffness `k_s` (N/m, seed Eq. 4.2) and damping `k_d`
/// (N s/m, seed Eq. 4.5).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SpringParams {
    /// Stiffness (N/m), > 0.
    pub stiffness: f64,
    /// Damping coefficient (N s/m), >= 0.
    pub damping: f64,
}

/// One spring between particles `a` and `b`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Spring {
    /// First particle.
    pub a: usize,
    /// Second particle.
    pub b: usize,
    /// Rest length (m), the distance in the rest configuration.
    pub rest_length: f64,
    /// Type (selects the constants).
    pub kind: SpringKind,
}

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
    /// 3D UV sphere (seed Sec. 3.5.1) with `slices` meridians and `stacks` bands, poles on `z`.
    UvSphere {
        /// Meridians (>= 3).
        slices: usize,
        /// Latitude bands (>= 2).
        stacks: usize,
    },
    /// 3D octahedron subdivided `level` times (seed Sec. 3.5.2), `4^(level+1) + 2` particles per
    /// layer.
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
/// creates a [`super::TwoLayerSimulation`].
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
    /// Normalise the spring force sum at each particle by `mean valence / valence` (seed
    /// Sec. 3.5.3), default off. Breaks action = reaction: momentum and energy are then not
    /// conserved exactly.
    pub valence_normalization: bool,
    /// Blow-up bound: the step fails when the total energy exceeds the initial energy plus the
    /// work done by the drag by more than `blowup_tolerance` times the body's energy scale
    /// (see [`super::TwoLayerForces::energy_scale`]). Default 1.
    pub blowup_tolerance: f64,
}

impl TwoLayerBody {
    fn with_shape(shape: Shape) -> Self {
        let s = |k: f64| SpringParams {
            stiffness: k,
            damping: 0.05,
        };
        Self {
            shape,
            inner_radius: 0.8,
            outer_radius: 1.0,
            inner_mass: 0.01,
            outer_mass: 0.01,
            springs: [s(100.0), s(50.0), s(50.0), s(50.0)],
            outer_pressure: 0.0,
            inner_pressure: 0.0,
            gravity: 9.81,
            center: Point3::origin(),
            collision_box: None,
            restitution: 0.5,
            valence_normalization: false,
            blowup_tolerance: 1.0,
        }
    }

    /// 1D object: one spring of rest `length` (m), top end fixed (seed Sec. 3.3).
    pub fn line(length: f64) -> Self {
        Self::with_shape(Shape::Line { length })
    }

    /// 2D two-layer circle with `particles` per layer (seed Sec. 3.4).
    pub fn circle(particles: usize) -> Self {
        Self::with_shape(Shape::Circle { particles })
    }

    /// 3D two-layer UV sphere (seed Sec. 3.5.1).
    pub fn uv_sphere(slices: usize, stacks: usize) -> Self {
        Self::with_shape(Shape::UvSphere { slices, stacks })
    }

    /// 3D two-layer subdivided-octahedron sphere (seed Sec. 3.5.2).
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

    /// Turns valence normalisation of spring forces on or off (seed Sec. 3.5.3).
    pub fn with_valence_normalization(mut self, on: bool) -> Self {
        self.valence_normalization = on;
        self
    }

    /// Sets the blow-up tolerance (relative to the energy scale).
    pub fn with_blowup_tolerance(mut self, tolerance: f64) -> Self {
        self.blowup_tolerance = tolerance;
        self
    }

    /// Validates the parameters and builds particles, springs and layers.
    pub fn build(&self) -> Result<TwoLayerModel, TwoLayerError> {
        self.validate()?;
        let c = self.center.coords;
        let mut m = match self.shape {
            Shape::Line { length } => {
                let length = positive("length", length)?;
                TwoLayerModel {
                    dimension: Dimension::One,
                    rest_positions: vec![c.x, c.y, c.z, c.x - length, c.y, c.z],
                    masses: vec![self.outer_mass, self.outer_mass],
                    fixed: vec![true, false],
                    springs: vec![Spring {
                        a: 0,
                        b: 1,
                        rest_length: length,
                        kind: SpringKind::Structural,
                    }],
                    layer_size: 0,
                    surface: Vec::new(),
                    gas_outer: 0.0,
                    gas_inner: 0.0,
                    rest_volume_outer: 0.0,
                    rest_volume_inner: 0.0,
                }
            }
            Shape::Circle { particles } => {
                if !(3..=1_000_000).contains(&particles) {
                    return Err(TwoLayerError::InvalidParameter {
                        name: "particles",
                        value: particles.to_string(),
                        reason: "a 2D circle needs between 3 and 1000000 particles per layer"
                            .into(),
                    });
                }
                let unit: Vec<Vector3<f64>> = (0..particles)
                    .map(|i| {
                        let a = std::f64::consts::TAU * i as f64 / particles as f64;
                        Vector3::new(a.cos(), a.sin(), 0.0)
                    })
                    .collect();
                let edges: Vec<[usize; 2]> =
                    (0..particles).map(|i| [i, (i + 1) % particles]).collect();
                self.layered(Dimension::Two, &unit, &edges, Vec::new())
            }
            Shape::UvSphere { slices, stacks } => {
                if slices > 2000 || stacks > 2000 {
                    return Err(TwoLayerError::InvalidParameter {
                        name: "slices/stacks",
                        value: format!("{slices}/{stacks}"),
                        reason: "at most 2000 each".into(),
                    });
                }
                let mesh = balloon_mesh::generate::uv_sphere(1.0, slices, stacks)?;
                self.layered_from_mesh(mesh)
            }
            Shape::OctahedronSphere { level } => {
                if level > 7 {
                    return Err(TwoLayerError::InvalidParameter {
                        name: "level",
                        value: level.to_string(),
                        reason: "at most 7 (65538 particles per layer)".into(),
                    });
                }
                let mesh = balloon_mesh::generate::octahedron_sphere(1.0, level)?;
                self.layered_from_mesh(mesh)
            }
        };
        if m.dimension != Dimension::One {
            m.rest_volume_outer = m.layer_volume(&m.rest_positions, true);
            m.rest_volume_inner = m.layer_volume(&m.rest_positions, false);
            m.gas_outer = self.outer_pressure * m.rest_volume_outer;
            m.gas_inner = self.inner_pressure * m.rest_volume_inner;
        }
        Ok(m)
    }

    fn layered_from_mesh(&self, mesh: TriMesh) -> TwoLayerModel {
        let unit: Vec<Vector3<f64>> = mesh.vertices.iter().map(|p| p.coords).collect();
        let mut edges = BTreeSet::new();
        for t in &mesh.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                edges.insert([a.min(b), a.max(b)]);
            }
        }
        let edges: Vec<[usize; 2]> = edges.into_iter().collect();
        self.layered(Dimension::Three, &unit, &edges, mesh.triangles)
    }

    /// Two layers on the unit directions `unit`, springs per seed Sec. 3.4.2 / 3.5.2: structural
    /// springs on `edges` of each layer, one radius spring per pair, and for each edge `(a, b)`
    /// a left shear spring inner `a` - outer `b` and a right one inner `b` - outer `a`.
    fn layered(
        &self,
        dimension: Dimension,
        unit: &[Vector3<f64>],
        edges: &[[usize; 2]],
        surface: Vec<[usize; 3]>,
    ) -> TwoLayerModel {
        let n = unit.len();
        let c = self.center.coords;
        let mut rest_positions = Vec::with_capacity(6 * n);
        for (radius, _) in [(self.inner_radius, 0), (self.outer_radius, 1)] {
            for u in unit {
                let p = c + u * radius;
                rest_positions.extend_from_slice(&[p.x, p.y, p.z]);
            }
        }
        let dist = |a: usize, b: usize| {
            let d = Vector3::new(
                rest_positions[3 * a] - rest_positions[3 * b],
                rest_positions[3 * a + 1] - rest_positions[3 * b + 1],
                rest_positions[3 * a + 2] - rest_positions[3 * b + 2],
            );
            d.norm()
        };
        let mut springs = Vec::with_capacity(4 * edges.len() + n);
        let mut push = |a: usize, b: usize, kind: SpringKind| {
            springs.push(Spring {
                a,
                b,
                rest_length: dist(a, b),
                kind,
            });
        };
        for layer in 0..2 {
            for &[a, b] in edges {
                push(layer * n + a, layer * n + b, SpringKind::Structural);
            }
        }
        for j in 0..n {
            push(j, n + j, SpringKind::Radius);
        }
        for &[a, b] in edges {
            push(a, n + b, SpringKind::ShearLeft);
            push(b, n + a, SpringKind::ShearRight);
        }
        let mut masses = vec![self.inner_mass; n];
        masses.extend(std::iter::repeat_n(self.outer_mass, n));
        TwoLayerModel {
            dimension,
            rest_positions,
            masses,
            fixed: vec![false; 2 * n],
            springs,
            layer_size: n,
            surface,
            gas_outer: 0.0,
            gas_inner: 0.0,
            rest_volume_outer: 0.0,
            rest_volume_inner: 0.0,
        }
    }

    fn validate(&self) -> Result<(), TwoLayerError> {
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
            positive(STIFF[k], s.stiffness)?;
            non_negative(DAMP[k], s.damping)?;
        }
        non_negative("outer_pressure", self.outer_pressure)?;
        non_negative("inner_pressure", self.inner_pressure)?;
        if !self.gravity.is_finite() {
            return Err(TwoLayerError::InvalidParameter {
                name: "gravity",
                value: self.gravity.to_string(),
                reason: "must be finite (m/s^2)".into(),
            });
        }
        if !(self.center.coords.iter().all(|c| c.is_finite())) {
            return Err(TwoLayerError::InvalidParameter {
                name: "center",
                value: format!("{:?}", self.center),
                reason: "must be finite".into(),
            });
        }
        check_restitution(self.restitution)?;
        positive("blowup_tolerance", self.blowup_tolerance)?;
        if let Some(b) = &self.collision_box {
            AxisBox::try_new(b.min, b.max)?;
        }
        Ok(())
    }
}

/// A built two-layer object: particles, springs and layers (seed Ch. 3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TwoLayerModel {
    /// Dimension.
    pub dimension: Dimension,
    /// Rest positions, flat `[x0, y0, z0, ...]` (m).
    pub rest_positions: Vec<f64>,
    /// Particle masses (kg).
    pub masses: Vec<f64>,
    /// Fixed particles (never move).
    pub fixed: Vec<bool>,
    /// Springs.
    pub springs: Vec<Spring>,
    /// Particles per layer (`n`; 0 in 1D). Inner layer `0..n`, outer `n..2n`.
    pub layer_size: usize,
    /// 3D layer connectivity (local indices `0..n`, outward oriented), shared by both layers;
    /// empty in 1D and 2D (the 2D layers are the polygons `0, 1, ..., n-1`).
    pub surface: Vec<[usize; 3]>,
    /// `nRT` of the outer gas (J; J/m in 2D).
    pub gas_outer: f64,
    /// `nRT` of the inner gas.
    pub gas_inner: f64,
    /// Outer volume at rest (m^3; m^2 in 2D).
    pub rest_volume_outer: f64,
    /// Inner volume at rest.
    pub rest_volume_inner: f64,
}

impl TwoLayerModel {
    /// Number of particles.
    pub fn num_particles(&self) -> usize {
        self.masses.len()
    }

    /// Whether the object has two closed layers (2D and 3D).
    pub fn has_layers(&self) -> bool {
        self.layer_size > 0
    }

    /// Volume enclosed by the outer (`outer = true`) or inner layer for flat positions `x`:
    /// the divergence theorem in 3D, `V = 1/6 sum_f x_a . (x_b x x_c)` (seed Eq. 4.12-4.16),
    /// Green's theorem in 2D, `A = 1/2 sum_i (x_i y_(i+1) - x_(i+1) y_i)`. 0 in 1D.
    pub fn layer_volume(&self, x: &[f64], outer: bool) -> f64 {
        let n = self.layer_size;
        let layer = if outer { &x[3 * n..6 * n] } else { &x[..3 * n] };
        match self.dimension {
            Dimension::One => 0.0,
            Dimension::Two => balloon_gas::layer::polygon_area(layer),
            // NaN for a model whose surface indices are out of range (never from `build`).
            Dimension::Three => {
                balloon_gas::enclosed_volume(layer, &self.surface).unwrap_or(f64::NAN)
            }
        }
    }

    /// Triangles for drawing, in global particle indices: in 3D the outer and the inner
    /// surface (both outward oriented); in 2D the quads between the layers split into two
    /// triangles each (seed Fig. 3.5); none in 1D.
    pub fn draw_triangles(&self) -> Vec<[usize; 3]> {
        let n = self.layer_size;
        match self.dimension {
            Dimension::One => Vec::new(),
            Dimension::Two => (0..n)
                .flat_map(|i| {
                    let j = (i + 1) % n;
                    [[i, n + i, n + j], [i, n + j, j]]
                })
                .collect(),
            Dimension::Three => self
                .surface
                .iter()
                .map(|t| [n + t[0], n + t[1], n + t[2]])
                .chain(self.surface.iter().copied())
                .collect(),
        }
    }

    /// Number of springs of each kind (indexed by `kind as usize`).
    pub fn spring_counts(&self) -> [usize; 4] {
        let mut c = [0; 4];
        for s in &self.springs {
            c[s.kind as usize] += 1;
        }
        c
    }

    /// Number of springs attached to each particle (its valence).
    pub fn valences(&self) -> Vec<usize> {
        let mut v = vec![0; self.num_particles()];
        for s in &self.springs {
            v[s.a] += 1;
            v[s.b] += 1;
        }
        v
    }
}
