//! Tests of the membrane models and of the analytic sphere.

use super::*;
use crate::MaterialError;
use balloon_test_support::{
    Rng, assert_second_order, check_gradient, check_jacobian, taylor_remainder_orders,
};
use nalgebra::{Matrix2, Rotation2};

const MU: f64 = 4.0e5;

/// One of every model, with parameters in the usual ranges (and the presets).
fn models() -> Vec<MembraneModel> {
    vec![
        MembraneNeoHookean::try_new(MU).unwrap().into(),
        MembraneMooneyRivlin::try_new(1.6e5, 0.4e5).unwrap().into(),
        MembraneGent::try_new(MU, 30.0).unwrap().into(),
        MembraneOgden::try_new(vec![0.63e6, 0.0012e6, -0.01e6], vec![1.3, 5.0, -2.0])
            .unwrap()
            .into(),
        MembraneOgden::try_new(vec![3.0e5, 1.0e4], vec![1.7, 4.5])
            .unwrap()
            .into(),
        MembraneYeoh::try_new(1.1e5, 2.0e4, 5.0e2).unwrap().into(),
        MembraneYeoh::try_new(1.0e5, -1.0e3, 50.0).unwrap().into(),
        MembranePreset::NaturalRubber.model(),
        MembranePreset::ElastosilM4601.model(),
    ]
}

/// `C` from its Voigt entries `[C11, C22, C12]`.
fn c_of(x: &[f64]) -> Matrix2<f64> {
    Matrix2::new(x[0], x[2], x[2], x[1])
}

/// A random symmetric positive definite `C = Fm^T Fm` with stretches roughly in `[0.5, 3]`.
fn random_c(rng: &mut Rng) -> Matrix2<f64> {
    let f = Matrix2::new(
        1.7 + 1.2 * rng.next_f64(),
        0.5 * rng.next_f64(),
        0.5 * rng.next_f64(),
        1.7 + 1.2 * rng.next_f64(),
    );
    f.transpose() * f
}

fn voigt(s: &Matrix2<f64>) -> Vec<f64> {
    vec![s[(0, 0)], s[(1, 1)], 0.5 * (s[(0, 1)] + s[(1, 0)])]
}

/// The states every derivative check runs on: random ones, the rest state, equibiaxial states
/// (coincident principal stretches, the delicate case for Ogden) and a nearly equibiaxial one.
fn states(rng: &mut Rng) -> Vec<Matrix2<f64>> {
    let mut v: Vec<_> = (0..8).map(|_| random_c(rng)).collect();
    v.push(Matrix2::identity());
    v.push(Matrix2::identity() * 2.25);
    v.push(Matrix2::identity() * 0.64);
    v.push(Matrix2::new(1.9, 1e-9, 1e-9, 1.9 + 1e-9));
    v
}

#[test]
fn stress_is_the_gradient_of_energy() {
    let mut rng = Rng::new(21);
    for m in models() {
        for c in states(&mut rng) {
            let x = [c[(0, 0)], c[(1, 1)], c[(0, 1)]];
            // dW/d[C11, C22, C12] = [S11/2, S22/2, S12] (C12 appears twice in C).
            let grad = |x: &[f64]| {
                let s = m.stress(&c_of(x));
                vec![0.5 * s[(0, 0)], 0.5 * s[(1, 1)], s[(0, 1)]]
            };
            let dx = rng.vector(3);
            // At rest the gradient vanishes and only round-off is left to compare (the zero
            // stress at rest is checked on its own below).
            if c != Matrix2::identity() {
                check_gradient(|x| m.energy(&c_of(x)), grad, &x, 1e-6, 1e-6);
                let ratios = taylor_remainder_orders(|x| m.energy(&c_of(x)), grad, &x, &dx, 2e-3);
                assert_second_order(&ratios);
            }
            let (w, s) = m.energy_and_stress(&c);
            assert!((w - m.energy(&c)).abs() <= 1e-12 * w.abs().max(1.0));
            assert!((s - m.stress(&c)).norm() <= 1e-12 * s.norm().max(1.0));
            assert!(
                (s - s.transpose()).norm() <= 1e-10 * s.norm().max(1.0),
                "{m:?}"
            );
        }
    }
}

