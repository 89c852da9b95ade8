//! Tests of the hinge bending element: derivatives against central differences, invariances,
//! and the energy of a triangulated strip bent into a cylinder against the plate's.

use std::collections::HashMap;

use super::*;
use balloon_test_support::{Rng, check_gradient};
use nalgebra::{Matrix3, Rotation3};

/// Length scale of the random hinges (m).
const SCALE: f64 = 0.02;
/// Bending modulus of the tests (N m).
const MODULUS: f64 = 2.5e-3;

fn rvec(rng: &mut Rng) -> Vector3<f64> {
    Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64())
}

fn rotation(rng: &mut Rng) -> Matrix3<f64> {
    Rotation3::new(rvec(rng) * 3.0).into_inner()
}

fn flat(x: &[Vector3<f64>; 4]) -> Vec<f64> {
    x.iter().flat_map(|v| v.iter().copied()).collect()
}

fn arr(x: &[f64]) -> [Vector3<f64>; 4] {
    std::array::from_fn(|i| Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]))
}

fn max_abs(it: impl IntoIterator<Item = f64>) -> f64 {
    it.into_iter().fold(0.0f64, |m, a| m.max(a.abs()))
}

/// A hinge in its local frame: edge `x0 = 0`, `x1 = (len, 0, 0)`, wing `A` in the half plane
/// `y > 0`, wing `B` rotated by `fold` (rad) about the edge out of the half plane `y < 0`.
#[derive(Clone, Copy, Debug)]
struct Shape {
    len: f64,
    sa: f64,
    ha: f64,
    sb: f64,
    hb: f64,
    fold: f64,
}

impl Shape {
    fn random(rng: &mut Rng) -> Self {
        Self {
            len: SCALE * (1.0 + 0.4 * rng.next_f64()),
            sa: SCALE * (0.5 + 0.8 * rng.next_f64()),
            ha: SCALE * (0.8 + 0.5 * rng.next_f64()),
            sb: SCALE * (0.5 + 0.8 * rng.next_f64()),
            hb: SCALE * (0.8 + 0.5 * rng.next_f64()),
            fold: 0.8 * rng.next_f64(),
        }
    }

    fn local(&self) -> [Vector3<f64>; 4] {
        let (s, c) = self.fold.sin_cos();
        [
            Vector3::zeros(),
            Vector3::new(self.len, 0.0, 0.0),
            Vector3::new(self.sa, self.ha, 0.0),
            Vector3::new(self.sb, -self.hb * c, -self.hb * s),
        ]
    }
}

/// `x` moved by a random rotation and translation.
fn place(rng: &mut Rng, x: &[Vector3<f64>; 4]) -> [Vector3<f64>; 4] {
    let q = rotation(rng);
    let t = rvec(rng) * SCALE;
    x.map(|p| q * p + t)
}

/// A random rest hinge and a current state whose fold differs by `dfold` (rad), with every
/// vertex moved by up to `noise` (relative to `SCALE`), rotated and translated.
fn rest_and_current(
    rng: &mut Rng,
    dfold: f64,
    noise: f64,
) -> ([Vector3<f64>; 4], Hinge, [Vector3<f64>; 4]) {
    let shape = Shape::random(rng);
    let rest = place(rng, &shape.local());
    let hinge = Hinge::try_new(&rest).unwrap();
    let bent = Shape {
        fold: shape.fold + dfold,
        ..shape
    }
    .local()
    .map(|p| p + rvec(rng) * (noise * SCALE));
    (rest, hinge, place(rng, &bent))
}

#[test]
fn hinge_angle_is_the_constructed_fold() {
    let mut rng = Rng::new(4);
    for _ in 0..20 {
        let mut shape = Shape::random(&mut rng);
        shape.fold = 3.0 * rng.next_f64();
        let x = place(&mut rng, &shape.local());
        // Wing B turned by `fold` about -e (away from nA): nB = |nB| (0, -sin, cos) in the
        // local frame, (nA x nB) . e = |nA| |nB| |e| sin(fold), so theta = fold.
        let theta = Hinge::angle(&x);
        assert!(
            (theta - shape.fold).abs() <= 1e-12,
            "{theta} vs {}",
            shape.fold
        );
    }
    // Flat and consistently oriented: exactly zero rest angle.
    let flat = Shape {
        fold: 0.0,
        ..Shape::random(&mut rng)
    };
    assert_eq!(Hinge::try_new(&flat.local()).unwrap().rest_angle(), 0.0);
}

