//! Discrete-shell hinge bending element (Grinspun, Hirani, Desbrun and Schröder 2003,
//! "Discrete Shells", Eq. 3), with the gradient of the dihedral angle of Bridson, Marino and
//! Fedkiw 2003 and its exact Hessian by forward-mode differentiation of that gradient.

use std::f64::consts::PI;
use std::ops::{Add, Div, Mul, Neg, Sub};

use nalgebra::{SMatrix, Vector3};

use crate::ElementError;
use crate::triangle::DEGENERACY_TOL;

const NAME: &str = "hinge";

/// A bending hinge of a triangle mesh: the interior edge `(x0, x1)` with its two triangles
/// `A = (x0, x1, x2)` and `B = (x1, x0, x3)` of a consistently oriented mesh.
///
/// **Angle.** With `e = x1 - x0`, `nA = (x1 - x0) x (x2 - x0)` and `nB = (x0 - x1) x (x3 - x1)`
/// (the triangles' area-weighted normals), the dihedral angle is
/// `theta = atan2((nA x nB) . e / |e|, nA . nB)` in `[-pi, pi]` ([`Hinge::angle`]): 0 on a flat
/// hinge, positive when wing `B` turns away from the side `nA` points to (a convex fold for
/// outward normals), negative when it turns toward it. Its gradient (Bridson, Marino and Fedkiw
/// 2003) is `g2 = -|e| nA / |nA|^2`, `g3 = -|e| nB / |nB|^2`, `g1 = -(sa g2 + sb g3)`,
/// `g0 = -(g1 + g2 + g3)` with `sa = (x2 - x0) . e / |e|^2`, `sb = (x3 - x0) . e / |e|^2`.
///
/// **Energy** (Grinspun et al. 2003, Eq. 3, with a bending modulus `D` in N m passed per call):
///
/// `E = D/2 w delta^2`,  `delta = theta - theta_bar` wrapped into `(-pi, pi]`,
/// `w = 3 |E|^2 / (A_A + A_B)` (dimensionless),
///
/// with the rest angle `theta_bar`, the rest edge length `|E|` and the rest triangle areas
/// `A_A`, `A_B` ([`Hinge::rest_angle`], [`Hinge::weight`]); `w = |E| / h_E` with `h_E` a sixth
/// of the sum of the two rest triangles' heights over the edge, Grinspun et al.'s weight. The
/// energy is invariant under rigid motions and under a uniform scaling of both the rest and the
/// current shape (`theta` and `w` are), so its forces have zero sum and zero torque. The
/// wrapping puts a kink at `delta = ±pi` (a hinge folded right through): the energy is
/// continuous there but its gradient changes sign.
///
/// **Calibration against a plate** (derived here from a second-order expansion of the dihedral
/// angles of a triangulated quadric and checked numerically by the tests; not stated in the
/// paper). `D` is *not* the
/// flexural rigidity of a Kirchhoff plate. Summed over all the interior edges of a fine flat mesh
/// bent into a cylinder of curvature `k`, the hinge energy tends to `c D/2 k^2 A` (`A` the mesh
/// area), not to the plate's `D/2 k^2 A`, with a factor `c` that depends on the triangulation:
///
/// * `c = 3` for a rectangular grid with diagonals bent along a grid direction (the diagonals
///   and the edges along the bend direction stay flat; each edge along the axis carries
///   `w theta^2 = (3 b/a)(a/R)^2`, so a strip of `N` cells gets exactly `3 (N-1)/N`);
/// * `c = 3` for an equilateral mesh, whatever the direction of the bend (for such a mesh the
///   energy density tends to `D/2 [(k1 + k2)^2 + 2 (k1 - k2)^2]`, i.e. exactly the plate's
///   `D/2 (k1 + k2)^2` on a sphere but three times it on a cylinder);
/// * `c = 6 + 3 sin 2phi - 3 cos^2 2phi`, between 3 and 9, for a grid of square cells with
///   diagonals along `(1, 1)` bent along the direction at angle `phi` to the grid's first axis:
///   3 when the bend runs across the diagonals (`phi = -pi/4`), 9 when it runs along them
///   (`phi = pi/4`).
///
/// The tests check these values (`hinge/tests.rs`). No modulus reproduces a plate at every
/// curvature, even on an equilateral mesh: `D = D_plate` gives the plate's energy on a sphere
/// and three times it on a cylinder, `D = D_plate / 3` the plate's cylinder and a third of its
/// sphere; on a right-triangle grid the answer also depends on the direction of the bend.
///
/// Conventions as for the other elements: positions in metres, forces in newtons,
/// `forces = -dE/dx`, stiffness `K = d^2E/dx^2 = D w (g g^T + delta H_theta)` (N/m, 12x12,
/// vertex-major `[x0 y0 z0 x1 ...]`, symmetric, in general indefinite), with `H_theta` the exact
/// Hessian of the angle. No allocation.
///
/// **Degenerate current state.** A current triangle of zero area (`nA = 0` or `nB = 0`) leaves
/// the angle undefined. The methods do not check for it and return no error: the forces and the
/// stiffness are then non-finite (NaN), and the angle and energy are meaningless (the angle is
/// `atan2(0, 0) = 0` for an exactly zero normal, NaN for `x0 = x1`). The caller (the shell)
/// detects and reports the degenerate triangle itself.
///
/// ```
/// use balloon_element::Hinge;
/// use nalgebra::Vector3;
///
/// // A flat unit square split along its diagonal (x0, x1).
/// let rest = [
///     Vector3::new(0.0, 0.0, 0.0),
///     Vector3::new(1.0, 1.0, 0.0),
///     Vector3::new(0.0, 1.0, 0.0),
///     Vector3::new(1.0, 0.0, 0.0),
/// ];
/// let hinge = Hinge::try_new(&rest)?;
/// assert_eq!(hinge.rest_angle(), 0.0);
/// assert!((hinge.weight() - 6.0).abs() < 1e-12); // 3 |E|^2 / (1/2 + 1/2)
/// // Lift x3 out of the plane: the hinge folds and resists.
/// let mut x = rest;
/// x[3].z = 0.3;
/// let (f, k) = hinge.forces_and_stiffness(&x, 1.0e-3);
/// assert!(hinge.energy(&x, 1.0e-3) > 0.0);
/// assert!(f[3].z < 0.0); // pushed back toward the plane
/// assert!((k - k.transpose()).norm() == 0.0);
/// # Ok::<(), balloon_element::ElementError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hinge {
    rest_angle: f64,
    weight: f64,
}

