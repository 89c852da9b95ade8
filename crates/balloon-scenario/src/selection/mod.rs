//! Vertex selections: the vertices (or particles) of a rest shape picked by index, by a file of
//! indices, by a half-space, by a box or by a PLY vertex group; and what the runs do with them:
//! rest-thickness maps ([`thickness`]), anchors and scheduled loads ([`specs`], applied by
//! [`apply`]).
//!
//! A selector is written `indices:1,2,3`, `file:PATH` (one vertex index per line, `#`
//! comments), `below:AXIS:VALUE` / `above:AXIS:VALUE` (a half-space, coordinate in m, `AXIS` one
//! of `x`, `y`, `z`), `box:XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX` (m, bounds included) or
//! `ply:PATH:PROPERTY` (a vertex group stored in a PLY file: the vertices whose `PROPERTY` is
//! not zero, typically the mesh's own file, e.g. `ply:balloon.ply:neck`).
//!
//! ```
//! use balloon_scenario::selection::{Selector, parse_selector};
//! // Three vertices, flat x, y, z (m).
//! let x = [0.0, 0.0, 0.0, 1.0, 0.0, 0.5, 0.0, 1.0, 1.0];
//! let below = parse_selector("below:z:0.6").unwrap();
//! assert_eq!(below.select(&x).unwrap(), vec![0, 1]);
//! assert_eq!(Selector::Indices(vec![2, 0, 2]).select(&x).unwrap(), vec![0, 2]);
//! // An empty selection is an error naming the selector.
//! let e = parse_selector("below:z:-1").unwrap().select(&x).unwrap_err();
//! assert_eq!(e.to_string(), "`below:z:-1.0` selects no vertex of the mesh");
//! ```

pub mod apply;
mod selector;
pub mod specs;
pub mod thickness;

pub use apply::{ShellLoads, TwoLayerLoads, VolumetricLoads};
pub use selector::{STIFFNESS, SelectionError, Selector, parse_selector, stiffness};
pub use specs::{Load, LoadKind, Pin, parse_load, parse_pin, rewrite_paths};
pub use thickness::{LinearRule, parse_rule, thickness_map};

#[cfg(test)]
mod tests;
