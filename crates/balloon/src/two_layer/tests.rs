//! Tests of the two-layer system (forces, stepping, the viewer's controls) through the
//! builder of this module: the stage crate `balloon-two-layer` cannot build bodies from shapes.

mod forces {
    use super::super::*;
    use nalgebra::{Point3, Vector3};

    fn vec3(x: &[f64], i: usize) -> Vector3<f64> {
        Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
    }
    use balloon_test_support::{Rng, assert_second_order, check_gradient, taylor_remainder_orders};

    fn perturbed(model: &TwoLayerModel, amp: f64, seed: u64) -> Vec<f64> {
        let mut rng = Rng::new(seed);
        let free = model.dimension.free_axes();
        model
            .rest_positions
            .iter()
            .enumerate()
            .map(|(k, x)| {
                if k % 3 < free {
                    x + amp * rng.next_f64()
                } else {
                    *x
                }
            })
            .collect()
    }

    fn bodies() -> Vec<TwoLayerBody> {
        vec![
            TwoLayerBody::line(0.5),
            TwoLayerBody::circle(7),
            TwoLayerBody::uv_sphere(5, 4),
            TwoLayerBody::octahedron_sphere(1),
        ]
        .into_iter()
        .map(|b| {
            b.with_radii(0.6, 1.0)
                .with_pressure(300.0, 150.0)
                .with_spring(SpringKind::Radius, 70.0, 0.0)
                .with_spring(SpringKind::ShearLeft, 30.0, 0.0)
                .with_spring(SpringKind::ShearRight, 40.0, 0.0)
                .with_damping(0.0)
                .with_gravity(3.0)
        })
        .collect()
    }

    /// Undamped forces are minus the gradient of spring + gas + gravity + drag energy (central
    /// differences and a Taylor remainder that falls 4x per halving).
    #[test]
    fn conservative_forces_are_minus_energy_gradient() {
        for body in bodies() {
            let model = body.build().unwrap();
            let x0 = perturbed(&model, 0.05, 3);
            let mut forces = TwoLayerForces::new(model.clone(), &body);
            forces.set_drag(
                Some(DragTarget {
                    point: Point3::new(2.0, 0.5, -0.3),
                    stiffness: 20.0,
                    damping: 0.0,
                    rest_length: 0.1,
                }),
                &x0,
            );
            let zero_v = vec![0.0; x0.len()];
            let energy = |x: &[f64]| forces.energies(x, &zero_v).potential();
            let grad = |x: &[f64]| {
                let mut f = vec![0.0; x.len()];
                forces.clone().forces_into(x, &zero_v, &mut f);
                f.iter().map(|c| -c).collect::<Vec<f64>>()
            };
            check_gradient(energy, grad, &x0, 1e-6, 1e-6);
            let dx = Rng::new(9).vector(x0.len());
            assert_second_order(&taylor_remainder_orders(energy, grad, &x0, &dx, 1e-3));
        }
    }

    /// Spring and drag damping only dissipate: the power of the damping forces `F_d . v` is
    /// never positive, and internal forces sum to zero (action = reaction), so with no gravity,
    /// gas or drag the net force vanishes.
    #[test]
    fn damping_dissipates_and_internal_forces_balance() {
        let body = TwoLayerBody::octahedron_sphere(1)
            .with_damping(0.3)
            .with_gravity(0.0);
        let model = body.build().unwrap();
        let x = perturbed(&model, 0.05, 5);
        let v = Rng::new(11).vector(x.len());
        let mut forces = TwoLayerForces::new(model, &body);
        let mut f_damped = vec![0.0; x.len()];
        let mut f_still = vec![0.0; x.len()];
        forces.forces_into(&x, &v, &mut f_damped);
        forces.forces_into(&x, &vec![0.0; x.len()], &mut f_still);
        let power: f64 = f_damped
            .iter()
            .zip(&f_still)
            .zip(&v)
            .map(|((a, b), vi)| (a - b) * vi)
            .sum();
        assert!(power < 0.0, "damping power {power} must be negative");
        for d in 0..3 {
            let net: f64 = f_damped.iter().skip(d).step_by(3).sum();
            assert!(net.abs() < 1e-10, "net internal force {net} along axis {d}");
        }
    }

