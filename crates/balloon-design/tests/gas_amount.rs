//! A load given as an amount of ideal gas (`DesignProblem::with_gas_amount`, `docs/design.md`,
//! "A gas amount as the load"): the design at the gas's pressure on the target, and a forward
//! check whose pressure follows the volume.

use balloon_design::{
    DesignError, DesignParams, DesignProblem, design, distance, enclosed_volume, forward_check,
    rigidly_aligned,
};
use balloon_integrate::statics::StaticParams;
use balloon_material::membrane::{MembraneModel, MembraneNeoHookean};
use balloon_shell::ShellMaterialModel;

mod support;
use support::{H, ellipsoid, inflate};

/// Standard atmosphere, Pa.
const AMBIENT: f64 = 101_325.0;

fn membrane() -> ShellMaterialModel {
    MembraneModel::from(MembraneNeoHookean::try_new(4.0e5).unwrap()).into()
}

/// The membrane ellipsoid inflated at a constant 8 kPa to `x*`, and the amount of gas
/// `nRT = (p + p_a) V(x*)` that holds `x*` at the same gauge pressure.
fn target_and_amount() -> (balloon_mesh::TriMesh, balloon_mesh::TriMesh, f64) {
    let rest = ellipsoid(2);
    let x_star = inflate(&rest, &membrane(), 8.0e3);
    let mut target = rest.clone();
    target.set_positions_flat(&x_star);
    let amount = (8.0e3 + AMBIENT) * enclosed_volume(&x_star, &target.triangles);
    (rest, target, amount)
}

/// The round trip with the load as an amount of gas: the problem's pressure is the gas's
/// gauge pressure at the target, the design recovers the rest shape, and the forward check
/// (solved with the gas) lands on the target at the target's volume.
#[test]
fn a_gas_amount_designs_the_rest_shape_that_holds_it() {
    let (rest, target, amount) = target_and_amount();
    let n = target.num_triangles();
    let problem =
        DesignProblem::with_gas_amount(&target, vec![H; n], membrane(), amount, AMBIENT).unwrap();
    assert!(
        (problem.pressure() - 8.0e3).abs() < 1e-9 * 8.0e3,
        "{}",
        problem.pressure()
    );
    let result = design(&problem, &DesignParams::default(), |_| true).unwrap();
    assert!(result.inverse.converged, "{:?}", result.inverse);
    let x0 = rest.positions_flat();
    let recovered = distance(&rigidly_aligned(&result.rest, &x0), &x0);
    assert!(recovered.max_relative < 1e-3, "{recovered:?}");
    assert!(result.check.converged);
    assert!(
        result.check.distance.max_relative < 1e-4,
        "{:?}",
        result.check.distance
    );
    let v_star = enclosed_volume(problem.target(), problem.triangles());
    assert!(
        (result.check.volume - v_star).abs() < 1e-6 * v_star,
        "{} vs {v_star}",
        result.check.volume
    );
}

/// From a rest shape that is not the design (the target's rest shape scaled by 0.95) the
/// forward check with the gas ends where the gas's pressure `nRT / V - p_a` holds the shell:
/// solving the same rest shape at that constant pressure gives the same volume; and it is not
/// the equilibrium at the target's pressure (the gas's pressure followed the volume).
#[test]
fn the_forward_check_of_a_gas_amount_follows_the_volume() {
    let (rest, target, amount) = target_and_amount();
    let n = target.num_triangles();
    let gas =
        DesignProblem::with_gas_amount(&target, vec![H; n], membrane(), amount, AMBIENT).unwrap();
    let smaller: Vec<f64> = rest.positions_flat().iter().map(|x| 0.95 * x).collect();
    let params = StaticParams {
        tolerance: 1e-11,
        ..StaticParams::default()
    };
    let with_gas = forward_check(&gas, &smaller, &params).unwrap();
    assert!(with_gas.converged);
    let p_eff = amount / with_gas.volume - AMBIENT;
    let at_p_eff = DesignProblem::try_new(&target, vec![H; n], membrane(), p_eff).unwrap();
    let constant = forward_check(&at_p_eff, &smaller, &params).unwrap();
    assert!(constant.converged);
    assert!(
        (constant.volume - with_gas.volume).abs() < 1e-7 * with_gas.volume,
        "gas {} vs constant pressure {p_eff} Pa: {}",
        with_gas.volume,
        constant.volume
    );
    let at_target_pressure =
        DesignProblem::try_new(&target, vec![H; n], membrane(), 8.0e3).unwrap();
    let fixed = forward_check(&at_target_pressure, &smaller, &params).unwrap();
    assert!(
        (fixed.volume - with_gas.volume).abs() > 1e-3 * with_gas.volume,
        "{} vs {}",
        fixed.volume,
        with_gas.volume
    );
}

#[test]
fn a_gas_amount_below_the_ambient_pressure_is_refused() {
    let (_, target, amount) = target_and_amount();
    let n = target.num_triangles();
    let v = enclosed_volume(&target.positions_flat(), &target.triangles);
    for (amount, ambient, name) in [
        (0.99 * AMBIENT * v, AMBIENT, "gas_amount"),
        (-amount, AMBIENT, "gas_amount"),
        (f64::NAN, AMBIENT, "gas_amount"),
        (amount, 0.0, "ambient"),
    ] {
        let e = DesignProblem::with_gas_amount(&target, vec![H; n], membrane(), amount, ambient)
            .unwrap_err();
        assert!(
            matches!(e, DesignError::InvalidParameter { name: n, .. } if n == name),
            "{e}"
        );
    }
}
