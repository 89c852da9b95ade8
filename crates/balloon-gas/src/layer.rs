//! The gas inside one closed layer of a two-layer body (Song 2009, Sec. 4.5 and 4.7 Steps 5-9):
//! the enclosed volume of a closed polygon (2D) or triangle surface (3D), the isothermal
//! pressure `P = nRT / V` (Eq. 4.10), its energy `-nRT ln(V / V0)` and the pressure forces on the
//! layer's particles (Eq. 4.11-4.16).
//!
//! A [`ClosedLayer`] is the geometry: `particles` consecutive particles of a flat position array
//! (`[x0, y0, z0, x1, ...]`; the caller passes the layer's own slice), joined either as a
//! counter-clockwise polygon in the `xy` plane or by outward-oriented triangles. A [`LayerGas`]
//! is the gas: its constant `nRT` and rest volume. The pressure forces are exactly minus the
//! gradient of the gas energy (on a closed surface), so an undamped body conserves energy.
//!
//! ```
//! use balloon_gas::layer::{ClosedLayer, LayerGas};
//! // The unit square, counter-clockwise, at initial pressure 2 Pa (per unit depth).
//! let x = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0];
//! let square = ClosedLayer::polygon(4);
//! let v0 = square.volume(&x);
//! let gas = LayerGas::try_from_pressure(2.0, v0)?;
//! assert_eq!(gas.pressure(v0), 2.0);
//! let mut f = [0.0; 12];
//! square.add_pressure_forces(&x, gas.pressure(v0), &mut f);
//! // Corner (1, 1) is pushed outward along the diagonal; the forces have no resultant.
//! assert_eq!([f[6], f[7]], [1.0, 1.0]);
//! assert_eq!(f.iter().step_by(3).sum::<f64>(), 0.0);
//! # Ok::<(), balloon_gas::GasError>(())
//! ```

use nalgebra::Vector3;

use crate::GasError;
use crate::volume::{add_to, enclosed_volume_unchecked, vertex};

/// How the particles of a [`ClosedLayer`] are joined.
#[derive(Clone, Debug, PartialEq)]
pub enum LayerShape {
    /// A closed polygon `0, 1, ..., n-1` in the `xy` plane, counter-clockwise (2D bodies; volumes
    /// are areas per unit depth, m^2).
    Polygon,
    /// A closed, outward-oriented triangle surface with local vertex indices `0..n` (3D bodies).
    Surface(Vec<[usize; 3]>),
}

/// The geometry of one closed layer: `particles` consecutive particles joined as a
/// [`LayerShape`].
///
/// Methods take the layer's own slice of a flat position array, at least `3 * particles` numbers
/// long, and panic on a shorter slice or (for a surface) on a triangle index `>= particles`;
/// [`ClosedLayer::validate`] checks the indices once up front.
#[derive(Clone, Debug, PartialEq)]
pub struct ClosedLayer {
    particles: usize,
    shape: LayerShape,
}

impl ClosedLayer {
    /// A counter-clockwise polygon of `particles` particles in the `xy` plane.
    pub fn polygon(particles: usize) -> Self {
        Self {
            particles,
            shape: LayerShape::Polygon,
        }
    }

    /// A closed surface of `particles` particles joined by outward-oriented `triangles` (local
    /// indices).
    pub fn surface(particles: usize, triangles: Vec<[usize; 3]>) -> Self {
        Self {
            particles,
            shape: LayerShape::Surface(triangles),
        }
    }

    /// Number of particles.
    pub fn particles(&self) -> usize {
        self.particles
    }

    /// The shape.
    pub fn shape(&self) -> &LayerShape {
        &self.shape
    }

    /// Checks that a polygon has at least 3 particles and that every triangle index is in range.
    ///
    /// # Errors
    /// [`GasError::InvalidParameter`] (`particles`) or [`GasError::VertexOutOfRange`].
    pub fn validate(&self) -> Result<(), GasError> {
        match &self.shape {
            LayerShape::Polygon if self.particles < 3 => Err(GasError::InvalidParameter {
                name: "particles",
                value: self.particles as f64,
                requirement: "a closed polygon needs at least 3 particles",
            }),
            LayerShape::Polygon => Ok(()),
            LayerShape::Surface(triangles) => {
                crate::check_surface(&vec![0.0; 3 * self.particles], triangles)
            }
        }
    }