#[test]
fn stress_differential_and_tangent_are_the_derivative_of_stress() {
    let mut rng = Rng::new(22);
    for m in models() {
        for (k, c) in states(&mut rng).into_iter().enumerate() {
            let x = [c[(0, 0)], c[(1, 1)], c[(0, 1)]];
            check_jacobian(
                |x| voigt(&m.stress(&c_of(x))),
                |x, dx| voigt(&m.stress_differential(&c_of(x), &c_of(dx))),
                &x,
                1e-6,
                1e-6,
                k as u64 + 1,
            );
            // The Voigt tangent applied to [dE11, dE22, 2 dE12] = [dC11/2, dC22/2, dC12].
            let d = m.tangent(&c);
            assert!((d - d.transpose()).norm() <= 1e-9 * d.norm(), "{m:?}: {d}");
            let dx = rng.vector(3);
            let ds = voigt(&m.stress_differential(&c, &c_of(&dx)));
            let via_d = d * nalgebra::Vector3::new(0.5 * dx[0], 0.5 * dx[1], dx[2]);
            for i in 0..3 {
                assert!(
                    (ds[i] - via_d[i]).abs() <= 1e-10 * d.norm(),
                    "{m:?} at {c}: {ds:?} vs {via_d}"
                );
            }
        }
    }
}

#[test]
fn rest_state_is_stress_free_and_linearises_to_the_shear_modulus() {
    // At rest there is no energy and no stress; the small-strain response of an incompressible
    // isotropic material depends only on its initial shear modulus, so every model's tangent
    // at rest equals the neo-Hookean tangent with mu = mu0.
    for m in models() {
        let id = Matrix2::identity();
        assert!(m.energy(&id).abs() <= 1e-9 * m.initial_shear_modulus());
        assert!(m.stress(&id).norm() <= 1e-9 * m.initial_shear_modulus());
        let nh = MembraneNeoHookean::try_new(m.initial_shear_modulus()).unwrap();
        let (d, dn) = (m.tangent(&id), nh.tangent(&id));
        assert!((d - dn).norm() <= 1e-9 * dn.norm(), "{m:?}: {d} vs {dn}");
    }
    // The neo-Hookean tangent at rest: dS = mu (dC + tr(dC) I), i.e. D = 2 mu [[2,1,0],[1,2,0],
    // [0,0,1/2]] in the engineering-shear Voigt form.
    let d = MembraneNeoHookean::try_new(MU)
        .unwrap()
        .tangent(&Matrix2::identity());
    let expected = nalgebra::Matrix3::new(4.0, 2.0, 0.0, 2.0, 4.0, 0.0, 0.0, 0.0, 1.0) * MU;
    assert!((d - expected).norm() <= 1e-9 * MU, "{d}");
}

#[test]
fn frame_invariance() {
    // Rotating the rest frame in its plane turns C into R^T C R: the energy is unchanged and
    // the stress turns with it (isotropy).
    let mut rng = Rng::new(23);
    for m in models() {
        for _ in 0..5 {
            let c = random_c(&mut rng);
            let r = Rotation2::new(3.0 * rng.next_f64()).into_inner();
            let cr = r.transpose() * c * r;
            let (w, s) = m.energy_and_stress(&c);
            let (wr, sr) = m.energy_and_stress(&cr);
            assert!((w - wr).abs() <= 1e-10 * w.abs(), "{m:?}");
            assert!(
                (r.transpose() * s * r - sr).norm() <= 1e-9 * s.norm(),
                "{m:?}"
            );
        }
    }
}

/// Asserts that two models agree in energy, stress and tangent at a few states.
fn assert_same_model(a: &impl MembraneMaterial, b: &impl MembraneMaterial, rel: f64) {
    let mut rng = Rng::new(24);
    assert!(
        (a.initial_shear_modulus() - b.initial_shear_modulus()).abs()
            <= rel * b.initial_shear_modulus()
    );
    for c in states(&mut rng) {
        let (wa, sa) = a.energy_and_stress(&c);
        let (wb, sb) = b.energy_and_stress(&c);
        let scale = b.initial_shear_modulus();
        assert!((wa - wb).abs() <= rel * wb.abs().max(scale), "{wa} vs {wb}");
        assert!(
            (sa - sb).norm() <= rel * sb.norm().max(scale),
            "{sa} vs {sb}"
        );
        let (da, db) = (a.tangent(&c), b.tangent(&c));
        assert!((da - db).norm() <= rel * db.norm(), "{da} vs {db}");
    }
}

