//! Finite-difference and invariance tests of every element with every material.

use balloon_material::{Lame, Material, NeoHookean, StVenantKirchhoff};
use balloon_test_support::{
    Rng, assert_second_order, check_gradient, check_jacobian, taylor_remainder_orders,
};
use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Vector3};

use crate::{ElementError, Spring, TargetSpring, ThreePrism};

fn flat<const N: usize>(x: &[Vector3<f64>; N]) -> Vec<f64> {
    x.iter().flat_map(|v| v.iter().copied()).collect()
}

fn arr<const N: usize>(x: &[f64]) -> [Vector3<f64>; N] {
    std::array::from_fn(|i| Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]))
}

fn dmat<const N: usize>(k: &nalgebra::SMatrix<f64, N, N>) -> DMatrix<f64> {
    DMatrix::from_column_slice(N, N, k.as_slice())
}

fn rvec(rng: &mut Rng) -> Vector3<f64> {
    Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64())
}

fn rotation(rng: &mut Rng) -> Matrix3<f64> {
    Rotation3::new(rvec(rng) * 3.0).into_inner()
}

type DifferentialFn<'a> = &'a dyn Fn(&[f64], &[f64]) -> Vec<f64>;
type FusedFn<'a> = &'a dyn Fn(&[f64]) -> (Vec<f64>, DMatrix<f64>);

/// The closures describing one element with `n` vertices at a fixed parameter set.
struct Element<'a> {
    energy: &'a dyn Fn(&[f64]) -> f64,
    forces: &'a dyn Fn(&[f64]) -> Vec<f64>,
    differential: DifferentialFn<'a>,
    stiffness: &'a dyn Fn(&[f64]) -> DMatrix<f64>,
    fused: FusedFn<'a>,
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, a| m.max(a.abs()))
}

/// All derivative checks at state `x` (length scale `l`).
fn verify(e: &Element<'_>, x: &[f64], l: f64, seed: u64) {
    let n = x.len();
    let grad = |x: &[f64]| (e.forces)(x).iter().map(|f| -f).collect::<Vec<_>>();
    // Energy -> forces (f = -dE/dx).
    check_gradient(e.energy, grad, x, 1e-6 * l, 1e-6);
    // Forces -> differential (df = -K dx).
    check_jacobian(e.forces, e.differential, x, 1e-6 * l, 1e-6, seed);
    let mut rng = Rng::new(seed + 100);
    let dx = rng.vector(n);
    // Taylor remainder of the energy: second order if the forces are right.
    let ratios = taylor_remainder_orders(e.energy, grad, x, &dx, 0.005 * l);
    assert_second_order(&ratios);
    // Taylor remainder of w . f: second order if the differential is right.
    let w = DVector::from_vec(rng.vector(n));
    let wf = |x: &[f64]| w.dot(&DVector::from_vec((e.forces)(x)));
    let wf_grad = |x: &[f64]| {
        ((e.stiffness)(x).transpose() * &w * -1.0)
            .as_slice()
            .to_vec()
    };
    assert_second_order(&taylor_remainder_orders(wf, wf_grad, x, &dx, 0.005 * l));
    // Stiffness: symmetric (a Hessian) and consistent with the differential.
    let k = (e.stiffness)(x);
    let kn = k.norm();
    assert!(
        (&k - k.transpose()).norm() <= 1e-10 * kn,
        "stiffness not symmetric"
    );
    let kdx = &k * DVector::from_column_slice(&dx);
    let df = DVector::from_vec((e.differential)(x, &dx));
    assert!(
        (&kdx + &df).norm() <= 1e-10 * kdx.norm().max(1e-300),
        "differential != -K dx"
    );
    // The fused call equals the separate calls.
    let (ff, kf) = (e.fused)(x);
    let f = (e.forces)(x);
    let fs = max_abs(&f).max(1e-300);
    assert!(
        f.iter().zip(&ff).all(|(a, b)| (a - b).abs() <= 1e-12 * fs),
        "fused forces differ"
    );
    assert!((&kf - &k).norm() <= 1e-12 * kn, "fused stiffness differs");
    // Internal forces of a translation- and rotation-invariant energy have no net force and no
    // net torque (Newton's third law / conservation of linear and angular momentum).
    let xs: Vec<Vector3<f64>> = x.chunks(3).map(Vector3::from_column_slice).collect();
    let fv: Vec<Vector3<f64>> = f.chunks(3).map(Vector3::from_column_slice).collect();
    let net: Vector3<f64> = fv.iter().sum();
    let torque: Vector3<f64> = xs.iter().zip(&fv).map(|(p, q)| p.cross(q)).sum();
    let xmax = max_abs(x).max(l);
    assert!(net.norm() <= 1e-12 * fs, "net force {net}");
    assert!(torque.norm() <= 1e-11 * fs * xmax, "net torque {torque}");
    // The differential of a translation-invariant force sums to zero too.
    let dfv: Vector3<f64> = df
        .as_slice()
        .chunks(3)
        .map(Vector3::from_column_slice)
        .sum();
    assert!(dfv.norm() <= 1e-11 * df.norm().max(1e-300));
}