    /// Gas pressure on a closed layer exerts zero net force and zero net torque (a closed
    /// surface has zero vector area and zero moment of area).
    #[test]
    fn pressure_has_zero_net_force_and_torque() {
        let body = TwoLayerBody::uv_sphere(6, 5)
            .with_pressure(1e3, 5e2)
            .with_gravity(0.0);
        let model = body.build().unwrap();
        let x = perturbed(&model, 0.1, 17);
        let mut forces = TwoLayerForces::new(model.clone(), &body);
        let mut f_gas = vec![0.0; x.len()];
        forces.forces_into(&x, &vec![0.0; x.len()], &mut f_gas);
        let mut net = Vector3::zeros();
        let mut torque = Vector3::zeros();
        for i in 0..model.num_particles() {
            net += vec3(&f_gas, i);
            torque += vec3(&x, i).cross(&vec3(&f_gas, i));
        }
        assert!(net.norm() < 1e-9 * 1e3, "net force {net}");
        assert!(torque.norm() < 1e-9 * 1e3, "net torque {torque}");
    }

    #[test]
    fn valence_normalisation_equalises_kernel_points() {
        // Octahedron kernel points have 4 structural neighbours, subdivision points 6 (Song
        // 2009, Sec. 3.5.3); normalisation scales their spring forces by mean/valence.
        let body = TwoLayerBody::octahedron_sphere(2).with_valence_normalization(true);
        let model = body.build().unwrap();
        let val = model.valences();
        let forces = TwoLayerForces::new(model.clone(), &body);
        let w = forces.valence_factors().unwrap();
        let n = model.layer_size;
        // Inner kernel point 0 has fewer springs than inner point 6 (a subdivision point).
        assert!(val[0] < val[6]);
        assert!(w[0] > 1.0 && w[6] < 1.0);
        assert!((w[0] * val[0] as f64 - w[6] * val[6] as f64).abs() < 1e-12);
        let mean: f64 = (0..n).map(|i| val[i] as f64).sum::<f64>() / n as f64;
        assert!((w[0] - mean / val[0] as f64).abs() < 1e-15);
    }
}

mod viewer_api {
    use super::super::*;
    use nalgebra::Vector3;

    fn sphere() -> TwoLayerSimulation {
        TwoLayerBody::octahedron_sphere(1)
            .with_radii(0.8, 1.0)
            .with_pressure(200.0, 200.0)
            .with_gravity(0.0)
            .simulate(ExplicitMethod::Rk4, 1e-3)
            .unwrap()
    }

    fn pos(sim: &TwoLayerSimulation, i: usize) -> Vector3<f64> {
        let x = sim.positions();
        Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
    }

    #[test]
    fn drag_on_a_chosen_particle_pulls_it_towards_the_target() {
        let mut sim = sphere();
        let n = sim.model().layer_size;
        let particle = n + 3;
        let start = pos(&sim, particle);
        // A target beyond the particle, farther from it than from several other particles'
        // positions would not matter: the chosen particle is the one pulled.
        let target = Point3::from(start * 1.6);
        let drag = DragTarget {
            point: target,
            stiffness: 50.0,
            damping: 0.5,
            rest_length: 0.0,
        };
        assert_eq!(sim.set_drag_particle(particle, drag).unwrap(), particle);
        assert_eq!(sim.forces().drag().map(|(_, i)| i), Some(particle));
        assert!(sim.work_done() > 0.0);
        let d0 = (target.coords - start).norm();
        sim.run(200).unwrap();
        let d1 = (target.coords - pos(&sim, particle)).norm();
        assert!(d1 < 0.8 * d0, "distance to the target {d0} -> {d1}");
        // Moving the target keeps the same particle even when another one is nearer to it.
        let other = pos(&sim, n + 10);
        let moved = DragTarget {
            point: Point3::from(other + Vector3::new(1e-3, 0.0, 0.0)),
            ..drag
        };
        sim.set_drag_particle(particle, moved).unwrap();
        assert_eq!(sim.forces().drag().map(|(_, i)| i), Some(particle));
    }