impl Hinge {
    /// Rest data from the rest positions `rest = [X0, X1, X2, X3]` (m) of the hinge with edge
    /// `(X0, X1)` and triangles `A = (X0, X1, X2)`, `B = (X1, X0, X3)`: the rest angle
    /// `theta_bar` and the weight `w = 3 |E|^2 / (A_A + A_B)`.
    ///
    /// # Errors
    /// * [`ElementError::NonFinite`] (quantity `rest position`) for a non-finite position;
    /// * [`ElementError::DegenerateRest`] (quantity `area`) if triangle `A` or `B` is (near)
    ///   degenerate, `|E12 x E13| <= 1e-12 (|E12|^2 + |E13|^2)` as for the triangle elements
    ///   (this includes coincident `X0`, `X1`).
    pub fn try_new(rest: &[Vector3<f64>; 4]) -> Result<Self, ElementError> {
        if rest.iter().any(|p| !p.iter().all(|v| v.is_finite())) {
            return Err(ElementError::NonFinite {
                element: NAME,
                quantity: "rest position",
            });
        }
        let [x0, x1, x2, x3] = rest;
        let area_a = rest_area(&(x1 - x0), &(x2 - x0))?;
        let area_b = rest_area(&(x0 - x1), &(x3 - x1))?;
        let weight = 3.0 * (x1 - x0).norm_squared() / (area_a + area_b);
        Ok(Self {
            rest_angle: Self::angle(rest),
            weight,
        })
    }

    /// The rest dihedral angle `theta_bar` (rad, in `[-pi, pi]`).
    #[inline]
    pub fn rest_angle(&self) -> f64 {
        self.rest_angle
    }

    /// The weight `w = 3 |E|^2 / (A_A + A_B)` (dimensionless).
    #[inline]
    pub fn weight(&self) -> f64 {
        self.weight
    }

    /// The dihedral angle `theta = atan2((nA x nB) . e / |e|, nA . nB)` (rad, in `[-pi, pi]`) of
    /// the hinge at `x = [x0, x1, x2, x3]` (m); 0 when flat. NaN if `x0 = x1`.
    #[inline]
    pub fn angle(x: &[Vector3<f64>; 4]) -> f64 {
        let e = x[1] - x[0];
        let na = e.cross(&(x[2] - x[0]));
        let nb = (x[3] - x[0]).cross(&e);
        (na.cross(&nb).dot(&e) / e.norm()).atan2(na.dot(&nb))
    }