#[test]
fn special_cases_reduce_to_neo_hookean() {
    let nh = MembraneNeoHookean::try_new(MU).unwrap();
    // Ogden with one term and alpha = 2 is neo-Hookean with mu = mu_1.
    let ogden = MembraneOgden::try_new(vec![MU], vec![2.0]).unwrap();
    assert_same_model(&ogden, &nh, 1e-12);
    // Mooney-Rivlin with c2 = 0 and Yeoh with only c1 are neo-Hookean with mu = 2 c1.
    assert_same_model(
        &MembraneMooneyRivlin::try_new(0.5 * MU, 0.0).unwrap(),
        &nh,
        1e-14,
    );
    assert_same_model(
        &MembraneYeoh::try_new(0.5 * MU, 0.0, 0.0).unwrap(),
        &nh,
        1e-14,
    );
    // Gent tends to neo-Hookean as jm grows; the difference falls like 1/jm.
    let mut rng = Rng::new(25);
    let c = random_c(&mut rng);
    let gap = |jm: f64| {
        let g = MembraneGent::try_new(MU, jm).unwrap();
        (g.stress(&c) - nh.stress(&c)).norm() / nh.stress(&c).norm()
    };
    let (g1, g2) = (gap(1e3), gap(1e4));
    assert!(g1 < 1e-2 && (g1 / g2 - 10.0).abs() < 0.5, "{g1} {g2}");
    assert_same_model(&MembraneGent::try_new(MU, 1e12).unwrap(), &nh, 1e-8);
}

#[test]
fn ogden_is_smooth_where_principal_stretches_coincide() {
    // Coincident eigenvalues of C make the spectral formula's divided difference 0/0; it must
    // agree with its limit. Compare exactly equibiaxial states with slightly perturbed ones.
    let m = MembranePreset::NaturalRubber.model();
    for a in [0.5, 1.0, 1.9, 6.0] {
        let c0 = Matrix2::identity() * a;
        for eps in [1e-12, 1e-8, 1e-5] {
            let c1 = Matrix2::new(a * (1.0 + eps), 0.0, 0.0, a);
            let (d0, d1) = (m.tangent(&c0), m.tangent(&c1));
            assert!(
                (d0 - d1).norm() <= 1e2 * eps.max(1e-13) * d0.norm(),
                "a = {a}, eps = {eps}: {d0} vs {d1}"
            );
            assert!((m.stress(&c0) - m.stress(&c1)).norm() <= 1e2 * eps * d0.norm());
        }
    }
}

#[test]
fn inadmissible_states() {
    let flat = Matrix2::new(1.0, 1.0, 1.0, 1.0);
    let negative = Matrix2::new(-1.0, 0.0, 0.0, 2.0);
    for m in models() {
        for c in [flat, negative, Matrix2::new(f64::NAN, 0.0, 0.0, 1.0)] {
            assert!(!m.is_admissible(&c));
            assert_eq!(m.energy(&c), f64::INFINITY);
            assert!(m.stress(&c).iter().all(|v| v.is_nan()));
            assert!(m.stress_differential(&c, &c).iter().all(|v| v.is_nan()));
        }
        assert!(m.is_admissible(&Matrix2::identity()));
    }
    // Gent: I1 - 3 must stay below jm. Equibiaxial l = 3: I1 - 3 = 18 + 1/81 - 3 > 10.
    let g = MembraneGent::try_new(MU, 10.0).unwrap();
    let c = Matrix2::identity() * 9.0;
    assert!(!g.is_admissible(&c));
    assert_eq!(g.energy(&c), f64::INFINITY);
    assert!(g.stress(&c)[(0, 0)].is_nan());
    assert!(g.is_admissible(&(Matrix2::identity() * 4.0)));
    assert_eq!(
        incompressible_thickness(1e-3, &(Matrix2::identity() * 4.0)),
        2.5e-4
    );
    assert!(incompressible_thickness(1e-3, &flat).is_nan());
}

fn param_name(e: MaterialError) -> &'static str {
    match e {
        MaterialError::InvalidParameter { name, .. } => name,
        other => panic!("expected InvalidParameter, got {other:?}"),
    }
}