/// A well-conditioned rest triangle of size ~`l` somewhere near the origin.
fn rest_triangle(rng: &mut Rng, l: f64) -> [Vector3<f64>; 3] {
    let p0 = rvec(rng) * l;
    let a = Vector3::new(1.0, 0.2 * rng.next_f64(), 0.2 * rng.next_f64());
    let b = Vector3::new(0.3 * rng.next_f64(), 1.0, 0.2 * rng.next_f64());
    let r = rotation(rng);
    [p0, p0 + r * a * l, p0 + r * b * l]
}

/// A deformed state: random rotation, uniform scale `s` times a near-identity map, and small
/// per-vertex perturbations.
fn deform<const N: usize>(
    rng: &mut Rng,
    rest: &[Vector3<f64>; N],
    s: f64,
    l: f64,
) -> [Vector3<f64>; N] {
    let r = rotation(rng);
    let g = Matrix3::from_iterator((0..9).map(|_| rng.next_f64()));
    let a = r * (Matrix3::identity() + g * 0.15) * s;
    let t = rvec(rng) * l;
    rest.map(|p| a * p + t + rvec(rng) * (0.05 * l))
}

fn lame() -> Lame {
    Lame::try_from_young_poisson(1.0e6, 0.4).unwrap()
}

fn prism_suite<M: Material>(mat: &M) {
    let mut rng = Rng::new(21);
    for (case, (l, big_h)) in [(1.0, 0.1), (0.01, 1.0e-3)].into_iter().enumerate() {
        for (i, s) in [0.8, 1.0, 1.3].into_iter().enumerate() {
            let rest = rest_triangle(&mut rng, l);
            let p = ThreePrism::try_new(rest, big_h).unwrap();
            let x = deform(&mut rng, &rest, s, l);
            let h = big_h * (1.0 + 0.3 * rng.next_f64());
            p.check_state(&x, h).unwrap();
            let e = Element {
                energy: &|x| p.energy(mat, &arr(x), h),
                forces: &|x| flat(&p.forces(mat, &arr(x), h)),
                differential: &|x, d| flat(&p.force_differential(mat, &arr(x), h, &arr(d))),
                stiffness: &|x| dmat(&p.stiffness(mat, &arr(x), h)),
                fused: &|x| {
                    let (f, k) = p.forces_and_stiffness(mat, &arr(x), h);
                    (flat(&f), dmat(&k))
                },
            };
            verify(&e, &flat(&x), l, (10 * case + i) as u64);
            // The cached linearisation reproduces the direct evaluations.
            let lin = p.linearize(mat, &x, h);
            let f = p.forces(mat, &x, h);
            let fl = lin.forces();
            let dx = [rvec(&mut rng), rvec(&mut rng), rvec(&mut rng)];
            let df = p.force_differential(mat, &x, h, &dx);
            let dfl = lin.force_differential(mat, &dx);
            for j in 0..3 {
                assert!((f[j] - fl[j]).norm() <= 1e-14 * f[j].norm().max(1e-300) + 1e-300);
                assert!((df[j] - dfl[j]).norm() <= 1e-14 * df[j].norm().max(1e-300) + 1e-300);
            }
            assert_eq!(lin.thickness_force(), p.thickness_force(mat, &x, h));
            assert_eq!(*lin.deformation_gradient(), p.deformation_gradient(&x, h));
            // Thickness force: -dE/dh by central differences.
            let dh = 1e-6 * h;
            let fd = -(p.energy(mat, &x, h + dh) - p.energy(mat, &x, h - dh)) / (2.0 * dh);
            let tf = p.thickness_force(mat, &x, h);
            assert!(
                (fd - tf).abs() <= 1e-6 * tf.abs().max(1e-300),
                "{fd} vs {tf}"
            );
        }
    }
}

