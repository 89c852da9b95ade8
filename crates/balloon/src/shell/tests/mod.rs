//! Tests of the shell simulation that run the whole step (builder, Newton, projection) on the
//! shell system of `balloon-shell` (whose own tests check its forces and stiffness).

use crate::gas::GasKind;
use crate::integrate::TangentKind;
use crate::integrate::linear::LinearSolverKind;
use crate::material::{Lame, StVenantKirchhoff};
use crate::mesh::generate::icosphere;
use crate::mesh::geometry;
use crate::shell::ShellBalloon;
use crate::shell::analytic::sphere_stretch;

mod builder_examples;
mod live_controls;
mod pins;
mod time_accuracy;

/// Projected Newton (per-element PSD stiffness) converges to the same equilibrium as the
/// exact tangent: the analytic StVK sphere stretch within 0.5 % on the 2562-vertex icosphere
/// at two pressures, with both assembled solvers that rely on an SPD matrix.
#[test]
fn projected_tangent_inflates_the_sphere_to_the_analytic_stretch() {
    let mesh = icosphere(0.1, 4).unwrap();
    let r = 3.0 * geometry::enclosed_volume(&mesh) / geometry::surface_area(&mesh);
    let lame = Lame::try_from_young_poisson(1.0e6, 0.45).unwrap();
    let material = StVenantKirchhoff::new(lame);
    let h0 = 3.0e-4;
    for (p, kind) in [
        (1500.0, LinearSolverKind::Cholesky),
        (3000.0, LinearSolverKind::FactorizedPcg),
    ] {
        let mut sim = ShellBalloon::new(mesh.clone())
            .with_material(material)
            .with_thickness(h0)
            .with_gas(GasKind::Constant)
            .with_gauge_pressure(p)
            .with_linear_solver(kind)
            .with_dt(1.0)
            .build()
            .unwrap();
        sim.configure_integrator(|p| p.tangent = TangentKind::Projected)
            .unwrap();
        let mut last = 0.0;
        let mut settled = false;
        for _ in 0..60 {
            let s = sim.step().unwrap();
            if (s.gas_volume - last).abs() < 1e-9 * s.gas_volume {
                settled = true;
                break;
            }
            last = s.gas_volume;
        }
        assert!(settled, "p = {p}, {kind}: did not settle");
        let lambda = (sim.gas_volume() / sim.rest_gas_volume()).cbrt();
        let expected = sphere_stretch(&material, h0, r, p).unwrap();
        assert!(
            (lambda / expected - 1.0).abs() < 5e-3,
            "p = {p}, {kind}: stretch {lambda} vs analytic {expected}"
        );
    }
}
