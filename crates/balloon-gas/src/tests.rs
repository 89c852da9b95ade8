//! Unit tests of the gas models and the pressure load.

use balloon_mesh::generate::icosphere;
use balloon_test_support::{
    Rng, assert_second_order, check_gradient, check_jacobian, taylor_remainder_orders,
};

use crate::*;

fn sphere(radius: f64, subdivisions: u32) -> (Vec<f64>, Vec<[usize; 3]>) {
    let m = icosphere(radius, subdivisions).expect("icosphere");
    (m.positions_flat(), m.triangles.clone())
}

/// A closed but irregular surface: a sphere with randomly displaced vertices, shifted off the
/// origin (so origin-dependent mistakes show up).
fn lumpy(seed: u64) -> (Vec<f64>, Vec<[usize; 3]>) {
    let (mut x, t) = sphere(0.3, 1);
    let mut rng = Rng::new(seed);
    for (i, xi) in x.iter_mut().enumerate() {
        *xi += 0.03 * rng.next_f64() + [0.7, -0.2, 0.4][i % 3];
    }
    (x, t)
}

fn forces_of<G: GasModel + Clone + 'static>(
    load: PressureLoad<G>,
    tris: &[[usize; 3]],
) -> impl Fn(&[f64]) -> Vec<f64> + '_ {
    move |x: &[f64]| {
        let mut l = load.clone();
        let mut f = vec![0.0; x.len()];
        l.evaluate(0.0, x, tris, &mut f).unwrap();
        f
    }
}

#[test]
fn volume_of_sphere_approaches_analytic_and_gradient_is_exact() {
    let (x, t) = sphere(1.0, 3);
    let v = enclosed_volume(&x, &t).unwrap();
    let exact = 4.0 / 3.0 * std::f64::consts::PI;
    // An inscribed polyhedron is slightly smaller than the sphere.
    assert!(v < exact && v > 0.98 * exact, "V = {v}");
    let (x, t) = lumpy(3);
    check_gradient(
        |x| enclosed_volume(x, &t).unwrap(),
        |x| {
            let mut g = vec![0.0; x.len()];
            volume_and_gradient(x, &t, &mut g).unwrap();
            g
        },
        &x,
        1e-6,
        1e-8,
    );
}

#[test]
fn closed_mesh_gradient_equals_one_third_area_normal_sum() {
    // On a closed surface dV/dx_i = (1/3) sum A^e n^e = (1/6) sum e12 x e13 (Eq. 15's geometry).
    let (x, t) = lumpy(5);
    let mut g = vec![0.0; x.len()];
    volume_and_gradient(&x, &t, &mut g).unwrap();
    let mut an = vec![0.0; x.len()];
    for tri in &t {
        let p: Vec<nalgebra::Vector3<f64>> = tri
            .iter()
            .map(|&i| nalgebra::Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]))
            .collect();
        let area_normal = 0.5 * (p[1] - p[0]).cross(&(p[2] - p[0]));
        for &i in tri {
            for k in 0..3 {
                an[3 * i + k] += area_normal[k] / 3.0;
            }
        }
    }
    for (a, b) in g.iter().zip(&an) {
        assert!((a - b).abs() < 1e-14, "{a} vs {b}");
    }
}

#[test]
fn ideal_gas_forces_are_minus_potential_gradient() {
    let (x, t) = lumpy(11);
    let v0 = enclosed_volume(&x, &t).unwrap();
    let gas = IdealGas::try_from_gauge(3000.0, STANDARD_ATMOSPHERE, 0.9 * v0).unwrap();
    let load = PressureLoad::new(gas);
    let energy = |x: &[f64]| {
        let mut l = load.clone();
        let mut f = vec![0.0; x.len()];
        l.evaluate(0.0, x, &t, &mut f).unwrap();
        l.potential(0.0).unwrap()
    };
    let grad = |x: &[f64]| {
        forces_of(load.clone(), &t)(x)
            .iter()
            .map(|v| -v)
            .collect::<Vec<_>>()
    };
    check_gradient(energy, grad, &x, 1e-6, 1e-6);
    let dx = Rng::new(2).vector(x.len());
    assert_second_order(&taylor_remainder_orders(energy, grad, &x, &dx, 1e-2));
}

