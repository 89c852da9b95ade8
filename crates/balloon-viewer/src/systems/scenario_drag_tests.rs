//! Tests of the page's drag in scenario runs: it moves the picked vertex of every kind of
//! scenario, acts on top of the scenario's anchors and scheduled loads (a load that starts
//! during the drag keeps it), and goes away on release.

use super::scenario::ScenarioView;
use super::scenario::builtin_connect;
use super::test_support::{DragSequence, random_drag_sequences};
use super::view::{DragRequest, ViewSystem, bbox_diagonal};
use crate::protocol::DragMode;
use balloon_scenario::Scenario;

fn scenario(text: &str) -> (tempfile::TempDir, Scenario) {
    let (dir, path) = super::test_support::scenario_dir(text);
    let s = balloon_scenario::file::read(&path, &[]).unwrap().scenario;
    (dir, s)
}

fn point(view: &ScenarioView, i: usize) -> [f64; 3] {
    let x = view.positions();
    [x[3 * i], x[3 * i + 1], x[3 * i + 2]]
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|d| (a[d] - b[d]).powi(2)).sum::<f64>().sqrt()
}

/// The vertex with the largest coordinate `axis` (the top of the body along the page's up).
fn top(view: &ScenarioView, axis: usize) -> usize {
    let x = view.positions();
    (0..x.len() / 3)
        .max_by(|&i, &j| x[3 * i + axis].total_cmp(&x[3 * j + axis]))
        .unwrap()
}

/// Steps `text`'s scenario `n` times with and without a drag of its top vertex (along
/// `axis`) towards a target `pull` (m) beyond it sideways; returns the dragged and the free
/// view and the distances of the vertex to the target after the steps (dragged, free).
fn drag_against_free(
    text: &str,
    axis: usize,
    pull: f64,
    n: usize,
) -> (ScenarioView, ScenarioView, usize, f64, f64) {
    let (_dir, s) = scenario(text);
    let mut dragged = ScenarioView::new(s.clone()).unwrap();
    let mut free = ScenarioView::new(s).unwrap();
    let v = top(&dragged, axis);
    let mut target = point(&dragged, v);
    target[axis] += pull;
    target[(axis + 1) % 3] += pull;
    let drag = DragRequest {
        vertex: v,
        target,
        mode: DragMode::Grab,
    };
    for _ in 0..n {
        dragged.apply_drag(Some(&drag)).unwrap();
        dragged.step().unwrap();
        free.apply_drag(None).unwrap();
        free.step().unwrap();
    }
    let d_drag = distance(point(&dragged, v), target);
    let d_free = distance(point(&free, v), target);
    (dragged, free, v, d_drag, d_free)
}

const SHELL: &str = r#"
[mesh]
path = "sphere.obj"
[shell]
thickness = 5e-4
[gas]
model = "constant"
pressure = 300
[run]
dt = 0.005
[[anchors]]
spec = "below:y:-0.09@500"
[[loads]]
spec = "grab=0.2,0,0;on=indices:4;stiffness=50;start=0.02"
"#;

#[test]
fn a_drag_pulls_a_shell_scenario_on_top_of_its_anchors_and_loads() {
    let anchors = {
        let (_dir, s) = scenario(SHELL);
        let Scenario::Shell(shell) = &s else { panic!() };
        let (sim, _) = shell.build(None).unwrap();
        sim.anchor_springs().len()
    };
    assert!(anchors > 0);
    let (mut view, free, v, dragged, undragged) = drag_against_free(SHELL, 1, 0.03, 10);
    assert!(
        dragged < 0.5 * undragged,
        "vertex {v}: {dragged} m from the target with the drag, {undragged} m without"
    );
    // The grab load started during the drag (t = 0.02 s) and the drag stayed: the anchors'
    // springs, the grab's and the drag's are all set.
    let during = view.anchor_spring_counts()[0];
    assert!(during > anchors + 1, "{during} springs (anchors {anchors})");
    assert_eq!(free.anchor_spring_counts(), vec![anchors + 1]);
    // Released: the scenario's springs alone.
    view.apply_drag(None).unwrap();
    view.step().unwrap();
    assert_eq!(view.anchor_spring_counts(), vec![anchors + 1]);
    // A pinch is offered and takes the same neighbourhood, squeezed.
    assert_eq!(view.drag_modes(), vec!["grab", "pinch"]);
}

