//! Tests of the built-in set-ups saved as scenarios: the saved file reads back, names the
//! view's settings, and `balloon run`'s job of it takes the view's steps.

use super::shell::ShellView;
use super::view::ViewSystem;
use crate::protocol::ControlValue;
use balloon::Simulation;
use balloon_scenario::Scenario;

fn max_difference(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Saves `view`'s scenario into `dir`, reads it back, runs `steps` steps of it with
/// `balloon run`'s job and of the view (its springs set before each step, as the server does),
/// and returns the saved scenario and the largest position difference.
fn saved_against_view(
    view: &mut ShellView,
    dir: &std::path::Path,
    steps: usize,
) -> (balloon_scenario::shell::ShellScenario, f64) {
    let text = ViewSystem::scenario_text(view).expect("a built-in shell saves its scenario");
    let path = dir.join("saved.toml");
    std::fs::write(&path, &text).unwrap();
    let Scenario::Shell(mut saved) = balloon_scenario::file::read(&path, &[]).unwrap().scenario
    else {
        panic!("not a shell scenario:\n{text}")
    };
    saved.run.steps = steps;
    for _ in 0..steps {
        view.apply_drag(None).unwrap();
        ViewSystem::step(view).unwrap();
    }
    let (done, _) = balloon_run::jobs::shell::run(&saved, None, None, true).unwrap();
    assert_eq!(Simulation::steps(&done.sim), steps);
    let d = max_difference(&view.positions(), Simulation::positions(&done.sim));
    (saved, d)
}

#[test]
fn the_default_shell_saves_what_balloon_run_repeats() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = crate::default_mesh(crate::SystemKind::Shell).unwrap();
    let mut view = ShellView::new(mesh).unwrap();
    let (saved, d) = saved_against_view(&mut view, dir.path(), 3);
    assert!(d <= 1e-12, "the view and `balloon run` differ by {d} m");
    assert_eq!(saved.mesh.path, super::DEFAULT_SHELL_MESH);
    assert_eq!(saved.run.newton_iters, 3);
    assert_eq!(saved.run.newton_tol, 0.0);
    // `hold`: one spring anchor holding exactly the view's held vertices.
    assert_eq!(saved.anchors.len(), 1);
    let rest = view.rest.clone();
    let picked = saved.anchors[0].selector.select(&rest).unwrap();
    let held: Vec<usize> = view.held.iter().map(|h| h.0).collect();
    assert_eq!(picked, held);
    let springs = view.sim.anchor_springs();
    assert_eq!(springs.len(), held.len());
    assert_eq!(saved.anchors[0].stiffness, Some(springs[0].stiffness));
}

#[test]
fn membranes_gases_and_a_mesh_file_are_saved_as_they_run() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
    let obj = dir.path().join("sphere.obj");
    balloon_mesh::io::write_obj(&obj, &sphere).unwrap();
    let cases: &[&[(&str, ControlValue)]] = &[
        &[],
        &[("hold", ControlValue::Bool(false))],
        &[
            ("material", ControlValue::Choice("membrane-mooney-rivlin")),
            ("gas", ControlValue::Choice("ideal")),
            ("hold", ControlValue::Bool(false)),
        ],
        &[
            ("material", ControlValue::Choice("membrane-ogden")),
            ("gas", ControlValue::Choice("pump")),
            ("pump_rate", ControlValue::Number(2e-3)),
        ],
        &[
            ("material", ControlValue::Choice("membrane-gent")),
            ("gas", ControlValue::Choice("supply-pump")),
            ("solver", ControlValue::Choice("pcg")),
        ],
        &[
            ("material", ControlValue::Choice("membrane-yeoh")),
            ("gas", ControlValue::Choice("leak")),
            ("tangent", ControlValue::Choice("exact")),
        ],
        &[
            ("material", ControlValue::Choice("neo-hookean")),
            ("gas", ControlValue::Choice("polytropic")),
            ("thickness", ControlValue::Number(0.5)),
            ("young", ControlValue::Number(2.0)),
            ("dt", ControlValue::Number(0.004)),
        ],
    ];
    for controls in cases {
        let mut view = ShellView::new(sphere.clone())
            .unwrap()
            .with_mesh_spec(Some(obj.display().to_string()));
        for (name, value) in *controls {
            if view.set_control(name, value).unwrap() {
                view.rebuild().unwrap();
            }
        }
        let (saved, d) = saved_against_view(&mut view, dir.path(), 3);
        assert!(
            d <= 1e-12,
            "{controls:?}: the view and `balloon run` differ by {d} m"
        );
        assert!(std::path::Path::new(&saved.mesh.path).is_absolute());
    }
}

#[test]
fn the_builtin_two_layer_body_saves_what_balloon_run_repeats() {
    let dir = tempfile::tempdir().unwrap();
    for controls in [
        vec![],
        vec![
            ("pressure", ControlValue::Number(80.0)),
            ("integrator", ControlValue::Choice("midpoint")),
            ("gravity", ControlValue::Number(3.0)),
            ("box", ControlValue::Bool(false)),
            ("dt", ControlValue::Number(1e-3)),
        ],
    ] {
        let mut view = super::two_layer::TwoLayerView::new().unwrap();
        for (name, value) in &controls {
            if view.set_control(name, value).unwrap() {
                view.rebuild().unwrap();
            }
        }
        let text = ViewSystem::scenario_text(&view).unwrap();
        let path = dir.path().join("saved.toml");
        std::fs::write(&path, &text).unwrap();
        let Scenario::TwoLayer(mut saved) =
            balloon_scenario::file::read(&path, &[]).unwrap().scenario
        else {
            panic!("not a two-layer scenario:\n{text}")
        };
        saved.run.steps = 20;
        for _ in 0..20 {
            view.apply_drag(None).unwrap();
            ViewSystem::step(&mut view).unwrap();
        }
        let done = balloon_run::jobs::two_layer::run(&saved, None, true).unwrap();
        let d = max_difference(&view.positions(), &Simulation::surface(&done.sim).positions);
        assert!(
            d <= 1e-12,
            "{controls:?}: the view and `balloon run` differ by {d} m"
        );
    }
}
