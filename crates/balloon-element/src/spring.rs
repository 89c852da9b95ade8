//! Damped linear spring between two particles ([`Spring`]) and from a particle to a prescribed,
//! possibly moving, target point ([`TargetSpring`], the drag or "mouse" spring of Song 2009
//! Sec. 4.4).

use nalgebra::{Matrix3, Point3, SMatrix, Vector3};

use crate::ElementError;

const NAME: &str = "spring";

/// Hooke spring with dashpot damping along its axis (Song 2009's mass-spring layers, Diziol, Bender and Bayer 2011's
/// cell springs).
///
/// With `l = |x2 - x1|`, `u = (x2 - x1)/l`:
///
/// * energy `k/2 (l - L0)^2` (J);
/// * force on end 1 `f1 = [k (l - L0) + c (v2 - v1) . u] u`, `f2 = -f1` (N), so a stretched spring
///   pulls its ends together and the dashpot resists the relative axial velocity;
/// * elastic stiffness `K = -df/dx = [[Kl, -Kl], [-Kl, Kl]]`,
///   `Kl = k u u^T + k (1 - L0/l)(I - u u^T)` (N/m), 6x6 ordered `[x1 y1 z1 x2 y2 z2]`;
/// * damping matrix `C = -df/dv = [[Cl, -Cl], [-Cl, Cl]]`, `Cl = c u u^T` (N s/m).
///
/// Zero-length guard: when `l = 0` the direction `u` is undefined; the methods then treat the
/// spring as exerting no force (`u = 0`), which is exact for `L0 = 0` and otherwise a
/// documented fallback; [`Spring::check_state`] reports the situation as an error for solvers
/// that must not continue.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spring {
    rest_length: f64,
    stiffness: f64,
    damping: f64,
}

#[inline]
fn outer(a: &Vector3<f64>, b: &Vector3<f64>) -> Matrix3<f64> {
    a * b.transpose()
}

#[inline]
fn block2(b: &Matrix3<f64>) -> SMatrix<f64, 6, 6> {
    let mut k = SMatrix::<f64, 6, 6>::zeros();
    k.fixed_view_mut::<3, 3>(0, 0).copy_from(b);
    k.fixed_view_mut::<3, 3>(3, 3).copy_from(b);
    k.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-b));
    k.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-b));
    k
}

