//! The accuracy of the time stepping against the step size: the thickness coupled to the
//! shell-volume projection removes the first-order splitting error of a pumped balloon.

use crate::mesh::generate::icosphere;
use crate::shell::ShellBalloon;

/// The gauge pressure after `time` s of the default pump on a flattened 5 cm sphere, at step
/// `dt`, with the thickness prediction and coupling on or off.
fn pumped_pressure(dt: f64, time: f64, coupled: bool) -> f64 {
    let mut mesh = icosphere(0.05, 3).unwrap();
    for v in &mut mesh.vertices {
        v.z *= 0.7;
    }
    let mut sim = ShellBalloon::new(mesh)
        .with_dt(dt)
        .with_thickness_prediction(coupled)
        .build()
        .unwrap();
    let steps = (time / dt).round() as usize;
    for _ in 0..steps {
        sim.step().unwrap();
    }
    sim.gauge_pressure()
}

/// With the solve's thickness coupled to the projection, 10 ms steps give the pressure of
/// 2 ms steps to a fraction of the splitting error the paper's Algorithm 1 leaves (which
/// shrinks with the step: first order).
#[test]
fn the_coupled_thickness_removes_the_splitting_error_of_the_pump() {
    let t = 0.1;
    let (c10, c2) = (
        pumped_pressure(0.01, t, true),
        pumped_pressure(0.002, t, true),
    );
    let (s10, s2) = (
        pumped_pressure(0.01, t, false),
        pumped_pressure(0.002, t, false),
    );
    let (coupled, split) = ((c10 / c2 - 1.0).abs(), (s10 / s2 - 1.0).abs());
    assert!(c2 > 100.0, "the pump raised the pressure: {c2} Pa");
    assert!(
        split > 0.02,
        "the splitting error is visible at 10 ms: {s10} vs {s2} Pa"
    );
    assert!(
        coupled < 0.1 * split,
        "coupled {c10} vs {c2} Pa ({coupled:e}), split {s10} vs {s2} Pa ({split:e})"
    );
    // Both converge to the same pressure.
    assert!((c2 / s2 - 1.0).abs() < split, "{c2} vs {s2}");
}
