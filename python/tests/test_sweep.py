"""balloon.sweep on a dask LocalCluster of two workers equals the serial sweep."""

import pytest

import balloon
from conftest import without_timing

distributed = pytest.importorskip("distributed")

RUNS = [
    {"thickness": 2e-4, "steps": 3, "gas": "constant"},
    {"thickness": -1.0},  # an invalid run: reported, the sweep goes on
    {"thickness": 4e-4, "steps": 3, "gas": "constant"},
    {"thickness": 3e-4, "steps": 2, "gas": "ideal", "pressure": 500.0},
]


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as c:
        yield c


def clean(results):
    return [r if "error" in r and r.get("error_type") else without_timing(r) for r in results]


def test_sweep_on_a_local_cluster_equals_the_serial_sweep(client, tmp_path):
    serial = balloon.sweep("builtin:sphere", RUNS, out=tmp_path / "serial")
    parallel = balloon.sweep("builtin:sphere", RUNS, client=client, out=tmp_path / "dask")
    assert len(parallel) == len(RUNS)
    assert parallel[1]["error_type"] == "InvalidOption"
    assert "--thickness" in parallel[1]["error"]
    assert [r.get("error") for r in serial] == [r.get("error") for r in parallel]
    assert clean(serial) == clean(parallel)
    # In order: the thicker shell grows less under the same pressure.
    assert parallel[0]["final_gas_volume"] > parallel[2]["final_gas_volume"]
    assert (tmp_path / "dask" / "run_0000" / "summary.json").is_file()
    assert not (tmp_path / "dask" / "run_0001" / "summary.json").exists()


def test_sweeps_of_other_systems_and_scenarios(client, tmp_path):
    runs = [{"steps": 10, "dim": 2}, {"steps": 10, "dim": 3, "level": 1}]
    assert clean(balloon.sweep(None, runs, client=client, system="two_layer")) == clean(
        balloon.sweep(None, runs, system="two_layer")
    )
    path = tmp_path / "s.toml"
    path.write_text('[mesh]\npath = "builtin:sphere"\n[gas]\nmodel = "constant"\n[run]\nsteps = 2\n')
    runs = [{"pressure": 300.0}, {"pressure": 600.0}, {"dt": 7.0}]
    res = balloon.sweep_scenario(path, runs, client=client)
    assert [r["final_gauge_pressure"] for r in res[:2]] == [300.0, 600.0]
    assert "--dt" in res[2]["error"]
    assert clean(res) == clean(balloon.sweep_scenario(path, runs))
    with pytest.raises(ValueError):
        balloon.sweep(None, runs, system="bogus")
