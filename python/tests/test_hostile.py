"""What a careless user does from Python: every mistake is a BalloonError naming the parameter
(never a bare TypeError / OverflowError / ValueError), indices are not truncated, the state
read after a failed step is the rolled-back one, and a bad sweep entry names its run."""

import numpy as np
import pytest

import balloon

SPHERE = "builtin:sphere"


def shell(**options):
    return balloon.Shell(SPHERE, gas="constant", pressure=500.0, **options)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda s: s.set_dt("0.01"), "--dt.*number"),
        (lambda s: s.set_dt(None), "--dt.*number"),
        (lambda s: s.set_dt(True), "--dt.*number"),
        (lambda s: s.set_dt(5.0), "--dt"),
        (lambda s: s.set_dt(-1), "--dt"),
        (lambda s: s.set_dt(10**400), "--dt"),
        (lambda s: s.set_pressure(1e30), r"--pressure.*\[-1e7, 1e7\]|--pressure.*1e7"),
        (lambda s: s.set_pressure(float("nan")), "--pressure"),
        (lambda s: s.set_pressure("high"), "--pressure.*number"),
        (lambda s: s.set_pump_rate([1]), "--pump-rate.*number"),
        (lambda s: s.set_anchor_springs([(-1, (0, 0, 0), 1.0)]), "vertex of anchor spring 0"),
        (lambda s: s.set_anchor_springs([(2**70, (0, 0, 0), 1.0)]), "anchor spring 0"),
        (lambda s: s.set_anchor_springs([(1.7, (0, 0, 0), 1.0)]), "float is not an index"),
        (lambda s: s.set_anchor_springs([(1, (0, 0), 1.0)]), "point of anchor spring 0"),
        (lambda s: s.set_anchor_springs([(1, (0, 0, 0), "stiff")]), "stiffness"),
        (lambda s: s.set_anchor_springs([(1, (0, 0, 0))]), "anchor spring 0 must be"),
        (lambda s: s.set_anchor_springs(5), "list of"),
    ],
)
def test_shell_setters_raise_balloon_errors_naming_the_parameter(call, match):
    sim = shell()
    with pytest.raises(balloon.BalloonError, match=match):
        call(sim)
    # Nothing changed: the simulation still steps.
    sim.step()


def test_the_pressure_setter_takes_the_range_of_the_option():
    sim = shell()
    with pytest.raises(balloon.InvalidOption) as e:
        sim.set_pressure(1e30)
    assert "1e30" in str(e.value) and "--pressure" in str(e.value)
    sim.set_pressure(1e4)
    sim.set_pressure(np.float64(800.0))
    assert sim.gauge_pressure == 800.0


def test_other_setters_raise_balloon_errors():
    two = balloon.TwoLayer(dim=2, steps=1)
    for call in (
        lambda: two.set_dt("x"),
        lambda: two.set_dt(1e30),
        lambda: two.set_drag((0.0, 0.0)),
        lambda: two.set_drag((0.0, 0.0, 0.0), stiffness="stiff"),
    ):
        with pytest.raises(balloon.BalloonError):
            call()
    assert two.set_drag((0.0, 0.0, 0.0)) is not None
    vol = balloon.Volumetric(SPHERE, cells=60)
    with pytest.raises(balloon.InvalidOption, match="--dt"):
        vol.set_dt(-0.5)


def test_non_integer_face_indices_are_refused_not_truncated():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    # The same faces as whole-number floats are fine (np.loadtxt gives floats).
    balloon.Shell((v, faces.astype(float)), gas="constant", pressure=100.0)
    bad = faces.astype(float)
    bad[1, 2] = 2.6
    with pytest.raises(balloon.MeshError, match="non-integer"):
        balloon.Shell((v, bad))
    with pytest.raises(balloon.MeshError, match="non-integer"):
        balloon.inflate((v, bad), steps=1)
    with pytest.raises(balloon.MeshError, match="dtype"):
        balloon.Shell((v, faces.astype(str)))


def test_gauge_pressure_before_the_first_step_is_the_true_one():
    assert shell().gauge_pressure == 500.0
    ideal = balloon.Shell(SPHERE, gas="ideal", pressure=700.0)
    assert ideal.gauge_pressure == pytest.approx(700.0, rel=1e-12)
    pump = balloon.Shell(SPHERE, gas="pump", pump_rate=1e-3)
    assert pump.gauge_pressure == pytest.approx(0.0, abs=1e-6)
    # After a step it is the gas law's at the new volume (what the next step starts from); the
    # step's own figure was taken at its last force evaluation, so the two differ by a few
    # parts in 1e5 of the absolute pressure (ambient 101325 Pa).
    stats = ideal.step()
    assert abs(ideal.gauge_pressure - stats["gauge_pressure"]) < 1e-4 * 101325.0
    assert ideal.gauge_pressure < 700.0  # the gas expanded


def test_state_after_a_failed_step_is_the_rolled_back_one():
    sim = balloon.Shell(SPHERE, gas="constant", pressure=1e7, newton_iters=1)
    v0, p0 = sim.gas_volume, sim.gauge_pressure
    with pytest.raises(balloon.SolverError):
        sim.step()
    assert sim.steps == 0
    assert sim.gas_volume == v0 and sim.gauge_pressure == p0 == 1e7


def test_a_bad_sweep_entry_names_its_run_and_the_others_go_on():
    runs = [
        {"steps": 2, "gas": "constant"},
        "steps=2",
        {"steps": 2, "gas": "constant", "thickness": -1.0},
        {"steps": 2, 3: "x"},
        {"steps": 2, "gas": "constant", "pressure": 600.0},
    ]
    res = balloon.sweep(SPHERE, runs)
    assert len(res) == 5
    assert res[0]["steps"] == 2 and res[4]["final_gauge_pressure"] == 600.0
    for i in (1, 2, 3):
        assert res[i]["run"] == i and res[i]["error"].startswith(f"run {i}: "), res[i]
        assert res[i]["error_type"] == "InvalidOption"
    assert "dict" in res[1]["error"] and "--thickness" in res[2]["error"]
    with pytest.raises(balloon.InvalidOption, match="system"):
        balloon.sweep(SPHERE, runs, system="bogus")


@pytest.mark.parametrize(
    "make, what",
    [
        (lambda: balloon.Volumetric(pin="below:z:100"), "particles of the lattice"),
        (lambda: balloon.TwoLayer(pin="below:z:100"), "particles of the body"),
        (lambda: balloon.volumetric(pin="below:z:100", steps=1), "particles of the lattice"),
    ],
)
def test_hard_pins_on_every_particle_are_refused_naming_the_selection(make, what):
    with pytest.raises(balloon.BalloonError, match="holds all") as e:
        make()
    assert what in str(e.value) and "`below:z:100.0`" in str(e.value), str(e.value)
