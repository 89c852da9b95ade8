//! Incompressible rubber membranes in the shell: [`ShellBalloon::with_membrane`] (the
//! [`Membrane`] material wrapper and the analytic sphere stretch for a pressure,
//! [`membrane_sphere_stretch`], live in `balloon-shell`).
//!
//! A membrane shell runs through the same system, Newton solver (exact and projected tangents),
//! gas models, anchors, statistics and `Simulation` trait as the three-prism shell; only the
//! element differs ([`balloon_element::HyperMembrane`], `docs/membranes.md` M22-M25), and the
//! thickness is not a state but `h = H / (l1 l2)` (M2), refreshed after every solve.

#[cfg(doc)]
use balloon_material::MembraneModel;
use balloon_material::membrane::MembraneMaterial;

#[cfg(doc)]
use super::membrane_sphere_stretch;
use super::{Membrane, ShellBalloon, ShellGas};

impl<M: super::ShellMaterial, G: ShellGas> ShellBalloon<M, G> {
    /// Makes the shell an incompressible rubber membrane of `model` (any [`MembraneMaterial`],
    /// e.g. `MembraneGent::try_new(mu, jm)?` or a [`MembraneModel`] such as
    /// `MembranePreset::NaturalRubber.model()`): [`balloon_element::HyperMembrane`] elements
    /// instead of three-prisms, the rest thickness set by [`ShellBalloon::with_thickness`] as
    /// `H`.
    ///
    /// It also switches the shell-volume projection off. For a membrane it is redundant: the
    /// thickness follows incompressibility, `h = H / (l1 l2)`, so every element keeps its
    /// material volume `A h = A0 H` exactly and the projection of Wang et al. 2015 (Alg. 1, line 10;
    /// Eq. 24-28) has nothing to correct. A projector set again after this call is consistent
    /// with it: the shell refreshes the thickness before the projector runs, so the constraint
    /// holds and the projection moves nothing (and the thickness is refreshed again after it).
    ///
    /// ```
    /// use balloon::gas::GasKind;
    /// use balloon::material::membrane::MembraneNeoHookean;
    /// use balloon::shell::ShellBalloon;
    ///
    /// let mesh = balloon::mesh::generate::icosphere(0.1, 2)?;
    /// let rubber = MembraneNeoHookean::try_new(4.0e5)?;
    /// let mut sim = ShellBalloon::new(mesh)
    ///     .with_membrane(rubber)
    ///     .with_thickness(1.0e-3)
    ///     .with_gas(GasKind::Constant)
    ///     .with_gauge_pressure(3000.0)
    ///     .build()?;
    /// let stats = sim.step()?;
    /// assert!(stats.gas_volume > sim.rest_gas_volume());
    /// // Incompressible: every element keeps its material volume, thickness = H / (l1 l2).
    /// assert!((stats.shell_volume_ratio - 1.0).abs() < 1e-12);
    /// assert!(stats.thickness_max < 1.0e-3);
    /// assert_eq!(stats.projection_iterations, 0);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn with_membrane<W: MembraneMaterial>(self, model: W) -> ShellBalloon<Membrane<W>, G> {
        self.with_material(Membrane(model)).with_projection(None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gas::GasKind;
    use crate::integrate::TangentKind;
    use crate::material::membrane::{
        MembraneGent, MembraneMooneyRivlin, MembraneNeoHookean, MembraneOgden, MembranePreset,
        MembraneYeoh,
    };
    use crate::mesh::generate::icosphere;
    use crate::mesh::geometry;
    use crate::shell::{ShellMaterial, ShellMaterialModel, membrane_sphere_stretch};
    use balloon_material::MembraneModel;
    use balloon_material::membrane::ThinSphere;

    fn neo_hookean() -> MembraneNeoHookean {
        MembraneNeoHookean::try_new(4.0e5).unwrap()
    }

    /// Steps until the gas volume changes by less than `tol` (relative) over a step; returns the
    /// steps taken, or `None` when it did not settle within `max_steps`.
    fn settle<M: ShellMaterial>(
        sim: &mut crate::shell::ShellSimulation<M>,
        max_steps: usize,
        tol: f64,
    ) -> Option<usize> {
        let mut last = sim.gas_volume();
        for k in 1..=max_steps {
            let s = sim.step().unwrap();
            if (s.gas_volume - last).abs() < tol * s.gas_volume {
                return Some(k);
            }
            last = s.gas_volume;
        }
        None
    }

    /// The neo-Hookean membrane icosphere (642 vertices, `R = 3 V0 / A0`) under a constant gauge
    /// pressure of 80 % and 97 % of the analytic maximum settles at the analytic stretch of
    /// `ThinSphere` (M18) within 0.1 %, with the exact and the projected tangent, and its
    /// thickness is `H / l^2` there (every element keeps `A h = A0 H`).
    #[test]
    fn membrane_sphere_settles_at_the_analytic_stretch() {
        let mesh = icosphere(0.1, 3).unwrap();
        let r = 3.0 * geometry::enclosed_volume(&mesh) / geometry::surface_area(&mesh);
        let h0 = 1.0e-3;
        let material = neo_hookean();
        let sphere = ThinSphere::try_new(r, h0).unwrap();
        let p_max = sphere.extrema(&material, 3.0).unwrap()[0].pressure;
        for (fraction, tangent) in [
            (0.8, TangentKind::Exact),
            (0.8, TangentKind::Projected),
            (0.97, TangentKind::Exact),
        ] {
            let p = fraction * p_max;
            let expected = membrane_sphere_stretch(&sphere, &material, p).unwrap();
            assert!(expected > 1.1 && expected < 7f64.powf(1.0 / 6.0));
            let mut sim = ShellBalloon::new(mesh.clone())
                .with_membrane(material)
                .with_thickness(h0)
                .with_gas(GasKind::Constant)
                .with_gauge_pressure(p)
                .with_dt(0.05)
                .build()
                .unwrap();
            sim.configure_integrator(|p| p.tangent = tangent).unwrap();
            let steps = settle(&mut sim, 200, 1e-9);
            assert!(steps.is_some(), "{tangent}: did not settle");
            let lambda = (sim.gas_volume() / sim.rest_gas_volume()).cbrt();
            // Measured: 3.3e-6 at 0.8 P_max, 8.5e-6 at 0.97 P_max (the brief asks for 1 %).
            assert!(
                (lambda / expected - 1.0).abs() < 1e-3,
                "{fraction} P_max, {tangent}: stretch {lambda} vs analytic {expected}"
            );
            // Incompressibility: h = H / l^2 on every element (up to the mesh's spread of
            // element stretches), and the mean within 1 % of the analytic thickness.
            let th = sim.thickness();
            let mean = th.iter().sum::<f64>() / th.len() as f64;
            let want = sphere.current_thickness(expected);
            assert!(
                (mean / want - 1.0).abs() < 1e-2,
                "{tangent}: mean thickness {mean} vs H / l^2 = {want}"
            );
            for (e, (&h, t)) in th.iter().zip(sim.triangles()).enumerate() {
                let x = sim.positions();
                let a = |v: usize| nalgebra::Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
                let area = 0.5 * (a(t[1]) - a(t[0])).cross(&(a(t[2]) - a(t[0]))).norm();
                let r0 = sim.rest_positions();
                let b = |v: usize| nalgebra::Vector3::new(r0[3 * v], r0[3 * v + 1], r0[3 * v + 2]);
                let area0 = 0.5 * (b(t[1]) - b(t[0])).cross(&(b(t[2]) - b(t[0]))).norm();
                assert!(
                    (h * area / (h0 * area0) - 1.0).abs() < 1e-10,
                    "element {e}: A h = {} vs A0 H = {}",
                    h * area,
                    h0 * area0
                );
            }
            let shell = sim.shell_volume() / sim.rest_shell_volume();
            assert!((shell - 1.0).abs() < 1e-12, "shell volume ratio {shell}");
        }
    }

    /// A static volume continuation of a membrane sphere reports, at every point, the
    /// incompressible thickness of that point's own shape: every element keeps `A h = A0 H`
    /// (measured from the returned positions) and the shell volume is the rest one. (The
    /// thickness was once refreshed from the shape before the solve, so each point reported the
    /// previous point's thickness and a shell volume 13 % off at V / V0 = 3.)
    #[test]
    fn static_points_report_their_own_incompressible_thickness() {
        use crate::shell::statics::{StaticControl, StaticOptions};
        let mesh = icosphere(0.1, 2).unwrap();
        let h0 = 1.0e-3;
        let mut sim = ShellBalloon::new(mesh)
            .with_membrane(neo_hookean())
            .with_thickness(h0)
            .with_gas(GasKind::Constant)
            .build()
            .unwrap();
        let v0 = sim.rest_gas_volume();
        for ratio in [1.5, 2.0, 3.0] {
            let report = sim
                .solve_static(&StaticOptions {
                    control: StaticControl::Volume { target: ratio * v0 },
                    ..Default::default()
                })
                .unwrap();
            assert!((report.gas_volume / (ratio * v0) - 1.0).abs() < 1e-6);
            let x = sim.positions();
            let r0 = sim.rest_positions();
            let area = |p: &[f64], t: &[usize; 3]| {
                let a = |v: usize| nalgebra::Vector3::new(p[3 * v], p[3 * v + 1], p[3 * v + 2]);
                0.5 * (a(t[1]) - a(t[0])).cross(&(a(t[2]) - a(t[0]))).norm()
            };
            let mut sum = 0.0;
            for (e, (&h, t)) in sim.thickness().iter().zip(sim.triangles()).enumerate() {
                let kept = h * area(x, t) / (h0 * area(r0, t));
                assert!(
                    (kept - 1.0).abs() < 1e-10,
                    "V/V0 = {ratio}, element {e}: A h / (A0 H) = {kept}"
                );
                sum += h;
            }
            let mean = sum / sim.thickness().len() as f64;
            assert!(
                (report.thickness_mean / mean - 1.0).abs() < 1e-12,
                "V/V0 = {ratio}: report {} vs thickness {mean}",
                report.thickness_mean
            );
            let shell = sim.shell_volume() / sim.rest_shell_volume();
            assert!(
                (shell - 1.0).abs() < 1e-10,
                "V/V0 = {ratio}: shell volume ratio {shell}"
            );
        }
    }

    /// Above the neo-Hookean maximum a constant pressure has no equilibrium: the analytic helper
    /// says so, and the membrane balloon runs away (the limit point the StVK shell lacks).
    #[test]
    fn above_the_maximum_there_is_no_equilibrium() {
        let mesh = icosphere(0.1, 2).unwrap();
        let r = 3.0 * geometry::enclosed_volume(&mesh) / geometry::surface_area(&mesh);
        let h0 = 1.0e-3;
        let material = neo_hookean();
        let sphere = ThinSphere::try_new(r, h0).unwrap();
        let p_max = sphere.extrema(&material, 3.0).unwrap()[0].pressure;
        assert_eq!(
            membrane_sphere_stretch(&sphere, &material, 1.1 * p_max),
            None
        );
        let mut sim = ShellBalloon::new(mesh)
            .with_membrane(material)
            .with_thickness(h0)
            .with_gas(GasKind::Constant)
            .with_gauge_pressure(1.1 * p_max)
            .with_dt(0.05)
            .build()
            .unwrap();
        let mut grew_past = false;
        for _ in 0..200 {
            match sim.step() {
                Ok(_) => {
                    let l = (sim.gas_volume() / sim.rest_gas_volume()).cbrt();
                    if l > 2.0 {
                        grew_past = true;
                        break;
                    }
                }
                Err(_) => {
                    grew_past = true;
                    break;
                }
            }
        }
        assert!(grew_past, "the balloon held above the pressure maximum");
    }

    /// Every membrane model (and the run-time enum, and both presets) inflates a small sphere
    /// with the ideal gas: the gas volume grows, the stats report the incompressible thickness
    /// and the shell volume is kept without a projection.
    #[test]
    fn every_model_inflates_through_the_shared_paths() {
        let mesh = icosphere(0.1, 1).unwrap();
        let models: Vec<MembraneModel> = vec![
            neo_hookean().into(),
            MembraneMooneyRivlin::try_new(1.8e5, 0.2e5).unwrap().into(),
            MembraneGent::try_new(4.0e5, 30.0).unwrap().into(),
            MembraneOgden::try_new(vec![6.3e5, 1.2e3, -1.0e4], vec![1.3, 5.0, -2.0])
                .unwrap()
                .into(),
            MembraneYeoh::try_new(1.1e5, 2.0e4, 0.0).unwrap().into(),
            MembranePreset::NaturalRubber.model(),
            MembranePreset::ElastosilM4601.model(),
        ];
        for model in models {
            let by_enum = ShellMaterialModel::Membrane(model.clone());
            let mut a = ShellBalloon::new(mesh.clone())
                .with_membrane(model.clone())
                .with_thickness(1e-3)
                .with_gas(GasKind::Ideal)
                .with_gauge_pressure(2000.0)
                .build()
                .unwrap();
            let mut b = ShellBalloon::new(mesh.clone())
                .with_material(by_enum)
                .with_projection(None)
                .with_thickness(1e-3)
                .with_gas(GasKind::Ideal)
                .with_gauge_pressure(2000.0)
                .build()
                .unwrap();
            for _ in 0..3 {
                let sa = a.step().unwrap();
                let sb = b.step().unwrap();
                // The run-time enum computes exactly what the generic membrane computes.
                assert_eq!(sa.gas_volume, sb.gas_volume, "{model:?}");
                assert_eq!(a.positions(), b.positions(), "{model:?}");
                assert!(sa.thickness_max < 1e-3 && sa.thickness_min > 0.0);
                assert!((sa.shell_volume_ratio - 1.0).abs() < 1e-12);
            }
            assert!(a.gas_volume() > 1.01 * a.rest_gas_volume(), "{model:?}");
        }
    }

    /// A projector switched on again after `with_membrane` is consistent: the thickness already
    /// satisfies the shell-volume constraint, so the global projection changes nothing
    /// measurable.
    #[test]
    fn the_projection_is_redundant_for_membranes() {
        let mesh = icosphere(0.1, 2).unwrap();
        let build = |projection: bool| {
            let b = ShellBalloon::new(mesh.clone())
                .with_membrane(neo_hookean())
                .with_thickness(1e-3)
                .with_gas(GasKind::Constant)
                .with_gauge_pressure(3000.0);
            let b = if projection {
                b.with_projection(Some(Default::default()))
            } else {
                b
            };
            b.build().unwrap()
        };
        let (mut off, mut on) = (build(false), build(true));
        for _ in 0..5 {
            off.step().unwrap();
            on.step().unwrap();
        }
        let scale = off.positions().iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (u, v) in off.positions().iter().zip(on.positions()) {
            assert!((u - v).abs() <= 1e-9 * scale, "{u} vs {v}");
        }
        for (u, v) in off.thickness().iter().zip(on.thickness()) {
            assert!((u - v).abs() <= 1e-9 * u, "{u} vs {v}");
        }
    }
}