/// Test 1: `forces = -dE/dx` against central differences of `energy`.
#[test]
fn hinge_energy_gradient_matches_central_differences() {
    for seed in 1..=8 {
        let mut rng = Rng::new(seed);
        let dfold = 1.2 * rng.next_f64();
        let (_, hinge, x) = rest_and_current(&mut rng, dfold, 0.1);
        let theta = Hinge::angle(&x);
        assert!(theta.abs() > 1e-3, "the state must not be flat");
        assert!(hinge.energy(&x, MODULUS) > 0.0);
        let energy = |y: &[f64]| hinge.energy(&arr(y), MODULUS);
        let grad = |y: &[f64]| -> Vec<f64> {
            flat(&hinge.forces(&arr(y), MODULUS))
                .iter()
                .map(|f| -f)
                .collect()
        };
        let rep = check_gradient(energy, grad, &flat(&x), 1e-6 * SCALE, 1e-6);
        assert!(rep.relative_error() <= 1e-6);
        // The fused method agrees with the separate ones.
        let (f, e) = hinge.forces_and_energy(&x, MODULUS);
        assert_eq!(e, hinge.energy(&x, MODULUS));
        assert_eq!(f, hinge.forces(&x, MODULUS));
        let (fk, _) = hinge.forces_and_stiffness(&x, MODULUS);
        for i in 0..4 {
            assert!((fk[i] - f[i]).norm() <= 1e-14 * max_abs(flat(&f)));
        }
    }
}

/// Test 2: the exact stiffness against central differences of `forces`, column by column,
/// near and far from rest; far from rest the `delta H_theta` term is far above the tolerance.
#[test]
fn hinge_stiffness_matches_central_differences_of_forces() {
    const TOL: f64 = 1e-6;
    let h = 1e-6 * SCALE;
    let mut largest_delta_term = 0.0f64;
    for (seed, dfold) in [0.05, 0.5, -0.8, 1.0, 1.5, -2.0, 2.0, 0.3]
        .into_iter()
        .enumerate()
    {
        let mut rng = Rng::new(40 + seed as u64);
        let (_, hinge, x) = rest_and_current(&mut rng, dfold, 0.03);
        let delta = Hinge::angle(&x) - hinge.rest_angle();
        assert!(
            (delta.abs() - dfold.abs()).abs() < 0.3,
            "delta {delta} far from the requested {dfold}"
        );
        let (_, k) = hinge.forces_and_stiffness(&x, MODULUS);
        let x0 = flat(&x);
        let mut k_fd = SMatrix::<f64, 12, 12>::zeros();
        for c in 0..12 {
            let mut xp = x0.clone();
            xp[c] += h;
            let mut xm = x0.clone();
            xm[c] -= h;
            let fp = flat(&hinge.forces(&arr(&xp), MODULUS));
            let fm = flat(&hinge.forces(&arr(&xm), MODULUS));
            for r in 0..12 {
                k_fd[(r, c)] = -(fp[r] - fm[r]) / (2.0 * h);
            }
        }
        let scale = max_abs(k.iter().copied());
        let err = max_abs((k - k_fd).iter().copied()) / scale;
        assert!(err <= TOL, "dfold {dfold}: stiffness error {err:.3e}");
        assert_eq!(k, k.transpose());
        // The Hessian of the angle is symmetric before the final symmetrisation.
        let (g, ht) = angle_gradient_and_hessian(&x);
        let hs = SMatrix::<f64, 12, 12>::from_fn(|r, c| ht[r][c]);
        let hn = max_abs(hs.iter().copied());
        assert!(max_abs((hs - hs.transpose()).iter().copied()) <= 1e-12 * hn);
        // Without the delta H_theta term (Gauss-Newton only) the check would fail.
        let gv = SMatrix::<f64, 12, 1>::from_column_slice(&g);
        let gauss_newton = gv * gv.transpose() * (MODULUS * hinge.weight());
        let delta_term = max_abs((k_fd - gauss_newton).iter().copied()) / scale;
        if dfold.abs() >= 0.5 {
            assert!(
                delta_term >= 1e4 * TOL,
                "dfold {dfold}: delta H term {delta_term:.3e} not far above the tolerance"
            );
        }
        largest_delta_term = largest_delta_term.max(delta_term);
    }
    assert!(largest_delta_term > 0.1, "{largest_delta_term}");
}

