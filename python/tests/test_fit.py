"""pamc.fit against the known truth and against `pamc fit`; the GIL is free while it runs."""
import json
import threading

import pytest

import pamc
from conftest import TRUTH, run_pamc


def test_fit_recovers_the_plant_parameters(records):
    model, report = pamc.fit(pamc.read_csv(records["truth"]), method="lm")
    p = model.parameters
    for name in ("k", "rho", "b", "beta", "gamma"):
        assert p[name] == pytest.approx(TRUTH[name], rel=1e-3), name
    assert report["rmse"] < 1e-6
    assert report["method"] == "lm" and report["samples"] == len(pamc.read_csv(records["truth"]))


def test_fit_equals_the_cli_fit(records, pamc_exe, tmp_path):
    out = tmp_path / "m.json"
    run_pamc(pamc_exe, "fit", records["physics"], "--method", "lm", "--seed", 3, "--quiet", "--out", out)
    cli = json.loads(out.read_text())
    data = pamc.read_csv(records["physics"])
    model, report = pamc.fit(data.t, data.u, data.y, method="lm", seed=3)
    assert model.parameters == pamc.Model.load(out).parameters
    for key in cli["fit"]:
        if key not in ("seconds", "data"):
            assert report[key] == cli["fit"][key], key
    assert set(report) == set(cli["fit"])


def test_fit_releases_the_gil(records):
    data = pamc.read_csv(records["physics"])
    inside = threading.Event()
    done = threading.Event()

    def work():
        inside.set()
        pamc.fit(data, method="lm", threads=1)
        done.set()

    worker = threading.Thread(target=work)
    worker.start()
    inside.wait()
    spins = 0
    while not done.is_set():
        spins += 1
    worker.join()
    # Holding the GIL for the whole fit would leave this thread a handful of turns at most.
    assert spins > 10000
