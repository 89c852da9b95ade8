//! The uniform gas acting on a closed surface: pressure forces (Eq. 15) and their tangent
//! (Eq. 16-17, with the factor derived here rather than copied).

use balloon_linalg::LowRankTerm;
use serde::{Deserialize, Serialize};

use crate::model::{GasModel, STANDARD_ATMOSPHERE};
use crate::volume::{
    add_volume_hessian_product, add_volume_hessian_triplets, check_surface, volume_and_gradient,
};
use crate::{Gas, GasError};

/// The state of the gas after [`PressureLoad::evaluate`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct GasState {
    /// Enclosed volume `V`, m^3 (Eq. 13).
    pub volume: f64,
    /// Absolute pressure `p(V, t)`, Pa.
    pub absolute_pressure: f64,
    /// Gauge pressure `p - p_ambient`, Pa: what loads the surface.
    pub gauge_pressure: f64,
}

/// A uniform gas model acting on a closed, outward-oriented triangle surface.
///
/// Forces: `f_p = (p - p_amb) dV/dx` (Eq. 15; on a closed mesh `dV/dx_i = (1/3) sum A^e n^e`).
///
/// Tangent `K_p = -df_p/dx = -(dp/dV) g g^T - (p - p_amb) H_V` with `g = dV/dx` and
/// `H_V = d^2V/dx^2`. The first term is the paper's rank-1 Eq. 16-17. Writing it with
/// `An_i = sum_{e ∋ i} A^e n^e = 3 g_i` gives `-(dp/dV) / 9 * An An^T`, i.e. for the ideal gas
/// `(1/9) p0 V0 / V^2 An An^T`: the paper's `1/27` is wrong by a factor 3 (verified by finite
/// differences in the tests). The second ("follower", area-normal) term is neglected by default,
/// as in the paper, to keep `K` positive semi-definite; enable it with
/// [`PressureLoad::with_follower_term`].
#[derive(Clone, Debug)]
pub struct PressureLoad<G: GasModel = Gas> {
    gas: G,
    ambient_pressure: f64,
    follower: bool,
    state: GasState,
    dpressure_dvolume: f64,
    rank1: LowRankTerm,
}

impl<G: GasModel> PressureLoad<G> {
    /// A load for `gas` with the ambient pressure at [`STANDARD_ATMOSPHERE`] (101 325 Pa) and the
    /// follower term off.
    pub fn new(gas: G) -> Self {
        Self {
            gas,
            ambient_pressure: STANDARD_ATMOSPHERE,
            follower: false,
            state: GasState::default(),
            dpressure_dvolume: 0.0,
            rank1: LowRankTerm::default(),
        }
    }

    /// Sets the ambient (outside) pressure, Pa. Must be finite and non-negative.
    pub fn with_ambient_pressure(mut self, ambient_pressure: f64) -> Result<Self, GasError> {
        if !(ambient_pressure.is_finite() && ambient_pressure >= 0.0) {
            return Err(GasError::InvalidParameter {
                name: "ambient_pressure",
                value: ambient_pressure,
                requirement: "must be non-negative and finite",
            });
        }
        self.ambient_pressure = ambient_pressure;
        Ok(self)
    }

    /// Includes the follower term `-(p - p_amb) H_V` in the differential and the triplets
    /// (default `false`, as the paper).
    pub fn with_follower_term(mut self, enabled: bool) -> Self {
        self.follower = enabled;
        self
    }

    /// Whether the follower term is included.
    pub fn follower_term(&self) -> bool {
        self.follower
    }

    /// The ambient pressure, Pa.
    pub fn ambient_pressure(&self) -> f64 {
        self.ambient_pressure
    }

    /// The gas model.
    pub fn gas(&self) -> &G {
        &self.gas
    }

    /// The gas model, mutably (e.g. to call [`GasModel::reset_reference`]).
    pub fn gas_mut(&mut self) -> &mut G {
        &mut self.gas
    }

    /// The state at the last [`PressureLoad::evaluate`].
    pub fn state(&self) -> GasState {
        self.state
    }

    /// Evaluates the gas at positions `x` (flat, length `3N`, m) and time `time` (s): computes
    /// `V` and `g = dV/dx`, adds the pressure forces `(p - p_amb) g` (N) to `f` (length `3N`),
    /// and stores what the tangent needs.
    ///
    /// Errors if an index is out of range, a length is wrong, `V <= 0` or not finite, or the
    /// pressure is not finite.
    pub fn evaluate(
        &mut self,
        time: f64,
        x: &[f64],
        triangles: &[[usize; 3]],
        f: &mut [f64],
    ) -> Result<GasState, GasError> {
        if f.len() != x.len() {
            return Err(GasError::LengthMismatch {
                name: "f",
                len: f.len(),
                expected: x.len(),
            });
        }
        self.rank1.vector.resize(x.len(), 0.0);
        let volume = volume_and_gradient(x, triangles, &mut self.rank1.vector)?;
        if !(volume.is_finite() && volume > 0.0) {
            return Err(GasError::InvalidVolume { volume });
        }
        let p = self.gas.absolute_pressure(volume, time);
        let dpdv = self.gas.dpressure_dvolume(volume, time);
        for (quantity, value) in [("absolute pressure", p), ("dp/dV", dpdv)] {
            if !value.is_finite() {
                return Err(GasError::NonFinite {
                    quantity,
                    value,
                    volume,
                    time,
                });
            }
        }
        let gauge = p - self.ambient_pressure;
        for (fi, gi) in f.iter_mut().zip(&self.rank1.vector) {
            *fi += gauge * gi;
        }
        self.dpressure_dvolume = dpdv;
        self.rank1.coefficient = -dpdv;
        self.state = GasState {
            volume,
            absolute_pressure: p,
            gauge_pressure: gauge,
        };
        Ok(self.state)
    }

