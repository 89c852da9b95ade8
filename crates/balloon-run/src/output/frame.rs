//! One frame of a run: the surface, its per-vertex and per-face fields and the scene's rigid
//! objects.

use anyhow::{Context, Result};
use balloon::fields;
use balloon_render::{Framing, Prop};
use balloon_scenario::output::ColorField;

/// A named per-vertex or per-face array of a frame.
#[derive(Clone, Debug)]
pub struct Field {
    /// Name in the `.vtp` file.
    pub name: &'static str,
    /// 1 (scalar) or 3 (vector).
    pub components: usize,
    /// Flat values.
    pub values: Vec<f64>,
}

impl Field {
    /// A scalar field.
    pub fn scalar(name: &'static str, values: Vec<f64>) -> Self {
        Self {
            name,
            components: 1,
            values,
        }
    }

    /// A vector field (3 per tuple).
    pub fn vector(name: &'static str, values: Vec<f64>) -> Self {
        Self {
            name,
            components: 3,
            values,
        }
    }
}

/// One body of a frame's surface (a balloon of a connected set, or the whole surface): the USD
/// output writes each body as its own mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct Body {
    /// Prim name (a USD identifier: letters, digits, `_`).
    pub name: String,
    /// Its vertices in the frame's surface.
    pub vertices: std::ops::Range<usize>,
    /// Its triangles in the frame's surface (they use only its vertices).
    pub faces: std::ops::Range<usize>,
    /// Gauge pressure of its gas (Pa), when it encloses one.
    pub pressure: Option<f64>,
}

impl Body {
    /// The whole surface of `vertices` vertices and `faces` triangles as one body.
    pub fn whole(name: &str, vertices: usize, faces: usize) -> Self {
        Self {
            name: name.into(),
            vertices: 0..vertices,
            faces: 0..faces,
            pressure: None,
        }
    }

    /// The same body with gauge pressure `pressure` (Pa).
    pub fn with_pressure(mut self, pressure: f64) -> Self {
        self.pressure = Some(pressure);
        self
    }
}

/// One frame of a run: the surface and its fields.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Step number.
    pub step: usize,
    /// Simulated time, s.
    pub time: f64,
    /// Flat positions.
    pub positions: Vec<f64>,
    /// Triangles.
    pub triangles: Vec<[usize; 3]>,
    /// Per-vertex fields (velocity, speed, pressure force, ...).
    pub point_data: Vec<Field>,
    /// Per-face fields (thickness, stretch, ...).
    pub cell_data: Vec<Field>,
    /// Rigid objects of the scene at this step (the volumetric drop-sphere's sphere and floor):
    /// written beside the frame file (`sphere_NNNNN.<ext>`, `floor.<ext>`, see
    /// [`super::OutputDir::frame`]) and drawn in the pictures.
    pub props: Vec<Prop>,
    /// The bodies the surface is made of (empty: one body, the whole surface).
    pub bodies: Vec<Body>,
}

impl Frame {
    /// A frame with no fields.
    pub fn new(step: usize, time: f64, positions: Vec<f64>, triangles: Vec<[usize; 3]>) -> Self {
        Self {
            step,
            time,
            positions,
            triangles,
            point_data: Vec::new(),
            cell_data: Vec::new(),
            props: Vec::new(),
            bodies: Vec::new(),
        }
    }

    /// The same frame made of `bodies` (see [`Body`]).
    pub fn with_bodies(mut self, bodies: Vec<Body>) -> Self {
        self.bodies = bodies;
        self
    }

    /// The same frame with the rigid objects `props` of the scene.
    pub fn with_props(mut self, props: Vec<Prop>) -> Self {
        self.props = props;
        self
    }

    /// The region pictures show: the surface and every sphere (not the planes, which extend
    /// beyond it); `None` without props, so that a frame without them is framed as before.
    pub(crate) fn framing(&self) -> Option<Framing> {
        let spheres = self.props.iter().filter_map(|p| match *p {
            Prop::Sphere { center, radius, .. } => Some(Framing { center, radius }),
            Prop::Plane { .. } => None,
        });
        let mut f: Option<Framing> = None;
        for s in spheres {
            let base = f
                .or_else(|| Framing::of_points(&self.positions))
                .unwrap_or(s);
            f = Some(base.union(&s));
        }
        f
    }

    /// Adds velocity (vector) and speed (scalar) from flat velocities.
    pub fn with_velocity(mut self, v: Vec<f64>) -> Result<Self> {
        let speed = fields::vertex_speeds(&v)?;
        self.point_data.push(Field::vector("velocity", v));
        self.point_data.push(Field::scalar("speed", speed));
        Ok(self)
    }

    /// Adds per-face `stretch` (sqrt(A/A0)) and `max_stretch` (largest principal stretch)
    /// against `rest`. A degenerate rest triangle (possible in a triangle soup) gets NaN.
    pub fn with_stretch(mut self, rest: &[f64]) -> Result<Self> {
        let area = fields::face_area_stretch_or_nan(rest, &self.positions, &self.triangles)?;
        let max = fields::face_max_stretch_or_nan(rest, &self.positions, &self.triangles)?;
        self.cell_data.push(Field::scalar("stretch", area));
        self.cell_data.push(Field::scalar("max_stretch", max));
        Ok(self)
    }

    fn field<'a>(list: &'a [Field], name: &str) -> Option<&'a [f64]> {
        list.iter()
            .find(|f| f.name == name)
            .map(|f| f.values.as_slice())
    }

    /// Per-vertex values for `color` and the legend label, or `None` for [`ColorField::None`].
    pub(crate) fn color_values(
        &self,
        color: ColorField,
    ) -> Result<Option<(Vec<f64>, &'static str)>> {
        let face = |name: &str| -> Result<Vec<f64>> {
            let v = Self::field(&self.cell_data, name)
                .with_context(|| format!("`color` = {color}: this run has no {name} field"))?;
            Ok(fields::face_to_vertex(&self.positions, &self.triangles, v)?)
        };
        Ok(match color {
            ColorField::None => None,
            ColorField::Thickness => Some((
                face("thickness")?.into_iter().map(|t| 1e3 * t).collect(),
                "thickness (mm)",
            )),
            ColorField::Stretch => Some((face("stretch")?, "stretch sqrt(A/A0)")),
            ColorField::Speed => Some((
                Self::field(&self.point_data, "speed")
                    .context("`color` = speed: this run has no velocities")?
                    .to_vec(),
                "speed (m/s)",
            )),
        })
    }
}