#[test]
fn a_drag_pulls_one_of_connected_balloons() {
    let text = r#"
[system]
kind = "connect"
[mesh]
path = "sphere.obj"
[connect]
copies = 2
stretches = [1.1, 1.3]
[shell]
material = "membrane-neo-hookean"
mu = 4e5
thickness = 1e-3
[run]
dt = 0.01
mass_damping = 5.0
"#;
    let (mut view, _, v, dragged, undragged) = drag_against_free(text, 1, 0.03, 8);
    assert!(
        dragged < 0.7 * undragged,
        "vertex {v}: {dragged} m from the target with the drag, {undragged} m without"
    );
    // Only the balloon of the picked vertex holds springs.
    let counts = view.anchor_spring_counts();
    let picked = usize::from(v >= 162);
    assert!(counts[picked] > 0 && counts[1 - picked] == 0, "{counts:?}");
    view.apply_drag(None).unwrap();
    view.step().unwrap();
    assert_eq!(view.anchor_spring_counts(), vec![0, 0]);
}

#[test]
fn a_drag_pulls_volumetric_and_two_layer_scenarios() {
    let volumetric = r#"
[system]
kind = "volumetric"
[mesh]
path = "sphere.obj"
[lattice]
cells = 60
[run]
scene = "free"
gravity = 0
[[anchors]]
spec = "below:z:-0.05@50"
"#;
    let (_, _, v, dragged, undragged) = drag_against_free(volumetric, 2, 0.02, 200);
    assert!(
        dragged < 0.8 * undragged,
        "volumetric vertex {v}: {dragged} m from the target with the drag, {undragged} m without"
    );
    // A two-layer body with a scripted drag elsewhere: the page's drag replaces it while it
    // lasts.
    let two_layer = r#"
[system]
kind = "two-layer"
[body]
level = 1
[run]
drag = "0,0,-3@0:10"
"#;
    let (_, _, v, dragged, undragged) = drag_against_free(two_layer, 2, 0.3, 400);
    assert!(
        dragged < 0.8 * undragged,
        "two-layer vertex {v}: {dragged} m from the target with the drag, {undragged} m without"
    );
}

/// `examples/static-sphere/static-sphere.toml`: a stiff StVK sphere (1 MPa, 0.3 mm) under
/// 300 Pa, stepping at `dt` = 0.01 s in the viewer.
fn static_sphere() -> Scenario {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/static-sphere/static-sphere.toml"
    );
    balloon_scenario::file::read(std::path::Path::new(path), &[])
        .unwrap()
        .scenario
}

/// A pinch of the highest vertex along `axis` towards its position moved `dx` (m) along x.
fn pinch_at_top(view: &ScenarioView, axis: usize, dx: f64) -> DragRequest {
    let vertex = top(view, axis);
    let mut target = point(view, vertex);
    target[0] += dx;
    DragRequest {
        vertex,
        target,
        mode: DragMode::Pinch,
    }
}

/// Holds `drag` on `view` step by step until the view undoes it: the step at which it did and
/// its notice. Panics when a step fails or after `most` steps without an undo.
fn hold_until_undone(view: &mut ScenarioView, drag: &DragRequest, most: usize) -> (usize, String) {
    for k in 0..most {
        view.apply_drag(Some(drag)).unwrap();
        if let Err(e) = view.step() {
            panic!("{:?} step {k} failed: {e}", drag.mode);
        }
        if let Some(notice) = view.take_notice() {
            return (k, notice);
        }
    }
    panic!("{most} steps of {drag:?} were not undone");
}

/// The volume ratio a view's stats report.
fn volume_ratio(view: &ScenarioView) -> f64 {
    view.stats()["volume_ratio"].as_f64().unwrap()
}