#[test]
fn constant_pressure_forces_are_minus_potential_gradient() {
    let (x, t) = lumpy(13);
    let gas = ConstantPressure::try_from_gauge(500.0, STANDARD_ATMOSPHERE).unwrap();
    let load = PressureLoad::new(gas)
        .with_ambient_pressure(90_000.0)
        .unwrap();
    let energy = |x: &[f64]| {
        let mut l = load.clone();
        let mut f = vec![0.0; x.len()];
        l.evaluate(0.0, x, &t, &mut f).unwrap();
        l.potential(0.0).unwrap()
    };
    let grad = |x: &[f64]| {
        forces_of(load.clone(), &t)(x)
            .iter()
            .map(|v| -v)
            .collect::<Vec<_>>()
    };
    check_gradient(energy, grad, &x, 1e-6, 1e-6);
}

#[test]
fn full_differential_with_follower_term_matches_finite_differences() {
    for gas in [
        Gas::Ideal(IdealGas::try_from_gauge(2000.0, STANDARD_ATMOSPHERE, 0.1).unwrap()),
        Gas::Constant(ConstantPressure::try_new(150_000.0).unwrap()),
        Gas::Pump(Pump::try_from_rest(0.05, STANDARD_ATMOSPHERE, 1e4).unwrap()),
    ] {
        let (x, t) = lumpy(17);
        let mut load = PressureLoad::new(gas).with_follower_term(true);
        let f = forces_of(load.clone(), &t);
        let mut scratch = vec![0.0; x.len()];
        load.evaluate(0.0, &x, &t, &mut scratch).unwrap();
        check_jacobian(
            &f,
            |x, dx| {
                let mut df = vec![0.0; x.len()];
                load.add_differential(x, &t, dx, &mut df).unwrap();
                df
            },
            &x,
            1e-6,
            1e-6,
            21,
        );
        // The assembled follower triplets plus the rank-1 term give the same product.
        let mut trip = Vec::new();
        load.add_follower_triplets(&x, &t, &mut trip).unwrap();
        let dx = Rng::new(4).vector(x.len());
        let mut kdx = vec![0.0; x.len()];
        for &(r, c, v) in &trip {
            kdx[r] += v * dx[c];
        }
        let lr = load.low_rank_term();
        let udx: f64 = lr.vector.iter().zip(&dx).map(|(a, b)| a * b).sum();
        let mut df = vec![0.0; x.len()];
        load.add_differential(&x, &t, &dx, &mut df).unwrap();
        for i in 0..x.len() {
            let k = kdx[i] + lr.coefficient * udx * lr.vector[i];
            assert!(
                (df[i] + k).abs() < 1e-9 * (1.0 + df[i].abs()),
                "{i}: {} vs {}",
                df[i],
                -k
            );
        }
        // The follower stiffness is symmetric (it is a Hessian).
        let mut dense = vec![0.0; x.len() * x.len()];
        for &(r, c, v) in &trip {
            dense[r * x.len() + c] += v;
        }
        for r in 0..x.len() {
            for c in 0..r {
                let (a, b) = (dense[r * x.len() + c], dense[c * x.len() + r]);
                assert!((a - b).abs() <= 1e-9 * (1.0 + a.abs()));
            }
        }
    }
}

