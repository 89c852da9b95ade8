//! Software rendering of simulation frames for users without a viewer.
//!
//! **For:** shaded pictures of a triangle surface (a balloon, a volumetric body's embedded
//! surface, a two-layer object) on a headless machine: a z-buffer rasteriser ([`Renderer`]) with
//! a perspective or orthographic [`Camera`] framing the mesh, Lambert + Blinn-Phong shading, an
//! optional per-vertex scalar colour map ([`ColorMap`], perceptual, viridis-like) with a legend
//! bar and numeric labels drawn in a built-in bitmap font ([`font`]), an optional title; PNG
//! output ([`Image::write_png`]); animated GIF output ([`GifWriter`], median-cut palette per
//! frame); rigid scene objects drawn beside the surface ([`Prop`]: a sphere, a floor plane;
//! [`Renderer::render_with_props`], [`pov::scene_with_props`]); POV-Ray scene export
//! ([`pov::scene`], the paper's own rendering pipeline); and small
//! line charts ([`plot::LinePlot`], e.g. a pressure-volume curve) in the same font.
//!
//! **Not for:** interactive display (see `balloon-viewer`) or computing the fields themselves
//! (see `balloon_mesh::fields`; this crate only uses its vertex normals).
//!
//! Positions are flat arrays `x = [x0, y0, z0, x1, ...]` (metres) and triangles are vertex index
//! triples, as everywhere in the workspace.
//!
//! ```
//! use balloon_render::{Camera, ColorScale, RenderOptions, Renderer, Surface};
//! // A tetrahedron coloured by its vertex index.
//! let x = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
//! let tris = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
//! let s = [0.0, 1.0, 2.0, 3.0];
//! let opts = RenderOptions {
//!     color_scale: Some(ColorScale::new(0.0, 3.0, "index")),
//!     title: Some("tetrahedron".into()),
//!     ..RenderOptions::new(160, 120)
//! };
//! let mut r = Renderer::new();
//! let img = r.render(&Surface::new(&x, &tris).with_scalars(&s), &opts, None).unwrap();
//! assert_eq!((img.width(), img.height()), (160, 120));
//! ```

mod camera;
mod colormap;
mod error;
pub mod font;
mod gif_out;
mod image;
pub mod plot;
pub mod pov;
pub mod props;
mod raster;

pub use camera::{Camera, Framing, Projection, UpAxis};
pub use colormap::{ColorMap, ColorScale, format_tick, tick_labels};
pub use error::RenderError;
pub use gif_out::{GifWriter, quantize, read_gif};
pub use image::Image;
pub use props::Prop;
pub use raster::{RenderOptions, Renderer, Surface};
