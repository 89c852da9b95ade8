//! The analytic inflated sphere of the three-prism model (derivation: `docs/analytic-sphere.md`).
//!
//! Under a uniform gauge pressure `p` a spherical three-prism shell of rest radius `R` and rest
//! thickness `H` stretches uniformly by `lambda`; the shell-volume projection (Wang et al. 2015,
//! Eq. 24-28) sets the thickness to `h = H / lambda^2`, and equilibrium at fixed thickness gives
//!
//! `p(lambda) = H / (R lambda^2) * (P_11 + P_22)` at `F = diag(lambda, lambda, 1/lambda^2)`,
//!
//! with `P` the first Piola-Kirchhoff stress of the material (Eq. 9 for StVK). Use
//! `R = 3 V0 / A0` of a polyhedral mesh.

use balloon_material::Material;
use nalgebra::Matrix3;

/// Gauge pressure (Pa) that holds a sphere of rest radius `radius` (m) and rest thickness
/// `thickness` (m) at uniform stretch `stretch` (dimensionless, > 0).
pub fn sphere_pressure<M: Material>(
    material: &M,
    thickness: f64,
    radius: f64,
    stretch: f64,
) -> f64 {
    let l = stretch;
    let f = Matrix3::from_diagonal(&nalgebra::Vector3::new(l, l, 1.0 / (l * l)));
    let p = material.first_piola(&f);
    thickness * (p[(0, 0)] + p[(1, 1)]) / (radius * l * l)
}

/// Stretch `lambda >= 1` at which the sphere is in equilibrium under gauge pressure `pressure`
/// (Pa, >= 0), on the rising branch of `p(lambda)` starting at the rest state. `None` when the
/// pressure exceeds the maximum of the curve (no equilibrium: the balloon runs away) or the
/// stretch would exceed 100.
pub fn sphere_stretch<M: Material>(
    material: &M,
    thickness: f64,
    radius: f64,
    pressure: f64,
) -> Option<f64> {
    if pressure <= 0.0 {
        return (pressure == 0.0).then_some(1.0);
    }
    let p = |l: f64| sphere_pressure(material, thickness, radius, l);
    let mut hi = 1.0;
    let mut lo;
    let mut p_prev = 0.0;
    loop {
        let next = hi * 1.01;
        let pn = p(next);
        if pn < p_prev || next > 100.0 {
            return None;
        }
        lo = hi;
        hi = next;
        p_prev = pn;
        if pn >= pressure {
            break;
        }
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if p(mid) < pressure {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-14 * hi {
            break;
        }
    }
    Some(0.5 * (lo + hi))
}

#[cfg(test)]
mod tests {
    use super::*;
    use balloon_material::{Lame, NeoHookean, StVenantKirchhoff};

    #[test]
    fn closed_forms_match_the_generic_evaluation() {
        let lame = Lame::try_from_young_poisson(1.0e6, 0.45).unwrap();
        let (mu, la) = (lame.mu(), lame.lambda());
        let (h, r) = (3e-4, 0.1);
        for l in [1.05f64, 1.3, 1.7, 2.5] {
            // StVK: p = 2H/(R l) (2 mu a + lambda (2a + b)), a = (l^2-1)/2, b = (l^-4 - 1)/2.
            let a = (l * l - 1.0) / 2.0;
            let b = (l.powi(-4) - 1.0) / 2.0;
            let stvk = 2.0 * h / (r * l) * (2.0 * mu * a + la * (2.0 * a + b));
            let got = sphere_pressure(&StVenantKirchhoff::new(lame), h, r, l);
            assert!((got - stvk).abs() <= 1e-9 * stvk.abs(), "{got} vs {stvk}");
            // Neo-Hookean: J = 1 on the curve, p = 2 mu H / R (1/l - 1/l^3).
            let nh = 2.0 * mu * h / r * (1.0 / l - l.powi(-3));
            let got = sphere_pressure(&NeoHookean::new(lame), h, r, l);
            assert!((got - nh).abs() <= 1e-9 * nh.abs(), "{got} vs {nh}");
        }
    }

    #[test]
    fn stretch_inverts_pressure_and_detects_runaway() {
        let lame = Lame::try_from_young_poisson(1.0e6, 0.45).unwrap();
        let stvk = StVenantKirchhoff::new(lame);
        for l in [1.01, 1.2, 1.8] {
            let p = sphere_pressure(&stvk, 3e-4, 0.1, l);
            let back = sphere_stretch(&stvk, 3e-4, 0.1, p).unwrap();
            assert!((back - l).abs() < 1e-9, "{back} vs {l}");
        }
        // Neo-Hookean maximum: p_max = 4 mu H / (3 sqrt(3) R) at lambda = sqrt(3).
        let nh = NeoHookean::new(lame);
        let p_max = 4.0 * lame.mu() * 3e-4 / (3.0 * 3f64.sqrt() * 0.1);
        assert!(sphere_stretch(&nh, 3e-4, 0.1, 0.99 * p_max).unwrap() < 3f64.sqrt());
        assert!(sphere_stretch(&nh, 3e-4, 0.1, 1.01 * p_max).is_none());
    }
}
