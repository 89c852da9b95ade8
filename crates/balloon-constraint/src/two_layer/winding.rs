//! Generalised winding numbers of a point about a closed layer: the exact inside test of the
//! two-layer containment and of the statistics.

use nalgebra::{Point3, Vector3};

fn point(positions: &[f64], i: usize) -> Vector3<f64> {
    Vector3::new(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2])
}

/// Generalised winding number of `p` with respect to the closed triangle layer whose vertex `j`
/// is particle `offset + j`: the sum of the signed solid angles of its triangles divided by
/// `4 pi` (Van Oosterom and Strackee). About 1 inside an outward-oriented closed surface, 0
/// outside.
pub fn winding_number(
    p: &Point3<f64>,
    positions: &[f64],
    offset: usize,
    triangles: &[[usize; 3]],
) -> f64 {
    let mut omega = 0.0;
    for t in triangles {
        let a = point(positions, offset + t[0]) - p.coords;
        let b = point(positions, offset + t[1]) - p.coords;
        let c = point(positions, offset + t[2]) - p.coords;
        let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
        let num = a.dot(&b.cross(&c));
        let den = la * lb * lc + a.dot(&b) * lc + a.dot(&c) * lb + b.dot(&c) * la;
        omega += 2.0 * num.atan2(den);
    }
    omega / (4.0 * std::f64::consts::PI)
}

/// Winding number of `p` (its `x`, `y`) with respect to the closed polygon in the `xy` plane
/// whose vertex `j` is particle `offset + j`, `j < count`: the sum of the signed angles its
/// edges subtend divided by `2 pi`. About 1 inside a counter-clockwise polygon, 0 outside.
pub fn polygon_winding_number(
    p: &Point3<f64>,
    positions: &[f64],
    offset: usize,
    count: usize,
) -> f64 {
    let mut angle = 0.0;
    for j in 0..count {
        let a = point(positions, offset + j) - p.coords;
        let b = point(positions, offset + (j + 1) % count) - p.coords;
        angle += (a.x * b.y - a.y * b.x).atan2(a.x * b.x + a.y * b.y);
    }
    angle / (2.0 * std::f64::consts::PI)
}