#[test]
fn three_prism_derivatives_stvk() {
    prism_suite(&StVenantKirchhoff::new(lame()));
}

#[test]
fn three_prism_derivatives_neo_hookean() {
    prism_suite(&NeoHookean::new(lame()));
}

/// An anisotropic test material: StVK plus a fibre along the oblique rest direction `a`,
/// `psi = psi_StVK + k/4 (a.C a - 1)^2`, `C = F^T F`. For isotropic materials the three-prism's
/// normal-lever terms vanish identically (see `docs/elements.md`); this material has
/// thickness-plane shear stress, so it exercises them.
#[derive(Clone, Debug)]
pub(crate) struct FibreMaterial {
    base: StVenantKirchhoff,
    k: f64,
    a: Vector3<f64>,
}

impl FibreMaterial {
    pub(crate) fn new() -> Self {
        Self {
            base: StVenantKirchhoff::new(lame()),
            k: 3.0e6,
            a: Vector3::new(0.6, -0.3, 0.8).normalize(),
        }
    }
}

impl Material for FibreMaterial {
    fn energy_density(&self, f: &Matrix3<f64>) -> f64 {
        let s = (f * self.a).norm_squared() - 1.0;
        self.base.energy_density(f) + 0.25 * self.k * s * s
    }
    fn first_piola(&self, f: &Matrix3<f64>) -> Matrix3<f64> {
        let fa = f * self.a;
        let s = fa.norm_squared() - 1.0;
        self.base.first_piola(f) + fa * self.a.transpose() * (self.k * s)
    }
    fn first_piola_differential(&self, f: &Matrix3<f64>, df: &Matrix3<f64>) -> Matrix3<f64> {
        let fa = f * self.a;
        let dfa = df * self.a;
        let s = fa.norm_squared() - 1.0;
        let ds = 2.0 * fa.dot(&dfa);
        self.base.first_piola_differential(f, df)
            + (fa * ds + dfa * s) * self.a.transpose() * self.k
    }
}

#[test]
fn fibre_test_material_is_consistent() {
    let m = FibreMaterial::new();
    let mut rng = Rng::new(3);
    let f = Matrix3::identity() + Matrix3::from_iterator((0..9).map(|_| 0.3 * rng.next_f64()));
    let x = f.as_slice().to_vec();
    let mf = |x: &[f64]| Matrix3::from_column_slice(x);
    check_gradient(
        |x| m.energy_density(&mf(x)),
        |x| m.first_piola(&mf(x)).as_slice().to_vec(),
        &x,
        1e-6,
        1e-7,
    );
    check_jacobian(
        |x| m.first_piola(&mf(x)).as_slice().to_vec(),
        |x, d| {
            m.first_piola_differential(&mf(x), &mf(d))
                .as_slice()
                .to_vec()
        },
        &x,
        1e-6,
        1e-7,
        4,
    );
}

#[test]
fn three_prism_derivatives_anisotropic() {
    prism_suite(&FibreMaterial::new());
}

