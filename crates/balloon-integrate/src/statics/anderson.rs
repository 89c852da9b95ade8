//! Anderson acceleration of a fixed-point iteration on a vector (Walker and Ni 2011, "Anderson
//! acceleration for fixed-point iterations", type II): [`Anderson`].
//!
//! For a map `G` with a fixed point `y* = G(y*)`, the plain iteration `y_{k+1} = G(y_k)`
//! converges linearly at best. Anderson keeps the last `m + 1` iterates and their images and
//! extrapolates: with `f_j = G(y_j) - y_j` and the differences `dF`, `dG` of consecutive `f_j`
//! and `G(y_j)`,
//!
//! ```text
//! y_{k+1} = G(y_k) - dG gamma,    gamma = argmin |f_k - dF gamma|.
//! ```
//!
//! On an affine map of dimension `d` it reaches the fixed point after `d` differences. The
//! iterates are scaled by the first one seen (`y_e / |y0_e|`), so components of different
//! magnitude weigh alike. Safeguards fall back to the plain update `G(y_k)` (and start a new
//! history): when the residual `|f_k|` grew, when the least-squares problem is singular, or
//! when the extrapolation would move a component by more than
//! [`AndersonParams::max_deviation`] times its plain update's value (or, with
//! [`AndersonParams::positive`], make it non-positive).
//!
//! A *companion* vector can follow the iterates: a state that depends on the iterate to first
//! order linearly (for example the equilibrium solved at a thickness). An extrapolated update
//! moves it to the kept companions combined with the same weights,
//! `x_k - sum_j gamma_j (x_{j+1} - x_j)`, a first-order prediction of the companion at the new
//! iterate.
//!
//! The static rest shape of a shell (`balloon_shell::statics`) accelerates its thickness fixed
//! point with it.
//!
//! ```
//! use balloon_integrate::statics::{Anderson, AndersonParams};
//! // The affine map y -> A y + b in 2D, fixed point (1, 1).
//! let g = |y: &[f64]| vec![0.5 * y[0] + 0.1 * y[1] + 0.4, -0.2 * y[0] + 0.6 * y[1] + 0.6];
//! let mut anderson = Anderson::new(AndersonParams::default());
//! let (mut y, mut companion) = (vec![2.0, 3.0], Vec::new());
//! for _ in 0..3 {
//!     let image = g(&y);
//!     anderson.next(&mut y, image, &mut companion);
//! }
//! // Two differences span the plane: the third update lands on the fixed point.
//! assert!((y[0] - 1.0).abs() < 1e-12 && (y[1] - 1.0).abs() < 1e-12);
//! ```

use std::collections::VecDeque;

/// Parameters of [`Anderson`] acceleration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AndersonParams {
    /// Previous iterates kept, `m` (default 3): the extrapolation combines up to `m`
    /// differences.
    pub depth: usize,
    /// The largest change of a component the extrapolation may make from its plain update
    /// `G(y_k)`, relative to that update's value (default 0.5).
    pub max_deviation: f64,
    /// Whether the components must stay positive (default `false`; a thickness must).
    pub positive: bool,
}

impl Default for AndersonParams {
    fn default() -> Self {
        Self {
            depth: 3,
            max_deviation: 0.5,
            positive: false,
        }
    }
}

/// One kept iterate: the scaled iterate, its scaled image, its companion.
type Iterate = (Vec<f64>, Vec<f64>, Vec<f64>);

/// Anderson acceleration (type II) of a fixed point `y = G(y)`, with safeguards and an
/// optional companion vector (module docs).
#[derive(Clone, Debug, Default)]
pub struct Anderson {
    params: AndersonParams,
    /// `|y0_e|` of the first iterate seen (at least the smallest positive number).
    scale: Vec<f64>,
    /// `(y_j, G(y_j), x_j)` scaled, oldest first, at most `depth + 1`.
    history: VecDeque<Iterate>,
}

impl Anderson {
    /// An accelerator with no history.
    pub fn new(params: AndersonParams) -> Self {
        Self {
            params,
            scale: Vec::new(),
            history: VecDeque::new(),
        }
    }