/// Test 3: zero energy and force at rest; invariance under rigid motions (forces and stiffness
/// rotate) and under a uniform scaling of rest and current shapes; the wrapped angle difference.
#[test]
fn hinge_rest_state_and_invariances() {
    let mut rng = Rng::new(7);
    for _ in 0..6 {
        let dfold = 0.9 * rng.next_f64();
        let (rest, hinge, x) = rest_and_current(&mut rng, dfold, 0.1);
        // At rest.
        assert_eq!(hinge.energy(&rest, MODULUS), 0.0);
        let (f0, k0) = hinge.forces_and_stiffness(&rest, MODULUS);
        assert!(f0.iter().all(|f| f.norm() == 0.0), "{f0:?}");
        // At rest the stiffness is the rank-one D w g g^T: positive semi-definite.
        let ev = k0.symmetric_eigenvalues();
        let emax = max_abs(ev.iter().copied());
        assert!(ev.iter().all(|&l| l >= -1e-12 * emax));
        assert_eq!(ev.iter().filter(|&&l| l > 1e-9 * emax).count(), 1);

        let e = hinge.energy(&x, MODULUS);
        let (f, k) = hinge.forces_and_stiffness(&x, MODULUS);
        let fmax = max_abs(flat(&f));
        // Rotation plus translation.
        let q = rotation(&mut rng);
        let t = rvec(&mut rng) * SCALE;
        let y = x.map(|p| q * p + t);
        assert!((hinge.energy(&y, MODULUS) - e).abs() <= 1e-12 * e);
        let (fy, ky) = hinge.forces_and_stiffness(&y, MODULUS);
        for i in 0..4 {
            assert!((fy[i] - q * f[i]).norm() <= 1e-10 * fmax);
        }
        let mut big_q = SMatrix::<f64, 12, 12>::zeros();
        for i in 0..4 {
            big_q.fixed_view_mut::<3, 3>(3 * i, 3 * i).copy_from(&q);
        }
        let kmax = max_abs(k.iter().copied());
        let rotated = big_q * k * big_q.transpose();
        assert!(max_abs((ky - rotated).iter().copied()) <= 1e-10 * kmax);
        // Uniform scaling of both rest and current shape: same weight, angle and energy.
        for s in [0.01, 0.37, 2.9, 150.0] {
            let scaled = Hinge::try_new(&rest.map(|p| p * s)).unwrap();
            assert!((scaled.weight() - hinge.weight()).abs() <= 1e-12 * hinge.weight());
            assert!((scaled.rest_angle() - hinge.rest_angle()).abs() <= 1e-12);
            let xs = x.map(|p| p * s);
            assert!((scaled.energy(&xs, MODULUS) - e).abs() <= 1e-11 * e);
            // Forces scale as 1/s.
            let fs = scaled.forces(&xs, MODULUS);
            for i in 0..4 {
                assert!((fs[i] * s - f[i]).norm() <= 1e-10 * fmax);
            }
        }
    }
    // The angle difference is wrapped into (-pi, pi]: folds of 3 rad and -3 rad (one turned
    // into the other through the fully folded state) differ by 2 pi - 6, not by 6, both ways.
    for fold in [3.0, -3.0] {
        let base = Shape {
            len: 1.0,
            sa: 0.4,
            ha: 1.0,
            sb: 0.6,
            hb: 0.8,
            fold,
        };
        let hinge = Hinge::try_new(&base.local()).unwrap();
        let x = Shape {
            fold: -fold,
            ..base
        }
        .local();
        let d = 2.0 * PI - 6.0;
        let expected = 0.5 * MODULUS * hinge.weight() * d * d;
        assert!((hinge.energy(&x, MODULUS) - expected).abs() <= 1e-12 * expected);
    }
}