#[test]
fn three_prism_rest_rotation_and_kinematics() {
    let mut rng = Rng::new(5);
    let mats = [
        balloon_material::MaterialModel::StVenantKirchhoff(StVenantKirchhoff::new(lame())),
        balloon_material::MaterialModel::NeoHookean(NeoHookean::new(lame())),
    ];
    for mat in &mats {
        let (l, big_h) = (0.02, 1.0e-3);
        let rest = rest_triangle(&mut rng, l);
        let p = ThreePrism::try_new(rest, big_h).unwrap();
        let force_scale = lame().mu() * p.rest_volume() / l;
        // The undeformed element stores no energy and exerts no force.
        assert!(p.energy(mat, &rest, big_h).abs() <= 1e-12 * force_scale * l);
        let f0 = p.forces(mat, &rest, big_h);
        assert!(f0.iter().all(|f| f.norm() <= 1e-9 * force_scale));
        assert!(p.thickness_force(mat, &rest, big_h).abs() <= 1e-9 * force_scale);
        // A rigid motion leaves F a rotation: no energy, no force.
        let r = rotation(&mut rng);
        let t = rvec(&mut rng);
        let moved = rest.map(|q| r * q + t);
        assert!((p.deformation_gradient(&moved, big_h) - r).norm() <= 1e-10);
        assert!(p.energy(mat, &moved, big_h).abs() <= 1e-10 * force_scale * l);
        // Rotating a deformed state rotates the forces and keeps the energy (frame indifference).
        let x = deform(&mut rng, &rest, 1.2, l);
        let h = 0.8 * big_h;
        let xr = x.map(|q| r * q);
        let (e0, e1) = (p.energy(mat, &x, h), p.energy(mat, &xr, h));
        assert!((e0 - e1).abs() <= 1e-12 * e0.abs());
        let (f, fr) = (p.forces(mat, &x, h), p.forces(mat, &xr, h));
        let fs = f.iter().map(|v| v.norm()).fold(0.0, f64::max);
        for i in 0..3 {
            assert!((r * f[i] - fr[i]).norm() <= 1e-10 * fs);
        }
        // F maps the rest frame [E12 E13 D H] to the current one [e12 e13 d h] (Eq. 4), and
        // det F = (current area * h) / (rest area * H) > 0.
        let fm = p.deformation_gradient(&x, h);
        let n = (x[1] - x[0]).cross(&(x[2] - x[0]));
        let big_n = (rest[1] - rest[0]).cross(&(rest[2] - rest[0]));
        assert!((fm * (rest[1] - rest[0]) - (x[1] - x[0])).norm() <= 1e-12 * l);
        assert!((fm * (rest[2] - rest[0]) - (x[2] - x[0])).norm() <= 1e-12 * l);
        assert!((fm * big_n.normalize() * big_h - n.normalize() * h).norm() <= 1e-12 * l);
        let det = fm.determinant();
        assert!((det - n.norm() * h / (big_n.norm() * big_h)).abs() <= 1e-10 * det);
        // A uniformly stretched sheet pulls its vertices towards the centroid.
        let c = (rest[0] + rest[1] + rest[2]) / 3.0;
        let big = rest.map(|q| c + (q - c) * 1.2);
        let fb = p.forces(mat, &big, big_h);
        let work: f64 = (0..3).map(|i| fb[i].dot(&(big[i] - c))).sum();
        assert!(work < 0.0);
        // Stretching in-plane at fixed thickness makes the sheet want to thin: -dE/dh < 0
        // (Poisson effect).
        assert!(p.thickness_force(mat, &big, big_h) < 0.0);
        // The thickness effect (Wang et al. 2015, Fig. 7): at the same stretch a twice-thicker sheet stores
        // twice the energy.
        let p2 = ThreePrism::try_new(rest, 2.0 * big_h).unwrap();
        let (ea, eb) = (
            p.energy(mat, &big, big_h),
            p2.energy(mat, &big, 2.0 * big_h),
        );
        assert!((eb - 2.0 * ea).abs() <= 1e-12 * eb);
    }
}

