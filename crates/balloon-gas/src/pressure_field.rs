//! Per-vertex pressure force of a uniform gauge pressure, for output and display.

use balloon_mesh::fields::{FieldError, vertex_area_normal_sums};

/// Gas pressure force on each vertex (flat, N), Wang et al. 2015, Eq. 15 in its area-normal form:
/// `f_i = p sum_{f ∋ i} A_f n_f / 3`, with `p` the gauge pressure (Pa, inside minus ambient).
/// On a closed surface this equals `p dV/dx_i`, the force [`crate::PressureLoad`] applies.
///
/// # Errors
/// [`FieldError`] for a position array whose length is not a multiple of 3 or a triangle
/// index out of range.
pub fn vertex_pressure_forces(
    x: &[f64],
    tris: &[[usize; 3]],
    gauge_pressure: f64,
) -> Result<Vec<f64>, FieldError> {
    let mut f = vertex_area_normal_sums(x, tris)?;
    // A n = (1/2) e12 x e13, so p A n / 3 = p / 6 * (e12 x e13).
    let s = gauge_pressure / 6.0;
    f.iter_mut().for_each(|c| *c *= s);
    Ok(f)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ConstantPressure, PressureLoad};
    use balloon_mesh::fields::vertex_normals;

    #[test]
    fn pressure_forces_sum_to_zero_and_match_the_pressure_load() {
        let mesh = balloon_mesh::generate::icosphere(1.0, 2).unwrap();
        let tris = mesh.triangles.clone();
        // An irregular closed surface: perturb the sphere.
        let x: Vec<f64> = mesh
            .positions_flat()
            .chunks_exact(3)
            .flat_map(|v| {
                let r = 1.0 + 0.2 * (3.0 * v[0]).sin() * v[1];
                [r * v[0], 1.3 * r * v[1], 0.8 * r * v[2]]
            })
            .collect();
        let gauge = 2500.0;
        let f = vertex_pressure_forces(&x, &tris, gauge).unwrap();
        for k in 0..3 {
            let s: f64 = f.iter().skip(k).step_by(3).sum();
            assert!(s.abs() < 1e-9, "resultant component {k} = {s}");
        }
        let mut load =
            PressureLoad::new(ConstantPressure::try_from_gauge(gauge, 101_325.0).unwrap());
        let mut g = vec![0.0; x.len()];
        let state = load.evaluate(0.0, &x, &tris, &mut g).unwrap();
        assert!((state.gauge_pressure - gauge).abs() < 1e-9);
        let scale = f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(scale > 1.0);
        for (a, b) in f.iter().zip(&g) {
            assert!((a - b).abs() < 1e-10 * scale, "{a} vs {b}");
        }
        // Outward on a convex-ish shape: force . normal > 0 everywhere.
        let n = vertex_normals(&x, &tris).unwrap();
        for (fi, ni) in f.chunks_exact(3).zip(n.chunks_exact(3)) {
            assert!(fi[0] * ni[0] + fi[1] * ni[1] + fi[2] * ni[2] > 0.0);
        }
        assert!(vertex_pressure_forces(&x[..4], &tris, gauge).is_err());
    }
}