    /// `delta = theta(x) - theta_bar` wrapped into `(-pi, pi]` (rad).
    #[inline]
    fn delta(&self, theta: f64) -> f64 {
        let d = theta - self.rest_angle;
        if d > PI {
            d - 2.0 * PI
        } else if d <= -PI {
            d + 2.0 * PI
        } else {
            d
        }
    }

    /// Bending energy `D/2 w delta^2` (J) at `x` (m) with modulus `modulus` = `D` (N m, `>= 0`).
    #[inline]
    pub fn energy(&self, x: &[Vector3<f64>; 4], modulus: f64) -> f64 {
        let d = self.delta(Self::angle(x));
        0.5 * modulus * self.weight * d * d
    }

    /// Forces `f = -dE/dx = -D w delta g` (N) on `[x0, x1, x2, x3]`.
    #[inline]
    pub fn forces(&self, x: &[Vector3<f64>; 4], modulus: f64) -> [Vector3<f64>; 4] {
        self.forces_and_energy(x, modulus).0
    }

    /// Forces (N) and energy (J) together, sharing the angle.
    #[inline]
    pub fn forces_and_energy(
        &self,
        x: &[Vector3<f64>; 4],
        modulus: f64,
    ) -> ([Vector3<f64>; 4], f64) {
        let xs = x.map(|p| [p.x, p.y, p.z]);
        let g = angle_gradient(&xs);
        let d = self.delta(Self::angle(x));
        let s = -modulus * self.weight * d;
        let f = g.map(|gi| Vector3::new(gi[0] * s, gi[1] * s, gi[2] * s));
        (f, 0.5 * modulus * self.weight * d * d)
    }

    /// Forces (N) and the exact stiffness `K = d^2E/dx^2 = D w (g g^T + delta H_theta)` (N/m,
    /// 12x12, vertex-major, symmetric; indefinite in general, e.g. far from rest). The forces
    /// are bit for bit those of [`Hinge::forces`].
    pub fn forces_and_stiffness(
        &self,
        x: &[Vector3<f64>; 4],
        modulus: f64,
    ) -> ([Vector3<f64>; 4], SMatrix<f64, 12, 12>) {
        let (g, h) = angle_gradient_and_hessian(x);
        let d = self.delta(Self::angle(x));
        let dw = modulus * self.weight;
        // The forces of the plain `f64` path, bit for bit those of `forces` (the gradient's
        // dual evaluation rounds differently).
        let f = self.forces(x, modulus);
        let mut k = SMatrix::<f64, 12, 12>::zeros();
        for c in 0..12 {
            for r in 0..12 {
                k[(r, c)] = dw * (g[r] * g[c] + d * h[r][c]);
            }
        }
        // H_theta is a Jacobian of a gradient, symmetric up to round-off: symmetrise.
        for c in 0..12 {
            for r in 0..c {
                let m = 0.5 * (k[(r, c)] + k[(c, r)]);
                k[(r, c)] = m;
                k[(c, r)] = m;
            }
        }
        (f, k)
    }
}

impl Hinge {
    /// The gradient `[g0, g1, g2, g3]` (1/m) of the dihedral angle [`Hinge::angle`] at
    /// `x = [x0, x1, x2, x3]` (m), Bridson, Marino and Fedkiw 2003 (the form in the [`Hinge`]
    /// documentation); the same vectors the forces are made of. Non-finite for a current
    /// triangle of zero area.
    pub fn angle_gradient(x: &[Vector3<f64>; 4]) -> [Vector3<f64>; 4] {
        let xs = x.map(|p| [p.x, p.y, p.z]);
        angle_gradient(&xs).map(|g| Vector3::new(g[0], g[1], g[2]))
    }