    #[test]
    fn bad_drag_particles_and_dt_are_rejected() {
        let mut sim = sphere();
        let n = sim.model().layer_size;
        let drag = DragTarget {
            point: Point3::new(0.0, 0.0, 2.0),
            stiffness: 50.0,
            damping: 0.0,
            rest_length: 0.0,
        };
        let e = sim.set_drag_particle(0, drag).unwrap_err().to_string();
        assert!(e.contains("outer layer"), "{e}");
        assert!(sim.set_drag_particle(2 * n, drag).is_err());
        let bad = DragTarget {
            stiffness: -1.0,
            ..drag
        };
        assert!(sim.set_drag_particle(n, bad).is_err());
        // A particle already on the target of another: the target is at particle n + 1.
        let on = DragTarget {
            point: Point3::from(pos(&sim, n + 1)),
            ..drag
        };
        assert!(sim.set_drag_particle(n + 2, on).is_err());
        assert!(sim.forces().drag().is_none());
        assert!(sim.set_dt(0.0).is_err());
        sim.set_dt(5e-4).unwrap();
        assert_eq!(sim.dt(), 5e-4);
        sim.set_method(ExplicitMethod::Symplectic);
        assert_eq!(sim.method(), ExplicitMethod::Symplectic);
        sim.step().unwrap();
    }
}

mod stepping {
    use super::super::*;
    use balloon_mesh::generate::octahedron_sphere;
    use nalgebra::Vector3;

