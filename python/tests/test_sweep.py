"""pamc.sweep: the robustness sweep in parts on dask.distributed, against the command's own run."""
import json

import pytest
from dask.distributed import Client, LocalCluster

import pamc
import pamc.sweep
from conftest import run_pamc

# A short sweep: two axes (the sensor noise, the valve flow) and their 5x5 grid, trajectories at 5 %
# of their length, the fast fit.
SHORT = {"only_axes": ["noise", "flow"], "duration_scale": 0.05, "fit_method": "lm", "figures": False}
CLI_SHORT = ["--only-axes", "noise,flow", "--duration-scale", 0.05, "--method", "lm", "--no-figures"]
FILES = ["axis_noise.csv", "axis_flow.csv", "grid.csv", "ident_A2.90.csv"]
TIMING = ("seconds", "threads", "shards")


def without_timing(summary):
    return {k: v for k, v in summary.items() if k not in TIMING}


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory, pamc_exe):
    out = tmp_path_factory.mktemp("cli") / "robustness"
    run_pamc(pamc_exe, "robustness", *CLI_SHORT, "--out-dir", out)
    return out


def test_on_a_local_cluster_of_two_workers_the_result_is_the_commands(tmp_path, cli_run):
    out = tmp_path / "dask"
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster, Client(cluster) as client:
        summary = pamc.sweep.robustness(str(out), client=client, **SHORT)
    for f in FILES:
        assert (out / f).read_bytes() == (cli_run / f).read_bytes(), f
    assert summary["shards"] == 2
    assert summary["grid"]["rows"] in ("noise", "flow")
    assert without_timing(summary) == without_timing(json.loads((cli_run / "summary.json").read_text()))


def test_without_a_client_it_runs_here_with_the_same_result(tmp_path, cli_run):
    summary = pamc.sweep.robustness(str(tmp_path / "local"), parts=None, threads=2, **SHORT)
    assert (tmp_path / "local" / "grid.csv").read_bytes() == (cli_run / "grid.csv").read_bytes()
    assert without_timing(summary) == without_timing(json.loads((cli_run / "summary.json").read_text()))


def test_bad_settings_raise_before_anything_runs(tmp_path):
    with pytest.raises(ValueError, match="unknown axis 'valve_speed'"):
        pamc.sweep.robustness(str(tmp_path / "a"), only_axes=["valve_speed"])
    with pytest.raises(FileNotFoundError):
        pamc.sweep.robustness(str(tmp_path / "b"), model=tmp_path / "missing.json")
    with pytest.raises(TypeError, match="unknown controller setting .kq."):
        pamc.sweep.robustness(str(tmp_path / "c"), kq=1.0)
    assert not (tmp_path / "a").exists()


def test_calibrate_on_a_local_cluster_chooses_as_the_threads_do(tmp_path):
    """One free parameter (the payload mass, five values), one reading of ki, one pass: the same points and
    the same table from the cluster's workers as from two threads here."""
    short = {"axes": ["mass_kg"], "ki_grid": [3.0], "passes": 1}
    here = pamc.sweep.calibrate(str(tmp_path / "here"), threads=2, **short)
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster, Client(cluster) as client:
        there = pamc.sweep.calibrate(str(tmp_path / "there"), client=client, **short)
    assert len(here["points"]) == 5
    assert there["table"] == here["table"]
    assert there["best"] == here["best"]
    with pytest.raises(ValueError, match="unknown free parameter 'spring'"):
        pamc.sweep.calibrate(str(tmp_path / "bad"), axes=["spring"])
    assert not (tmp_path / "bad").exists()