    /// The gradient `dw/dX` of the weight `w = 3 |E|^2 / (A_A + A_B)` with respect to the rest
    /// positions `rest = [X0, X1, X2, X3]` (1/m):
    /// `dw = 3 d|E|^2 / (A_A + A_B) - w (dA_A + dA_B) / (A_A + A_B)`, with
    /// `d|E|^2/dX1 = -d|E|^2/dX0 = 2 E` and the area gradients
    /// `dA/dP_i = 1/2 n x (P_(i+2) - P_(i+1))` of a triangle `(P0, P1, P2)` with unit normal `n`
    /// (cyclic indices). For a rest hinge that [`Hinge::try_new`] accepts; not checked here.
    pub fn weight_gradient(rest: &[Vector3<f64>; 4]) -> [Vector3<f64>; 4] {
        let [x0, x1, x2, x3] = rest;
        let e = x1 - x0;
        let na = e.cross(&(x2 - x0));
        let nb = (x0 - x1).cross(&(x3 - x1));
        let (la, lb) = (na.norm(), nb.norm());
        let (ua, ub) = (na / la, nb / lb);
        let sum = 0.5 * (la + lb);
        let w = 3.0 * e.norm_squared() / sum;
        // Triangle A = (X0, X1, X2), triangle B = (X1, X0, X3).
        let da = [
            0.5 * ua.cross(&(x2 - x1)),
            0.5 * ua.cross(&(x0 - x2)),
            0.5 * ua.cross(&(x1 - x0)),
        ];
        let db = [
            0.5 * ub.cross(&(x3 - x0)),
            0.5 * ub.cross(&(x1 - x3)),
            0.5 * ub.cross(&(x0 - x1)),
        ];
        // Area gradient per hinge corner: A holds X0, X1, X2; B holds X1 (its 0), X0 (its 1),
        // X3 (its 2).
        let darea = [da[0] + db[1], da[1] + db[0], da[2], db[2]];
        let de2 = [-2.0 * e, 2.0 * e, Vector3::zeros(), Vector3::zeros()];
        std::array::from_fn(|i| (3.0 * de2[i] - w * darea[i]) / sum)
    }

    /// Forces (N, bit for bit those of [`Hinge::forces`]) and their exact Jacobian with respect
    /// to the rest positions `rest` (N/m, 12x12, vertex-major; rows the forces on
    /// `[x0, x1, x2, x3]`, columns `[X0, X1, X2, X3]`), for a hinge built from `rest`
    /// (`Hinge::try_new(rest)`), at the current positions `x` with modulus `modulus` = `D`:
    ///
    /// `df/dX = -D g(x) (delta dw/dX - w dtheta_bar/dX)^T`,
    ///
    /// `g(x)` the angle gradient at `x` ([`Hinge::angle_gradient`]), `dw/dX`
    /// [`Hinge::weight_gradient`] and `dtheta_bar/dX` the angle gradient at the rest hinge (the
    /// forces `-D w delta g(x)` depend on the rest shape only through `w` and `theta_bar`;
    /// the wrapping of `delta` does not change `d delta / d theta_bar = -1`). The inverse
    /// problem (the rest shape whose equilibrium is a given shape) needs it. Rank one, and
    /// zero under rigid motions and uniform scalings of `rest` (`w` and `theta_bar` do not
    /// change).
    pub fn forces_and_rest_jacobian(
        &self,
        rest: &[Vector3<f64>; 4],
        x: &[Vector3<f64>; 4],
        modulus: f64,
    ) -> ([Vector3<f64>; 4], SMatrix<f64, 12, 12>) {
        let f = self.forces(x, modulus);
        let g = Self::angle_gradient(x);
        let gbar = Self::angle_gradient(rest);
        let dw = Self::weight_gradient(rest);
        let d = self.delta(Self::angle(x));
        let c: [Vector3<f64>; 4] = std::array::from_fn(|b| d * dw[b] - self.weight * gbar[b]);
        let mut j = SMatrix::<f64, 12, 12>::zeros();
        for b in 0..4 {
            for l in 0..3 {
                let s = -modulus * c[b][l];
                for a in 0..4 {
                    for k in 0..3 {
                        j[(3 * a + k, 3 * b + l)] = s * g[a][k];
                    }
                }
            }
        }
        (f, j)
    }
}

/// Area of the rest triangle with edges `e1`, `e2` from its first vertex, with the degeneracy
/// test of `crate::triangle` (`|e1 x e2| <= 1e-12 (|e1|^2 + |e2|^2)`).
fn rest_area(e1: &Vector3<f64>, e2: &Vector3<f64>) -> Result<f64, ElementError> {
    let nn = e1.cross(e2).norm();
    if nn <= DEGENERACY_TOL * (e1.norm_squared() + e2.norm_squared()) {
        return Err(ElementError::DegenerateRest {
            element: NAME,
            quantity: "area",
            value: 0.5 * nn,
        });
    }
    Ok(0.5 * nn)
}

/// The scalar operations the closed-form angle gradient needs, so that one formula serves
/// plain `f64` (forces) and [`Dual`] numbers (its Jacobian, the Hessian of the angle).
trait Scalar:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self>
{
    fn sqrt(self) -> Self;
    fn neg(self) -> Self;
}

