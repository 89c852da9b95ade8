//! Incompressible rubber membranes as a shell material: the [`Membrane`] wrapper and the
//! analytic sphere stretch for a pressure.
//!
//! A membrane shell runs through the same system, Newton solver (exact and projected tangents),
//! gas models and anchors as the three-prism shell; only the element differs
//! ([`balloon_element::HyperMembrane`], `docs/membranes.md` M22-M25), and the thickness is not a
//! state but `h = H / (l1 l2)` (M2), refreshed after every solve
//! ([`crate::ShellSystem::refresh_thickness`]).

use balloon_material::MembraneModel;
use balloon_material::membrane::{MembraneMaterial, ThinSphere};

/// An incompressible hyperelastic membrane model (any [`MembraneMaterial`]: neo-Hookean,
/// Mooney-Rivlin, Gent, Ogden, Yeoh or the run-time [`MembraneModel`]) used as a shell
/// material: every triangle becomes a [`balloon_element::HyperMembrane`] with energy
/// `A0 H W(C)` (`docs/membranes.md` M23) and thickness `H / sqrt(det C)` (M2).
///
/// ```
/// use balloon_material::membrane::MembraneNeoHookean;
/// use balloon_shell::{Membrane, ShellMaterial};
/// use nalgebra::Vector3;
///
/// let rubber = Membrane(MembraneNeoHookean::try_new(4.0e5)?);
/// let rest = [Vector3::zeros(), Vector3::x(), Vector3::y()];
/// let element = rubber.element(rest, 1.0e-3)?;
/// // Stretched by 2 in both directions: the area grows 4 times, the thickness falls 4 times.
/// let stretched = rest.map(|p| 2.0 * p);
/// assert!(rubber.thickness_follows_stretch());
/// let h = rubber.current_thickness(&element, &stretched, 1.0e-3);
/// assert!((h - 0.25e-3).abs() < 1e-15);
/// assert!(rubber.energy(&element, &stretched, h) > 0.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Membrane<W: MembraneMaterial = MembraneModel>(pub W);

impl<W: MembraneMaterial> Membrane<W> {
    /// The membrane model.
    pub fn model(&self) -> &W {
        &self.0
    }
}

/// The stretch `l >= 1` at which a thin membrane sphere (`sphere`: rest radius `R`, rest
/// thickness `H`) of `material` is in equilibrium under the gauge pressure `pressure` (Pa), on the
/// rising branch from the rest state: the root of `P(l) = H / (R l^2) w'(l)`
/// (`docs/membranes.md` M18) below the first pressure maximum, by bisection. `None` when
/// `pressure` is negative or not finite, above the first maximum (no equilibrium on this branch:
/// the balloon snaps through), or when no root is found up to `l = 100`.
pub fn membrane_sphere_stretch<W: MembraneMaterial>(
    sphere: &ThinSphere,
    material: &W,
    pressure: f64,
) -> Option<f64> {
    if !(pressure.is_finite() && pressure >= 0.0) {
        return None;
    }
    if pressure == 0.0 {
        return Some(1.0);
    }
    let p = |l: f64| sphere.pressure(material, l);
    // March up the curve until it passes `pressure` (or turns down before it).
    let mut lo;
    let mut hi = 1.0;
    let mut p_prev = 0.0;
    loop {
        let next = hi * 1.005;
        let pn = p(next);
        if !pn.is_finite() || pn < p_prev || next > 100.0 {
            return None;
        }
        (lo, hi) = (hi, next);
        p_prev = pn;
        if pn >= pressure {
            break;
        }
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if p(mid) < pressure {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi))
}