    /// Enclosed volume (m^3; m^2 per unit depth for a polygon) at positions `x`: Green's theorem
    /// `A = 1/2 sum_i (x_i y_(i+1) - x_(i+1) y_i)` for a polygon, the divergence theorem
    /// `V = 1/6 sum_f x_a . (x_b x x_c)` for a surface (Song 2009, Eq. 4.12-4.16; the same volume
    /// as [`crate::enclosed_volume`]).
    pub fn volume(&self, x: &[f64]) -> f64 {
        match &self.shape {
            LayerShape::Polygon => polygon_area(&x[..3 * self.particles]),
            LayerShape::Surface(triangles) => enclosed_volume_unchecked(x, triangles),
        }
    }

    /// Adds the force of the uniform `pressure` (Pa, N/m in 2D) on the layer at positions `x` to
    /// `f` (Song 2009, Eq. 4.11-4.16). Polygon: each side `(dx, dy)` takes `P (dy, -dx)` (outward
    /// normal times length), half to each end. Surface: each face takes `P A n = P/2 (b - a) x
    /// (c - a)`, a third to each corner. On a closed layer this is `P dV/dx`.
    pub fn add_pressure_forces(&self, x: &[f64], pressure: f64, f: &mut [f64]) {
        let n = self.particles;
        match &self.shape {
            LayerShape::Polygon => {
                for i in 0..n {
                    let (a, b) = (i, (i + 1) % n);
                    let e = vertex(x, b) - vertex(x, a);
                    let fe = Vector3::new(e.y, -e.x, 0.0) * (0.5 * pressure);
                    add_to(f, a, &fe);
                    add_to(f, b, &fe);
                }
            }
            LayerShape::Surface(triangles) => {
                for t in triangles {
                    let xa = vertex(x, t[0]);
                    let ff =
                        (vertex(x, t[1]) - xa).cross(&(vertex(x, t[2]) - xa)) * (pressure / 6.0);
                    add_to(f, t[0], &ff);
                    add_to(f, t[1], &ff);
                    add_to(f, t[2], &ff);
                }
            }
        }
    }
}

/// Signed area (m^2) of the closed polygon whose vertices are the consecutive points of `x`
/// (3 numbers each, `z` ignored), positive when counter-clockwise in the `xy` plane:
/// `A = 1/2 sum_i (x_i y_(i+1) - x_(i+1) y_i)`.
pub fn polygon_area(x: &[f64]) -> f64 {
    let n = x.len() / 3;
    let mut a = 0.0;
    for i in 0..n {
        let (p, q) = (3 * i, 3 * ((i + 1) % n));
        a += x[p] * x[q + 1] - x[q] * x[p + 1];
    }
    0.5 * a
}

/// The isothermal gas of one closed layer (Song 2009, Sec. 4.5): a constant `nRT` (J; J/m in 2D)
/// and the rest volume `V0` at which the gas energy is zero.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LayerGas {
    nrt: f64,
    rest_volume: f64,
}

impl LayerGas {
    /// A gas with constant `nrt` and rest volume `rest_volume`, without validation (for values
    /// validated upstream; `nrt = 0` is "no gas"). Use [`LayerGas::try_new`] for user input.
    pub const fn new(nrt: f64, rest_volume: f64) -> Self {
        Self { nrt, rest_volume }
    }

    /// A gas with constant `nrt >= 0` (J) and rest volume `rest_volume > 0`.
    ///
    /// # Errors
    /// [`GasError::InvalidParameter`] naming the parameter.
    pub fn try_new(nrt: f64, rest_volume: f64) -> Result<Self, GasError> {
        if !(nrt.is_finite() && nrt >= 0.0) {
            return Err(GasError::InvalidParameter {
                name: "nrt",
                value: nrt,
                requirement: "finite and >= 0 J",
            });
        }
        if !(rest_volume.is_finite() && rest_volume > 0.0) {
            return Err(GasError::InvalidParameter {
                name: "rest_volume",
                value: rest_volume,
                requirement: "finite and > 0",
            });
        }
        Ok(Self::new(nrt, rest_volume))
    }

    /// The gas at initial pressure `pressure >= 0` in `rest_volume > 0`: `nRT = P0 V0`.
    ///
    /// # Errors
    /// [`GasError::InvalidParameter`] naming the parameter.
    pub fn try_from_pressure(pressure: f64, rest_volume: f64) -> Result<Self, GasError> {
        if !(pressure.is_finite() && pressure >= 0.0) {
            return Err(GasError::InvalidParameter {
                name: "pressure",
                value: pressure,
                requirement: "finite and >= 0 Pa",
            });
        }
        Self::try_new(pressure * rest_volume, rest_volume)
    }

    /// `nRT` (J; J/m in 2D).
    pub fn nrt(&self) -> f64 {
        self.nrt
    }

    /// The rest volume `V0`.
    pub fn rest_volume(&self) -> f64 {
        self.rest_volume
    }

