//! The model of a two-layer object (Song 2009, Ch. 3): particles, springs by kind, and the two
//! closed layers with their gas; built as the 1D spring, the 2D two-layer circle or two 3D
//! layers on a unit sphere mesh (UV sphere or subdivided octahedron).

use crate::error::TwoLayerError;
use balloon_mesh::TriMesh;
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;

/// Spatial dimension of a two-layer object.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Dimension {
    /// Two particles on the `x` axis, one spring, motion along `x` only (Song 2009, Sec. 3.3).
    One,
    /// Two concentric polygons in the `xy` plane, motion in the plane (Song 2009, Sec. 3.4).
    Two,
    /// Two concentric closed triangle meshes (Song 2009, Sec. 3.5).
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

/// The type of a spring (Song 2009, Sec. 3.4.1, Fig. 3.4); each type has its own constants.
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

/// Constants of one spring type: Hooke stiffness `k_s` (N/m, Song 2009, Eq. 4.2) and damping `k_d`
/// (N s/m, Song 2009, Eq. 4.5).
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

/// The layout of the two layers of [`TwoLayerModel::layered`]: unit directions, the edges of one
/// layer, and (in 3D) its outward triangles.
#[derive(Clone, Debug)]
pub struct Layers<'a> {
    /// [`Dimension::Two`] or [`Dimension::Three`].
    pub dimension: Dimension,
    /// One unit direction from the centre per particle of a layer.
    pub unit: &'a [Vector3<f64>],
    /// The edges of one layer (local indices): its structural springs.
    pub edges: &'a [[usize; 2]],
    /// The outward triangles of a 3D layer (local indices); empty in 2D, where the layer is the
    /// polygon `0, 1, ..., n - 1`.
    pub surface: Vec<[usize; 3]>,
}