impl Spring {
    /// A spring with rest length `rest_length` (m, `>= 0`), stiffness `stiffness` (N/m, `>= 0`)
    /// and damping `damping` (N s/m, `>= 0`).
    ///
    /// # Errors
    /// [`ElementError::InvalidParameter`] naming the parameter that is negative or not finite.
    pub fn try_new(rest_length: f64, stiffness: f64, damping: f64) -> Result<Self, ElementError> {
        for (name, value, allowed) in [
            ("rest_length", rest_length, "finite and >= 0 m"),
            ("stiffness", stiffness, "finite and >= 0 N/m"),
            ("damping", damping, "finite and >= 0 N s/m"),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ElementError::InvalidParameter {
                    element: NAME,
                    name,
                    value,
                    allowed,
                });
            }
        }
        Ok(Self {
            rest_length,
            stiffness,
            damping,
        })
    }

    /// A spring with the given constants and no validation, for constants that were validated
    /// upstream (e.g. by a body's builder). A negative or non-finite constant gives an unphysical
    /// spring (one that produces energy), never a panic; use [`Spring::try_new`] for user input.
    pub const fn new(rest_length: f64, stiffness: f64, damping: f64) -> Self {
        Self {
            rest_length,
            stiffness,
            damping,
        }
    }

    /// A spring whose rest length is the current distance between `x1` and `x2`.
    ///
    /// # Errors
    /// As [`Spring::try_new`], plus [`ElementError::DegenerateRest`] if the ends coincide and
    /// [`ElementError::NonFinite`] for non-finite positions.
    pub fn try_from_rest(
        x1: &Vector3<f64>,
        x2: &Vector3<f64>,
        stiffness: f64,
        damping: f64,
    ) -> Result<Self, ElementError> {
        let l = (x2 - x1).norm();
        if !l.is_finite() {
            return Err(ElementError::NonFinite {
                element: NAME,
                quantity: "rest position",
            });
        }
        if l == 0.0 {
            return Err(ElementError::DegenerateRest {
                element: NAME,
                quantity: "length",
                value: l,
            });
        }
        Self::try_new(l, stiffness, damping)
    }

    /// Rest length `L0` (m).
    #[inline]
    pub fn rest_length(&self) -> f64 {
        self.rest_length
    }

    /// Stiffness `k` (N/m).
    #[inline]
    pub fn stiffness_constant(&self) -> f64 {
        self.stiffness
    }

    /// Damping coefficient `c` (N s/m).
    #[inline]
    pub fn damping(&self) -> f64 {
        self.damping
    }

    /// Checks that the ends are finite and do not coincide.
    ///
    /// # Errors
    /// [`ElementError::NonFinite`] or [`ElementError::Degenerate`] (quantity `length`).
    pub fn check_state(&self, x1: &Vector3<f64>, x2: &Vector3<f64>) -> Result<(), ElementError> {
        let l = (x2 - x1).norm();
        if !l.is_finite() {
            return Err(ElementError::NonFinite {
                element: NAME,
                quantity: "position",
            });
        }
        if l == 0.0 {
            return Err(ElementError::Degenerate {
                element: NAME,
                quantity: "length",
                value: l,
            });
        }
        Ok(())
    }

    /// `(l, u)` with the zero-length guard `u = 0`.
    #[inline]
    fn axis(x1: &Vector3<f64>, x2: &Vector3<f64>) -> (f64, Vector3<f64>) {
        let e = x2 - x1;
        let l = e.norm();
        if l > 0.0 {
            (l, e / l)
        } else {
            (0.0, Vector3::zeros())
        }
    }

    /// Current length `|x2 - x1|` (m).
    #[inline]
    pub fn length(&self, x1: &Vector3<f64>, x2: &Vector3<f64>) -> f64 {
        (x2 - x1).norm()
    }

    /// Elastic energy `k/2 (l - L0)^2` (J).
    #[inline]
    pub fn energy(&self, x1: &Vector3<f64>, x2: &Vector3<f64>) -> f64 {
        let s = (x2 - x1).norm() - self.rest_length;
        0.5 * self.stiffness * (s * s)
    }

    /// Forces on the two ends (N), elastic plus damping (Song 2009, Eq. 4.2-4.6): `[f1, -f1]` with
    /// `f1 = [k (l - L0) + c (v2 - v1) . u] u`, evaluated as `[k (l - L0) + c (v2 - v1) . e / l]
    /// e / l` with `e = x2 - x1` (one square root, one division).
    #[inline]
    pub fn force(
        &self,
        x1: &Vector3<f64>,
        x2: &Vector3<f64>,
        v1: &Vector3<f64>,
        v2: &Vector3<f64>,
    ) -> [Vector3<f64>; 2] {
        let e = x2 - x1;
        let len2 = e.x * e.x + e.y * e.y + e.z * e.z;
        if len2 <= 0.0 {
            // The zero-length guard of the type documentation.
            return [Vector3::zeros(); 2];
        }
        let len = len2.sqrt();
        let inv = 1.0 / len;
        let dv = v2 - v1;
        // Relative speed along the spring times its length: (v2 - v1) . e.
        let rel = dv.x * e.x + dv.y * e.y + dv.z * e.z;
        let mag = (self.stiffness * (len - self.rest_length) + self.damping * rel * inv) * inv;
        let f1 = e * mag;
        [f1, -f1]
    }

    /// Elastic forces only (N), `-dE/dx`.
    #[inline]
    pub fn elastic_force(&self, x1: &Vector3<f64>, x2: &Vector3<f64>) -> [Vector3<f64>; 2] {
        let (l, u) = Self::axis(x1, x2);
        let f1 = u * (self.stiffness * (l - self.rest_length));
        [f1, -f1]
    }

    /// `Kl = k u u^T + k (1 - L0/l)(I - u u^T)`. At zero length: `k I` if `L0 = 0` (exact: the
    /// spring is then linear), otherwise zero (the guard of the type documentation).
    #[inline]
    fn elastic_block(&self, x1: &Vector3<f64>, x2: &Vector3<f64>) -> Matrix3<f64> {
        let (l, u) = Self::axis(x1, x2);
        if l == 0.0 {
            // Limit of the block for L0 = 0 (a zero-rest-length spring is linear: f1 = k (x2 - x1)).
            return if self.rest_length == 0.0 {
                Matrix3::identity() * self.stiffness
            } else {
                Matrix3::zeros()
            };
        }
        let uu = outer(&u, &u);
        uu * self.stiffness
            + (Matrix3::identity() - uu) * (self.stiffness * (1.0 - self.rest_length / l))
    }

    /// Differential of the elastic forces along end displacements `dx1`, `dx2` (m):
    /// `df1 = Kl (dx2 - dx1)`, `df2 = -df1` (N). Damping is not included (see
    /// [`Spring::damping_differential`]).
    pub fn force_differential(
        &self,
        x1: &Vector3<f64>,
        x2: &Vector3<f64>,
        dx1: &Vector3<f64>,
        dx2: &Vector3<f64>,
    ) -> [Vector3<f64>; 2] {
        let df1 = self.elastic_block(x1, x2) * (dx2 - dx1);
        [df1, -df1]
    }

    /// Elastic stiffness `K = -df/dx` (N/m), 6x6, symmetric; positive semi-definite when
    /// stretched (`l >= L0`).
    pub fn stiffness(&self, x1: &Vector3<f64>, x2: &Vector3<f64>) -> SMatrix<f64, 6, 6> {
        block2(&self.elastic_block(x1, x2))
    }

    /// Differential of the damping forces along end velocity changes `dv1`, `dv2` (m/s), at fixed
    /// positions: `df1 = c u u^T (dv2 - dv1)`, `df2 = -df1` (N).
    pub fn damping_differential(
        &self,
        x1: &Vector3<f64>,
        x2: &Vector3<f64>,
        dv1: &Vector3<f64>,
        dv2: &Vector3<f64>,
    ) -> [Vector3<f64>; 2] {
        let (_, u) = Self::axis(x1, x2);
        let df1 = u * (self.damping * u.dot(&(dv2 - dv1)));
        [df1, -df1]
    }

    /// Damping matrix `C = -df/dv` (N s/m), 6x6, symmetric positive semi-definite.
    pub fn damping_matrix(&self, x1: &Vector3<f64>, x2: &Vector3<f64>) -> SMatrix<f64, 6, 6> {
        let (_, u) = Self::axis(x1, x2);
        block2(&(outer(&u, &u) * self.damping))
    }
}

