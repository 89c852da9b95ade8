//! Shared test support for the `balloon` workspace (not published).
//!
//! Finite-difference checkers used by every crate so that derivatives are verified the same way:
//!
//! * [`check_gradient`]: an energy `E(x)` against its gradient `g(x)` (or a force `f = -g`),
//! * [`check_jacobian`]: a vector function `f(x)` against its directional differential `df(x; dx)`,
//! * [`taylor_remainder_orders`]: the Taylor remainder `|E(x + h dx) - E(x) - h g.dx|`, which must
//!   fall about 4x when `h` halves (second order) if the gradient is right.
//!
//! Tolerances are relative to the magnitude of the quantities compared.

use nalgebra::DVector;

/// Deterministic pseudo-random numbers in `[-1, 1)` (xorshift64*), so tests need no RNG crate and
/// are reproducible.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator from a non-zero seed (zero is replaced by a fixed constant).
    pub fn new(seed: u64) -> Self {
        Self(if seed == 0 {
            0x9E37_79B9_7F4A_7C15
        } else {
            seed
        })
    }

    /// The next number in `[-1, 1)`.
    pub fn next_f64(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let v = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (v >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }

    /// A vector of `n` numbers in `[-1, 1)`.
    pub fn vector(&mut self, n: usize) -> Vec<f64> {
        (0..n).map(|_| self.next_f64()).collect()
    }
}

/// Result of a finite-difference comparison.
#[derive(Clone, Debug)]
pub struct FdReport {
    /// Largest absolute difference between analytic and numeric values.
    pub max_abs_error: f64,
    /// Scale used for the relative error (largest magnitude seen, at least `1e-300`).
    pub scale: f64,
}

impl FdReport {
    /// `max_abs_error / scale`.
    pub fn relative_error(&self) -> f64 {
        self.max_abs_error / self.scale
    }
}

/// Compares the analytic gradient `grad(x)` of `energy` with central differences along every
/// coordinate, using step `h`. Returns the report; panics with a readable message if the relative
/// error exceeds `rel_tol`.
pub fn check_gradient(
    energy: impl Fn(&[f64]) -> f64,
    grad: impl Fn(&[f64]) -> Vec<f64>,
    x: &[f64],
    h: f64,
    rel_tol: f64,
) -> FdReport {
    let g = grad(x);
    assert_eq!(g.len(), x.len(), "gradient length");
    let mut xp = x.to_vec();
    let mut max_err = 0.0f64;
    let mut scale = 1e-300f64;
    let mut worst = 0;
    for i in 0..x.len() {
        xp[i] = x[i] + h;
        let ep = energy(&xp);
        xp[i] = x[i] - h;
        let em = energy(&xp);
        xp[i] = x[i];
        let fd = (ep - em) / (2.0 * h);
        let err = (fd - g[i]).abs();
        if err > max_err {
            max_err = err;
            worst = i;
        }
        scale = scale.max(g[i].abs()).max(fd.abs());
    }
    let rep = FdReport {
        max_abs_error: max_err,
        scale,
    };
    assert!(
        rep.relative_error() <= rel_tol,
        "gradient check failed: relative error {:.3e} > {:.1e} (worst coordinate {worst}, abs {:.3e}, scale {:.3e})",
        rep.relative_error(),
        rel_tol,
        max_err,
        scale
    );
    rep
}