#[test]
fn parameters_are_validated_naming_them() {
    assert_eq!(
        param_name(MembraneNeoHookean::try_new(0.0).unwrap_err()),
        "mu"
    );
    assert_eq!(
        param_name(MembraneNeoHookean::try_new(f64::NAN).unwrap_err()),
        "mu"
    );
    assert_eq!(
        param_name(MembraneMooneyRivlin::try_new(-1.0, 0.0).unwrap_err()),
        "c1"
    );
    assert_eq!(
        param_name(MembraneMooneyRivlin::try_new(1.0, -1.0).unwrap_err()),
        "c2"
    );
    assert_eq!(
        param_name(MembraneGent::try_new(-1.0, 10.0).unwrap_err()),
        "mu"
    );
    let e = MembraneGent::try_new(1.0, 0.0).unwrap_err();
    assert!(
        e.to_string().contains("jm") && e.to_string().contains("> 0"),
        "{e}"
    );
    // A vanishing limit: even the rest shape's rounding of I1 - 3 would exceed it.
    for tiny in [1e-300, 1e-20, 1e-7] {
        let e = MembraneGent::try_new(1.0, tiny).unwrap_err();
        assert_eq!(param_name(e.clone()), "jm");
        assert!(e.to_string().contains("at least 1e-6"), "{e}");
    }
    assert!(MembraneGent::try_new(1.0, MembraneGent::MIN_JM).is_ok());
    assert_eq!(
        param_name(MembraneYeoh::try_new(0.0, 1.0, 1.0).unwrap_err()),
        "c1"
    );
    assert_eq!(
        param_name(MembraneYeoh::try_new(1.0, f64::INFINITY, 1.0).unwrap_err()),
        "c2"
    );
    assert_eq!(
        param_name(MembraneYeoh::try_new(1.0, 1.0, f64::NAN).unwrap_err()),
        "c3"
    );
    // Ogden: matching, non-empty lists; non-zero exponents; positive initial shear modulus.
    assert_eq!(
        MembraneOgden::try_new(vec![1.0, 2.0, 3.0], vec![1.0, 2.0]).unwrap_err(),
        MaterialError::OgdenTermMismatch {
            mu_terms: 3,
            alpha_terms: 2
        }
    );
    assert!(matches!(
        MembraneOgden::try_new(vec![], vec![]),
        Err(MaterialError::OgdenTermMismatch { .. })
    ));
    assert_eq!(
        param_name(MembraneOgden::try_new(vec![1.0], vec![0.0]).unwrap_err()),
        "ogden_alpha"
    );
    assert_eq!(
        param_name(MembraneOgden::try_new(vec![f64::NAN], vec![2.0]).unwrap_err()),
        "ogden_mu"
    );
    let e = MembraneOgden::try_new(vec![-1.0, 0.1], vec![2.0, 2.0]).unwrap_err();
    assert_eq!(param_name(e.clone()), "ogden_initial_shear_modulus");
    assert!(e.to_string().contains("sum mu_p alpha_p / 2 > 0"), "{e}");
    // A negative mu with a negative alpha is a positive contribution (Ogden's own fit).
    assert!(MembraneOgden::try_new(vec![-1.0], vec![-2.0]).is_ok());
    // Every preset passes its model's checks.
    for p in MembranePreset::ALL {
        let m = p.model();
        let again: MembraneModel =
            serde_json::from_str(&serde_json::to_string(&m).unwrap()).unwrap();
        assert_eq!(again, m);
        assert!(!p.source().is_empty());
    }
}