#[test]
fn three_prism_masses_and_errors() {
    let rest = [
        Vector3::zeros(),
        Vector3::new(0.03, 0.0, 0.0),
        Vector3::new(0.0, 0.02, 0.0),
    ];
    let p = ThreePrism::try_new(rest, 2.0e-3).unwrap();
    assert!((p.rest_area() - 3.0e-4).abs() <= 1e-18);
    assert!((p.rest_volume() - 6.0e-7).abs() <= 1e-20);
    // Mass is conserved by the lumping: the weights sum to one (Eq. 19 with w = 1/3, and the
    // projection weights 3 * 1/6 + 1/2).
    let rho = 1100.0;
    let m = p.lumped_masses(rho);
    assert!((m.iter().sum::<f64>() - rho * 6.0e-7).abs() <= 1e-15);
    let (mr, mv) = p.projection_masses(rho);
    assert!((mr.iter().sum::<f64>() + mv - rho * 6.0e-7).abs() <= 1e-15);
    assert!((mv - 3.0 * mr[0]).abs() <= 1e-18);

    let collinear = [
        Vector3::zeros(),
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(2.0, 0.0, 0.0),
    ];
    assert!(matches!(
        ThreePrism::try_new(collinear, 1.0),
        Err(ElementError::DegenerateRest {
            quantity: "area",
            ..
        })
    ));
    let err = ThreePrism::try_new(rest, 0.0).unwrap_err();
    assert!(err.to_string().contains("thickness"), "{err}");
    assert!(matches!(
        ThreePrism::try_new(rest, f64::NAN),
        Err(ElementError::NonFinite { .. })
    ));
    let mut bad = rest;
    bad[1].y = f64::INFINITY;
    assert!(matches!(
        ThreePrism::try_new(bad, 1.0),
        Err(ElementError::NonFinite { .. })
    ));
    // Current-state checks.
    assert!(p.check_state(&rest, 1e-3).is_ok());
    let flat_state = [rest[0], rest[1], rest[1] * 0.5];
    let err = p.check_state(&flat_state, 1e-3).unwrap_err();
    assert!(matches!(
        err,
        ElementError::Degenerate {
            quantity: "area",
            ..
        }
    ));
    assert!(err.to_string().contains("area"));
    assert!(p.check_state(&rest, -1e-3).is_err());
    assert!(p.check_state(&bad, 1e-3).is_err());
}