/// `examples/static-sphere/static-sphere.toml` (a stiff StVK sphere stepping at `dt` = 0.01 s
/// in the viewer) grabbed, pulled 14 cm (most of its 0.2 m diameter), released, pinched and
/// released as the e2e test does: every step succeeds, and 60 steps later the sphere's volume
/// is within 1 % of an undragged run's. With the live view's three Newton iterations on the
/// exact tangent the run ran away (a negative thickness 10 to 17 steps after the release).
#[test]
fn a_stiff_sphere_keeps_stepping_after_a_drag_and_a_pinch() {
    let s = static_sphere();
    let mut view = ScenarioView::new(s.clone()).unwrap();
    let mut free = ScenarioView::new(s).unwrap();
    let mut steps = 0;
    let mut step = |view: &mut ScenarioView, what: &str| {
        steps += 1;
        if let Err(e) = view.step() {
            panic!("step {steps} ({what}) failed: {e}");
        }
    };
    for _ in 0..5 {
        step(&mut view, "before the drag");
    }
    let v = top(&view, 2);
    let p0 = point(&view, v);
    let mut target = p0;
    for k in 0..20 {
        if k < 8 {
            target[0] += 0.012;
            target[1] += 0.012;
        }
        let grab = DragRequest {
            vertex: v,
            target,
            mode: DragMode::Grab,
        };
        view.apply_drag(Some(&grab)).unwrap();
        step(&mut view, "grab");
    }
    assert!(
        distance(point(&view, v), target) < 0.1 * distance(p0, target),
        "the grabbed vertex did not follow the drag"
    );
    view.apply_drag(None).unwrap();
    for _ in 0..5 {
        step(&mut view, "after the grab");
    }
    let pinch = pinch_at_top(&view, 2, 5e-4);
    for _ in 0..3 {
        view.apply_drag(Some(&pinch)).unwrap();
        step(&mut view, "pinch");
    }
    view.apply_drag(None).unwrap();
    for _ in 0..60 {
        step(&mut view, "after the pinch");
    }
    for _ in 0..steps {
        free.step().unwrap();
    }
    let (dragged, undragged) = (volume_ratio(&view), volume_ratio(&free));
    eprintln!("volume ratio {dragged} dragged, {undragged} not");
    assert!(
        (dragged - undragged).abs() < 0.01 * undragged,
        "volume ratio {dragged} after the drag, {undragged} without"
    );
}

/// A grab and a pinch of the built-in `connect` (two rubber balloons joined by a tube) as the
/// page makes them, where the pinch target is where the page last drew the vertex: the
/// dragged run keeps stepping. With the paper's three full Newton steps per step (the live
/// view's until this test) this sequence turned balloon 0 inside out in the second step after
/// the pinch (enclosed gas volume -1.1 m^3).
#[test]
fn connected_balloons_keep_stepping_after_a_grab_and_a_stale_pinch() {
    let sequence = DragSequence {
        pre: 16,
        grab: 647,
        pull: 0.08714757839534137,
        hold: 10,
        gap: 3,
        pinch: 1523,
        stale: 9,
        jitter: 0.004195217847357422,
        pinch_hold: 2,
        after: 6,
    };
    let mut view = ScenarioView::new(Scenario::Connect(builtin_connect())).unwrap();
    if let Err(e) = sequence.run(&mut view) {
        panic!("{sequence:?}: {e}");
    }
}

/// Random drag sequences ([`DragSequence::random`]) of the built-in `connect`; prints each and
/// the first error. The measurement of docs/viewer.md ("Dragging connected balloons"):
/// `SEED=2 TRIALS=60 cargo test --release -p balloon-viewer --lib random_drag_sequences_of_connected -- --ignored --nocapture`.
#[test]
#[ignore = "a measurement (minutes in release): SEED, TRIALS"]
fn random_drag_sequences_of_connected_balloons() {
    random_drag_sequences(|| ScenarioView::new(Scenario::Connect(builtin_connect())).unwrap());
}