#[test]
fn rank1_coefficient_is_p0v0_over_v_squared_and_factor_is_one_ninth() {
    let (x, t) = sphere(0.5, 2);
    let v = enclosed_volume(&x, &t).unwrap();
    let gas = IdealGas::try_new(2.0e5, 1.3 * v).unwrap();
    let mut load = PressureLoad::new(gas);
    let mut f = vec![0.0; x.len()];
    load.evaluate(0.0, &x, &t, &mut f).unwrap();
    let c = load.low_rank_term().coefficient;
    let expected = 2.0e5 * 1.3 * v / (v * v);
    assert!((c - expected).abs() <= 1e-12 * expected);
    // With An_i = sum A^e n^e = 3 g_i, c g g^T = (c / 9) An An^T: the constant is 1/9, not 1/27.
    let g = &load.low_rank_term().vector;
    let mut an = vec![0.0; x.len()];
    for tri in &t {
        let p: Vec<nalgebra::Vector3<f64>> = tri
            .iter()
            .map(|&i| nalgebra::Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]))
            .collect();
        let area_normal = 0.5 * (p[1] - p[0]).cross(&(p[2] - p[0]));
        for &i in tri {
            for k in 0..3 {
                an[3 * i + k] += area_normal[k];
            }
        }
    }
    for (gi, ai) in g.iter().zip(&an) {
        assert!((9.0 * gi * gi - ai * ai).abs() <= 1e-12 * (1.0 + ai * ai));
    }
    // Without the follower term the differential is exactly -c g (g . dx) (Eq. 17, corrected).
    let dx = Rng::new(9).vector(x.len());
    let mut df = vec![0.0; x.len()];
    load.add_differential(&x, &t, &dx, &mut df).unwrap();
    let gdx: f64 = g.iter().zip(&dx).map(|(a, b)| a * b).sum();
    for i in 0..x.len() {
        assert!((df[i] + c * gdx * g[i]).abs() <= 1e-9 * (1.0 + df[i].abs()));
    }
}

#[test]
fn pressure_has_no_net_force_or_torque_on_closed_surfaces() {
    // Uniform pressure on a closed surface has no resultant force and no resultant torque
    // (the integral of p n dA over a closed surface, and of x x p n dA, both vanish).
    for (x, t) in [sphere(1.0, 2), lumpy(23), lumpy(29)] {
        let v = enclosed_volume(&x, &t).unwrap();
        let mut load = PressureLoad::new(IdealGas::try_from_gauge(5000.0, 1e5, v).unwrap())
            .with_ambient_pressure(1e5)
            .unwrap();
        let mut f = vec![0.0; x.len()];
        load.evaluate(0.0, &x, &t, &mut f).unwrap();
        let mut net = nalgebra::Vector3::zeros();
        let mut torque = nalgebra::Vector3::zeros();
        let mut scale = 0.0f64;
        for i in 0..x.len() / 3 {
            let fi = nalgebra::Vector3::new(f[3 * i], f[3 * i + 1], f[3 * i + 2]);
            let xi = nalgebra::Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
            net += fi;
            torque += xi.cross(&fi);
            scale = scale.max(fi.norm());
        }
        assert!(net.norm() < 1e-11 * scale, "net force {net:?}");
        assert!(torque.norm() < 1e-11 * scale, "net torque {torque:?}");
    }
}

#[test]
fn isothermal_gas_keeps_pv_constant() {
    // Boyle's law: at fixed temperature and amount, p V = p0 V0 whatever the volume change.
    // Neither factor is read from the gas state: the volume of the sphere scaled by `s` is
    // `s^3 V0`, and the gauge pressure is the one the forces imply, `sum f.x / (3 V)` (the
    // enclosed volume is homogeneous of degree 3, so `sum x.dV/dx = 3 V` and `f = p dV/dx`).
    let (x0, t) = sphere(0.2, 2);
    let v0 = enclosed_volume(&x0, &t).unwrap();
    let p0v0 = (1500.0 + STANDARD_ATMOSPHERE) * v0;
    let gas = IdealGas::try_from_gauge(1500.0, STANDARD_ATMOSPHERE, v0).unwrap();
    let mut load = PressureLoad::new(gas);
    for s in [0.7, 1.0, 1.3, 2.0] {
        let x: Vec<f64> = x0.iter().map(|v| v * s).collect();
        let mut f = vec![0.0; x.len()];
        load.evaluate(0.0, &x, &t, &mut f).unwrap();
        let v = s * s * s * v0;
        let gauge = f.iter().zip(&x).map(|(f, x)| f * x).sum::<f64>() / (3.0 * v);
        let pv = (gauge + STANDARD_ATMOSPHERE) * v;
        assert!(
            (pv / p0v0 - 1.0).abs() <= 1e-12,
            "s = {s}: pV / p0V0 = {}",
            pv / p0v0
        );
    }
}