#[test]
fn spring_derivatives_damping_and_guards() {
    let mut rng = Rng::new(71);
    for (i, stretch) in [0.7, 1.15, 1.4].into_iter().enumerate() {
        let x1 = rvec(&mut rng);
        let dir = rvec(&mut rng).normalize();
        let s = Spring::try_new(0.5, 200.0, 3.0).unwrap();
        let x2 = x1 + dir * (0.5 * stretch);
        let e = Element {
            energy: &|x| s.energy(&arr::<2>(x)[0], &arr::<2>(x)[1]),
            forces: &|x| {
                let a = arr::<2>(x);
                flat(&s.elastic_force(&a[0], &a[1]))
            },
            differential: &|x, d| {
                let (a, b) = (arr::<2>(x), arr::<2>(d));
                flat(&s.force_differential(&a[0], &a[1], &b[0], &b[1]))
            },
            stiffness: &|x| {
                let a = arr::<2>(x);
                dmat(&s.stiffness(&a[0], &a[1]))
            },
            fused: &|x| {
                let a = arr::<2>(x);
                (
                    flat(&s.elastic_force(&a[0], &a[1])),
                    dmat(&s.stiffness(&a[0], &a[1])),
                )
            },
        };
        verify(&e, &flat(&[x1, x2]), 0.5, 80 + i as u64);
        // Damping: the force is linear in the velocities with matrix -C, and it only ever removes
        // energy (dissipated power f . v <= 0).
        let v = [rvec(&mut rng), rvec(&mut rng)];
        let full = s.force(&x1, &x2, &v[0], &v[1]);
        let el = s.elastic_force(&x1, &x2);
        let damp = [full[0] - el[0], full[1] - el[1]];
        let c = s.damping_matrix(&x1, &x2);
        let cv = c * nalgebra::SVector::<f64, 6>::from_column_slice(&flat(&v));
        assert!(
            (cv + nalgebra::SVector::<f64, 6>::from_column_slice(&flat(&damp))).norm()
                <= 1e-12 * cv.norm()
        );
        let dd = s.damping_differential(&x1, &x2, &v[0], &v[1]);
        assert!((dd[0] - damp[0]).norm() <= 1e-12 * damp[0].norm().max(1e-300));
        assert!(damp[0].dot(&v[0]) + damp[1].dot(&v[1]) <= 0.0);
        assert!((c - c.transpose()).norm() == 0.0);
    }
    // A spring stretched beyond its rest length pulls its ends together.
    let s = Spring::try_new(1.0, 10.0, 0.0).unwrap();
    let (a, b) = (Vector3::zeros(), Vector3::new(2.0, 0.0, 0.0));
    let f = s.force(&a, &b, &Vector3::zeros(), &Vector3::zeros());
    assert!((f[0] - Vector3::new(10.0, 0.0, 0.0)).norm() < 1e-14 && f[1].x < 0.0);
    assert_eq!(s.energy(&a, &b), 5.0);
    // Zero-length guard: finite (zero) forces, and check_state reports the degeneracy.
    let f0 = s.force(&a, &a, &Vector3::x(), &Vector3::zeros());
    assert!(f0.iter().all(|v| v.norm() == 0.0));
    assert!(s.stiffness(&a, &a).iter().all(|v| v.is_finite()));
    assert!(matches!(
        s.check_state(&a, &a),
        Err(ElementError::Degenerate {
            quantity: "length",
            ..
        })
    ));
    assert!(s.check_state(&a, &b).is_ok());
    // A zero-rest-length spring is linear, also through zero length.
    let z = Spring::try_new(0.0, 4.0, 0.0).unwrap();
    assert_eq!(z.stiffness(&a, &a), z.stiffness(&a, &b));
    for (l, k, c, name) in [
        (-1.0, 1.0, 0.0, "rest_length"),
        (1.0, -1.0, 0.0, "stiffness"),
        (1.0, 1.0, f64::NAN, "damping"),
    ] {
        match Spring::try_new(l, k, c) {
            Err(ElementError::InvalidParameter { name: n, .. }) => assert_eq!(n, name),
            other => panic!("expected error on {name}, got {other:?}"),
        }
    }
    assert!(Spring::try_from_rest(&a, &a, 1.0, 0.0).is_err());
    assert_eq!(
        Spring::try_from_rest(&a, &b, 1.0, 0.0)
            .unwrap()
            .rest_length(),
        2.0
    );
}

/// The damped force of [`Spring::force`] at rest velocities is minus the energy gradient (central
/// differences and a second-order Taylor remainder), and the unvalidated constructor builds the
/// same spring as the validated one.
#[test]
fn spring_force_at_zero_velocity_is_minus_energy_gradient() {
    let mut rng = Rng::new(5);
    let s = Spring::try_new(0.4, 150.0, 2.0).unwrap();
    assert_eq!(Spring::new(0.4, 150.0, 2.0), s);
    let x0 = flat(&[rvec(&mut rng), rvec(&mut rng) + Vector3::new(0.5, 0.0, 0.0)]);
    let energy = |x: &[f64]| s.energy(&arr::<2>(x)[0], &arr::<2>(x)[1]);
    let grad = |x: &[f64]| {
        let a = arr::<2>(x);
        let f = s.force(&a[0], &a[1], &Vector3::zeros(), &Vector3::zeros());
        flat(&f).iter().map(|c| -c).collect::<Vec<f64>>()
    };
    check_gradient(energy, grad, &x0, 1e-6, 1e-7);
    let dx = Rng::new(6).vector(6);
    assert_second_order(&taylor_remainder_orders(energy, grad, &x0, &dx, 1e-3));
}