/// A built two-layer object: particles, springs and layers (Song 2009, Ch. 3).
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
    /// 1D object (Song 2009, Sec. 3.3): particle 0 fixed at `center`, particle 1 hanging `length`
    /// (m) below it along `-x`, one structural spring between them; both particles of mass `mass`
    /// (kg).
    pub fn line(center: Point3<f64>, length: f64, mass: f64) -> Self {
        let c = center.coords;
        TwoLayerModel {
            dimension: Dimension::One,
            rest_positions: vec![c.x, c.y, c.z, c.x - length, c.y, c.z],
            masses: vec![mass, mass],
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

    /// Two 2D layers (Song 2009, Sec. 3.4): concentric counter-clockwise polygons of `particles`
    /// particles each in the `xy` plane about `center`; see [`TwoLayerModel::layered`] for the
    /// springs.
    pub fn circle(
        particles: usize,
        center: Point3<f64>,
        radii: [f64; 2],
        masses: [f64; 2],
    ) -> Self {
        let unit: Vec<Vector3<f64>> = (0..particles)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / particles as f64;
                Vector3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let edges: Vec<[usize; 2]> = (0..particles).map(|i| [i, (i + 1) % particles]).collect();
        let layers = Layers {
            dimension: Dimension::Two,
            unit: &unit,
            edges: &edges,
            surface: Vec::new(),
        };
        Self::layered(layers, center, radii, masses)
    }

    /// Two 3D layers on the vertices of a unit sphere `mesh` (Song 2009, Sec. 3.5): its vertices
    /// are the unit directions and its outward triangles the layers' connectivity; see
    /// [`TwoLayerModel::layered`] for the springs.
    pub fn from_unit_sphere(
        mesh: TriMesh,
        center: Point3<f64>,
        radii: [f64; 2],
        masses: [f64; 2],
    ) -> Self {
        let unit: Vec<Vector3<f64>> = mesh.vertices.iter().map(|p| p.coords).collect();
        let mut edges = BTreeSet::new();
        for t in &mesh.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                edges.insert([a.min(b), a.max(b)]);
            }
        }
        let edges: Vec<[usize; 2]> = edges.into_iter().collect();
        let layers = Layers {
            dimension: Dimension::Three,
            unit: &unit,
            edges: &edges,
            surface: mesh.triangles,
        };
        Self::layered(layers, center, radii, masses)
    }

    /// Two layers on the unit directions `layers.unit` about `center`, at `radii = [inner, outer]`
    /// (m), with particle masses `masses = [inner, outer]` (kg); springs per Song 2009, Sec. 3.4.2
    /// / 3.5.2: structural springs on `layers.edges` of each layer, one radius spring per pair, and
    /// for each edge `(a, b)` a left shear spring inner `a` - outer `b` and a right one inner `b` -
    /// outer `a`. The rest volumes are measured; no gas yet ([`TwoLayerModel::with_pressures`]).
    pub fn layered(
        layers: Layers<'_>,
        center: Point3<f64>,
        radii: [f64; 2],
        masses: [f64; 2],
    ) -> Self {
        let Layers {
            dimension,
            unit,
            edges,
            surface,
        } = layers;
        let n = unit.len();
        let c = center.coords;
        let mut rest_positions = Vec::with_capacity(6 * n);
        for radius in radii {
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
        let mut particle_masses = vec![masses[0]; n];
        particle_masses.extend(std::iter::repeat_n(masses[1], n));
        let mut model = TwoLayerModel {
            dimension,
            rest_positions,
            masses: particle_masses,
            fixed: vec![false; 2 * n],
            springs,
            layer_size: n,
            surface,
            gas_outer: 0.0,
            gas_inner: 0.0,
            rest_volume_outer: 0.0,
            rest_volume_inner: 0.0,
        };
        model.rest_volume_outer = model.layer_volume(&model.rest_positions, true);
        model.rest_volume_inner = model.layer_volume(&model.rest_positions, false);
        model
    }

    /// Fills the layers with gas at the initial pressures `outer` and `inner` (Pa) at their rest
    /// volumes: `(nRT)_k = P_k V_k0`. Nothing in 1D.
    pub fn with_pressures(mut self, outer: f64, inner: f64) -> Self {
        if self.dimension != Dimension::One {
            self.gas_outer = outer * self.rest_volume_outer;
            self.gas_inner = inner * self.rest_volume_inner;
        }
        self
    }

    /// Checks that the arrays fit together: three coordinates, a mass and a `fixed` flag per
    /// particle, positive finite masses, finite rest positions, springs between particles, two
    /// layers of `layer_size` particles each, layer triangles within a layer.
    /// [`crate::TwoLayerSimulation::new`] calls it; the constructors above make models that pass.
    ///
    /// # Errors
    /// [`TwoLayerError::InvalidParameter`] naming the first array at fault.
    pub fn check(&self) -> Result<(), TwoLayerError> {
        let n = self.masses.len();
        let bad = |name: &'static str, value: String, reason: String| {
            Err(TwoLayerError::InvalidParameter {
                name,
                value,
                reason,
            })
        };
        if self.rest_positions.len() != 3 * n || self.fixed.len() != n {
            let lens = format!("{} / {}", self.rest_positions.len(), self.fixed.len());
            return bad(
                "rest_positions / fixed",
                lens,
                format!("expected {} / {n}", 3 * n),
            );
        }
        if let Some(m) = self.masses.iter().find(|m| !(m.is_finite() && **m > 0.0)) {
            return bad(
                "masses",
                m.to_string(),
                "must be positive and finite".into(),
            );
        }
        if let Some(x) = self.rest_positions.iter().find(|x| !x.is_finite()) {
            return bad("rest_positions", x.to_string(), "must be finite".into());
        }
        if let Some(s) = self.springs.iter().find(|s| s.a.max(s.b) >= n) {
            let ends = format!("{}-{}", s.a, s.b);
            return bad("springs", ends, format!("the model has {n} particles"));
        }
        let layers = self.dimension != Dimension::One;
        if layers && 2 * self.layer_size != n {
            let size = self.layer_size.to_string();
            return bad(
                "layer_size",
                size,
                format!("two layers must hold all {n} particles"),
            );
        }
        if let Some(t) = self
            .surface
            .iter()
            .find(|t| t.iter().any(|&k| k >= self.layer_size))
        {
            let face = format!("{t:?}");
            let reason = format!("a layer has {} particles", self.layer_size);
            return bad("surface", face, reason);
        }
        Ok(())
    }

    /// Number of particles.
    pub fn num_particles(&self) -> usize {
        self.masses.len()
    }

    /// Whether the object has two closed layers (2D and 3D).
    pub fn has_layers(&self) -> bool {
        self.layer_size > 0
    }

    /// Volume enclosed by the outer (`outer = true`) or inner layer for flat positions `x`:
    /// the divergence theorem in 3D, `V = 1/6 sum_f x_a . (x_b x x_c)` (Song 2009, Eq. 4.12-4.16),
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
    /// triangles each (Song 2009, Fig. 3.5); none in 1D.
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