/// Test 4: zero net force, zero net torque and translation in the null space of the
/// stiffness, on random states.
#[test]
fn hinge_net_force_and_torque_vanish() {
    let mut rng = Rng::new(11);
    for _ in 0..10 {
        let dfold = 2.0 * rng.next_f64();
        let (_, hinge, x) = rest_and_current(&mut rng, dfold, 0.2);
        let (f, k) = hinge.forces_and_stiffness(&x, MODULUS);
        let fmax = max_abs(flat(&f));
        let xmax = max_abs(flat(&x));
        assert!(fmax > 0.0);
        let net: Vector3<f64> = f.iter().sum();
        assert!(net.norm() <= 1e-12 * fmax, "net force {net}");
        let torque: Vector3<f64> = x.iter().zip(&f).map(|(p, fi)| p.cross(fi)).sum();
        assert!(torque.norm() <= 1e-12 * fmax * xmax, "net torque {torque}");
        let kmax = max_abs(k.iter().copied());
        for d in 0..3 {
            let t = SMatrix::<f64, 12, 1>::from_fn(|r, _| if r % 3 == d { 1.0 } else { 0.0 });
            assert!(max_abs((k * t).iter().copied()) <= 1e-12 * kmax);
        }
    }
}

/// Interior edges of a consistently oriented triangle list as hinges `[x0, x1, x2, x3]`
/// (triangles `(x0, x1, x2)` and `(x1, x0, x3)`).
fn hinges(tris: &[[usize; 3]]) -> Vec<[usize; 4]> {
    let mut opposite = HashMap::new();
    for t in tris {
        for k in 0..3 {
            let old = opposite.insert((t[k], t[(k + 1) % 3]), t[(k + 2) % 3]);
            assert!(old.is_none(), "inconsistent orientation");
        }
    }
    let mut out: Vec<[usize; 4]> = opposite
        .iter()
        .filter(|((a, b), _)| a < b)
        .filter_map(|(&(a, b), &c)| opposite.get(&(b, a)).map(|&d| [a, b, c, d]))
        .collect();
    out.sort_unstable();
    out
}

/// The hinge energy of the flat mesh `(points, tris)` (in the `(s, t)` plane) bent into the
/// cylinder `(s, t) -> (R sin(s/R), R (1 - cos(s/R)), t)`, divided by the plate's
/// `D/2 (1/R)^2 A` (`A` the mesh area).
fn cylinder_ratio(points: &[[f64; 2]], tris: &[[usize; 3]], radius: f64) -> f64 {
    let rest: Vec<Vector3<f64>> = points
        .iter()
        .map(|p| Vector3::new(p[0], p[1], 0.0))
        .collect();
    let bent: Vec<Vector3<f64>> = points
        .iter()
        .map(|p| {
            let a = p[0] / radius;
            Vector3::new(radius * a.sin(), radius * (1.0 - a.cos()), p[1])
        })
        .collect();
    let area: f64 = tris
        .iter()
        .map(|t| {
            0.5 * (rest[t[1]] - rest[t[0]])
                .cross(&(rest[t[2]] - rest[t[0]]))
                .norm()
        })
        .sum();
    let mut energy = 0.0;
    for h in hinges(tris) {
        let hinge = Hinge::try_new(&h.map(|v| rest[v])).unwrap();
        assert!(hinge.rest_angle().abs() <= 1e-12);
        energy += hinge.energy(&h.map(|v| bent[v]), MODULUS);
    }
    energy / (0.5 * MODULUS * area / (radius * radius))
}

/// How each cell of a rectangular grid is split.
#[derive(Clone, Copy, Debug)]
enum Diagonal {
    /// Along `(1, 1)`.
    Rising,
    /// Along `(1, -1)`.
    Falling,
    /// Alternating like a chessboard.
    Alternating,
}