#[test]
fn pump_pressure_grows_linearly_in_time_at_fixed_volume() {
    // A pump adds gas at a constant rate: at fixed volume p(t) = (nRT_0 + rate t) / V.
    let (x, t) = sphere(0.1, 1);
    let v = enclosed_volume(&x, &t).unwrap();
    let rate = 20.0;
    let mut load = PressureLoad::new(Gas::Pump(
        Pump::try_from_rest(v, STANDARD_ATMOSPHERE, rate).unwrap(),
    ));
    let mut f = vec![0.0; x.len()];
    let p0 = load.evaluate(0.0, &x, &t, &mut f).unwrap();
    assert!(p0.gauge_pressure.abs() < 1e-9, "starts at ambient");
    assert!(f.iter().all(|v| v.abs() < 1e-9), "no load at rest");
    let mut prev = p0.absolute_pressure;
    for k in 1..5 {
        let st = load.evaluate(0.5 * k as f64, &x, &t, &mut f).unwrap();
        let dp = st.absolute_pressure - prev;
        assert!((dp - rate * 0.5 / v).abs() <= 1e-9 * dp);
        prev = st.absolute_pressure;
    }
    // At each instant the pump is an ideal gas with the amount pumped in so far.
    let amount = v * STANDARD_ATMOSPHERE + rate * 1.0;
    let phi = load.potential(1.0).unwrap();
    let expected = -amount * v.ln() + STANDARD_ATMOSPHERE * v;
    assert!((phi - expected).abs() <= 1e-12 * expected.abs());
}

/// `-dPhi/dV = p` for every model, by central differences in `V` at several volumes and times
/// (the pump's amount, and so its potential, depends on the time).
#[test]
fn every_gas_potential_is_minus_the_integral_of_its_pressure() {
    let models: [(&str, Gas); 3] = [
        ("ideal", IdealGas::try_new(1.2e5, 2e-3).unwrap().into()),
        ("constant", ConstantPressure::try_new(9e4).unwrap().into()),
        (
            "pump",
            Pump::try_from_rest(2e-3, STANDARD_ATMOSPHERE, 300.0)
                .unwrap()
                .into(),
        ),
    ];
    for (name, gas) in models {
        for &volume in &[5e-4, 2e-3, 1e-2] {
            for &time in &[0.0, 0.7, 3.0] {
                let h = 1e-6 * volume;
                let phi = |v: f64| gas.potential(v, time).expect("a potential");
                let fd = -(phi(volume + h) - phi(volume - h)) / (2.0 * h);
                let p = gas.absolute_pressure(volume, time);
                assert!(
                    (fd - p).abs() <= 1e-7 * p,
                    "{name} V = {volume} t = {time}: -dPhi/dV = {fd} vs p = {p}"
                );
            }
        }
    }
}

/// The loaded potential at a point, `potential_at`, is `-` the antiderivative of the pressure
/// forces along a path for every model (the pump at a fixed time), and leaves the evaluated
/// state alone.
#[test]
fn loaded_potential_at_positions_has_the_forces_as_minus_gradient() {
    let (x, t) = lumpy(17);
    let v0 = enclosed_volume(&x, &t).unwrap();
    let gases: [Gas; 3] = [
        IdealGas::try_new(1.3e5, v0).unwrap().into(),
        ConstantPressure::try_new(1.05e5).unwrap().into(),
        Pump::try_from_rest(v0, STANDARD_ATMOSPHERE, 50.0)
            .unwrap()
            .into(),
    ];
    for gas in gases {
        for ambient in [0.0, STANDARD_ATMOSPHERE] {
            let load = PressureLoad::new(gas)
                .with_ambient_pressure(ambient)
                .unwrap();
            let time = 0.8;
            let energy = |x: &[f64]| load.potential_at(time, x, &t).unwrap().unwrap();
            let grad = |x: &[f64]| {
                let mut l = load.clone();
                let mut f = vec![0.0; x.len()];
                l.evaluate(time, x, &t, &mut f).unwrap();
                f.iter().map(|v| -v).collect::<Vec<_>>()
            };
            check_gradient(energy, grad, &x, 1e-6, 1e-6);
            let mut l = load.clone();
            let mut f = vec![0.0; x.len()];
            let state = l.evaluate(time, &x, &t, &mut f).unwrap();
            let moved: Vec<f64> = x.iter().map(|c| 1.1 * c).collect();
            let at = l.potential_at(time, &moved, &t).unwrap().unwrap();
            assert_eq!(l.state(), state, "potential_at changed the state");
            assert!((l.potential(time).unwrap() - energy(&x)).abs() <= 1e-12 * at.abs());
        }
    }
    let inverted: Vec<[usize; 3]> = t.iter().map(|&[a, b, c]| [a, c, b]).collect();
    let load = PressureLoad::new(Gas::Constant(ConstantPressure::try_new(1e5).unwrap()));
    assert!(load.potential_at(0.0, &x, &inverted).is_err());
}

