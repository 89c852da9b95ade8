//! Tests of scenario runs in the viewer: a scenario file runs with its anchors and loads, a
//! value changed on the page is in the saved scenario, and `balloon run`'s job of the saved
//! scenario takes the same steps as the viewer.

use super::scenario::{ScenarioView, builtin_connect};
use super::test_support::{max_difference, scenario_dir};
use super::view::ViewSystem;
use crate::protocol::ControlValue;
use balloon::Simulation;
use balloon_scenario::Scenario;
use std::path::Path;

fn read(path: &Path) -> Scenario {
    balloon_scenario::file::read(path, &[]).unwrap().scenario
}

/// Saves the view's scenario next to `path` and reads it back.
fn save_and_read(view: &ScenarioView, path: &Path) -> Scenario {
    let text = ViewSystem::scenario_text(view).expect("a scenario run saves its scenario");
    let saved = path.with_file_name("saved.toml");
    std::fs::write(&saved, text).unwrap();
    read(&saved)
}

fn steps(view: &mut ScenarioView, n: usize) {
    for _ in 0..n {
        view.step().unwrap();
    }
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
steps = 4
[[anchors]]
spec = "below:y:-0.09@500"
[[loads]]
spec = "force=0.02,0,0;on=indices:4;start=0;end=0.5"
"#;

#[test]
fn a_shell_scenario_runs_its_loads_and_saves_what_balloon_run_repeats() {
    let (_dir, path) = scenario_dir(SHELL);
    let mut view = ScenarioView::new(read(&path)).unwrap();
    assert_eq!(view.name(), "shell");
    // A value changed on the page is a key of the scenario (and rebuilds from it).
    let pressure = view.controls().into_iter().find(|c| c.name == "pressure");
    assert_eq!(pressure.map(|c| c.value), Some(serde_json::json!(300.0)));
    assert!(
        view.set_control("pressure", &ControlValue::Number(450.0))
            .unwrap()
    );
    view.rebuild().unwrap();
    let saved = save_and_read(&view, &path);
    assert_eq!(&saved, view.scenario());
    let Scenario::Shell(shell) = &saved else {
        panic!("{saved:?}")
    };
    assert_eq!(shell.gas.pressure, 450.0);
    assert_eq!(shell.anchors.len(), 1);
    assert_eq!(shell.loads.len(), 1);
    // `balloon run`'s job of the saved scenario takes the viewer's steps.
    steps(&mut view, 4);
    let (done, _) = balloon_run::jobs::shell::run(shell, None, None, true).unwrap();
    assert_eq!(Simulation::steps(&done.sim), 4);
    let d = max_difference(&view.positions(), Simulation::positions(&done.sim));
    assert!(d <= 1e-12, "the viewer and `balloon run` differ by {d} m");
    // The anchors and the load act: without them the same steps end elsewhere.
    let mut free = shell.clone();
    free.anchors.clear();
    free.loads.clear();
    let mut bare = ScenarioView::new(Scenario::Shell(free)).unwrap();
    steps(&mut bare, 4);
    let d = max_difference(&view.positions(), &bare.positions());
    assert!(d > 1e-7, "anchors and loads changed nothing ({d} m)");
}

#[test]
fn a_connect_scenario_file_runs_and_saves_what_balloon_run_repeats() {
    let (_dir, path) = scenario_dir(
        r#"
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
steps = 3
mass_damping = 5.0
"#,
    );
    let mut view = ScenarioView::new(read(&path)).unwrap();
    assert_eq!(view.name(), "connect");
    assert!(
        view.set_control("dt", &ControlValue::Number(0.005))
            .unwrap()
    );
    view.rebuild().unwrap();
    let saved = save_and_read(&view, &path);
    assert_eq!(&saved, view.scenario());
    let Scenario::Connect(connect) = &saved else {
        panic!("{saved:?}")
    };
    assert_eq!(connect.shell.run.dt, 0.005);
    // Both balloons are drawn.
    assert_eq!(view.positions().len(), 2 * 3 * 162);
    steps(&mut view, 3);
    let done = balloon_run::jobs::connect::run(connect, None, true).unwrap();
    let d = max_difference(&view.positions(), Simulation::positions(&done.sim));
    assert!(d <= 1e-12, "the viewer and `balloon run` differ by {d} m");
    let stats = view.stats();
    assert_eq!(stats["balloons"], 2);
    let pressures = done.sim.gauge_pressures();
    assert_eq!(stats["gauge_pressure_1"], pressures[0]);
    assert_eq!(stats["gauge_pressure_2"], pressures[1]);
    assert!(stats.get("gauge_pressure_3").is_none());
}

#[test]
fn volumetric_and_two_layer_scenarios_save_what_balloon_run_repeats() {
    let (_dir, path) = scenario_dir(
        r#"
[system]
kind = "two-layer"
[body]
level = 1
[run]
steps = 3
pin_stiffness = 50.0
[[anchors]]
spec = "below:z:-0.5"
"#,
    );
    let mut view = ScenarioView::new(read(&path)).unwrap();
    view.set_control("pressure", &ControlValue::Number(20.0))
        .unwrap();
    view.rebuild().unwrap();
    let saved = save_and_read(&view, &path);
    assert_eq!(&saved, view.scenario());
    let Scenario::TwoLayer(two) = &saved else {
        panic!("{saved:?}")
    };
    steps(&mut view, 3);
    let done = balloon_run::jobs::two_layer::run(two, None, true).unwrap();
    let d = max_difference(&view.positions(), &Simulation::surface(&done.sim).positions);
    assert!(
        d <= 1e-12,
        "two-layer: the viewer and `balloon run` differ by {d} m"
    );

    let (_dir, path) = scenario_dir(
        r#"
[system]
kind = "volumetric"
[mesh]
path = "sphere.obj"
[lattice]
cells = 60
[run]
scene = "free"
steps = 3
[[anchors]]
spec = "below:z:-0.05"
"#,
    );
    let mut view = ScenarioView::new(read(&path)).unwrap();
    assert_eq!(view.up(), [0.0, 0.0, 1.0]);
    view.set_control("gravity", &ControlValue::Number(-3.0))
        .unwrap();
    view.rebuild().unwrap();
    let saved = save_and_read(&view, &path);
    assert_eq!(&saved, view.scenario());
    let Scenario::Volumetric(vol) = &saved else {
        panic!("{saved:?}")
    };
    assert_eq!(vol.run.gravity, -3.0);
    steps(&mut view, 3);
    let done = balloon_run::jobs::volumetric::run(vol, None, None, true).unwrap();
    let d = max_difference(&view.positions(), &Simulation::surface(&done.sim).positions);
    assert!(
        d <= 1e-12,
        "volumetric: the viewer and `balloon run` differ by {d} m"
    );
}

#[test]
fn a_refused_value_leaves_the_scenario_unchanged() {
    let (_dir, path) = scenario_dir(SHELL);
    let mut view = ScenarioView::new(read(&path)).unwrap();
    let before = view.scenario().clone();
    // Within the slider but outside the scenario's own range of `thickness` (> 0).
    let e = view
        .set_control("thickness", &ControlValue::Number(0.0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("`thickness`"), "{e}");
    assert_eq!(view.scenario(), &before);
    let e = view
        .set_control("young", &ControlValue::Number(1e6))
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown control `young`"), "{e}");
}

#[test]
fn the_builtin_connect_is_the_two_balloon_experiment() {
    let c = builtin_connect();
    c.validate().unwrap();
    assert_eq!(c.shell.mesh.path, "builtin:icosphere");
    assert_eq!(c.connect.copies, Some(2));
    assert_eq!(c.connect.stretches, Some(vec![1.35, 1.6]));
    assert_eq!(c.shell.shell.thickness, 1e-3);
    assert_eq!(c.shell.run.dt, 0.01);
    assert_eq!(c.shell.run.mass_damping, 5.0);
    // The same as examples/two-balloons (but `steps`, `until_settled`, `volume_tol` and the
    // output, which the viewer does not use).
    let example =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/two-balloons/scenario.toml");
    let Scenario::Connect(mut e) = read(&example) else {
        panic!("not a connect scenario")
    };
    e.shell.run.steps = c.shell.run.steps;
    e.shell.run.volume_tol = c.shell.run.volume_tol;
    e.connect.until_settled = c.connect.until_settled;
    e.shell.output = c.shell.output.clone();
    assert_eq!(e, c);
}

#[test]
fn a_static_scenario_is_said_to_be_shown_stepping() {
    let (_dir, path) = scenario_dir(&SHELL.replace("steps = 4", "steps = 4\nstatic = true"));
    let mut view = ScenarioView::new(read(&path)).unwrap();
    assert_eq!(
        view.note().as_deref(),
        Some(super::scenario::STATIC_NOTE),
        "a static scenario shown stepping says so"
    );
    steps(&mut view, 2);
    // The saved scenario is still the static one.
    let Scenario::Shell(saved) = save_and_read(&view, &path) else {
        panic!("a shell scenario")
    };
    assert!(saved.run.static_solve);
    // A dynamic scenario has no note.
    let (_dir, path) = scenario_dir(SHELL);
    assert_eq!(ScenarioView::new(read(&path)).unwrap().note(), None);
}

#[test]
fn the_drop_sphere_of_a_volumetric_scenario_is_drawn_where_it_is() {
    // The default scene: a rigid sphere falls on the body resting on a floor.
    let (_dir, path) = scenario_dir(
        "[system]\nkind = \"volumetric\"\n[mesh]\npath = \"sphere.obj\"\n[lattice]\ncells = 60\n",
    );
    let mut view = ScenarioView::new(read(&path)).unwrap();
    let start = view.sphere().expect("the drop-sphere scene has a sphere");
    assert!(start.radius > 0.0);
    // Above the body (gravity along -z) and falling.
    let top = view
        .positions()
        .chunks_exact(3)
        .map(|p| p[2])
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(start.center[2] - start.radius > top, "{start:?} top {top}");
    steps(&mut view, 20);
    let later = view.sphere().unwrap();
    assert!(later.center[2] < start.center[2], "{start:?} -> {later:?}");
    // A scene without a sphere draws none.
    let (_dir, path) = scenario_dir(
        "[system]\nkind = \"volumetric\"\n[mesh]\npath = \"sphere.obj\"\n[lattice]\ncells = 60\n\
         [run]\nscene = \"free\"\n",
    );
    assert_eq!(ScenarioView::new(read(&path)).unwrap().sphere(), None);
}
