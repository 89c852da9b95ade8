//! Narrow-band unsigned distance field of a triangle soup on a voxel grid (Diziol, Bender and Bayer
//! 2011, Sec. 3, after Baerentzen 2005) and the surface "probability" `P(x) = 1 - c |d_min(x)|`.
//!
//! Exact point-triangle distances are evaluated only for voxels within `band` voxel sizes of a
//! triangle's bounding box (each z-slab of the grid knows the triangles that reach it), so the cost
//! is `O(triangles x band voxels)`, not `O(voxels x triangles)`. Voxels farther than the band get
//! `d = band` and so `P = 0`.

use crate::parallel::prelude::*;
use nalgebra::{Point3, Vector3};

/// A regular voxel grid: voxel `(i, j, k)` has its centre at
/// `origin + voxel_size * (i + 1/2, j + 1/2, k + 1/2)`. Index `i + nx (j + ny k)`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct VoxelGrid {
    pub origin: Point3<f64>,
    pub voxel_size: f64,
    pub dims: [usize; 3],
}

impl VoxelGrid {
    pub fn len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    pub fn centre(&self, i: usize, j: usize, k: usize) -> Point3<f64> {
        self.origin + Vector3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5) * self.voxel_size
    }

    /// Voxel index range `[lo, hi]` along `axis` whose centres lie within `[a, b]` (clamped).
    fn range(&self, axis: usize, a: f64, b: f64) -> Option<(usize, usize)> {
        let h = self.voxel_size;
        let lo = ((a - self.origin[axis]) / h - 0.5).ceil().max(0.0);
        let hi = ((b - self.origin[axis]) / h - 0.5).floor();
        let n = self.dims[axis] as f64;
        if hi < 0.0 || lo > n - 1.0 || lo > hi {
            return None;
        }
        Some((lo as usize, hi.min(n - 1.0) as usize))
    }
}

/// Closest point on segment `[a, b]` to `p`.
fn closest_on_segment(p: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>) -> Point3<f64> {
    let ab = b - a;
    let len2 = ab.norm_squared();
    if len2 <= f64::MIN_POSITIVE {
        return *a;
    }
    let t = ((p - a).dot(&ab) / len2).clamp(0.0, 1.0);
    a + ab * t
}

/// Exact Euclidean distance from `p` to triangle `(a, b, c)` (closest-point by Voronoi regions,
/// Ericson, "Real-Time Collision Detection", 5.1.5). Degenerate (zero-area) triangles fall back to
/// the distance to their three edges, so the result is always finite for finite input.
pub(crate) fn point_triangle_distance(
    p: &Point3<f64>,
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
) -> f64 {
    let ab = b - a;
    let ac = c - a;
    let n2 = ab.cross(&ac).norm_squared();
    let scale = ab.norm_squared().max(ac.norm_squared());
    if n2 <= 1e-24 * scale * scale || scale == 0.0 {
        let d1 = (p - closest_on_segment(p, a, b)).norm();
        let d2 = (p - closest_on_segment(p, b, c)).norm();
        let d3 = (p - closest_on_segment(p, c, a)).norm();
        return d1.min(d2).min(d3);
    }
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.norm();
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return bp.norm();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (p - (a + ab * v)).norm();
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return cp.norm();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (p - (a + ac * w)).norm();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).norm();
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    (p - (a + ab * v + ac * w)).norm()
}

/// Unsigned distance (m) from every voxel centre to the soup, exact within `band` (m) of the
/// surface and `band` beyond it. Deterministic (each z-slab is computed by one thread).
pub(crate) fn distance_field(
    grid: &VoxelGrid,
    vertices: &[Point3<f64>],
    triangles: &[[usize; 3]],
    band: f64,
) -> Vec<f64> {
    let [nx, ny, nz] = grid.dims;
    // Triangles reaching each z-slab (bounding box dilated by the band).
    let mut per_slab: Vec<Vec<u32>> = vec![Vec::new(); nz];
    let mut boxes = Vec::with_capacity(triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        let mut lo = vertices[tri[0]];
        let mut hi = lo;
        for &v in &tri[1..] {
            lo = lo.inf(&vertices[v]);
            hi = hi.sup(&vertices[v]);
        }
        let ranges = [0, 1, 2].map(|ax| grid.range(ax, lo[ax] - band, hi[ax] + band));
        boxes.push(ranges);
        if let Some((k0, k1)) = ranges[2] {
            for slab in &mut per_slab[k0..=k1] {
                slab.push(t as u32);
            }
        }
    }
    let mut field = vec![band; grid.len()];
    field
        .par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(k, slab)| {
            for &t in &per_slab[k] {
                let t = t as usize;
                let [Some((i0, i1)), Some((j0, j1)), _] = boxes[t] else {
                    continue;
                };
                let [a, b, c] = triangles[t].map(|v| vertices[v]);
                for j in j0..=j1 {
                    for i in i0..=i1 {
                        let d = point_triangle_distance(&grid.centre(i, j, k), &a, &b, &c);
                        let slot = &mut slab[i + nx * j];
                        if d < *slot {
                            *slot = d;
                        }
                    }
                }
            }
        });
    field
}

#[cfg(test)]
mod tests {
    use super::*;
    use balloon_test_support::Rng;

    #[test]
    fn point_triangle_distance_matches_dense_sampling() {
        // The exact distance is the minimum over the triangle, so it must be <= every sample's
        // distance and within the sampling resolution of the best sample.
        let mut rng = Rng::new(7);
        for _ in 0..50 {
            let mut pt = || Point3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
            let (a, b, c, p) = (pt(), pt(), pt(), pt() * 2.0);
            let d = point_triangle_distance(&p, &a, &b, &c);
            let mut best = f64::INFINITY;
            let n = 200;
            for i in 0..=n {
                for j in 0..=(n - i) {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    let q = a + (b - a) * u + (c - a) * v;
                    best = best.min((p - q).norm());
                }
            }
            assert!(d <= best + 1e-12, "exact {d} > sampled {best}");
            assert!(best - d < 2e-2, "exact {d} far below sampled {best}");
        }
        // Degenerate triangle: distance to the segment it collapses to.
        let a = Point3::new(0.0, 0.0, 0.0);
        let b = Point3::new(1.0, 0.0, 0.0);
        let d = point_triangle_distance(&Point3::new(0.5, 2.0, 0.0), &a, &b, &b);
        assert!((d - 2.0).abs() < 1e-14);
    }

    #[test]
    fn narrow_band_field_is_exact_in_band_and_clamped_outside() {
        let grid = VoxelGrid {
            origin: Point3::new(-1.0, -1.0, -1.0),
            voxel_size: 0.1,
            dims: [20, 20, 20],
        };
        let vertices = vec![
            Point3::new(-0.5, -0.5, 0.0),
            Point3::new(0.5, -0.5, 0.0),
            Point3::new(0.0, 0.5, 0.0),
        ];
        let tris = vec![[0, 1, 2]];
        let band = 0.3;
        let f = distance_field(&grid, &vertices, &tris, band);
        for k in 0..20 {
            for j in 0..20 {
                for i in 0..20 {
                    let p = grid.centre(i, j, k);
                    let exact =
                        point_triangle_distance(&p, &vertices[0], &vertices[1], &vertices[2]);
                    let got = f[grid.index(i, j, k)];
                    assert!((got - exact.min(band)).abs() < 1e-12, "{got} vs {exact}");
                }
            }
        }
    }
}