/// Compares the analytic directional differential `differential(x, dx)` of a vector function `f`
/// with central differences `(f(x + h dx) - f(x - h dx)) / 2h` for several random directions.
/// Panics if the relative error exceeds `rel_tol`.
pub fn check_jacobian(
    f: impl Fn(&[f64]) -> Vec<f64>,
    differential: impl Fn(&[f64], &[f64]) -> Vec<f64>,
    x: &[f64],
    h: f64,
    rel_tol: f64,
    seed: u64,
) -> FdReport {
    let mut rng = Rng::new(seed);
    let mut max_err = 0.0f64;
    let mut scale = 1e-300f64;
    for _ in 0..4 {
        let dx = rng.vector(x.len());
        let xp: Vec<f64> = x.iter().zip(&dx).map(|(a, b)| a + h * b).collect();
        let xm: Vec<f64> = x.iter().zip(&dx).map(|(a, b)| a - h * b).collect();
        let fp = f(&xp);
        let fm = f(&xm);
        let an = differential(x, &dx);
        assert_eq!(an.len(), fp.len(), "differential length");
        for i in 0..an.len() {
            let fd = (fp[i] - fm[i]) / (2.0 * h);
            max_err = max_err.max((fd - an[i]).abs());
            scale = scale.max(fd.abs()).max(an[i].abs());
        }
    }
    let rep = FdReport {
        max_abs_error: max_err,
        scale,
    };
    assert!(
        rep.relative_error() <= rel_tol,
        "jacobian check failed: relative error {:.3e} > {:.1e} (abs {:.3e}, scale {:.3e})",
        rep.relative_error(),
        rel_tol,
        max_err,
        scale
    );
    rep
}

/// Taylor remainders `r(h) = |E(x + h dx) - E(x) - h grad.dx|` for `h = h0, h0/2, h0/4, h0/8`.
/// With a correct gradient `r(h) = O(h^2)`, so successive ratios approach 4.
/// Returns the ratios `r(h)/r(h/2)`.
pub fn taylor_remainder_orders(
    energy: impl Fn(&[f64]) -> f64,
    grad: impl Fn(&[f64]) -> Vec<f64>,
    x: &[f64],
    dx: &[f64],
    h0: f64,
) -> Vec<f64> {
    let e0 = energy(x);
    let g = DVector::from_vec(grad(x));
    let d = DVector::from_column_slice(dx);
    let slope = g.dot(&d);
    let mut rems = Vec::new();
    let mut h = h0;
    for _ in 0..4 {
        let xp: Vec<f64> = x.iter().zip(dx).map(|(a, b)| a + h * b).collect();
        rems.push((energy(&xp) - e0 - h * slope).abs());
        h *= 0.5;
    }
    rems.windows(2).map(|w| w[0] / w[1].max(1e-300)).collect()
}

/// Asserts that the Taylor-remainder ratios of [`taylor_remainder_orders`] are close to 4
/// (between 3 and 5 for the ratios whose remainders are above round-off).
pub fn assert_second_order(ratios: &[f64]) {
    assert!(!ratios.is_empty());
    for r in ratios {
        assert!(
            (3.0..=5.0).contains(r),
            "Taylor remainder ratios {ratios:?} are not ~4: gradient is wrong"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detects_wrong_gradient() {
        let e = |x: &[f64]| x[0] * x[0] * x[1] + x[1].sin();
        let g = |x: &[f64]| vec![2.0 * x[0] * x[1], x[0] * x[0] + x[1].cos()];
        check_gradient(e, g, &[0.3, -0.7], 1e-6, 1e-8);
        let bad = |x: &[f64]| vec![2.0 * x[0] * x[1], x[0] * x[0]];
        let r = std::panic::catch_unwind(|| check_gradient(e, bad, &[0.3, -0.7], 1e-6, 1e-8));
        assert!(r.is_err());
        let ratios = taylor_remainder_orders(e, g, &[0.3, -0.7], &[0.5, 0.2], 1e-2);
        assert_second_order(&ratios);
    }

    #[test]
    fn detects_wrong_jacobian() {
        let f = |x: &[f64]| vec![x[0] * x[1], x[1].exp()];
        let df = |x: &[f64], d: &[f64]| vec![d[0] * x[1] + x[0] * d[1], x[1].exp() * d[1]];
        check_jacobian(f, df, &[0.4, 0.1], 1e-6, 1e-8, 7);
        let bad = |x: &[f64], d: &[f64]| vec![d[0] * x[1], x[1].exp() * d[1]];
        assert!(
            std::panic::catch_unwind(|| check_jacobian(f, bad, &[0.4, 0.1], 1e-6, 1e-8, 7))
                .is_err()
        );
    }
}
