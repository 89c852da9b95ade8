//! Analytic equilibrium of the pressurised 2D two-layer N-gon (derivation: `docs/two-layer.md`).
//!
//! With inner radius `a` and outer radius `b` of regular N-gons (rest `a0`, `b0`): structural
//! sides `2 r sin(pi/N)`, radius springs `b - a`, shear springs
//! `sqrt(a^2 + b^2 - 2ab cos(2 pi / N))`, and per-layer gas energy `-c ln A` with `A ~ r^2`
//! (`c = p A0`, Song 2009, P = nRT/V). The equilibrium solves `dU/da = dU/db = 0`; a damped
//! simulation must settle there.

/// The 2D body whose equilibrium is computed (all springs undamped at equilibrium).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CircleBody {
    /// Particles per layer (N >= 3).
    pub particles: usize,
    /// Rest inner radius `a0`, m.
    pub inner_radius: f64,
    /// Rest outer radius `b0`, m.
    pub outer_radius: f64,
    /// Structural spring stiffness, N/m.
    pub structural: f64,
    /// Radius spring stiffness, N/m.
    pub radius: f64,
    /// Shear spring stiffness (left and right), N/m.
    pub shear: f64,
    /// Initial outer-layer gas pressure at the rest area, Pa (per unit depth).
    pub outer_pressure: f64,
    /// Initial inner-layer gas pressure at the rest area, Pa.
    pub inner_pressure: f64,
}

impl CircleBody {
    /// `(dU/da, dU/db)` at radii `(a, b)`.
    pub fn energy_gradient(&self, a: f64, b: f64) -> [f64; 2] {
        let nf = self.particles as f64;
        let th = std::f64::consts::TAU / nf;
        let s2 = (2.0 * (std::f64::consts::PI / nf).sin()).powi(2);
        let area = |r: f64| 0.5 * nf * r * r * th.sin();
        let (a0, b0) = (self.inner_radius, self.outer_radius);
        let (c_out, c_in) = (
            self.outer_pressure * area(b0),
            self.inner_pressure * area(a0),
        );
        let shear_len = |a: f64, b: f64| (a * a + b * b - 2.0 * a * b * th.cos()).sqrt();
        let (l, l0) = (shear_len(a, b), shear_len(a0, b0));
        let r = (b - a) - (b0 - a0);
        let (ks, kr, ksh) = (self.structural, self.radius, self.shear);
        [
            nf * (ks * s2 * (a - a0) - kr * r + 2.0 * ksh * (l - l0) * (a - b * th.cos()) / l)
                - 2.0 * c_in / a,
            nf * (ks * s2 * (b - b0) + kr * r + 2.0 * ksh * (l - l0) * (b - a * th.cos()) / l)
                - 2.0 * c_out / b,
        ]
    }

    /// Equilibrium radii `(a, b)` by Newton's method from the rest radii (central-difference
    /// Jacobian); `None` when it does not converge to `|dU| < 1e-9`.
    pub fn equilibrium_radii(&self) -> Option<(f64, f64)> {
        let (mut a, mut b) = (self.inner_radius, self.outer_radius);
        let g = |a: f64, b: f64| self.energy_gradient(a, b);
        for _ in 0..50 {
            let r = g(a, b);
            let h = 1e-7;
            let (gap, gam) = (g(a + h, b), g(a - h, b));
            let (gbp, gbm) = (g(a, b + h), g(a, b - h));
            let j = [
                [(gap[0] - gam[0]) / (2.0 * h), (gbp[0] - gbm[0]) / (2.0 * h)],
                [(gap[1] - gam[1]) / (2.0 * h), (gbp[1] - gbm[1]) / (2.0 * h)],
            ];
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            a -= (j[1][1] * r[0] - j[0][1] * r[1]) / det;
            b -= (-j[1][0] * r[0] + j[0][0] * r[1]) / det;
        }
        let r = g(a, b);
        (r[0].abs() < 1e-9 && r[1].abs() < 1e-9 && a > 0.0 && b > a).then_some((a, b))
    }
}