/// A [`Spring`] from a particle to a prescribed target point that may move: the drag ("mouse")
/// spring of Song 2009, Sec. 4.4 (Eq. 4.7), which pulls the particle nearest to the mouse.
///
/// With `d = x - p` (particle minus target), `l = |d|`, `u = d / l`:
///
/// * energy `k/2 (l - L0)^2` (J);
/// * force on the particle `f = -[k (l - L0) + c (v - w) . u] u` (N), `w` the target velocity, so
///   the dashpot resists the particle's motion relative to the target along the spring.
///
/// The reaction on the target is not applied (the target is driven, not simulated). At zero
/// length the force is zero (the guard of [`Spring`]).
///
/// ```
/// use balloon_element::{Spring, TargetSpring};
/// use nalgebra::{Point3, Vector3};
/// let drag = TargetSpring::new(Spring::try_new(0.0, 20.0, 0.0)?);
/// let f = drag.force(&Vector3::new(1.0, 0.0, 0.0), &Vector3::zeros(), &Point3::origin(), &Vector3::zeros());
/// assert_eq!(f, Vector3::new(-20.0, 0.0, 0.0));
/// # Ok::<(), balloon_element::ElementError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TargetSpring {
    spring: Spring,
}

impl TargetSpring {
    /// A target spring with the rest length, stiffness and damping of `spring`.
    pub const fn new(spring: Spring) -> Self {
        Self { spring }
    }

    /// The spring constants.
    #[inline]
    pub fn spring(&self) -> &Spring {
        &self.spring
    }

    /// Elastic energy `k/2 (l - L0)^2` (J) of the particle at `x` pulled toward `target`.
    #[inline]
    pub fn energy(&self, x: &Vector3<f64>, target: &Point3<f64>) -> f64 {
        let l = (x - target.coords).norm();
        0.5 * self.spring.stiffness * (l - self.spring.rest_length).powi(2)
    }

    /// Force on the particle (N) at `x` with velocity `v`, pulled toward `target` moving with
    /// `target_velocity`: `-[k (l - L0) + c (v - w) . u] u`.
    #[inline]
    pub fn force(
        &self,
        x: &Vector3<f64>,
        v: &Vector3<f64>,
        target: &Point3<f64>,
        target_velocity: &Vector3<f64>,
    ) -> Vector3<f64> {
        let d = x - target.coords;
        let len = d.norm();
        if len > 0.0 {
            let dir = d / len;
            let s = &self.spring;
            -dir * (s.stiffness * (len - s.rest_length)
                + s.damping * (v - target_velocity).dot(&dir))
        } else {
            Vector3::zeros()
        }
    }
}