/// The drag spring: its force at rest is minus the energy gradient with respect to the particle
/// (central differences, Taylor remainder), it vanishes at the rest length, and its dashpot only
/// resists motion relative to a moving target.
#[test]
fn target_spring_force_is_minus_energy_gradient_and_damps_relative_motion() {
    let mut rng = Rng::new(21);
    let target = nalgebra::Point3::new(0.3, -0.2, 0.5);
    let drag = TargetSpring::new(Spring::try_new(0.25, 40.0, 1.5).unwrap());
    assert_eq!(drag.spring().stiffness_constant(), 40.0);
    let x0: Vec<f64> = (target.coords + rvec(&mut rng) + Vector3::new(0.6, 0.0, 0.0))
        .iter()
        .copied()
        .collect();
    let p = |x: &[f64]| Vector3::new(x[0], x[1], x[2]);
    let energy = |x: &[f64]| drag.energy(&p(x), &target);
    let grad = |x: &[f64]| {
        let f = drag.force(&p(x), &Vector3::zeros(), &target, &Vector3::zeros());
        vec![-f.x, -f.y, -f.z]
    };
    check_gradient(energy, grad, &x0, 1e-6, 1e-7);
    assert_second_order(&taylor_remainder_orders(
        energy,
        grad,
        &x0,
        &[0.3, -0.7, 0.2],
        1e-3,
    ));
    // At the rest length with no relative motion there is no force, whatever the common velocity.
    let at_rest = target.coords + Vector3::new(0.0, 0.25, 0.0);
    let w = Vector3::new(1.0, -2.0, 0.5);
    assert!(drag.force(&at_rest, &w, &target, &w).norm() < 1e-12);
    assert_eq!(drag.energy(&at_rest, &target), 0.0);
    // The dashpot part opposes the relative velocity: its power on the relative motion is <= 0.
    let (x, v) = (p(&x0), rvec(&mut rng));
    let damp = drag.force(&x, &v, &target, &w) - drag.force(&x, &w, &target, &w);
    assert!(damp.dot(&(v - w)) <= 0.0);
    // Zero length: no force, no NaN.
    assert_eq!(
        drag.force(&target.coords, &v, &target, &Vector3::zeros()),
        Vector3::zeros()
    );
}

#[test]
fn three_prism_degenerate_sweep_and_stiffness_covariance() {
    let mat = NeoHookean::new(lame());
    let rest = [
        Vector3::zeros(),
        Vector3::new(0.01, 0.0, 0.0),
        Vector3::new(0.004, 0.01, 0.0),
    ];
    let p = ThreePrism::try_new(rest, 1e-3).unwrap();
    // Flatten the current triangle towards a segment: while check_state accepts the state the
    // forces and stiffness stay finite and the derivatives stay consistent; the collapsed state
    // is rejected.
    for t in [1e-1, 1e-2, 1e-3] {
        let x = [rest[0], rest[1], Vector3::new(0.004, 0.01 * t, 1e-4)];
        p.check_state(&x, 1e-3).unwrap();
        let (f, k) = p.forces_and_stiffness(&mat, &x, 1e-3);
        assert!(f.iter().all(|v| v.iter().all(|c| c.is_finite())));
        assert!(k.iter().all(|c| c.is_finite()));
        let l = 0.01 * t;
        let e = Element {
            energy: &|x| p.energy(&mat, &arr(x), 1e-3),
            forces: &|x| flat(&p.forces(&mat, &arr(x), 1e-3)),
            differential: &|x, d| flat(&p.force_differential(&mat, &arr(x), 1e-3, &arr(d))),
            stiffness: &|x| dmat(&p.stiffness(&mat, &arr(x), 1e-3)),
            fused: &|x| {
                let (f, k) = p.forces_and_stiffness(&mat, &arr(x), 1e-3);
                (flat(&f), dmat(&k))
            },
        };
        verify(&e, &flat(&x), l, 90);
    }
    let collapsed = [rest[0], rest[1], rest[1] * 0.4];
    assert!(p.check_state(&collapsed, 1e-3).is_err());
    // Squashing the thickness costs unbounded neo-Hookean energy (J -> 0).
    assert!(p.energy(&mat, &rest, 1e-9) > 1e2 * p.energy(&mat, &rest, 0.5e-3));

    // The stiffness of a rotated state is the rotated stiffness: K(Rx) = R K(x) R^T blockwise
    // (the energy is frame indifferent, so its Hessian is a tensor).
    let mut rng = Rng::new(9);
    let x = deform(&mut rng, &rest, 1.1, 0.01);
    let r = rotation(&mut rng);
    let k = p.stiffness(&mat, &x, 0.9e-3);
    let kr = p.stiffness(&mat, &x.map(|q| r * q), 0.9e-3);
    let mut big_r = nalgebra::SMatrix::<f64, 9, 9>::zeros();
    for i in 0..3 {
        big_r.fixed_view_mut::<3, 3>(3 * i, 3 * i).copy_from(&r);
    }
    assert!((big_r * k * big_r.transpose() - kr).norm() <= 1e-10 * k.norm());
}