/// A pinch held on `examples/static-sphere/static-sphere.toml` (a stiff StVK sphere) crushes
/// its wall: a patch pulled to 30 % of its size turns inside out (a negative thickness in the
/// volume projection, 27 to 40 steps into the pinch in random drag sequences). The failing
/// step undoes the drag ([`super::shell::UNDO_WINDOW`]): every step succeeds, the run is
/// back at its state from before the pinch, says so once, and goes on as an undragged run.
#[test]
fn pinches_that_crush_the_wall_are_undone() {
    let mut view = ScenarioView::new(static_sphere()).unwrap();
    for _ in 0..5 {
        view.step().unwrap();
    }
    let before = view.positions();
    let pinch = pinch_at_top(&view, 1, 2e-3);
    let (k, notice) = hold_until_undone(&mut view, &pinch, 80);
    eprintln!("pinch step {k}: {notice}");
    // The failure's own advice (a smaller `dt`) is not the remedy here: the notice says so.
    assert!(
        notice.contains("undone")
            && notice.contains("back at step 5")
            && notice.contains("The drag caused the failure"),
        "{notice}"
    );
    assert_eq!(
        view.positions(),
        before,
        "not back at the state before the pinch"
    );
    assert_eq!(view.steps(), 5);
    view.apply_drag(None).unwrap();
    for k in 0..40 {
        if let Err(e) = view.step() {
            panic!("step {k} after the undo failed: {e}");
        }
        assert_eq!(view.take_notice(), None);
    }
    let mut free = ScenarioView::new(static_sphere()).unwrap();
    for _ in 0..view.steps() {
        free.step().unwrap();
    }
    let (undone, undragged) = (volume_ratio(&view), volume_ratio(&free));
    assert!(
        (undone - undragged).abs() < 0.01 * undragged,
        "volume ratio {undone} after the undone pinch, {undragged} without"
    );
}

/// Random drag sequences ([`DragSequence::random`]) of `examples/static-sphere` (a stiff StVK
/// sphere); prints each, the drags undone and the first error. The measurement of
/// docs/viewer.md ("Drags that crush the wall"):
/// `SEED=1 TRIALS=40 HOLD=100 cargo test --release -p balloon-viewer --lib random_drag_sequences_of_the_static_sphere -- --ignored --nocapture`.
#[test]
#[ignore = "a measurement (a minute in release): SEED, TRIALS, HOLD"]
fn random_drag_sequences_of_the_static_sphere() {
    let s = static_sphere();
    random_drag_sequences(|| ScenarioView::new(s.clone()).unwrap());
}

/// Two connected StVK balloons (the built-in icosphere, 1 MPa, 0.3 mm, 300 Pa): a grab towards
/// a target 10 m above them fails the step (the grabbed balloon's wall crushed in the volume
/// projection, after the other balloon had stepped): the drag is undone, both balloons are
/// back at their state before the grab, and the run goes on; 20 steps later the balloons are
/// where an undragged run has them. (The built-in `connect`'s 1 mm neo-Hookean walls take
/// the same grab.)
#[test]
fn a_grab_that_breaks_connected_balloons_is_undone() {
    let text = r#"
[system]
kind = "connect"
[mesh]
path = "builtin:icosphere"
[shell]
material = "stvk"
young = 1e6
thickness = 3e-4
[connect]
copies = 2
pressures = [300.0, 300.0]
[run]
dt = 0.01
"#;
    let (_dir, s) = scenario(text);
    let mut view = ScenarioView::new(s.clone()).unwrap();
    for _ in 0..5 {
        view.step().unwrap();
    }
    let before = view.positions();
    let v = top(&view, 1);
    let mut target = point(&view, v);
    target[1] += 10.0;
    let grab = DragRequest {
        vertex: v,
        target,
        mode: DragMode::Grab,
    };
    let (_, notice) = hold_until_undone(&mut view, &grab, 20);
    assert!(notice.contains("back at step 5"), "{notice}");
    assert_eq!(view.positions(), before);
    assert_eq!(view.steps(), 5);
    view.apply_drag(None).unwrap();
    for k in 0..20 {
        if let Err(e) = view.step() {
            panic!("step {k} after the undo failed: {e}");
        }
    }
    let mut free = ScenarioView::new(s).unwrap();
    for _ in 0..view.steps() {
        free.step().unwrap();
    }
    let diagonal = bbox_diagonal(&free.positions());
    let apart = view
        .positions()
        .iter()
        .zip(free.positions())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        apart < 1e-6 * diagonal,
        "{apart} m from the undragged run (diagonal {diagonal} m)"
    );
}
