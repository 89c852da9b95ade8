"""Ctrl-C stops a run cleanly, and the GIL is released while a run computes."""

import json
import signal
import subprocess
import sys
import textwrap
import threading
import time

import balloon

LONG_RUN = textwrap.dedent(
    """
    import sys, balloon
    print("started", flush=True)
    try:
        balloon.inflate("builtin:sphere", steps=1_000_000, gas="constant", out=sys.argv[1])
    except KeyboardInterrupt:
        print("interrupted", flush=True)
        sys.exit(7)
    """
)


def test_ctrl_c_stops_a_run_cleanly(tmp_path):
    out = tmp_path / "run"
    p = subprocess.Popen(
        [sys.executable, "-c", LONG_RUN, str(out)], stdout=subprocess.PIPE, text=True
    )
    assert p.stdout.readline().strip() == "started"
    time.sleep(3.0)
    p.send_signal(signal.SIGINT)
    stdout, _ = p.communicate(timeout=60)
    assert p.returncode == 7, stdout
    assert "interrupted" in stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True
    assert 0 < summary["steps"] < 1_000_000


def test_the_gil_is_released_during_a_run():
    ticks = 0
    done = threading.Event()

    def job():
        balloon.inflate("builtin:sphere", steps=8, gas="constant")
        done.set()

    t = threading.Thread(target=job)
    t.start()
    start = time.perf_counter()
    while not done.is_set():
        ticks += 1
        time.sleep(0.001)
    t.join()
    elapsed = time.perf_counter() - start
    # The main thread ran all along: about one tick per millisecond (a held GIL gives ~0).
    assert elapsed > 0.2 and ticks > 0.2 * elapsed * 1000, (ticks, elapsed)