#[test]
fn names_serde_and_presets() {
    for k in MembraneKind::ALL {
        assert_eq!(k.to_string().parse::<MembraneKind>().unwrap(), k);
    }
    assert_eq!("gent".parse::<MembraneKind>().unwrap(), MembraneKind::Gent);
    assert_eq!(
        " Membrane-Neo-Hookean ".parse::<MembraneKind>().unwrap(),
        MembraneKind::NeoHookean
    );
    let e = "membrane-stvk".parse::<MembraneKind>().unwrap_err();
    assert!(e.to_string().contains("membrane-yeoh"), "{e}");
    for m in models() {
        let json = serde_json::to_string(&m).unwrap();
        assert!(json.contains(m.kind().name()), "{json}");
        let back: MembraneModel = serde_json::from_str(&json).unwrap();
        assert_eq!(back, m);
    }
    let g: MembraneModel =
        serde_json::from_str(r#"{"model": "membrane-gent", "mu": 4e5, "jm": 60}"#).unwrap();
    assert_eq!(g.kind(), MembraneKind::Gent);
    let bad =
        serde_json::from_str::<MembraneModel>(r#"{"model": "membrane-gent", "mu": 4e5, "jm": 0}"#);
    assert!(bad.unwrap_err().to_string().contains("jm"));
    let bad = serde_json::from_str::<MembraneModel>(
        r#"{"model": "membrane-ogden", "mu": [1, 2], "alpha": [2]}"#,
    );
    assert!(bad.unwrap_err().to_string().contains("one alpha per mu"));
    let y: MembraneModel =
        serde_json::from_str(r#"{"model": "membrane-yeoh", "c1": 1e5}"#).unwrap();
    assert_eq!(y.initial_shear_modulus(), 2e5);
    // Presets: names round-trip, and the initial shear moduli of the published fits.
    for p in MembranePreset::ALL {
        assert_eq!(p.name().parse::<MembranePreset>().unwrap(), p);
    }
    assert!("ecoflex-00-30".parse::<MembranePreset>().is_err());
    let nr = MembranePreset::NaturalRubber
        .model()
        .initial_shear_modulus();
    assert!((nr - 0.4225e6).abs() < 1e-6, "{nr}");
    let el = MembranePreset::ElastosilM4601
        .model()
        .initial_shear_modulus();
    assert!((el - 0.22e6).abs() < 1e-6, "{el}");
}

fn sphere() -> ThinSphere {
    ThinSphere::try_new(0.1, 1.0e-3).unwrap()
}

#[test]
fn sphere_pressure_is_the_energy_derivative() {
    // P(l) = H/(R l^2) w'(l): the pressure from the model's stress against a central difference
    // of the energy w(l) = W(l^2 I), and dP/dl against a central difference of P.
    let s = sphere();
    for m in models() {
        for l in [1.05, 1.3, 1.8, 2.5, 3.5] {
            let h = 1e-6;
            let dw = (s.energy_density(&m, l + h) - s.energy_density(&m, l - h)) / (2.0 * h);
            let p_fd = s.thickness() / (s.radius() * l * l) * dw;
            let p = s.pressure(&m, l);
            assert!(
                (p - p_fd).abs() <= 1e-6 * p.abs(),
                "{m:?} l = {l}: {p} vs {p_fd}"
            );
            let dp_fd = (s.pressure(&m, l + h) - s.pressure(&m, l - h)) / (2.0 * h);
            let dp = s.pressure_slope(&m, l);
            let scale = p / l;
            assert!(
                (dp - dp_fd).abs() <= 1e-5 * scale,
                "{m:?} l = {l}: {dp} vs {dp_fd}"
            );
        }
        assert_eq!(s.pressure(&m, 1.0), 0.0);
    }
    assert!((s.current_thickness(2.0) - 2.5e-4).abs() < 1e-18);
    assert!((s.volume(1.0) - 4.0 / 3.0 * std::f64::consts::PI * 1e-3).abs() < 1e-15);
}

#[test]
fn neo_hookean_sphere_maximum_matches_the_closed_form() {
    // Closed form, independent of the code: P = 2 mu H/R (1/l - 1/l^7), maximal where
    // l^6 = 7, with P_max = 2 (7^(-1/6) - 7^(-7/6)) mu H/R = 1.2395 mu H/R.
    let s = sphere();
    let nh = MembraneNeoHookean::try_new(MU).unwrap();
    let ex = s.extrema(&nh, 6.0).unwrap();
    assert_eq!(ex.len(), 1, "{ex:?}");
    assert_eq!(ex[0].kind, ExtremumKind::Maximum);
    let l_star = 7f64.powf(1.0 / 6.0);
    assert!((ex[0].stretch - l_star).abs() < 1e-10, "{ex:?}");
    assert!((l_star - 1.3831).abs() < 1e-4);
    let unit = MU * s.thickness() / s.radius();
    assert!(
        (ex[0].pressure / unit - 1.2395).abs() < 1e-4,
        "{}",
        ex[0].pressure / unit
    );
    let closed = 2.0 * (7f64.powf(-1.0 / 6.0) - 7f64.powf(-7.0 / 6.0));
    assert!((ex[0].pressure / unit - closed).abs() < 1e-12);
    for l in [1.1f64, 2.0, 4.0] {
        let p = 2.0 * unit * (1.0 / l - 1.0 / l.powi(7));
        assert!((s.pressure(&nh, l) - p).abs() < 1e-10 * p);
    }
}

#[test]
fn stiffening_models_show_a_maximum_then_a_minimum() {
    let s = sphere();
    let cases: Vec<(&str, MembraneModel)> = vec![
        (
            "gent jm = 30",
            MembraneGent::try_new(MU, 30.0).unwrap().into(),
        ),
        (
            "gent jm = 97.2",
            MembraneGent::try_new(MU, 97.2).unwrap().into(),
        ),
        (
            "ogden natural rubber",
            MembranePreset::NaturalRubber.model(),
        ),
        (
            "mooney-rivlin c2/c1 = 0.1",
            MembraneMooneyRivlin::try_new(1.0e5, 1.0e4).unwrap().into(),
        ),
    ];
    for (name, m) in cases {
        let ex = s.extrema(&m, 12.0).unwrap();
        assert_eq!(ex.len(), 2, "{name}: {ex:?}");
        assert_eq!(ex[0].kind, ExtremumKind::Maximum, "{name}");
        assert_eq!(ex[1].kind, ExtremumKind::Minimum, "{name}");
        assert!(
            ex[0].stretch < ex[1].stretch && ex[1].pressure < ex[0].pressure,
            "{name}"
        );
        for e in &ex {
            assert!(
                s.pressure_slope(&m, e.stretch).abs() <= 1e-6 * e.pressure,
                "{name}"
            );
        }
    }
    // Mooney-Rivlin with a large c2/c1 has no limit point at all, and neither has the
    // Elastosil Yeoh fit (its c2/c1 = 0.18 stiffens too early): its pressure rises
    // monotonically.
    let mr = MembraneMooneyRivlin::try_new(1.0e5, 3.0e4).unwrap();
    assert!(s.extrema(&mr, 12.0).unwrap().is_empty());
    let el = MembranePreset::ElastosilM4601.model();
    assert!(s.extrema(&el, 12.0).unwrap().is_empty());
    for l in [1.1, 1.5, 2.0, 4.0] {
        assert!(s.pressure_slope(&el, l) > 0.0);
    }
    // A Gent material with a small jm stiffens before any limit point (the curve is monotonic),
    // and the scan stops at the extensibility limit (l about 2.4 for jm = 10) instead of
    // failing.
    let g = MembraneGent::try_new(MU, 10.0).unwrap();
    assert!(s.extrema(&g, 50.0).unwrap().is_empty());
    assert!(s.pressure(&g, 3.0).is_nan());
    assert!(matches!(
        s.extrema(&g, 1.0),
        Err(MaterialError::InvalidParameter {
            name: "max_stretch",
            ..
        })
    ));
    assert!(ThinSphere::try_new(0.0, 1.0).is_err());
    assert!(ThinSphere::try_new(1.0, f64::NAN).is_err());
}

#[test]
fn joined_pair_is_one_pressure_on_both_branches_with_the_amount_kept() {
    let s = sphere();
    let m = MembraneNeoHookean::try_new(4.0e5).unwrap();
    let v0 = 4.0 / 3.0 * std::f64::consts::PI * 0.1f64.powi(3);
    let ambient = 101_325.0;
    // Start: 1.25 and 1.7, on opposite sides of 7^(1/6) = 1.383.
    let start = |l: f64| (ambient + s.pressure(&m, l)) * v0 * l.powi(3);
    let amount = start(1.25) + start(1.7);
    let (ls, ll, p) = s
        .joined_pair(&m, ambient, v0, amount, 10.0)
        .unwrap()
        .unwrap();
    let l_max = 7f64.powf(1.0 / 6.0);
    assert!(1.0 < ls && ls < 1.25 && ll > 1.7 && ll < 10.0 && ls < l_max && ll > l_max);
    // Neo-Hookean in closed form: P = 2 mu H / R (1/l - 1/l^7).
    let closed = |l: f64| 2.0 * 4.0e5 * 1.0e-3 / 0.1 * (1.0 / l - l.powi(-7));
    assert!((closed(ls) / p - 1.0).abs() < 1e-10);
    assert!((closed(ll) / p - 1.0).abs() < 1e-10);
    let kept = (ambient + p) * v0 * (ls.powi(3) + ll.powi(3));
    assert!((kept / amount - 1.0).abs() < 1e-12);
    // No state for a model without a maximum, or an amount out of reach.
    let stiff = MembraneGent::try_new(4.0e5, 2.0).unwrap();
    if s.extrema(&stiff, 10.0).unwrap().is_empty() {
        assert!(
            s.joined_pair(&stiff, ambient, v0, amount, 10.0)
                .unwrap()
                .is_none()
        );
    }
    assert!(
        s.joined_pair(&m, ambient, v0, 1e-9, 10.0)
            .unwrap()
            .is_none()
    );
}
