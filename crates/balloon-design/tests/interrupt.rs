//! A stop asked of every solve of the process (the `balloon` command's Ctrl-C, through
//! `balloon_integrate::newton::set_cancel_check`) stops a design and keeps its best rest shape,
//! and the check of that rest shape is still a real forward solve. In a test binary of its own:
//! the cancellation check is process-wide.

use balloon_design::{
    DesignParams, DesignProblem, DesignProgress, FallbackMode, FallbackParams, FallbackStop,
    InverseParams, design,
};
use balloon_integrate::statics::StaticParams;
use balloon_material::membrane::{MembraneModel, MembraneNeoHookean};
use balloon_shell::ShellMaterialModel;
use std::sync::atomic::{AtomicBool, Ordering};

#[allow(dead_code)] // The test uses only the wall thickness of the shared set-up.
mod support;
use support::H;

/// Whether a stop was asked for.
static STOP: AtomicBool = AtomicBool::new(false);

/// A box target: flat faces under pressure have no exact design, so the shape optimisation has
/// work to do after an unconverged inverse solve.
fn problem() -> DesignProblem {
    let target =
        balloon_mesh::generate::box_mesh(nalgebra::Vector3::new(0.1, 0.08, 0.06), 2).unwrap();
    let membrane: ShellMaterialModel =
        MembraneModel::from(MembraneNeoHookean::try_new(4.0e5).unwrap()).into();
    DesignProblem::try_new(&target, vec![H; target.num_triangles()], membrane, 2.0e3).unwrap()
}

fn params() -> DesignParams {
    DesignParams {
        inverse: InverseParams {
            max_halvings: 4,
            ..InverseParams::default()
        },
        fallback: FallbackParams {
            mode: FallbackMode::Always,
            ..FallbackParams::default()
        },
        ..DesignParams::default()
    }
}

#[test]
fn a_stop_asked_of_the_solves_keeps_the_best_design_and_checks_it() {
    assert!(balloon_integrate::newton::set_cancel_check(
        || STOP.load(Ordering::SeqCst)
    ));
    let problem = problem();

    // Not stopped: the shape optimisation takes several steps.
    let plain = design(&problem, &params(), |_| true).unwrap();
    let full = plain.inverse.fallback.as_ref().unwrap();
    assert!(full.iterations > 1, "{full:?}");
    assert!(plain.check.converged);

    // Asked to stop after the first step of the shape optimisation (the callback itself goes
    // on, as the signal is seen by the solves first): every later trial's forward solve stops,
    // which ends the optimisation as interrupted, not as a failed search.
    let result = design(&problem, &params(), |p| {
        if matches!(p, DesignProgress::Fallback(_)) {
            STOP.store(true, Ordering::SeqCst);
        }
        true
    })
    .unwrap();
    let stopped = result.inverse.fallback.as_ref().unwrap();
    assert_eq!(stopped.stopped, FallbackStop::Interrupted, "{stopped:?}");
    assert_eq!(stopped.iterations, 1, "{stopped:?}");
    // The check is a real forward solve of the rest shape kept, with the stop still asked for:
    // it converges, and it finds the equilibrium the optimisation's first step had.
    assert!(balloon_integrate::newton::cancel_requested());
    assert!(result.check.converged, "{:?}", result.check.iterations);
    assert!(result.check.iterations > 0);
    let end = stopped.end.unwrap();
    assert!(
        (result.check.distance.rms - end.rms).abs() < 1e-6 * end.rms,
        "{:?} vs {end:?}",
        result.check.distance
    );
    assert!(end.rms < stopped.start.unwrap().rms);
    // Without the suspension the same check stops at once, unconverged.
    let unchecked =
        balloon_design::forward_check(&problem, &result.rest, &StaticParams::default()).unwrap();
    assert!(!unchecked.converged && unchecked.iterations == 0);

    // Asked to stop during the inverse solve: no shape optimisation starts (the design is
    // stopped), and the inverse's best rest shape is checked.
    STOP.store(false, Ordering::SeqCst);
    let result = design(&problem, &params(), |p| {
        if matches!(p, DesignProgress::Inverse(_)) {
            STOP.store(true, Ordering::SeqCst);
        }
        true
    })
    .unwrap();
    assert!(result.inverse.fallback.is_none(), "{:?}", result.inverse);
    assert!(result.check.converged && result.check.iterations > 0);
    STOP.store(false, Ordering::SeqCst);
}