/// A rectangular grid of `n x m` cells of `a x b` (m), counter-clockwise triangles, with
/// vertex `(i, j)` at `(i a, j b)` rotated by `rot` (rad) about the origin.
fn grid(
    n: usize,
    m: usize,
    a: f64,
    b: f64,
    diagonal: Diagonal,
    rot: f64,
) -> (Vec<[f64; 2]>, Vec<[usize; 3]>) {
    let (s, c) = rot.sin_cos();
    let mut points = Vec::new();
    for j in 0..=m {
        for i in 0..=n {
            let (u, v) = (i as f64 * a, j as f64 * b);
            points.push([c * u - s * v, s * u + c * v]);
        }
    }
    let id = |i: usize, j: usize| j * (n + 1) + i;
    let mut tris = Vec::new();
    for j in 0..m {
        for i in 0..n {
            let (p00, p10, p01, p11) = (id(i, j), id(i + 1, j), id(i, j + 1), id(i + 1, j + 1));
            let rising = match diagonal {
                Diagonal::Rising => true,
                Diagonal::Falling => false,
                Diagonal::Alternating => (i + j) % 2 == 0,
            };
            if rising {
                tris.push([p00, p10, p11]);
                tris.push([p00, p11, p01]);
            } else {
                tris.push([p00, p10, p01]);
                tris.push([p10, p11, p01]);
            }
        }
    }
    (points, tris)
}

