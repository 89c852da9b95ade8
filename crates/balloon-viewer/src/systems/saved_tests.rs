//! Tests of the built-in set-ups saved as scenarios: the saved file reads back, names the
//! view's settings, and `balloon run`'s job of it takes the view's steps.

use super::shell::ShellView;
use super::test_support::{max_difference, sphere_dir};
use super::view::ViewSystem;
use crate::protocol::ControlValue;
use balloon::Simulation;
use balloon_scenario::Scenario;

/// Saves `view`'s scenario into `dir` and reads it back as `balloon run` does.
fn save_and_read(view: &dyn ViewSystem, dir: &std::path::Path) -> Scenario {
    let text = view
        .scenario_text()
        .unwrap_or_else(|| panic!("the built-in {} saves no scenario", view.name()));
    let path = dir.join("saved.toml");
    std::fs::write(&path, &text).unwrap();
    balloon_scenario::file::read(&path, &[])
        .unwrap_or_else(|e| panic!("{e}:\n{text}"))
        .scenario
}

/// Takes `steps` steps of `view` as the server does (its drag, none, set before each step).
fn step_view(view: &mut dyn ViewSystem, steps: usize) {
    for _ in 0..steps {
        view.apply_drag(None).unwrap();
        view.step().unwrap();
    }
}

/// Sets the page's `controls` on `view`, rebuilding where a control asks for it.
fn set_controls(view: &mut dyn ViewSystem, controls: &[(&str, ControlValue)]) {
    for (name, value) in controls {
        if view.set_control(name, value).unwrap() {
            view.rebuild().unwrap();
        }
    }
}

/// Saves `view`'s scenario into `dir`, reads it back, runs `steps` steps of it with
/// `balloon run`'s job and of the view (its springs set before each step, as the server does),
/// and returns the saved scenario and the largest position difference.
fn saved_against_view(
    view: &mut ShellView,
    dir: &std::path::Path,
    steps: usize,
) -> (balloon_scenario::shell::ShellScenario, f64) {
    let Scenario::Shell(mut saved) = save_and_read(view, dir) else {
        panic!("not a shell scenario")
    };
    saved.run.steps = steps;
    step_view(view, steps);
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
    let (dir, obj) = sphere_dir();
    let sphere = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
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
        set_controls(&mut view, controls);
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
        set_controls(&mut view, &controls);
        let Scenario::TwoLayer(mut saved) = save_and_read(&view, dir.path()) else {
            panic!("not a two-layer scenario")
        };
        saved.run.steps = 20;
        step_view(&mut view, 20);
        let done = balloon_run::jobs::two_layer::run(&saved, None, true).unwrap();
        let d = max_difference(&view.positions(), &Simulation::surface(&done.sim).positions);
        assert!(
            d <= 1e-12,
            "{controls:?}: the view and `balloon run` differ by {d} m"
        );
    }
}

#[test]
fn the_builtin_volumetric_body_saves_what_balloon_run_repeats() {
    let (dir, obj) = sphere_dir();
    let sphere = balloon_mesh::generate::icosphere(0.1, 2).unwrap();
    let cases: [(bool, Vec<(&str, ControlValue)>); 3] = [
        (true, vec![]),
        (
            true,
            vec![
                ("stiffness", ControlValue::Number(0.05)),
                ("solver", ControlValue::Choice("gauss-seidel")),
                ("correction", ControlValue::Choice("scaling")),
                // Live: the springs stay those of the time step the body was built with.
                ("dt", ControlValue::Number(3e-4)),
                ("gravity", ControlValue::Number(20.0)),
            ],
        ),
        (false, vec![("gravity", ControlValue::Number(30.0))]),
    ];
    for (builtin, controls) in cases {
        let mut view = if builtin {
            super::volumetric::VolumetricView::new(
                crate::default_mesh(crate::SystemKind::Volumetric).unwrap(),
            )
            .unwrap()
        } else {
            super::volumetric::VolumetricView::new(sphere.clone())
                .unwrap()
                .with_mesh_spec(Some(obj.display().to_string()))
        };
        set_controls(&mut view, &controls);
        let Scenario::Volumetric(mut saved) = save_and_read(&view, dir.path()) else {
            panic!("not a volumetric scenario")
        };
        assert_eq!(
            saved.run.scene,
            balloon_scenario::volumetric::SceneChoice::Floor
        );
        if builtin {
            assert_eq!(saved.mesh.path, super::DEFAULT_VOLUMETRIC_MESH);
        } else {
            assert!(std::path::Path::new(&saved.mesh.path).is_absolute());
        }
        // Enough steps to land on the floor (it starts 0.3 mm under the teddy).
        let steps = 60;
        saved.run.steps = steps;
        step_view(&mut view, steps);
        let done = balloon_run::jobs::volumetric::run(&saved, None, None, true).unwrap();
        let sim = &done.sim;
        assert_eq!(Simulation::steps(sim), steps);
        assert_eq!(sim.planes(), view.sim.planes(), "{controls:?}");
        let d = max_difference(&view.positions(), &Simulation::surface(sim).positions);
        assert!(
            d <= 1e-12,
            "{controls:?}: the view and `balloon run` differ by {d} m"
        );
        // The floor was reached: something touched it.
        let floor = &sim.planes()[0];
        let lowest = sim
            .positions()
            .iter()
            .map(|p| floor.distance(p))
            .fold(f64::INFINITY, f64::min);
        assert!(
            lowest < 1e-6,
            "{controls:?}: lowest particle {lowest} m above the floor"
        );
    }
}