#[test]
fn errors_name_the_problem() {
    let (x, t) = sphere(1.0, 0);
    // Inverted surface: negative volume.
    let flipped: Vec<[usize; 3]> = t.iter().map(|&[a, b, c]| [a, c, b]).collect();
    let mut load = PressureLoad::new(Gas::Constant(ConstantPressure::try_new(1e5).unwrap()));
    let mut f = vec![0.0; x.len()];
    let e = load.evaluate(0.0, &x, &flipped, &mut f).unwrap_err();
    assert!(matches!(e, GasError::InvalidVolume { volume } if volume < 0.0));
    assert!(e.to_string().contains("volume"));
    let bad = vec![[0, 1, 99]];
    let e = load.evaluate(0.0, &x, &bad, &mut f).unwrap_err();
    assert!(e.to_string().contains("vertex 99"), "{e}");
    assert!(
        IdealGas::try_new(-1.0, 1.0)
            .unwrap_err()
            .to_string()
            .contains("initial_pressure")
    );
    assert!(Pump::try_from_rest(1.0, 1e5, -2.0).is_err());
    assert!(load.clone().with_ambient_pressure(f64::NAN).is_err());
}

#[test]
fn gas_kind_parses_and_round_trips() {
    for (s, k) in [
        ("ideal", GasKind::Ideal),
        ("constant", GasKind::Constant),
        ("pump", GasKind::Pump),
    ] {
        assert_eq!(s.parse::<GasKind>().unwrap(), k);
        assert_eq!(k.to_string(), s);
        assert_eq!(serde_json::to_string(&k).unwrap(), format!("\"{s}\""));
        let g = Gas::try_from_kind(k, 0.01, 1000.0, STANDARD_ATMOSPHERE, 5.0).unwrap();
        assert_eq!(g.kind(), k);
        let back: Gas = serde_json::from_str(&serde_json::to_string(&g).unwrap()).unwrap();
        assert_eq!(back, g);
    }
    let law = GasLawParams {
        gamma: 1.3,
        leak_conductance: Some(1e-4),
        supply_pressure: Some(800.0),
    };
    for (s, k) in [
        ("polytropic", GasKind::Polytropic),
        ("leak", GasKind::Leak),
        ("supply-pump", GasKind::SupplyPump),
    ] {
        assert_eq!(s.parse::<GasKind>().unwrap(), k);
        assert_eq!(k.to_string(), s);
        assert_eq!(serde_json::to_string(&k).unwrap(), format!("\"{s}\""));
        let g = Gas::try_from_kind_with(k, 0.01, 1000.0, STANDARD_ATMOSPHERE, 5.0, &law).unwrap();
        assert_eq!(g.kind(), k);
        let back: Gas = serde_json::from_str(&serde_json::to_string(&g).unwrap()).unwrap();
        assert_eq!(back, g);
        // Built at the rest volume: the given gauge pressure (the supply pump: ambient).
        let gauge = g.absolute_pressure(0.01, 0.0) - STANDARD_ATMOSPHERE;
        let expected = if k == GasKind::SupplyPump {
            0.0
        } else {
            1000.0
        };
        assert!((gauge - expected).abs() < 1e-9, "{s}: {gauge}");
    }
    assert_eq!("adiabatic".parse::<GasKind>().unwrap(), GasKind::Polytropic);
    let e = "helium".parse::<GasKind>().unwrap_err();
    assert!(e.to_string().contains("helium"));
    assert!(e.to_string().contains("supply-pump"));
}

#[test]
fn reset_reference_reanchors() {
    let mut g = IdealGas::try_new(2e5, 1.0).unwrap();
    g.reset_reference(0.5, 0.0);
    assert_eq!(g.initial_volume, 0.5);
    assert!((g.absolute_pressure(0.5, 0.0) - 2e5).abs() < 1e-9);
    let mut p = Pump::try_from_rest(1.0, 1e5, 10.0).unwrap();
    p.reset_reference(2.0, 3.0);
    assert!((p.absolute_pressure(2.0, 3.0) - 1e5).abs() < 1e-9);
    assert!((p.absolute_pressure(2.0, 4.0) - (2e5 + 10.0) / 2.0).abs() < 1e-9);
}