impl Scalar for f64 {
    #[inline]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline]
    fn neg(self) -> Self {
        -self
    }
}

type V3<S> = [S; 3];

#[inline]
fn sub3<S: Scalar>(a: &V3<S>, b: &V3<S>) -> V3<S> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
fn dot3<S: Scalar>(a: &V3<S>, b: &V3<S>) -> S {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
fn cross3<S: Scalar>(a: &V3<S>, b: &V3<S>) -> V3<S> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline]
fn scale3<S: Scalar>(a: &V3<S>, s: S) -> V3<S> {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// The gradient `[g0, g1, g2, g3]` of the dihedral angle (Bridson, Marino and Fedkiw 2003) at
/// `x`, in the form given in the [`Hinge`] documentation.
#[inline]
fn angle_gradient<S: Scalar>(x: &[V3<S>; 4]) -> [V3<S>; 4] {
    let e = sub3(&x[1], &x[0]);
    let a = sub3(&x[2], &x[0]);
    let b = sub3(&x[3], &x[0]);
    let na = cross3(&e, &a);
    // (x0 - x1) x (x3 - x1) = (-e) x (b - e) = b x e.
    let nb = cross3(&b, &e);
    let le2 = dot3(&e, &e);
    let le = le2.sqrt();
    let g2 = scale3(&na, (le / dot3(&na, &na)).neg());
    let g3 = scale3(&nb, (le / dot3(&nb, &nb)).neg());
    let sa = dot3(&a, &e) / le2;
    let sb = dot3(&b, &e) / le2;
    let g1: V3<S> = std::array::from_fn(|k| (g2[k] * sa + g3[k] * sb).neg());
    let g0: V3<S> = std::array::from_fn(|k| (g1[k] + g2[k] + g3[k]).neg());
    [g0, g1, g2, g3]
}

/// Number of coordinates of a hinge.
const N: usize = 12;

/// A forward-mode dual number: a value and its partial derivatives with respect to the 12
/// coordinates of the hinge (private; only used for the Hessian of the angle).
#[derive(Clone, Copy, Debug)]
struct Dual {
    v: f64,
    d: [f64; N],
}

impl Add for Dual {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Self {
            v: self.v + o.v,
            d: std::array::from_fn(|i| self.d[i] + o.d[i]),
        }
    }
}

impl Sub for Dual {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Self {
            v: self.v - o.v,
            d: std::array::from_fn(|i| self.d[i] - o.d[i]),
        }
    }
}

impl Mul for Dual {
    type Output = Self;
    // The product rule adds the two partial products.
    #[allow(clippy::suspicious_arithmetic_impl)]
    #[inline]
    fn mul(self, o: Self) -> Self {
        Self {
            v: self.v * o.v,
            d: std::array::from_fn(|i| self.d[i] * o.v + self.v * o.d[i]),
        }
    }
}

impl Div for Dual {
    type Output = Self;
    #[inline]
    fn div(self, o: Self) -> Self {
        let inv = 1.0 / o.v;
        let v = self.v * inv;
        Self {
            v,
            d: std::array::from_fn(|i| (self.d[i] - v * o.d[i]) * inv),
        }
    }
}

impl Neg for Dual {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Self {
            v: -self.v,
            d: self.d.map(|a| -a),
        }
    }
}

impl Scalar for Dual {
    #[inline]
    fn sqrt(self) -> Self {
        let v = self.v.sqrt();
        let s = 0.5 / v;
        Self {
            v,
            d: self.d.map(|a| a * s),
        }
    }
    #[inline]
    fn neg(self) -> Self {
        -self
    }
}

/// The gradient `g` of the angle (flattened vertex-major) and its exact Hessian
/// `H_theta[r][c] = d g_r / d x_c` (row-major, symmetric up to round-off), by forward-mode
/// differentiation of [`angle_gradient`].
fn angle_gradient_and_hessian(x: &[Vector3<f64>; 4]) -> ([f64; N], [[f64; N]; N]) {
    let xd: [V3<Dual>; 4] = std::array::from_fn(|i| {
        std::array::from_fn(|k| {
            let mut d = [0.0; N];
            d[3 * i + k] = 1.0;
            Dual { v: x[i][k], d }
        })
    });
    let gd = angle_gradient(&xd);
    let g = std::array::from_fn(|r| gd[r / 3][r % 3].v);
    let h = std::array::from_fn(|r| gd[r / 3][r % 3].d);
    (g, h)
}

#[cfg(test)]
mod tests;