/// Eigenvalues of a symmetric 9x9 stiffness, ascending.
fn eigenvalues9(k: &nalgebra::SMatrix<f64, 9, 9>) -> Vec<f64> {
    let mut ev: Vec<f64> = k.symmetric_eigen().eigenvalues.iter().copied().collect();
    ev.sort_by(f64::total_cmp);
    ev
}

#[test]
fn three_prism_projected_stiffness_is_psd_and_exact_when_stretched() {
    let rest = [
        Vector3::zeros(),
        Vector3::new(0.01, 0.0, 0.0),
        Vector3::new(0.004, 0.01, 0.0),
    ];
    let big_h = 3e-4;
    let p = ThreePrism::try_new(rest, big_h).unwrap();
    let stvk = StVenantKirchhoff::new(lame());
    let neo = NeoHookean::new(lame());
    let mut rng = Rng::new(17);
    let r = rotation(&mut rng);
    let t = rvec(&mut rng) * 0.01;
    // In-plane compression to 70 % (a buckling state for a membrane): the exact stiffness has a
    // clearly negative eigenvalue, the projected one none; forces are untouched.
    let compressed = rest.map(|q| r * (q * 0.7) + t);
    for (name, k, kp, f, fp) in [
        {
            let (f, k) = p.forces_and_stiffness(&stvk, &compressed, big_h);
            let (fp, kp) = p.forces_and_projected_stiffness(&stvk, &compressed, big_h);
            ("stvk", k, kp, f, fp)
        },
        {
            let (f, k) = p.forces_and_stiffness(&neo, &compressed, big_h);
            let (fp, kp) = p.forces_and_projected_stiffness(&neo, &compressed, big_h);
            ("neo-hookean", k, kp, f, fp)
        },
    ] {
        let ev = eigenvalues9(&k);
        let evp = eigenvalues9(&kp);
        let scale = ev.last().unwrap().abs();
        assert!(
            ev[0] < -1e-3 * scale,
            "{name}: exact K is not indefinite: {ev:?}"
        );
        assert!(
            evp[0] >= -1e-10 * scale,
            "{name}: projected K not PSD: {evp:?}"
        );
        assert!((kp - kp.transpose()).norm() <= 1e-12 * kp.norm(), "{name}");
        assert_eq!(f, fp, "{name}: forces must be the exact ones");
        // Still translation invariant (rows of each 3-column block sum to zero).
        for c in 0..3 {
            let mut u = nalgebra::SVector::<f64, 9>::zeros();
            for v in 0..3 {
                u[3 * v + c] = 1.0;
            }
            assert!((kp * u).norm() <= 1e-10 * kp.norm(), "{name}: translation");
        }
        // The positive part is kept: K+ - K is PSD and K+ differs from K.
        let diff = eigenvalues9(&(kp - k));
        assert!(diff[0] >= -1e-10 * scale, "{name}: {diff:?}");
        assert!((kp - k).norm() > 1e-6 * k.norm(), "{name}");
        assert_eq!(
            p.projected_stiffness(&stvk, &compressed, big_h) == kp,
            name == "stvk"
        );
    }
    // Stretched (as in an inflated balloon): the exact stiffness is already positive definite
    // on the edge space, and the projected one equals it.
    for s in [1.1, 1.5, 2.5] {
        let r = rotation(&mut rng);
        let stretched = rest.map(|q| r * (q * s) + t);
        let k = p.stiffness(&stvk, &stretched, big_h / (s * s));
        let kp = p.projected_stiffness(&stvk, &stretched, big_h / (s * s));
        assert!(eigenvalues9(&k)[0] > -1e-10 * k.norm(), "s = {s}");
        assert!((kp - k).norm() <= 1e-12 * k.norm(), "s = {s}");
    }
}