    /// Potential energy of the loaded gas at the last evaluation, J: `Phi(V, t) + p_amb V`, so
    /// that `f_p = -dE/dx = (p - p_amb) dV/dx` at time `time` ([`GasModel::potential`]; for the
    /// pump the amount at `time`). `None` when the model has no potential.
    pub fn potential(&self, time: f64) -> Option<f64> {
        let v = self.state.volume;
        self.gas
            .potential(v, time)
            .map(|phi| phi + self.ambient_pressure * v)
    }

    /// Potential energy of the loaded gas at positions `x` (flat, m) and time `time` (s), J:
    /// `Phi(V(x), t) + p_amb V(x)` (see [`PressureLoad::potential`]), without changing the state
    /// of the last [`PressureLoad::evaluate`]. `Ok(None)` when the model has no potential; an
    /// error for a bad surface or a non-positive volume.
    pub fn potential_at(
        &self,
        time: f64,
        x: &[f64],
        triangles: &[[usize; 3]],
    ) -> Result<Option<f64>, GasError> {
        check_surface(x, triangles)?;
        let volume = crate::volume::enclosed_volume(x, triangles)?;
        if !(volume.is_finite() && volume > 0.0) {
            return Err(GasError::InvalidVolume { volume });
        }
        Ok(self
            .gas
            .potential(volume, time)
            .map(|phi| phi + self.ambient_pressure * volume))
    }

    /// The rank-1 part `c g g^T` of the tangent at the last evaluation, with `c = -dp/dV >= 0`
    /// (Pa/m^3) and `g = dV/dx` (m^2): Wang et al. 2015, Eq. 16 with the corrected constant (see the type
    /// docs). Return it from `ForceSystem::low_rank_terms` with `std::slice::from_ref`.
    pub fn low_rank_term(&self) -> &LowRankTerm {
        &self.rank1
    }

    /// `dp/dV` at the last evaluation, Pa/m^3.
    pub fn dpressure_dvolume(&self) -> f64 {
        self.dpressure_dvolume
    }

    /// Adds the force differential `df = -K_p dx` at the last evaluation to `df`, matrix-free in
    /// `O(N)`: `df += (dp/dV) (g . dx) g` (Eq. 17 with the corrected constant) plus, if enabled,
    /// the follower term `(p - p_amb) H_V dx`. `x` and `triangles` must be those of the last
    /// [`PressureLoad::evaluate`]; `dx`, `df` have length `3N`.
    pub fn add_differential(
        &self,
        x: &[f64],
        triangles: &[[usize; 3]],
        dx: &[f64],
        df: &mut [f64],
    ) -> Result<(), GasError> {
        let g = &self.rank1.vector;
        for (name, len) in [("x", x.len()), ("dx", dx.len()), ("df", df.len())] {
            if len != g.len() {
                return Err(GasError::LengthMismatch {
                    name,
                    len,
                    expected: g.len(),
                });
            }
        }
        self.add_rank1_differential(dx, df);
        if self.follower {
            check_surface(x, triangles)?;
            add_volume_hessian_product(x, triangles, self.state.gauge_pressure, dx, df);
        }
        Ok(())
    }

    /// Adds the rank-1 part of the force differential at the last evaluation,
    /// `df += (dp/dV) (g . dx) g` (Eq. 17 with the corrected constant), without the follower
    /// term (for a caller that has the follower term in its own element blocks). `dx` and `df`
    /// have the length of `g` (checked by [`PressureLoad::add_differential`]).
    pub fn add_rank1_differential(&self, dx: &[f64], df: &mut [f64]) {
        let g = &self.rank1.vector;
        let gdx: f64 = g.iter().zip(dx).map(|(a, b)| a * b).sum();
        let s = self.dpressure_dvolume * gdx;
        for (d, gi) in df.iter_mut().zip(g) {
            *d += s * gi;
        }
    }

    /// Appends the follower part of the stiffness, `K_f = -(p - p_amb) H_V`, as `(row, col,
    /// value)` triplets (duplicates to be summed), if the follower term is enabled; appends
    /// nothing otherwise. The rank-1 part is never assembled (use
    /// [`PressureLoad::low_rank_term`]).
    pub fn add_follower_triplets(
        &self,
        x: &[f64],
        triangles: &[[usize; 3]],
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), GasError> {
        if self.follower {
            check_surface(x, triangles)?;
            add_volume_hessian_triplets(x, triangles, -self.state.gauge_pressure, triplets);
        }
        Ok(())
    }
}