/// An equilateral mesh of `n x m` rows of triangles of edge `l` (odd rows shifted by `l/2`),
/// rotated by `rot` (rad).
fn equilateral(n: usize, m: usize, l: f64, rot: f64) -> (Vec<[f64; 2]>, Vec<[usize; 3]>) {
    let (s, c) = rot.sin_cos();
    let h = 0.75f64.sqrt() * l;
    let mut points = Vec::new();
    for j in 0..=m {
        for i in 0..=n {
            let u = i as f64 * l + if j % 2 == 1 { 0.5 * l } else { 0.0 };
            let v = j as f64 * h;
            points.push([c * u - s * v, s * u + c * v]);
        }
    }
    let id = |i: usize, j: usize| j * (n + 1) + i;
    let mut tris = Vec::new();
    for j in 0..m {
        for i in 0..n {
            if j % 2 == 0 {
                tris.push([id(i, j), id(i + 1, j), id(i, j + 1)]);
                tris.push([id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            } else {
                tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
                tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            }
        }
    }
    (points, tris)
}

/// Test 5a: a rectangular strip `L x W` of `N x M` cells bent along `L` into a cylinder of
/// radius `R`. Only the `(N - 1) M` interior edges along the axis fold, each by exactly
/// `a/R` (`a = L/N`) with weight `3 b/a` (`b = W/M`), whatever the diagonals (which stay
/// flat), so the energy is exactly `3 (N - 1)/N` times the plate's `D/2 L W / R^2`: the
/// hinge energy converges to three times the plate energy.
#[test]
fn hinge_strip_bent_into_cylinder_tends_to_three_times_plate_energy() {
    let (length, width, radius, m) = (0.3, 0.1, 0.2, 5);
    for diagonal in [Diagonal::Rising, Diagonal::Falling, Diagonal::Alternating] {
        let mut previous = 0.0;
        for n in [4, 8, 16, 32, 64, 128] {
            let (points, tris) = grid(n, m, length / n as f64, width / m as f64, diagonal, 0.0);
            let ratio = cylinder_ratio(&points, &tris, radius);
            let exact = 3.0 * (n - 1) as f64 / n as f64;
            assert!(
                (ratio - exact).abs() <= 1e-9 * exact,
                "{diagonal:?} N = {n}: ratio {ratio} vs 3 (N-1)/N = {exact}"
            );
            assert!(ratio > previous && ratio < 3.0);
            previous = ratio;
        }
        assert!((3.0 - previous).abs() < 0.025);
    }
}

/// Richardson extrapolation of `ratio(n)` and `ratio(2n)` assuming an `O(1/n)` error (the
/// boundary edges that are not hinges).
fn extrapolate(ratio: impl Fn(usize) -> f64, n: usize) -> (f64, f64) {
    let (coarse, fine) = (ratio(n), ratio(2 * n));
    (fine, 2.0 * fine - coarse)
}

/// Test 5b: the limit factor depends on the triangulation. A square grid whose diagonals run
/// along the bend gives 9, one whose diagonals run along the axis gives 3, and in general
/// `6 + 3 sin 2phi - 3 cos^2 2phi` (`phi` the bend direction in the grid frame); an
/// equilateral mesh gives 3 for any direction of the bend.
#[test]
fn hinge_cylinder_factor_depends_on_the_triangulation() {
    let radius = 1.0;
    let square = |phi: f64| {
        // The bend runs along s; in the grid frame its direction is at -rot.
        move |n: usize| {
            let (p, t) = grid(n, n, 1.0 / n as f64, 1.0 / n as f64, Diagonal::Rising, -phi);
            cylinder_ratio(&p, &t, radius)
        }
    };
    for phi in [PI / 4.0, -PI / 4.0, PI / 8.0, 0.3] {
        let limit = 6.0 + 3.0 * (2.0 * phi).sin() - 3.0 * (2.0 * phi).cos().powi(2);
        let (fine, extrapolated) = extrapolate(square(phi), 40);
        assert!(
            (extrapolated - limit).abs() <= 5e-3 * limit,
            "square grid, phi = {phi}: extrapolated {extrapolated} (n = 80: {fine}) vs {limit}"
        );
        assert!((fine - limit).abs() <= 0.1 * limit);
    }
    for rot in [0.0, PI / 2.0, 0.4] {
        let tri = move |n: usize| {
            let (p, t) = equilateral(n, n, 1.0 / n as f64, rot);
            cylinder_ratio(&p, &t, radius)
        };
        let (fine, extrapolated) = extrapolate(tri, 40);
        assert!(
            (extrapolated - 3.0).abs() <= 5e-3 * 3.0,
            "equilateral, rot = {rot}: extrapolated {extrapolated} (n = 80: {fine}) vs 3"
        );
    }
}

/// Test 6: degenerate or non-finite rest hinges are errors naming the hinge.
#[test]
fn hinge_degenerate_rest_is_an_error_naming_hinge() {
    let good = Shape {
        len: 1.0,
        sa: 0.4,
        ha: 1.0,
        sb: 0.6,
        hb: 0.8,
        fold: 0.2,
    }
    .local();
    assert!(Hinge::try_new(&good).is_ok());
    let mut cases = Vec::new();
    // x2 on the edge line: triangle A has no area.
    let mut x = good;
    x[2] = Vector3::new(2.5, 0.0, 0.0);
    cases.push(x);
    // x3 on x0: triangle B has no area.
    let mut x = good;
    x[3] = x[0];
    cases.push(x);
    // Coincident edge ends.
    let mut x = good;
    x[1] = x[0];
    cases.push(x);
    for x in cases {
        let err = Hinge::try_new(&x).unwrap_err();
        assert!(
            matches!(
                err,
                ElementError::DegenerateRest {
                    element: "hinge",
                    quantity: "area",
                    ..
                }
            ),
            "{err:?}"
        );
        assert!(err.to_string().contains("hinge"), "{err}");
    }
    let mut x = good;
    x[3].y = f64::NAN;
    let err = Hinge::try_new(&x).unwrap_err();
    assert_eq!(
        err,
        ElementError::NonFinite {
            element: "hinge",
            quantity: "rest position"
        }
    );
    assert!(err.to_string().contains("hinge"));
    // A degenerate current triangle gives non-finite values, as documented.
    let hinge = Hinge::try_new(&good).unwrap();
    let mut x = good;
    x[2] = Vector3::new(0.5, 0.0, 0.0);
    assert!(
        !hinge
            .forces(&x, MODULUS)
            .iter()
            .all(|f| f.iter().all(|v| v.is_finite()))
    );
}

/// The rest Jacobian of the forces against central differences of the forces of hinges rebuilt
/// from perturbed rest positions (the weight and the rest angle both move), near and far from
/// rest; both parts of `delta dw/dX - w dtheta_bar/dX` matter (each alone fails the check).
#[test]
fn hinge_rest_jacobian_matches_central_differences() {
    const TOL: f64 = 1e-6;
    let h = 1e-6 * SCALE;
    let (mut weight_part, mut angle_part) = (0.0f64, 0.0f64);
    for (seed, dfold) in [0.05, 0.5, -0.8, 1.5, -2.0].into_iter().enumerate() {
        let mut rng = Rng::new(90 + seed as u64);
        let (rest, hinge, x) = rest_and_current(&mut rng, dfold, 0.03);
        let (f, j) = hinge.forces_and_rest_jacobian(&rest, &x, MODULUS);
        assert_eq!(f, hinge.forces(&x, MODULUS));
        let r0 = flat(&rest);
        let mut j_fd = SMatrix::<f64, 12, 12>::zeros();
        let mut w_fd = [0.0; 12];
        for c in 0..12 {
            let mut rp = r0.clone();
            rp[c] += h;
            let mut rm = r0.clone();
            rm[c] -= h;
            let (hp, hm) = (
                Hinge::try_new(&arr(&rp)).unwrap(),
                Hinge::try_new(&arr(&rm)).unwrap(),
            );
            let fp = flat(&hp.forces(&x, MODULUS));
            let fm = flat(&hm.forces(&x, MODULUS));
            for r in 0..12 {
                j_fd[(r, c)] = (fp[r] - fm[r]) / (2.0 * h);
            }
            w_fd[c] = (hp.weight() - hm.weight()) / (2.0 * h);
        }
        let scale = max_abs(j.iter().copied());
        assert!(scale > 0.0);
        let err = max_abs((j - j_fd).iter().copied()) / scale;
        assert!(err <= TOL, "dfold {dfold}: rest Jacobian error {err:.3e}");
        let dw = flat(&Hinge::weight_gradient(&rest));
        let dw_scale = max_abs(dw.iter().copied());
        let dw_err = max_abs(dw.iter().zip(&w_fd).map(|(a, b)| a - b)) / dw_scale;
        assert!(
            dw_err <= TOL,
            "dfold {dfold}: weight gradient error {dw_err:.3e}"
        );
        // How far each part alone is from the differences (relative to the Jacobian).
        let g = flat(&Hinge::angle_gradient(&x));
        let gbar = flat(&Hinge::angle_gradient(&rest));
        let delta = Hinge::angle(&x) - hinge.rest_angle();
        let without = |keep_weight: bool| {
            let j_part = SMatrix::<f64, 12, 12>::from_fn(|r, c| {
                let term = if keep_weight {
                    delta * dw[c]
                } else {
                    -hinge.weight() * gbar[c]
                };
                -MODULUS * g[r] * term
            });
            max_abs((j_part - j_fd).iter().copied()) / scale
        };
        weight_part = weight_part.max(without(false));
        angle_part = angle_part.max(without(true));
    }
    assert!(weight_part > 1e3 * TOL, "{weight_part:e}");
    assert!(angle_part > 1e3 * TOL, "{angle_part:e}");
}

/// The rest Jacobian maps rigid motions and uniform scalings of the rest hinge to zero (its
/// weight and rest angle do not change under them).
#[test]
fn hinge_rest_jacobian_ignores_rigid_motions_and_scaling() {
    let mut rng = Rng::new(5);
    let (rest, hinge, x) = rest_and_current(&mut rng, 0.7, 0.03);
    let (_, j) = hinge.forces_and_rest_jacobian(&rest, &x, MODULUS);
    let scale = max_abs(j.iter().copied());
    let centre = rest.iter().sum::<Vector3<f64>>() / 4.0;
    let axis = rvec(&mut rng).normalize();
    let translation = Vector3::new(1.0, -2.0, 0.5);
    let motions: [[Vector3<f64>; 4]; 3] = [
        rest.map(|_| translation),
        rest.map(|p| axis.cross(&(p - centre))),
        rest.map(|p| p - centre),
    ];
    for (m, motion) in motions.iter().enumerate() {
        let v = SMatrix::<f64, 12, 1>::from_iterator(motion.iter().flat_map(|d| [d.x, d.y, d.z]));
        let jv = j * v;
        assert!(
            jv.amax() <= 1e-10 * scale * v.amax(),
            "motion {m}: {:e}",
            jv.amax()
        );
    }
}