    /// The parameters.
    pub fn params(&self) -> &AndersonParams {
        &self.params
    }

    /// Sets `y` (the iterate `G` was evaluated at) to the next iterate from `image = G(y)`;
    /// returns whether the update was extrapolated. An extrapolated update also moves
    /// `companion` (the state belonging to `y`, any length, empty for none) to the same
    /// combination of the kept companions; a plain update (`y = G(y)`) keeps it. A `y` of
    /// another length than the last one starts afresh.
    pub fn next(&mut self, y: &mut [f64], image: Vec<f64>, companion: &mut [f64]) -> bool {
        if self.scale.len() != y.len() {
            self.scale = y.iter().map(|v| v.abs().max(f64::MIN_POSITIVE)).collect();
            self.history.clear();
        }
        let ys: Vec<f64> = y.iter().zip(&self.scale).map(|(h, s)| h / s).collect();
        let g: Vec<f64> = image.iter().zip(&self.scale).map(|(h, s)| h / s).collect();
        let residual =
            |y: &[f64], g: &[f64]| -> Vec<f64> { g.iter().zip(y).map(|(g, y)| g - y).collect() };
        let f = residual(&ys, &g);
        if let Some(last) = self.history.back()
            && norm(&f) >= norm(&residual(&last.0, &last.1))
        {
            self.history.clear();
        }
        self.history.push_back((ys, g, companion.to_vec()));
        if self.history.len() > self.params.depth + 1 {
            self.history.pop_front();
        }
        if self.history.len() < 2 {
            y.copy_from_slice(&image);
            return false;
        }
        match self.extrapolate() {
            Some((next, gamma)) => {
                for ((h, y), s) in y.iter_mut().zip(&next).zip(&self.scale) {
                    *h = y * s;
                }
                let predicted = self.predict_companion(&gamma);
                if predicted.iter().all(|v| v.is_finite()) {
                    companion.copy_from_slice(&predicted);
                }
                true
            }
            None => {
                // Safeguard: the plain update, which starts a new history.
                self.history.drain(..self.history.len() - 1);
                y.copy_from_slice(&image);
                false
            }
        }
    }

    /// `x_k - dX gamma`: the companions combined with the weights of [`Self::extrapolate`].
    fn predict_companion(&self, gamma: &nalgebra::DVector<f64>) -> Vec<f64> {
        let m = self.history.len() - 1;
        let mut x = self.history[m].2.clone();
        for (j, c) in gamma.iter().enumerate() {
            let (a, b) = (&self.history[j].2, &self.history[j + 1].2);
            for ((x, a), b) in x.iter_mut().zip(a).zip(b) {
                *x -= c * (b - a);
            }
        }
        x
    }

