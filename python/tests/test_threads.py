"""Step-wise simulations shared between threads: concurrent calls wait for each other and never
deadlock, and Ctrl-C still reaches a thread that waits for the simulation.

Each case runs in a child interpreter under a timeout, so a deadlock fails the test instead of
hanging the suite (a deadlocked interpreter ignores Ctrl-C and only SIGKILL ends it)."""

import signal
import subprocess
import sys
import textwrap

import pytest

SPHERE = "builtin:sphere"

# One thread steps while the main thread reads the state and calls setters, for about a second.
SHARED = textwrap.dedent(
    """
    import sys, threading, time, balloon
    kind = sys.argv[1]
    if kind == "Shell":
        sim = balloon.Shell("builtin:sphere", gas="constant", pressure=500.0)
        reads = [lambda: sim.positions, lambda: sim.gas_volume, lambda: sim.gauge_pressure,
                 lambda: sim.thickness, lambda: sim.set_dt(sim.dt)]
    elif kind == "Volumetric":
        sim = balloon.Volumetric("builtin:sphere")
        reads = [lambda: sim.positions, lambda: sim.surface_positions,
                 lambda: sim.set_dt(sim.dt)]
    else:
        sim = balloon.TwoLayer(dim=2, particles=16)
        reads = [lambda: sim.positions, lambda: sim.velocities, lambda: sim.set_dt(sim.dt)]
    stop = threading.Event()
    steps = []

    def stepper():
        while not stop.is_set():
            steps.append(sim.step()["steps"])

    t = threading.Thread(target=stepper)
    t.start()
    n = 0
    end = time.monotonic() + 1.0
    while time.monotonic() < end:
        for r in reads:
            r()
            n += 1
    stop.set()
    t.join()
    assert steps == list(range(1, len(steps) + 1)), steps[:10]
    assert sim.steps == len(steps)
    print("ok", len(steps), n, flush=True)
    """
)


@pytest.mark.parametrize("kind", ["Shell", "Volumetric", "TwoLayer"])
def test_a_stepping_thread_and_a_reading_thread_never_deadlock(kind):
    p = subprocess.run(
        [sys.executable, "-c", SHARED, kind], capture_output=True, text=True, timeout=120
    )
    assert p.returncode == 0, p.stderr[-2000:]
    word, steps, reads = p.stdout.split()
    assert word == "ok"
    # Both threads made progress.
    assert int(steps) > 0 and int(reads) > 0, p.stdout


# The main thread waits for a simulation another thread keeps busy; SIGINT must end the wait.
WAITING = textwrap.dedent(
    """
    import signal, threading, balloon
    signal.signal(signal.SIGINT, signal.default_int_handler)
    sim = balloon.Shell("builtin:sphere", gas="constant", pressure=500.0)
    stop = threading.Event()

    def stepper():
        while not stop.is_set():
            sim.step()

    t = threading.Thread(target=stepper, daemon=True)
    t.start()
    print("started", flush=True)
    try:
        while True:
            sim.positions
    except KeyboardInterrupt:
        stop.set()
        t.join()
        print("interrupted", flush=True)
    """
)


def test_ctrl_c_reaches_a_thread_waiting_for_the_simulation():
    p = subprocess.Popen(
        [sys.executable, "-c", WAITING],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert p.stdout.readline().strip() == "started"
    import time

    time.sleep(1.0)
    p.send_signal(signal.SIGINT)
    try:
        stdout, stderr = p.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        p.kill()
        stdout, stderr = p.communicate()
        raise AssertionError(f"no exit 30 s after SIGINT: {stdout!r} {stderr[-2000:]!r}")
    assert p.returncode == 0, stderr[-2000:]
    assert "interrupted" in stdout
