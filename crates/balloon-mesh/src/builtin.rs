//! Built-in meshes by name and the `load` entry point used by the CLI and the simulators.

use crate::generate::{self, TeddyParams};
use crate::{MeshError, TriMesh};
use nalgebra::Vector3;
use std::path::Path;

/// Names accepted by [`builtin`], the default first.
pub const BUILTIN_NAMES: &[&str] = &[
    "teddy",
    "teddy-coarse",
    "icosphere",
    "sphere",
    "octasphere",
    "uvsphere",
    "torus",
    "box",
    "tube",
    "fin",
    "fin-coarse",
    "fin-thin",
    "wing",
    "wing-fine",
    "box-fine",
];

/// A built-in mesh by name (all closed, outward, centred at the origin, metres):
///
/// | name | mesh |
/// |---|---|
/// | `teddy` | [`generate::teddy()`] with default [`TeddyParams`] (0.3 m tall, ~8k vertices) |
/// | `teddy-coarse` | [`generate::teddy()`] at resolution 14 (1304 vertices): the live viewer's default shell |
/// | `icosphere`, `sphere` | icosphere level 4, radius 0.1 m (2562 vertices) |
/// | `octasphere` | subdivided octahedron level 5, radius 0.1 m (4098 vertices) |
/// | `uvsphere` | UV sphere, radius 0.1 m, 64 slices x 32 stacks |
/// | `torus` | torus R = 0.1 m, r = 0.03 m, 64 x 24 segments |
/// | `box` | 0.1 m cube, 10 x 10 quads per face |
/// | `tube` | [`generate::tube()`]: radius 0.05 m, 0.6 m tip to tip (hemispherical caps), 32 segments around (2260 vertices) |
/// | `fin` | [`generate::finned_ellipsoid()`] with default [`generate::FinParams`]: a 0.1 m flattened ellipsoid with a 6 mm thin fin (6404 vertices) |
/// | `fin-coarse` | the same with an 8 mm fin, mesher cell 4 mm (3598 vertices) |
/// | `fin-thin` | the same with a 4 mm fin, mesher cell 2 mm (14614 vertices) |
/// | `wing` | [`generate::winged_ellipsoid()`] with default [`generate::WingParams`]: a 0.1 m span, two 4 mm thin wings (642 vertices) |
/// | `wing-fine` | the same at icosphere level 4 (2562 vertices) |
/// | `box-fine` | 0.1 m cube, 25 x 25 quads per face (3752 vertices): sharp edges and corners |
///
/// Names are case-insensitive.
///
/// # Errors
/// [`MeshError::UnknownBuiltin`] for any other name.
pub fn builtin(name: &str) -> Result<TriMesh, MeshError> {
    match name.trim().to_ascii_lowercase().as_str() {
        "teddy" => generate::teddy(&TeddyParams::default()),
        "teddy-coarse" => generate::teddy(&TeddyParams {
            resolution: 14,
            ..TeddyParams::default()
        }),
        "icosphere" | "sphere" => generate::icosphere(0.1, 4),
        "octasphere" => generate::octahedron_sphere(0.1, 5),
        "uvsphere" => generate::uv_sphere(0.1, 64, 32),
        "torus" => generate::torus(0.1, 0.03, 64, 24),
        "box" => generate::box_mesh(Vector3::repeat(0.1), 10),
        "tube" => generate::tube(0.05, 0.6, 32),
        "fin" => generate::finned_ellipsoid(&generate::FinParams::default()),
        "fin-coarse" => generate::finned_ellipsoid(&generate::FinParams {
            fin_thickness: 0.008,
            cell_size: 0.004,
            ..generate::FinParams::default()
        }),
        "fin-thin" => generate::finned_ellipsoid(&generate::FinParams {
            fin_thickness: 0.004,
            cell_size: 0.002,
            ..generate::FinParams::default()
        }),
        "wing" => generate::winged_ellipsoid(&generate::WingParams::default()),
        "wing-fine" => generate::winged_ellipsoid(&generate::WingParams {
            subdivisions: 4,
            ..generate::WingParams::default()
        }),
        "box-fine" => generate::box_mesh(Vector3::repeat(0.1), 25),
        _ => Err(MeshError::UnknownBuiltin {
            name: name.to_string(),
            known: BUILTIN_NAMES.join(", "),
        }),
    }
}

/// Loads a mesh from a spec: `builtin` (the teddy), `builtin:NAME` (see [`builtin`]) or a file
/// path read by [`crate::io::read_mesh`] (format from the extension).
///
/// The mesh is returned as read; call [`crate::validate::validate_closed_manifold`] before
/// simulating it.
///
/// # Errors
/// Those of [`builtin`] and [`crate::io::read_mesh`].
pub fn load(spec: &str) -> Result<TriMesh, MeshError> {
    if spec == "builtin" {
        return builtin("teddy");
    }
    if let Some(name) = spec.strip_prefix("builtin:") {
        return builtin(name);
    }
    crate::io::read_mesh(Path::new(spec))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::validate::validate_closed_manifold;

    #[test]
    fn every_builtin_is_valid_and_unknown_names_fail() {
        // (The 14614-vertex thin fin is left to its generator's own test.)
        for name in BUILTIN_NAMES
            .iter()
            .filter(|n| !matches!(**n, "teddy" | "fin-thin"))
        {
            let m = load(&format!("builtin:{name}")).unwrap();
            validate_closed_manifold(&m).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        assert_eq!(builtin("sphere").unwrap(), builtin("ICOSPHERE").unwrap());
        assert_eq!(builtin("icosphere").unwrap().num_vertices(), 2562);
        assert_eq!(builtin("tube").unwrap().num_vertices(), 2260);
        assert_eq!(builtin("wing").unwrap().num_vertices(), 642);
        assert_eq!(builtin("wing-fine").unwrap().num_vertices(), 2562);
        assert_eq!(builtin("box-fine").unwrap().num_vertices(), 3752);
        assert_eq!(builtin("fin-coarse").unwrap().num_vertices(), 3598);
        let err = load("builtin:teapot").unwrap_err().to_string();
        assert!(err.contains("teapot") && err.contains("teddy"), "{err}");
        let err = load("/nonexistent/dir/mesh.obj").unwrap_err().to_string();
        assert!(err.contains("/nonexistent/dir/mesh.obj"), "{err}");
    }
}