#[test]
fn real_meshes_have_no_net_pressure_force_or_torque() {
    // Uniform pressure on a closed real surface (bunny, genus 0; torus, genus 1) has no resultant
    // force or torque, and the force equals -dE/dx along random directions.
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/meshes");
    if !dir.is_dir() {
        eprintln!("skipping: {} not found", dir.display());
        return;
    }
    for name in ["bunny_closed_libigl.off", "torus.obj"] {
        let mesh = balloon_mesh::io::read_mesh(&dir.join(name)).expect("readable mesh");
        let (x, t) = (mesh.positions_flat(), mesh.triangles.clone());
        let v = enclosed_volume(&x, &t).unwrap();
        assert!(v > 0.0, "{name}: outward oriented");
        let mut load = PressureLoad::new(Gas::Ideal(IdealGas::try_new(1.1e5, v).unwrap()));
        let mut f = vec![0.0; x.len()];
        load.evaluate(0.0, &x, &t, &mut f).unwrap();
        let mut net = nalgebra::Vector3::zeros();
        let mut torque = nalgebra::Vector3::zeros();
        let mut total = 0.0;
        for i in 0..x.len() / 3 {
            let fi = nalgebra::Vector3::new(f[3 * i], f[3 * i + 1], f[3 * i + 2]);
            let xi = nalgebra::Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
            net += fi;
            torque += xi.cross(&fi);
            total += fi.norm();
        }
        assert!(net.norm() < 1e-12 * total, "{name}: net force {net:?}");
        assert!(
            torque.norm() < 1e-12 * total * 10.0,
            "{name}: net torque {torque:?}"
        );
        // Directional derivative of the potential along a random direction = -f . dx.
        let dx = Rng::new(31).vector(x.len());
        let h = 1e-7;
        let energy = |s: f64| {
            let xs: Vec<f64> = x.iter().zip(&dx).map(|(a, b)| a + s * b).collect();
            let mut l = load.clone();
            let mut g = vec![0.0; x.len()];
            l.evaluate(0.0, &xs, &t, &mut g).unwrap();
            l.potential(0.0).unwrap()
        };
        let fd = (energy(h) - energy(-h)) / (2.0 * h);
        let an: f64 = -f.iter().zip(&dx).map(|(a, b)| a * b).sum::<f64>();
        assert!(
            (fd - an).abs() <= 1e-5 * an.abs().max(1e-12),
            "{name}: {fd} vs {an}"
        );
    }
}

