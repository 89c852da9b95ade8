//! The pictures of a run: PNG renders of chosen steps, an animated GIF of the written frames
//! and a POV-Ray scene of the last, drawn with `balloon-render`.

use super::frame::Frame;
use anyhow::{Context, Result};
use balloon_render::{
    Camera, ColorScale, Framing, GifWriter, Projection, Prop, RenderOptions, Renderer, Surface,
    UpAxis,
};
use balloon_scenario::output::{ColorField, ColorRange, RenderSpec};
use std::collections::BTreeSet;
use std::path::Path;

/// How a system is drawn.
#[derive(Clone, Copy, Debug)]
pub struct PictureStyle {
    /// System name for titles.
    pub system: &'static str,
    /// Camera.
    pub camera: Camera,
    /// Colour when none is asked.
    pub default_color: ColorField,
    /// Colours this system can provide.
    pub available: &'static [ColorField],
    /// The surface is closed and outward oriented, so back faces can be skipped when drawing.
    pub closed: bool,
}

impl PictureStyle {
    /// Perspective view from the front-left, slightly above, with `up` as the up axis.
    pub fn new(
        system: &'static str,
        up: UpAxis,
        default_color: ColorField,
        available: &'static [ColorField],
    ) -> Self {
        Self {
            system,
            camera: Camera {
                azimuth_deg: 30.0,
                elevation_deg: 20.0,
                up,
                projection: Projection::Perspective { fov_y_deg: 30.0 },
            },
            default_color,
            available,
            closed: false,
        }
    }
}

/// A frame kept for the GIF: positions and colour values.
pub(crate) struct GifFrame {
    pub(crate) step: usize,
    pub(crate) time: f64,
    pub(crate) positions: Vec<f64>,
    pub(crate) colors: Option<Vec<f64>>,
    pub(crate) props: Vec<Prop>,
}

/// Most frames kept for the GIF; beyond, every other one is dropped.
const MAX_GIF_FRAMES: usize = 120;

/// The picture outputs of a run and what they have kept so far.
pub(crate) struct Pictures {
    pub(crate) spec: Option<RenderSpec>,
    pub(crate) gif: bool,
    pub(crate) pov: bool,
    pub(crate) color: ColorField,
    pub(crate) color_range: ColorRange,
    pub(crate) label: &'static str,
    pub(crate) size: (u32, u32),
    pub(crate) style: PictureStyle,
    pub(crate) renderer: Renderer,
    pub(crate) triangles: Vec<[usize; 3]>,
    pub(crate) gif_frames: Vec<GifFrame>,
    pub(crate) gif_stride: usize,
    pub(crate) gif_seen: usize,
    pub(crate) rendered: BTreeSet<usize>,
    pub(crate) last_written: Option<Frame>,
}

/// Options for a picture of step `step` at time `time`: the system's camera, a colour scale over
/// `range` (or the range of `colors`), and a title naming the system, step and time.
pub(crate) fn render_options(
    p: &Pictures,
    (step, time): (usize, f64),
    colors: Option<&Vec<f64>>,
    range: Option<(f64, f64)>,
) -> RenderOptions {
    let color_scale = colors.map(|c| {
        let label = if p.label.is_empty() {
            p.color.name()
        } else {
            p.label
        };
        match range.or_else(|| p.color_range.of(c.iter())) {
            Some((lo, hi)) => ColorScale::new(lo, hi, label),
            None => ColorScale::from_values(c, label),
        }
    });
    RenderOptions {
        camera: p.style.camera,
        color_scale,
        cull_back_faces: p.style.closed,
        title: Some(format!(
            "{}  step {}  t = {} s",
            p.style.system,
            step,
            balloon_render::format_tick(time)
        )),
        ..RenderOptions::new(p.size.0, p.size.1)
    }
}

pub(crate) fn render_png(p: &mut Pictures, dir: &Path, frame: &Frame) -> Result<()> {
    let colors = frame.color_values(p.color)?;
    if let Some((_, label)) = &colors {
        p.label = label;
    }
    let opts = render_options(
        p,
        (frame.step, frame.time),
        colors.as_ref().map(|c| &c.0),
        None,
    );
    let mut surface = Surface::new(&frame.positions, &frame.triangles);
    if let Some((c, _)) = &colors {
        surface = surface.with_scalars(c);
    }
    let path = dir
        .join("renders")
        .join(format!("frame_{:05}.png", frame.step));
    p.renderer
        .render_with_props(&surface, &frame.props, &opts, frame.framing().as_ref())
        .and_then(|img| img.write_png(&path))
        .with_context(|| format!("cannot render {}", path.display()))?;
    p.rendered.insert(frame.step);
    Ok(())
}

pub(crate) fn keep_for_gif(p: &mut Pictures, frame: &Frame) -> Result<()> {
    p.gif_seen += 1;
    if !(p.gif_seen - 1).is_multiple_of(p.gif_stride) {
        return Ok(());
    }
    if p.triangles.is_empty() {
        p.triangles = frame.triangles.clone();
    }
    let colors = frame.color_values(p.color)?;
    if let Some((_, label)) = &colors {
        p.label = label;
    }
    p.gif_frames.push(GifFrame {
        step: frame.step,
        time: frame.time,
        positions: frame.positions.clone(),
        colors: colors.map(|c| c.0),
        props: frame.props.clone(),
    });
    if p.gif_frames.len() >= MAX_GIF_FRAMES {
        // Keep every other frame (always the first), and from now on every other new one.
        let mut k = 0;
        p.gif_frames.retain(|_| {
            k += 1;
            (k - 1) % 2 == 0
        });
        p.gif_stride *= 2;
    }
    Ok(())
}

pub(crate) fn write_gif(p: &mut Pictures, path: &Path) -> Result<()> {
    if p.gif_frames.is_empty() {
        return Ok(());
    }
    // One framing and one colour range for the whole animation.
    let framing = p
        .gif_frames
        .iter()
        .filter_map(|g| Framing::of_points(&g.positions))
        .chain(p.gif_frames.iter().flat_map(|g| {
            g.props.iter().filter_map(|prop| match *prop {
                Prop::Sphere { center, radius, .. } => Some(Framing { center, radius }),
                Prop::Plane { .. } => None,
            })
        }))
        .reduce(|a, b| a.union(&b))
        .context("--gif: no frame has finite coordinates")?;
    let range = p.color_range.of(p
        .gif_frames
        .iter()
        .filter_map(|g| g.colors.as_ref())
        .flatten());
    let n = p.gif_frames.len();
    // About 6 s for the whole run, between 4 and 20 hundredths per frame.
    let delay = (600 / n.max(1)).clamp(4, 20) as u16;
    let mut gif = GifWriter::create(path, p.size.0, p.size.1)?;
    let frames = std::mem::take(&mut p.gif_frames);
    for g in &frames {
        let opts = render_options(p, (g.step, g.time), g.colors.as_ref(), range);
        let mut surface = Surface::new(&g.positions, &p.triangles);
        if let Some(c) = &g.colors {
            surface = surface.with_scalars(c);
        }
        let img = p
            .renderer
            .render_with_props(&surface, &g.props, &opts, Some(&framing))
            .with_context(|| format!("cannot render GIF frame of step {}", g.step))?;
        gif.add_frame(img, delay)?;
    }
    p.gif_frames = frames;
    gif.finish()
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}