    /// `g_k - dG gamma` and `gamma` from the history (at least two entries; the last is
    /// iterate `k`), or `None` (safeguards).
    fn extrapolate(&self) -> Option<(Vec<f64>, nalgebra::DVector<f64>)> {
        let m = self.history.len().checked_sub(1).filter(|m| *m > 0)?;
        let k = &self.history[m];
        let fk: Vec<f64> = k.1.iter().zip(&k.0).map(|(g, y)| g - y).collect();
        // Columns j: f_{j+1} - f_j and g_{j+1} - g_j.
        let mut df = Vec::with_capacity(m);
        let mut dg = Vec::with_capacity(m);
        for j in 0..m {
            let (a, b) = (&self.history[j], &self.history[j + 1]);
            df.push(
                (0..fk.len())
                    .map(|i| (b.1[i] - b.0[i]) - (a.1[i] - a.0[i]))
                    .collect::<Vec<f64>>(),
            );
            dg.push((0..fk.len()).map(|i| b.1[i] - a.1[i]).collect::<Vec<f64>>());
        }
        let ata = nalgebra::DMatrix::from_fn(m, m, |a, b| dot(&df[a], &df[b]));
        let atb = nalgebra::DVector::from_fn(m, |a, _| dot(&df[a], &fk));
        let largest = ata.diagonal().max();
        if !(largest > 0.0 && largest.is_finite()) {
            return None;
        }
        let gamma = ata.svd(true, true).solve(&atb, 1e-12 * largest).ok()?;
        if !gamma.iter().all(|v| v.is_finite()) {
            return None;
        }
        let mut next = k.1.clone();
        for (c, col) in gamma.iter().zip(&dg) {
            for (n, d) in next.iter_mut().zip(col) {
                *n -= c * d;
            }
        }
        let (positive, max_deviation) = (self.params.positive, self.params.max_deviation);
        let safe = next.iter().zip(&k.1).all(|(n, g)| {
            n.is_finite() && (!positive || *n > 0.0) && (n - g).abs() <= max_deviation * g.abs()
        });
        safe.then_some((next, gamma))
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On an affine fixed point `h = A h + b` of two components with an affine companion
    /// `x(h) = C h + d`, Anderson with two differences is exact: the extrapolated iterate is
    /// the fixed point, and the predicted companion is its value there, `C h* + d` (the kept
    /// companions combined with the same weights); with one difference the companion moves; a
    /// plain update keeps it.
    #[test]
    fn extrapolated_iterate_comes_with_the_companion_combined_alike() {
        let a = nalgebra::Matrix2::new(0.3, 0.1, -0.05, 0.4);
        let b = nalgebra::Vector2::new(0.7, 0.6);
        let c = nalgebra::Matrix3x2::new(1.0, 2.0, -0.5, 0.25, 3.0, -1.0);
        let d = nalgebra::Vector3::new(0.1, -0.2, 0.3);
        let fixed = (nalgebra::Matrix2::identity() - a).try_inverse().unwrap() * b;
        let shape = |h: &[f64]| {
            let x = c * nalgebra::Vector2::new(h[0], h[1]) + d;
            vec![x[0], x[1], x[2]]
        };
        let mut acc = Anderson::new(AndersonParams {
            positive: true,
            ..AndersonParams::default()
        });
        let mut h = vec![1.0, 1.0];
        let mut accelerated = Vec::new();
        for _ in 0..3 {
            let mut x = shape(&h);
            let g = a * nalgebra::Vector2::new(h[0], h[1]) + b;
            let solved_at = h.clone();
            let was = acc.next(&mut h, vec![g[0], g[1]], &mut x);
            accelerated.push(was);
            if accelerated.len() == 2 {
                // One difference: a first-order prediction, moved from the last companion.
                assert!(was && x != shape(&solved_at));
            } else if was {
                let want = shape(&h);
                for i in 0..3 {
                    assert!((x[i] - want[i]).abs() <= 1e-12, "{i}: {x:?} vs {want:?}");
                }
            } else {
                assert_eq!(x, shape(&solved_at), "a plain update keeps the companion");
            }
        }
        assert_eq!(accelerated, [false, true, true]);
        // Two differences span the plane: the third iterate is the fixed point.
        assert!((h[0] - fixed[0]).abs() <= 1e-12 && (h[1] - fixed[1]).abs() <= 1e-12);
    }

    /// The safeguards: an extrapolation that would leave a positive component non-positive or
    /// move it by more than `max_deviation` of its plain update falls back to the plain update.
    #[test]
    fn unsafe_extrapolations_fall_back_to_the_plain_update() {
        // A map that overshoots wildly: y -> 10 - 3 y contracts nowhere, so the residual
        // grows and the history restarts; every update is the plain one.
        let mut acc = Anderson::new(AndersonParams {
            positive: true,
            ..AndersonParams::default()
        });
        let mut y = vec![1.0];
        for _ in 0..4 {
            let image = vec![10.0 - 3.0 * y[0]];
            let plain = image.clone();
            let was = acc.next(&mut y, image, &mut []);
            assert!(!was);
            assert_eq!(y, plain);
        }
        // A tight deviation bound refuses the extrapolation of a slowly converging map.
        let mut acc = Anderson::new(AndersonParams {
            max_deviation: 1e-6,
            ..AndersonParams::default()
        });
        let mut y = vec![2.0];
        for _ in 0..3 {
            let image = vec![0.9 * y[0] + 0.1];
            let plain = image.clone();
            assert!(!acc.next(&mut y, image, &mut []));
            assert_eq!(y, plain);
        }
    }
}