/// The gas laws of `laws` (polytropic, leak, supply pump) in every regime, by central differences
/// in `V`: `-dPhi/dV = p` (the potential) and `dp/dV` (the rank-1 tangent's coefficient).
#[test]
fn gas_law_potentials_and_slopes_match_finite_differences() {
    let pa = STANDARD_ATMOSPHERE;
    let mut leak = LeakyGas::try_new(1.2e5 * 2e-3, pa, 3e-4).unwrap();
    leak.time = 0.5;
    let supply = SupplyPump::try_new(pa * 2e-3, 400.0, 1.1e5).unwrap();
    // (name, gas, (volume, time) points)
    type Case = (&'static str, Gas, Vec<(f64, f64)>);
    let models: Vec<Case> = vec![
        (
            "adiabatic",
            Polytropic::try_new(1.2e5, 2e-3, 1.4).unwrap().into(),
            vec![(5e-4, 0.0), (2e-3, 1.0), (1e-2, 2.0)],
        ),
        (
            "isothermal polytropic",
            Polytropic::try_new(1.2e5, 2e-3, 1.0).unwrap().into(),
            vec![(5e-4, 0.0), (3e-3, 1.0)],
        ),
        (
            "polytropic 1.67",
            Polytropic::try_new(1.2e5, 2e-3, 5.0 / 3.0).unwrap().into(),
            vec![(1e-3, 0.0), (4e-3, 1.0)],
        ),
        (
            "leak",
            leak.into(),
            vec![(1e-3, 0.5), (2e-3, 0.7), (4e-3, 3.0)],
        ),
        // V1 = N0 / p_s = 1.842e-3, V2 = (N0 + 400 t) / p_s: stopped below V1, at the supply
        // pressure between, the full rate above V2.
        (
            "supply pump",
            supply.into(),
            vec![
                (1.0e-3, 0.1),
                (1.9e-3, 0.5),
                (2.0e-3, 0.5),
                (3.0e-3, 0.1),
                (5e-3, 1.0),
            ],
        ),
    ];
    for (name, gas, points) in models {
        for (volume, time) in points {
            let h = 1e-6 * volume;
            let phi = |v: f64| gas.potential(v, time).expect("a potential");
            let p = |v: f64| gas.absolute_pressure(v, time);
            let fd = -(phi(volume + h) - phi(volume - h)) / (2.0 * h);
            assert!(
                (fd - p(volume)).abs() <= 1e-7 * p(volume),
                "{name} V = {volume} t = {time}: -dPhi/dV = {fd} vs p = {}",
                p(volume)
            );
            let slope = (p(volume + h) - p(volume - h)) / (2.0 * h);
            let an = gas.dpressure_dvolume(volume, time);
            assert!(
                (slope - an).abs() <= 1e-6 * (an.abs() + 1e-3 * p(volume) / volume),
                "{name} V = {volume} t = {time}: dp/dV = {an} vs {slope}"
            );
        }
    }
    // The supply pump's potential is continuous across its regimes.
    let (n0, ps) = (supply.amount, supply.supply_pressure);
    for edge in [n0 / ps, (n0 + 400.0 * 0.5) / ps] {
        let a = supply.potential(edge * (1.0 - 1e-12), 0.5).unwrap();
        let b = supply.potential(edge * (1.0 + 1e-12), 0.5).unwrap();
        assert!(
            (a - b).abs() <= 1e-6 * a.abs(),
            "jump at {edge}: {a} vs {b}"
        );
    }
}

/// On a surface: the load's forces are minus the gradient of its potential (gauge pressure
/// times `dV/dx`), and its differential (rank-1 term from `dp/dV` plus the follower term) is the
/// forces' derivative, for every new law.
#[test]
fn gas_law_forces_and_tangents_on_a_surface_match_finite_differences() {
    let (x, t) = lumpy(23);
    let v0 = enclosed_volume(&x, &t).unwrap();
    let pa = STANDARD_ATMOSPHERE;
    let law = GasLawParams {
        gamma: 1.4,
        leak_conductance: Some(2e-4),
        supply_pressure: Some(1500.0),
    };
    for kind in [GasKind::Polytropic, GasKind::Leak, GasKind::SupplyPump] {
        // Built at 0.9 V0, so the surface is compressed (polytropic, leak) or above where the
        // pump would stop.
        let gas = Gas::try_from_kind_with(kind, 0.9 * v0, 2500.0, pa, 50.0, &law).unwrap();
        assert_eq!(gas.kind(), kind);
        let time = 0.3;
        let load = PressureLoad::new(gas).with_follower_term(true);
        let energy = |x: &[f64]| load.potential_at(time, x, &t).unwrap().unwrap();
        let forces = |x: &[f64]| {
            let mut l = load.clone();
            let mut f = vec![0.0; x.len()];
            l.evaluate(time, x, &t, &mut f).unwrap();
            f
        };
        check_gradient(
            energy,
            |x| forces(x).iter().map(|v| -v).collect(),
            &x,
            1e-6,
            1e-6,
        );
        let mut evaluated = load.clone();
        let mut scratch = vec![0.0; x.len()];
        evaluated.evaluate(time, &x, &t, &mut scratch).unwrap();
        check_jacobian(
            forces,
            |x, dx| {
                let mut df = vec![0.0; x.len()];
                evaluated.add_differential(x, &t, dx, &mut df).unwrap();
                df
            },
            &x,
            1e-6,
            1e-6,
            5,
        );
    }
    // Missing parameters are named.
    for (kind, name) in [
        (GasKind::Leak, "leak_conductance"),
        (GasKind::SupplyPump, "supply_pressure"),
    ] {
        let e = Gas::try_from_kind(kind, v0, 1000.0, pa, 1.0).unwrap_err();
        assert!(e.to_string().contains(name), "{e}");
    }
    let bad = GasLawParams { gamma: -1.0, ..law };
    let e = Gas::try_from_kind_with(GasKind::Polytropic, v0, 0.0, pa, 0.0, &bad).unwrap_err();
    assert!(e.to_string().contains("gamma"), "{e}");
    assert!(LeakyGas::try_new(1.0, pa, -1.0).is_err());
    assert!(SupplyPump::try_new(1.0, 1.0, 0.0).is_err());
}

/// The laws behave physically over a run of committed steps at a prescribed volume history:
/// adiabatic `p V^gamma` is conserved, a leak's gauge pressure decays (exponentially at a fixed
/// volume, rate `C / V`), a supply pump stops at its supply pressure.
#[test]
fn gas_laws_behave_physically_over_committed_steps() {
    let pa = STANDARD_ATMOSPHERE;
    // Adiabatic: any volume path.
    let mut air = Gas::from(Polytropic::try_new(1.3e5, 1e-3, 1.4).unwrap());
    let k = 1.3e5 * 1e-3f64.powf(1.4);
    for (i, v) in [1e-3, 1.4e-3, 0.8e-3, 2.5e-3].iter().enumerate() {
        let time = 0.1 * i as f64;
        let p = air.absolute_pressure(*v, time);
        assert!((p * v.powf(1.4) / k - 1.0).abs() < 1e-12);
        air.end_step(*v, time);
    }
    // Leak at a fixed volume: backward Euler of dN/dt = -C (N/V - p_a), converging to the
    // exponential as dt -> 0.
    let (v, c, gauge0) = (2e-3, 1e-4, 3000.0);
    let decay = |dt: f64| {
        let mut leak = Gas::from(LeakyGas::try_new((pa + gauge0) * v, pa, c).unwrap());
        let steps = (1.0 / dt).round() as usize;
        let mut last = gauge0;
        for s in 1..=steps {
            let time = s as f64 * dt;
            let g = leak.absolute_pressure(v, time) - pa;
            assert!(
                g < last && g > 0.0,
                "the gauge pressure decays monotonically"
            );
            last = g;
            leak.end_step(v, time);
        }
        last
    };
    let exact = gauge0 * (-c / v * 1.0).exp();
    let coarse = decay(0.1);
    let fine = decay(0.001);
    assert!((fine / exact - 1.0).abs() < 1e-3, "{fine} vs {exact}");
    assert!((fine - exact).abs() < 0.05 * (coarse - exact).abs());
    // Supply pump into a volume that grows slowly: the pressure rises and stops at the supply
    // pressure, then stays there (topping up as the volume grows).
    let supply_gauge = 2000.0;
    let mut pump = Gas::from(SupplyPump::try_new(pa * 1e-3, 20.0, pa + supply_gauge).unwrap());
    let mut reached = None;
    for s in 1..=200 {
        let time = 0.05 * s as f64;
        let v = 1e-3 * (1.0 + 1e-3 * time);
        let p = pump.absolute_pressure(v, time);
        assert!(p <= pa + supply_gauge + 1e-9);
        if reached.is_none() && p >= pa + supply_gauge - 1e-9 {
            reached = Some(time);
        }
        if reached.is_some() {
            assert!((p - pa - supply_gauge).abs() < 1e-9, "stays at the supply");
        }
        pump.end_step(v, time);
    }
    let t_reach = reached.expect("reaches the supply pressure");
    // Filling 1e-3 m^3 from ambient to +2000 Pa at 20 J/s takes about 2000e-3 / 20 = 0.1 s.
    assert!(t_reach > 0.09 && t_reach < 0.2, "{t_reach}");
    // Squeezed above the supply pressure, it neither pumps nor vents: Boyle's law.
    let Gas::SupplyPump(sp) = pump else {
        unreachable!()
    };
    let v_end = 1e-3 * (1.0 + 1e-3 * 10.0);
    let p = sp.absolute_pressure(0.9 * v_end, 10.5);
    assert!((p * 0.9 * v_end - sp.amount).abs() < 1e-9 * sp.amount);
    assert!(sp.stopped(0.9 * v_end, 10.5));
}