    fn centroid(x: &[f64], range: std::ops::Range<usize>) -> Vector3<f64> {
        let n = range.len() as f64;
        range
            .map(|i| Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]))
            .sum::<Vector3<f64>>()
            / n
    }

    fn mean_radius(x: &[f64], range: std::ops::Range<usize>) -> f64 {
        let c = centroid(x, range.clone());
        let n = range.len() as f64;
        range
            .map(|i| (Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]) - c).norm())
            .sum::<f64>()
            / n
    }

    /// The 1D hanging spring (Song 2009, Sec. 3.3) released from its rest length is a harmonic
    /// oscillator about `L + m g / k`: `x(t) = -L - (m g / k)(1 - cos(omega t))`. The global
    /// error at t = 1 s must fall with the method's order (Euler and symplectic 1, midpoint 2,
    /// RK4 4), fitted over four time steps within +-0.3.
    #[test]
    fn hanging_spring_converges_with_the_order_of_each_method() {
        let (mass, k, g, length): (f64, f64, f64, f64) = (1.0, 100.0, 9.81, 0.5);
        let omega = (k / mass).sqrt();
        for method in ExplicitMethod::ALL {
            let mut pts = Vec::new();
            for dt in [0.004f64, 0.002, 0.001, 0.0005] {
                let body = TwoLayerBody::line(length)
                    .with_masses(mass, mass)
                    .with_spring(SpringKind::Structural, k, 0.0)
                    .with_gravity(g);
                let mut sim = body.simulate(method, dt).unwrap();
                let steps = (1.0 / dt).round() as usize;
                sim.run(steps).unwrap();
                let t = sim.time();
                let exact = -length - mass * g / k * (1.0 - (omega * t).cos());
                let exact_v = -mass * g / k * omega * (omega * t).sin();
                let err = ((sim.positions()[3] - exact).powi(2)
                    + ((sim.velocities()[3] - exact_v) / omega).powi(2))
                .sqrt();
                // The fixed end never moves and nothing leaves the x axis.
                assert_eq!(&sim.positions()[0..3], &[0.0, 0.0, 0.0]);
                assert_eq!(&sim.positions()[4..6], &[0.0, 0.0]);
                pts.push((dt, err));
            }
            let n = pts.len() as f64;
            let mx = pts.iter().map(|p| p.0.ln()).sum::<f64>() / n;
            let my = pts.iter().map(|p| p.1.ln()).sum::<f64>() / n;
            let slope = pts
                .iter()
                .map(|p| (p.0.ln() - mx) * (p.1.ln() - my))
                .sum::<f64>()
                / pts.iter().map(|p| (p.0.ln() - mx).powi(2)).sum::<f64>();
            assert!(
                (slope - method.order() as f64).abs() < 0.3,
                "{method}: fitted order {slope:.3} (errors {pts:?})"
            );
        }
    }

    fn free_sphere() -> TwoLayerBody {
        TwoLayerBody::octahedron_sphere(1)
            .with_radii(0.7, 1.0)
            .with_pressure(40.0, 20.0)
            .with_damping(0.0)
    }

    /// Largest deviation of the total energy from its initial value over 1.5 s, and the largest
    /// kinetic energy seen.
    fn energy_drift(body: &TwoLayerBody, method: ExplicitMethod, dt: f64) -> (f64, f64) {
        let mut sim = body.simulate(method, dt).unwrap();
        let e0 = sim.energies().total();
        let (mut drift, mut kmax) = (0.0f64, 0.0f64);
        for _ in 0..(1.5 / dt).round() as usize {
            let s = sim.step().unwrap();
            drift = drift.max((s.total - e0).abs());
            kmax = kmax.max(s.kinetic);
        }
        (drift, kmax)
    }

    /// Without damping and collisions all forces are conservative (gravity, springs, gas), so
    /// the total energy is constant up to the integrator's error: RK4's drift is tiny and
    /// falls at least 16x when dt halves; symplectic Euler's stays bounded. Momentum: internal
    /// springs and the pressure of closed layers exert no net force, so with no gravity the
    /// centre of mass stays put.
    #[test]
    fn undamped_energy_is_conserved_and_momentum_without_gravity() {
        let body = free_sphere();
        let (d1, kmax) = energy_drift(&body, ExplicitMethod::Rk4, 1e-3);
        let (d2, _) = energy_drift(&body, ExplicitMethod::Rk4, 5e-4);
        // The gas inflates the body: the motion is not trivial.
        assert!(kmax > 1.0, "kinetic energy peak {kmax}");
        assert!(
            d2 < 1e-4 * kmax,
            "RK4 drift {d2:.3e} J vs kinetic peak {kmax:.3e} J"
        );
        assert!(
            d1 / d2 > 16.0,
            "RK4 drift must fall >= 16x per halving: {d1:.3e} -> {d2:.3e}"
        );
        let (ds, _) = energy_drift(&body, ExplicitMethod::Symplectic, 2.5e-4);
        assert!(ds < 0.05 * kmax, "symplectic Euler drift {ds:.3e} J");
        let mut sim = free_sphere()
            .with_gravity(0.0)
            .simulate(ExplicitMethod::Rk4, 1e-3)
            .unwrap();
        sim.run(500).unwrap();
        let n = sim.model().num_particles();
        let mut p = Vector3::zeros();
        for i in 0..n {
            p += Vector3::new(
                sim.velocities()[3 * i],
                sim.velocities()[3 * i + 1],
                sim.velocities()[3 * i + 2],
            ) * sim.model().masses[i];
        }
        assert!(p.norm() < 1e-10, "momentum {p}");
        assert!(centroid(sim.positions(), 0..n).norm() < 1e-10);
    }

    /// Radial force balance of the 2D two-layer N-gon (derivation in docs/two-layer.md): with
    /// inner radius `a` and outer `b`, structural sides `2 r sin(pi/N)`, radius springs `b - a`,
    /// shear springs `l = sqrt(a^2 + b^2 - 2ab cos(2pi/N))`, and gas energy `-c ln(A)` with
    /// `A ~ r^2`, the equilibrium solves `dU/da = dU/db = 0`. A damped simulation must settle
    /// there.
    #[test]
    fn pressurised_circle_settles_at_analytic_radii() {
        let (nn, a0, b0) = (12usize, 0.6, 1.0);
        let (ks, kr, ksh) = (100.0, 50.0, 40.0);
        let (p_out, p_in) = (150.0, 80.0);
        let body = TwoLayerBody::circle(nn)
            .with_radii(a0, b0)
            .with_spring(SpringKind::Structural, ks, 0.4)
            .with_spring(SpringKind::Radius, kr, 0.4)
            .with_spring(SpringKind::ShearLeft, ksh, 0.4)
            .with_spring(SpringKind::ShearRight, ksh, 0.4)
            .with_pressure(p_out, p_in)
            .with_gravity(0.0);
        let (a, b) = crate::two_layer::analytic::CircleBody {
            particles: nn,
            inner_radius: a0,
            outer_radius: b0,
            structural: ks,
            radius: kr,
            shear: ksh,
            outer_pressure: p_out,
            inner_pressure: p_in,
        }
        .equilibrium_radii()
        .expect("Newton converges");
        assert!(
            b > 1.05 * b0,
            "pressure should inflate the body noticeably (b = {b})"
        );
        let mut sim = body.simulate(ExplicitMethod::Rk4, 1e-3).unwrap();
        sim.run(4000).unwrap();
        let x = sim.positions();
        let (ra, rb) = (mean_radius(x, 0..nn), mean_radius(x, nn..2 * nn));
        assert!(
            (ra - a).abs() < 1e-4 * a,
            "inner radius {ra} vs analytic {a}"
        );
        assert!(
            (rb - b).abs() < 1e-4 * b,
            "outer radius {rb} vs analytic {b}"
        );
        assert!(sim.energies().kinetic < 1e-8);
    }

    /// 3D: the octahedron sphere with gas settles at the radial force balance. The potential
    /// over uniform scalings `(a, b)` of the two layers is computed here independently from the
    /// mesh and minimised by Newton (the 1D radial root find of `docs/two-layer.md`, done for
    /// both layers). The model's energy must agree with it on scaled shapes; the simulated
    /// equilibrium must have a lower energy (it minimises over all shapes) and lie within 2%
    /// of the predicted radii (the valence-4 kernel points bulge a little, Song 2009, Sec. 3.5.3).
    #[test]
    fn pressurised_sphere_settles_at_radial_force_balance() {
        let (a0, b0, level) = (0.7, 1.0, 2u32);
        let (ks, kr, ksh, p_out, p_in) = (100.0, 60.0, 40.0, 120.0, 60.0);
        let body = TwoLayerBody::octahedron_sphere(level)
            .with_radii(a0, b0)
            .with_spring(SpringKind::Structural, ks, 0.3)
            .with_spring(SpringKind::Radius, kr, 0.3)
            .with_spring(SpringKind::ShearLeft, ksh, 0.3)
            .with_spring(SpringKind::ShearRight, ksh, 0.3)
            .with_pressure(p_out, p_in)
            .with_gravity(0.0);
        let unit = octahedron_sphere(1.0, level).unwrap();
        let u: Vec<Vector3<f64>> = unit.vertices.iter().map(|p| p.coords).collect();
        let mut edges = std::collections::BTreeSet::new();
        for t in &unit.triangles {
            for k in 0..3 {
                let (i, j) = (t[k], t[(k + 1) % 3]);
                edges.insert((i.min(j), i.max(j)));
            }
        }
        let v_unit: f64 = unit
            .triangles
            .iter()
            .map(|t| u[t[0]].dot(&u[t[1]].cross(&u[t[2]])) / 6.0)
            .sum();
        let (c_out, c_in) = (p_out * v_unit * b0.powi(3), p_in * v_unit * a0.powi(3));
        let energy = |a: f64, b: f64| {
            let mut e = 0.0;
            for &(i, j) in &edges {
                let d = (u[i] - u[j]).norm();
                e += 0.5 * ks * d * d * ((a - a0).powi(2) + (b - b0).powi(2));
                let l = (u[j] * b - u[i] * a).norm();
                let l0 = (u[j] * b0 - u[i] * a0).norm();
                e += 2.0 * 0.5 * ksh * (l - l0).powi(2);
            }
            e += u.len() as f64 * 0.5 * kr * ((b - a) - (b0 - a0)).powi(2);
            e - c_in * 3.0 * (a / a0).ln() - c_out * 3.0 * (b / b0).ln()
        };
        let grad = |a: f64, b: f64| {
            let h = 1e-6;
            [
                (energy(a + h, b) - energy(a - h, b)) / (2.0 * h),
                (energy(a, b + h) - energy(a, b - h)) / (2.0 * h),
            ]
        };
        let (mut a, mut b) = (a0, b0);
        for _ in 0..40 {
            let g = grad(a, b);
            let h = 1e-5;
            let (ga, gb) = (grad(a + h, b), grad(a, b + h));
            let (gam, gbm) = (grad(a - h, b), grad(a, b - h));
            let j = [
                [(ga[0] - gam[0]) / (2.0 * h), (gb[0] - gbm[0]) / (2.0 * h)],
                [(ga[1] - gam[1]) / (2.0 * h), (gb[1] - gbm[1]) / (2.0 * h)],
            ];
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            a -= (j[1][1] * g[0] - j[0][1] * g[1]) / det;
            b -= (-j[1][0] * g[0] + j[0][0] * g[1]) / det;
        }
        assert!(
            b > 1.05 * b0,
            "pressure should inflate the body noticeably (b = {b})"
        );
        let mut sim = body.simulate(ExplicitMethod::Rk4, 1e-3).unwrap();
        let n = sim.model().layer_size;
        let scaled: Vec<f64> = sim
            .model()
            .rest_positions
            .iter()
            .enumerate()
            .map(|(k, x)| x * if k < 3 * n { a / a0 } else { b / b0 })
            .collect();
        let zero = vec![0.0; scaled.len()];
        let u_scaled = sim.forces().energies(&scaled, &zero).potential();
        assert!(
            (u_scaled - energy(a, b)).abs() < 1e-9 * energy(a, b).abs(),
            "model energy {u_scaled} vs independent {}",
            energy(a, b)
        );
        sim.run(3000).unwrap();
        let x = sim.positions();
        let (ra, rb) = (mean_radius(x, 0..n), mean_radius(x, n..2 * n));
        assert!(
            (rb - b).abs() < 0.02 * b,
            "outer radius {rb} vs predicted {b}"
        );
        assert!(
            (ra - a).abs() < 0.02 * a,
            "inner radius {ra} vs predicted {a}"
        );
        assert!(sim.energies().kinetic < 1e-8);
        assert!(sim.energies().potential() <= u_scaled + 1e-9 * u_scaled.abs());
        // A static equilibrium: the net force on every particle vanishes.
        let mut f = vec![0.0; x.len()];
        let mut forces = sim.forces().clone();
        forces.forces_into(x, &zero, &mut f);
        let worst = f.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        assert!(worst < 1e-6, "residual force {worst:.3e} N");
    }

    /// A body dropped in a box with damped collisions comes to rest on the floor: the floor
    /// removes kinetic energy at every bounce and the spring damping the vibrations; no
    /// particle leaves the box and no inner particle leaves the outer layer.
    #[test]
    fn dropped_body_comes_to_rest_on_the_floor() {
        let floor = -1.3;
        let bbox =
            AxisBox::try_new(Point3::new(-2.0, -2.0, floor), Point3::new(2.0, 2.0, 2.0)).unwrap();
        let body = TwoLayerBody::octahedron_sphere(1)
            .with_radii(0.7, 1.0)
            .with_pressure(30.0, 15.0)
            .with_damping(1.0)
            .with_box(Some(bbox))
            .with_restitution(0.3);
        let mut sim = body.simulate(ExplicitMethod::Rk4, 5e-4).unwrap();
        let mut touched = false;
        for _ in 0..6000 {
            let s = sim.step().unwrap();
            touched |= s.collisions > 0;
        }
        let s = sim.stats();
        assert!(touched);
        assert!(
            s.kinetic < 1e-5,
            "still moving: kinetic {:.3e} J",
            s.kinetic
        );
        assert!(
            (s.min_height - floor).abs() < 1e-3,
            "min height {}",
            s.min_height
        );
        assert!(
            s.total < sim.energy_initial(),
            "energy must have been dissipated"
        );
        assert_eq!(sim.escaped_particles(), 0);
        let n = sim.model().layer_size;
        // Resting on the floor, the body is squashed but still holds its gas.
        assert!(s.volume_outer > 0.7 * sim.model().rest_volume_outer);
        // It fell from its start (centre at z = 0) and sits above the floor.
        let cz = centroid(sim.positions(), n..2 * n).z;
        assert!(cz < -0.1 && cz > floor + 0.5, "centre height {cz}");
    }

    /// The drag spring pulls the nearest outer particle, and with it the body, toward the
    /// target; removing it leaves the body free.
    #[test]
    fn drag_moves_the_body_toward_the_target() {
        let body = TwoLayerBody::octahedron_sphere(1)
            .with_pressure(200.0, 100.0)
            .with_damping(0.2)
            .with_gravity(0.0);
        let mut sim = body.simulate(ExplicitMethod::Rk4, 1e-3).unwrap();
        let target = Point3::new(4.0, 0.0, 0.0);
        let pulled = sim
            .set_drag(Some(DragTarget {
                point: target,
                stiffness: 5.0,
                damping: 0.1,
                rest_length: 0.0,
            }))
            .unwrap()
            .unwrap();
        let n = sim.model().layer_size;
        assert_eq!(
            pulled, n,
            "outer particle 0 at (1, 0, 0) is nearest to the target"
        );
        assert!(sim.work_done() > 0.0);
        let c0 = centroid(sim.positions(), 0..2 * n);
        let d0 = (Vector3::new(sim.positions()[3 * pulled], 0.0, 0.0) - target.coords).norm();
        sim.run(1000).unwrap();
        let c1 = centroid(sim.positions(), 0..2 * n);
        let d1 = (Vector3::new(sim.positions()[3 * pulled], 0.0, 0.0) - target.coords).norm();
        assert!(c1.x > c0.x + 0.05, "centre moved {} -> {}", c0.x, c1.x);
        assert!(d1 < d0);
        assert!(
            c1.y.abs() < 1e-6 && c1.z.abs() < 1e-6,
            "pulled straight along x"
        );
        assert_eq!(sim.set_drag(None).unwrap(), None);
        assert!(sim.forces().drag().is_none());
        assert!(
            sim.set_drag(Some(DragTarget {
                point: target,
                stiffness: -1.0,
                damping: 0.0,
                rest_length: 0.0
            }))
            .is_err()
        );
    }

    #[test]
    fn invalid_parameters_are_errors_naming_the_parameter() {
        let check = |body: TwoLayerBody, dt: f64, name: &str| {
            let msg = body
                .simulate(ExplicitMethod::Rk4, dt)
                .expect_err("must fail")
                .to_string();
            assert!(msg.contains(name), "`{msg}` should name `{name}`");
        };
        let b = || TwoLayerBody::octahedron_sphere(1);
        check(b().with_masses(0.0, 1.0), 1e-3, "inner_mass");
        check(b().with_masses(1.0, -1.0), 1e-3, "outer_mass");
        check(b().with_radii(-0.1, 1.0), 1e-3, "inner_radius");
        check(
            b().with_radii(1.0, 1.0),
            1e-3,
            "must be below the outer radius",
        );
        check(b().with_radii(0.5, f64::NAN), 1e-3, "outer_radius");
        check(b(), 0.0, "dt");
        check(b(), -1e-3, "dt");
        check(
            b().with_spring(SpringKind::Radius, 0.0, 0.1),
            1e-3,
            "radius stiffness",
        );
        check(
            b().with_spring(SpringKind::ShearLeft, 1.0, -0.1),
            1e-3,
            "shear-left damping",
        );
        check(b().with_pressure(-1.0, 0.0), 1e-3, "outer_pressure");
        check(b().with_restitution(1.5), 1e-3, "restitution");
        check(TwoLayerBody::circle(2), 1e-3, "particles");
        check(TwoLayerBody::uv_sphere(2, 4), 1e-3, "slices");
        check(TwoLayerBody::octahedron_sphere(9), 1e-3, "level");
        check(TwoLayerBody::line(0.0), 1e-3, "length");
        let small = AxisBox::try_new(Point3::new(-0.5, -0.5, -0.5), Point3::new(0.5, 0.5, 0.5));
        check(b().with_box(Some(small.unwrap())), 1e-3, "collision_box");
    }

    /// Stiff springs at a large step: the explicit integrators leave their stability region,
    /// and the step reports a blow-up that names the step, integrator and dt.
    #[test]
    fn unstable_step_is_detected_as_blow_up() {
        for method in ExplicitMethod::ALL {
            let body = TwoLayerBody::octahedron_sphere(1)
                .with_spring(SpringKind::Structural, 1e5, 0.0)
                .with_pressure(100.0, 0.0);
            let mut sim = body.simulate(method, 5e-3).unwrap();
            let err = sim.run(2000).expect_err("must blow up");
            let msg = err.to_string();
            match err {
                TwoLayerError::BlowUp {
                    step,
                    dt,
                    suggested_dt,
                    reason,
                    ..
                } => {
                    assert!((1..2000).contains(&step));
                    assert_eq!(dt, 5e-3);
                    assert!(suggested_dt < dt);
                    // The reason carries its numbers and the message states them.
                    match reason {
                        BlowUpReason::NonFinite { particle, .. } => {
                            assert!(particle < sim.forces().model().num_particles())
                        }
                        BlowUpReason::InvertedLayer { volume, .. } => assert!(volume <= 0.0),
                        BlowUpReason::EnergyGrowth { total, bound, .. } => {
                            assert!(total > bound || !total.is_finite(), "{total} {bound}")
                        }
                    }
                    assert!(msg.contains(&format!(": {reason}; ")), "{msg}");
                }
                other => panic!("unexpected error {other}"),
            }
            assert!(
                msg.contains(method.name()) && msg.contains("smaller dt"),
                "{msg}"
            );
        }
        // The same body at a small step is fine.
        let body = TwoLayerBody::octahedron_sphere(1)
            .with_spring(SpringKind::Structural, 1e5, 0.0)
            .with_pressure(100.0, 0.0);
        let mut sim = body.simulate(ExplicitMethod::Rk4, 1e-4).unwrap();
        sim.run(200).unwrap();
    }

    /// 2D: the two-layer circle dropped on the floor of a box (gravity along -y) comes to rest
    /// on it with every particle in the box and the inner polygon inside the outer one; the same
    /// with valence normalisation on a 3D sphere stays stable and bounded.
    #[test]
    fn circle_rests_on_the_floor_and_normalised_sphere_is_stable() {
        let floor = -1.5;
        let bbox =
            AxisBox::try_new(Point3::new(-3.0, floor, -1.0), Point3::new(3.0, 3.0, 1.0)).unwrap();
        // 18 particles: the lowest point is a side, not a vertex (a polygon balanced on a
        // vertex is an unstable equilibrium and would roll away on the frictionless floor).
        let body = TwoLayerBody::circle(18)
            .with_radii(0.7, 1.0)
            .with_pressure(30.0, 15.0)
            .with_damping(1.0)
            .with_box(Some(bbox))
            .with_restitution(0.0);
        let mut sim = body.simulate(ExplicitMethod::Rk4, 5e-4).unwrap();
        sim.run(16000).unwrap();
        let s = sim.stats();
        // The inflated 2D body keeps a slow, weakly damped wobble: allow 0.1% of the fall energy.
        let fall = sim.model().masses.iter().sum::<f64>() * 9.81 * 0.5;
        assert!(s.kinetic < 1e-3 * fall, "kinetic {:.3e} J", s.kinetic);
        assert!((s.min_height - floor).abs() < 1e-3);
        assert_eq!(sim.escaped_particles(), 0);
        assert!(sim.positions().iter().skip(2).step_by(3).all(|z| *z == 0.0));
        let body = TwoLayerBody::octahedron_sphere(2)
            .with_valence_normalization(true)
            .with_pressure(50.0, 25.0)
            .with_box(Some(
                AxisBox::try_new(Point3::new(-2.0, -2.0, -1.2), Point3::new(2.0, 2.0, 2.0))
                    .unwrap(),
            ));
        let mut sim = body.simulate(ExplicitMethod::Rk4, 1e-3).unwrap();
        sim.run(1000).unwrap();
        assert_eq!(sim.escaped_particles(), 0);
    }

    #[test]
    fn builders_make_the_paper_spring_layout() {
        // 2D (Song 2009, Sec. 3.4.2): N structural springs per layer, N radius, N left and N right
        // shear springs; 2N drawing triangles.
        let m = TwoLayerBody::circle(12).build().unwrap();
        assert_eq!(m.num_particles(), 24);
        assert_eq!(m.spring_counts(), [24, 12, 12, 12]);
        assert_eq!(m.draw_triangles().len(), 24);
        assert!(
            (m.rest_volume_outer - 0.5 * 12.0 * (std::f64::consts::TAU / 12.0).sin()).abs() < 1e-12
        );
        // 3D octahedron level 1: V = 18, E = 48, F = 32 per layer (Euler: V - E + F = 2).
        let m = TwoLayerBody::octahedron_sphere(1).build().unwrap();
        assert_eq!(m.layer_size, 18);
        assert_eq!(m.spring_counts(), [96, 18, 48, 48]);
        assert_eq!(m.draw_triangles().len(), 64);
        // UV sphere: slices * (stacks - 1) + 2 particles per layer.
        let m = TwoLayerBody::uv_sphere(8, 6).build().unwrap();
        assert_eq!(m.layer_size, 8 * 5 + 2);
        // Rest lengths are the rest distances: the body at rest carries no spring force.
        let body = TwoLayerBody::uv_sphere(8, 6).with_gravity(0.0);
        let m = body.build().unwrap();
        let mut f = vec![0.0; m.rest_positions.len()];
        TwoLayerForces::new(m.clone(), &body).forces_into(
            &m.rest_positions,
            &vec![0.0; f.len()],
            &mut f,
        );
        assert!(f.iter().all(|c| c.abs() < 1e-12));
    }
}