    /// Pressure `P = nRT / V` at `volume` (Song 2009, Eq. 4.10); exactly 0 without gas.
    pub fn pressure(&self, volume: f64) -> f64 {
        if self.nrt == 0.0 {
            0.0
        } else {
            self.nrt / volume
        }
    }

    /// Energy `-nRT ln(V / V0)` (J) at `volume`, zero at the rest volume; exactly 0 without gas.
    /// Its negative gradient is the pressure force of [`ClosedLayer::add_pressure_forces`].
    pub fn energy(&self, volume: f64) -> f64 {
        if self.nrt > 0.0 {
            -(self.nrt * (volume / self.rest_volume).ln())
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use balloon_test_support::{Rng, assert_second_order, check_gradient, taylor_remainder_orders};

    fn perturbed(x: &[f64], amp: f64, seed: u64, planar: bool) -> Vec<f64> {
        let mut rng = Rng::new(seed);
        x.iter()
            .enumerate()
            .map(|(k, c)| {
                if planar && k % 3 == 2 {
                    *c
                } else {
                    c + amp * rng.next_f64()
                }
            })
            .collect()
    }

    fn check_layer(layer: &ClosedLayer, x0: &[f64], p0: f64) {
        let gas = LayerGas::try_from_pressure(p0, layer.volume(x0)).unwrap();
        let energy = |x: &[f64]| gas.energy(layer.volume(x));
        let grad = |x: &[f64]| {
            let mut f = vec![0.0; x.len()];
            layer.add_pressure_forces(x, gas.pressure(layer.volume(x)), &mut f);
            f.iter().map(|c| -c).collect::<Vec<f64>>()
        };
        let x = perturbed(x0, 0.05, 7, matches!(layer.shape(), LayerShape::Polygon));
        check_gradient(energy, grad, &x, 1e-6, 1e-6);
        let dx = Rng::new(8).vector(x.len());
        assert_second_order(&taylor_remainder_orders(energy, grad, &x, &dx, 1e-3));
        // Uniform pressure on a closed layer has no resultant.
        let g = grad(&x);
        for d in 0..3 {
            let net: f64 = g.iter().skip(d).step_by(3).sum();
            assert!(net.abs() < 1e-9 * p0, "net force {net} along axis {d}");
        }
    }

    /// Pressure forces are minus the gradient of the gas energy `-nRT ln(V / V0)`, for a
    /// polygon (exact) and a closed triangle surface.
    #[test]
    fn pressure_forces_are_minus_gas_energy_gradient() {
        let n = 9;
        let ring: Vec<f64> = (0..n)
            .flat_map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                [a.cos(), 0.7 * a.sin(), 0.0]
            })
            .collect();
        check_layer(&ClosedLayer::polygon(n), &ring, 300.0);
        let mesh = balloon_mesh::generate::icosphere(1.0, 1).unwrap();
        let layer = ClosedLayer::surface(mesh.num_vertices(), mesh.triangles.clone());
        layer.validate().unwrap();
        let x = mesh.positions_flat();
        assert!(
            (layer.volume(&x) - crate::enclosed_volume(&x, &mesh.triangles).unwrap()).abs() == 0.0
        );
        check_layer(&layer, &x, 1e3);
    }

    #[test]
    fn gas_laws_and_bad_parameters() {
        let gas = LayerGas::try_new(6.0, 2.0).unwrap();
        assert_eq!(gas.pressure(3.0), 2.0);
        assert_eq!(gas.energy(2.0), 0.0);
        assert!((gas.energy(4.0) + 6.0 * 2f64.ln()).abs() < 1e-15);
        let none = LayerGas::new(0.0, 1.0);
        assert_eq!((none.pressure(0.5), none.energy(0.5)), (0.0, 0.0));
        assert!(matches!(
            LayerGas::try_new(-1.0, 1.0),
            Err(GasError::InvalidParameter { name: "nrt", .. })
        ));
        assert!(matches!(
            LayerGas::try_from_pressure(1.0, 0.0),
            Err(GasError::InvalidParameter {
                name: "rest_volume",
                ..
            })
        ));
        assert!(ClosedLayer::polygon(2).validate().is_err());
        assert!(matches!(
            ClosedLayer::surface(3, vec![[0, 1, 3]]).validate(),
            Err(GasError::VertexOutOfRange { vertex: 3, .. })
        ));
        // A counter-clockwise unit square has area +1, clockwise -1.
        let sq = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0];
        assert_eq!(polygon_area(&sq), 1.0);
        let cw: Vec<f64> = sq.chunks(3).rev().flatten().copied().collect();
        assert_eq!(polygon_area(&cw), -1.0);
    }
}
