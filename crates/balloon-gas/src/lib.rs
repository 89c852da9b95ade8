//! Enclosed-volume gas models for the `balloon` toolkit.
//!
//! **For:** the uniform gas inside a closed, outward-oriented triangle surface (Wang et al. 2015,
//! Sec. 5): a [`GasModel`] gives the absolute pressure `p(V, t)` and `dp/dV`; a
//! [`PressureLoad`] turns it into nodal forces `(p - p_amb) dV/dx` (Eq. 15) and their tangent,
//! a rank-1 term applied matrix-free (Eq. 16-17, constant corrected from 1/27 to 1/9 for the
//! `sum A n` form) plus an optional follower term.
//!
//! The [`layer`] module holds the simpler gas of Song 2009's two-layer bodies: a constant `nRT`
//! per closed layer (polygon or triangle surface), `P = nRT / V` (Song 2009, Eq. 4.10) and its
//! forces on the layer.
//!
//! **Not for:** elastic forces (`balloon-element`) or time integration (`balloon-integrate`).
//! Works on flat position arrays `x = [x0, y0, z0, x1, ...]` and triangle index triples, so no
//! mesh type is needed.
//!
//! | model | `p(V, t)` | `dp/dV` | potential |
//! |---|---|---|---|
//! | [`IdealGas`] | `p0 V0 / V` (Eq. 14) | `-p0 V0 / V^2` | `-p0 V0 ln V` |
//! | [`ConstantPressure`] | `p` | `0` | `-p V` |
//! | [`Pump`] | `(nRT_0 + rate t) / V` | `-nRT(t) / V^2` | `-nRT(t) ln V` |
//! | [`Polytropic`] | `p0 (V0 / V)^gamma` | `-gamma p / V` | `p0 V0 (V0/V)^(gamma-1) / (gamma-1)` |
//! | [`LeakyGas`] | `(N0 + tau C p_a) / (V + tau C)` | `-p / (V + tau C)` | `-(N0 + tau C p_a) ln(V + tau C)` |
//! | [`SupplyPump`] | `min((N0 + rate tau) / V, p_s)`, never below `N0 / V` | piecewise | piecewise ([`laws`]) |
//!
//! The leak and the supply pump carry a history (`N0` at `t0`, `tau = t - t0`), committed by
//! [`GasModel::end_step`] after every accepted step.
//!
//! The ambient pressure defaults to [`STANDARD_ATMOSPHERE`] (101 325 Pa).
//!
//! ```
//! use balloon_gas::{IdealGas, PressureLoad, enclosed_volume};
//! // A unit right tetrahedron, outward oriented.
//! let x = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
//! let tris = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
//! let v0 = enclosed_volume(&x, &tris).unwrap();
//! assert!((v0 - 1.0 / 6.0).abs() < 1e-15);
//! let gas = IdealGas::try_from_gauge(1000.0, 101_325.0, v0).unwrap();
//! let mut load = PressureLoad::new(gas);
//! let mut f = [0.0; 12];
//! let state = load.evaluate(0.0, &x, &tris, &mut f).unwrap();
//! assert!((state.gauge_pressure - 1000.0).abs() < 1e-9);
//! // Uniform pressure on a closed surface has no resultant.
//! let fx: f64 = f.iter().step_by(3).sum();
//! assert!(fx.abs() < 1e-9);
//! ```

mod error;
mod kind;
pub mod laws;
pub mod layer;
mod load;
mod model;
mod pressure_field;
mod volume;

pub use error::GasError;
pub use kind::{Gas, GasKind, GasLawParams};
pub use laws::{LeakyGas, Polytropic, SupplyPump};
pub use load::{GasState, PressureLoad};
pub use model::{ConstantPressure, GasModel, IdealGas, Pump, STANDARD_ATMOSPHERE};
pub use pressure_field::vertex_pressure_forces;
pub use volume::{
    add_volume_hessian_block, add_volume_hessian_product, add_volume_hessian_triplets,
    check_surface, enclosed_volume, volume_and_gradient,
};

#[cfg(test)]
mod tests;
