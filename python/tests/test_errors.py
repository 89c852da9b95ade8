"""Errors become BalloonError subclasses with the CLI's messages; nothing crashes."""

import subprocess

import numpy as np
import pytest

import balloon

SPHERE = "builtin:sphere"


def test_hierarchy():
    for cls in (balloon.InvalidOption, balloon.MeshError, balloon.SolverError):
        assert issubclass(cls, balloon.BalloonError)
    assert issubclass(balloon.BalloonError, Exception)


def test_unknown_option_lists_the_options():
    with pytest.raises(balloon.InvalidOption, match=r"unknown option `stepz`.*steps"):
        balloon.inflate(SPHERE, stepz=3)
    with pytest.raises(balloon.InvalidOption, match="unknown option"):
        balloon.Shell(SPHERE, pressur=1.0)
    with pytest.raises(balloon.InvalidOption, match="unknown option"):
        balloon.two_layer(mesh="x")


@pytest.mark.parametrize(
    "flag, value, keyword, pyvalue",
    [
        ("--dt", "5.0", "dt", 5.0),
        ("--gas", "steam", "gas", "steam"),
        ("--steps", "-1", "steps", -1),
        ("--thickness", "NaN", "thickness", float("nan")),
    ],
)
def test_bad_values_give_the_cli_message(cli, flag, value, keyword, pyvalue):
    run = subprocess.run(
        [cli, "inflate", SPHERE, f"{flag}={value}"], capture_output=True, text=True
    )
    assert run.returncode != 0
    cli_line = run.stderr.strip().splitlines()[0].removeprefix("error: ")
    with pytest.raises(balloon.InvalidOption) as e:
        balloon.inflate(SPHERE, **{keyword: pyvalue})
    assert str(e.value) == cli_line


def test_type_errors():
    with pytest.raises(balloon.InvalidOption, match="True or False"):
        balloon.inflate(SPHERE, until_converged="yes")
    with pytest.raises(balloon.InvalidOption, match="on/off"):
        balloon.inflate(SPHERE, steps=True)
    with pytest.raises(balloon.InvalidOption, match="option `dt`"):
        balloon.inflate(SPHERE, dt=object())


def test_checks_of_the_command_are_errors_too():
    with pytest.raises(balloon.BalloonError, match="add --static"):
        balloon.inflate(SPHERE, gas="volume")


def test_mesh_errors(tmp_path):
    with pytest.raises(balloon.MeshError, match="cannot load mesh"):
        balloon.inflate(tmp_path / "missing.obj")
    with pytest.raises(balloon.MeshError, match="outside"):
        balloon.inflate((np.zeros((3, 3)), np.array([[0, 1, 5]])))
    with pytest.raises(balloon.MeshError, match=r"\(n, 3\)"):
        balloon.Shell((np.zeros((3, 2)), np.array([[0, 1, 2]])))
    with pytest.raises(balloon.MeshError):
        balloon.inflate(42)
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(balloon.BalloonError):
        balloon.inflate(bad, steps=1)


def test_solver_errors_keep_the_cli_message():
    with pytest.raises(balloon.SolverError, match="failed at step 1.*Newton did not converge"):
        balloon.inflate(SPHERE, gas="constant", pressure=1e7, steps=3, newton_iters=1)
    sim = balloon.Shell(SPHERE, gas="constant", pressure=1e7, newton_iters=1)
    x = sim.positions
    with pytest.raises(balloon.SolverError, match="Newton"):
        sim.step()
    # The failed step was rolled back.
    assert np.array_equal(sim.positions, x) and sim.steps == 0


def test_scenario_errors_name_file_and_line(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text("[run]\ndtt = 0.1\n")
    with pytest.raises(balloon.InvalidOption, match=r"s\.toml:2: `run\.dtt`: unknown key"):
        balloon.run_scenario(path)
    path.write_text("[run]\nsteps = 2\n")
    with pytest.raises(balloon.InvalidOption, match="unknown option"):
        balloon.run_scenario(path, nonsense=1)


def test_a_keyboard_interrupt_while_reading_an_option_is_not_an_invalid_option():
    """Ctrl-C while a keyword option is converted (here raised by the value itself) stays a
    KeyboardInterrupt; it was once reported as `InvalidOption: option `steps`: `."""

    class Interrupting:
        def __index__(self):
            raise KeyboardInterrupt

        def __float__(self):
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        balloon.inflate("builtin:sphere", steps=Interrupting())

    class NotANumber:
        pass

    # An ordinary wrong type is still an invalid option.
    with pytest.raises(balloon.InvalidOption, match="cannot use a value of type NotANumber"):
        balloon.inflate("builtin:sphere", steps=NotANumber())
