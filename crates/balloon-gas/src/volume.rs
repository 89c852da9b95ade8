//! Enclosed volume of a closed triangle surface and its exact first and second derivatives.
//!
//! `V(x) = (1/6) sum_e x_1 . (x_2 x x_3)` (the divergence theorem, Wang et al. 2015, Eq. 13 written
//! with the origin as apex of each tetrahedron). Its gradient with respect to the corners of one
//! triangle is `dV/dx_1 = (1/6) x_2 x x_3` (and cyclic).
//!
//! On a *closed* surface this gradient equals the area-normal form of Eq. 15,
//! `dV/dx_i = (1/3) sum_{e ∋ i} A^e n^e = (1/6) sum_{e ∋ i} e_12 x e_13`, because the
//! difference between the two is a sum of terms that cancel pairwise across shared edges. On an
//! open or not-yet-closed surface only the `(1/6) x_j x x_k` form is the gradient of `V`, so it is
//! the one used here: forces are then exactly `-dPhi/dx` for every mesh, and finite-difference
//! tests hold to round-off.

use balloon_mesh::geometry::{enclosed_volume_and_gradient_flat_into, enclosed_volume_flat};
use nalgebra::{Matrix3, Vector3};

use crate::GasError;

#[inline]
pub(crate) fn vertex(x: &[f64], i: usize) -> Vector3<f64> {
    Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
}

#[inline]
pub(crate) fn add_to(out: &mut [f64], i: usize, v: &Vector3<f64>) {
    out[3 * i] += v.x;
    out[3 * i + 1] += v.y;
    out[3 * i + 2] += v.z;
}

/// Checks `x.len() % 3 == 0` and every triangle index, without touching geometry.
pub fn check_surface(x: &[f64], triangles: &[[usize; 3]]) -> Result<(), GasError> {
    if !x.len().is_multiple_of(3) {
        return Err(GasError::LengthMismatch {
            name: "x",
            len: x.len(),
            expected: 3 * (x.len() / 3),
        });
    }
    let n = x.len() / 3;
    for (t, tri) in triangles.iter().enumerate() {
        for &v in tri {
            if v >= n {
                return Err(GasError::VertexOutOfRange {
                    triangle: t,
                    vertex: v,
                    num_vertices: n,
                });
            }
        }
    }
    Ok(())
}

/// Enclosed volume `V` (m^3) of the surface (Eq. 13), positive for an outward-oriented closed
/// surface. `x`: flat positions (length `3N`, m); `triangles`: vertex indices.
pub fn enclosed_volume(x: &[f64], triangles: &[[usize; 3]]) -> Result<f64, GasError> {
    check_surface(x, triangles)?;
    Ok(enclosed_volume_unchecked(x, triangles))
}

/// [`enclosed_volume`] for indices already checked (see [`check_surface`]); panics on an
/// out-of-range index. The mesh crate's kernel ([`enclosed_volume_flat`]).
pub(crate) fn enclosed_volume_unchecked(x: &[f64], triangles: &[[usize; 3]]) -> f64 {
    enclosed_volume_flat(x, triangles)
}

/// Enclosed volume `V` (m^3) and its exact gradient `dV/dx` written into `gradient` (length
/// `3N`, m^2, overwritten), by the mesh crate's kernel
/// ([`enclosed_volume_and_gradient_flat_into`]) after checking the sizes and indices. See the
/// module docs for why the `(1/6) x_j x x_k` form is used.
pub fn volume_and_gradient(
    x: &[f64],
    triangles: &[[usize; 3]],
    gradient: &mut [f64],
) -> Result<f64, GasError> {
    check_surface(x, triangles)?;
    if gradient.len() != x.len() {
        return Err(GasError::LengthMismatch {
            name: "gradient",
            len: gradient.len(),
            expected: x.len(),
        });
    }
    Ok(enclosed_volume_and_gradient_flat_into(
        x, triangles, gradient,
    ))
}

/// Adds `scale * H_V dx` to `out`, where `H_V = d^2V/dx^2` is the (sparse, symmetric) Hessian of
/// the enclosed volume: per triangle, `d/dx_b (dV/dx_a) = -(1/6) [x_c]_x` and
/// `d/dx_c (dV/dx_a) = (1/6) [x_b]_x` for each cyclic `(a, b, c)`; diagonal blocks vanish.
/// Indices must have been checked (see [`check_surface`]).
pub fn add_volume_hessian_product(
    x: &[f64],
    triangles: &[[usize; 3]],
    scale: f64,
    dx: &[f64],
    out: &mut [f64],
) {
    let s = scale / 6.0;
    for t in triangles {
        let (a, b, c) = (vertex(x, t[0]), vertex(x, t[1]), vertex(x, t[2]));
        let (da, db, dc) = (vertex(dx, t[0]), vertex(dx, t[1]), vertex(dx, t[2]));
        // d(b x c) = db x c + b x dc, and cyclic.
        add_to(out, t[0], &((db.cross(&c) + b.cross(&dc)) * s));
        add_to(out, t[1], &((dc.cross(&a) + c.cross(&da)) * s));
        add_to(out, t[2], &((da.cross(&b) + a.cross(&db)) * s));
    }
}

/// Cross-product matrix `[v]_x` with `[v]_x w = v x w`.
#[inline]
pub(crate) fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Adds `scale * H_t` to a triangle's dense 9x9 block (column-major, corner-major dofs
/// `[x_a y_a z_a x_b ...]`), `H_t` the triangle's share of the volume Hessian `H_V` (the blocks
/// of [`add_volume_hessian_product`]: `(a, b) = -(1/6) [x_c]_x`, `(a, c) = (1/6) [x_b]_x` for
/// each cyclic `(a, b, c)`; diagonal blocks vanish). With `scale = -(p - p_ambient)` it is the
/// triangle's block of the pressure follower stiffness.
pub fn add_volume_hessian_block(corners: &[Vector3<f64>; 3], scale: f64, block: &mut [f64]) {
    let s = scale / 6.0;
    for a in 0..3 {
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        for (col_corner, m) in [(b, skew(&corners[c]) * (-s)), (c, skew(&corners[b]) * s)] {
            for q in 0..3 {
                for r in 0..3 {
                    block[(3 * col_corner + q) * 9 + 3 * a + r] += m[(r, q)];
                }
            }
        }
    }
}

/// Appends `scale * H_V` as `(row, col, value)` triplets (off-diagonal 3x3 blocks only; 54 per
/// triangle). Indices must have been checked.
pub fn add_volume_hessian_triplets(
    x: &[f64],
    triangles: &[[usize; 3]],
    scale: f64,
    triplets: &mut Vec<(usize, usize, f64)>,
) {
    let s = scale / 6.0;
    triplets.reserve(54 * triangles.len());
    for t in triangles {
        for k in 0..3 {
            let (ia, ib, ic) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            let blocks = [
                (ib, skew(&vertex(x, ic)) * (-s)),
                (ic, skew(&vertex(x, ib)) * s),
            ];
            for (j, m) in blocks {
                for r in 0..3 {
                    for col in 0..3 {
                        triplets.push((3 * ia + r, 3 * j + col, m[(r, col)]));
                    }
                }
            }
        }
    }
}
