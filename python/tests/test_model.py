"""pamc.Model, the measurement files and pamc.compare against the pamc command on the same files."""
import csv
import json

import numpy as np
import pytest

import pamc
from conftest import run_pamc


def read_columns(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def test_read_csv_gives_the_file_columns(records):
    m = pamc.read_csv(records["physics"])
    cols = read_columns(records["physics"])
    for name in ("t", "u", "y"):
        np.testing.assert_array_equal(getattr(m, name), cols[name])
    np.testing.assert_array_equal(m.p, cols["p"])
    assert m.load is None
    assert len(m) == len(cols["t"])
    assert m.Ts == pytest.approx(1e-3, rel=1e-9)


def test_write_csv_round_trip(tmp_path):
    t = np.arange(5) * 1e-3
    u = np.array([0.1, 0.2, -0.3, 1e-7, 2.0])
    y = np.sqrt(np.arange(5.0))
    load = np.array([1.0, 2.0, 3.0, 4.0, 5.5])
    path = tmp_path / "rec.csv"
    pamc.write_csv(path, t, u, y, load=load)
    m = pamc.read_csv(path)
    for name, want in (("t", t), ("u", u), ("y", y), ("load", load)):
        np.testing.assert_array_equal(getattr(m, name), want)


def test_simulate_equals_compare_of_the_cli(records, fitted, pamc_exe, tmp_path):
    out = tmp_path / "cmp"
    run_pamc(pamc_exe, "compare", fitted, records["physics"], "--out-dir", out, "--json", tmp_path / "c.json")
    cli = read_columns(out / "compare.csv")
    m = pamc.read_csv(records["physics"])
    y = pamc.Model.load(fitted).simulate(m.u, m.Ts)
    # compare.csv holds 9 significant digits
    np.testing.assert_allclose(y, cli["y_model"], rtol=2e-9, atol=1e-9 * np.abs(cli["y_model"]).max())
    rmse = float(np.sqrt(np.mean((m.y - y) ** 2)))
    assert rmse == pytest.approx(json.loads((tmp_path / "c.json").read_text())["rmse"], rel=1e-12)


def test_compare_holds_what_compare_json_holds(records, fitted, pamc_exe, tmp_path):
    run_pamc(pamc_exe, "compare", fitted, records["physics"], "--out-dir", tmp_path / "cmp", "--json", tmp_path / "c.json")
    want = json.loads((tmp_path / "c.json").read_text())
    got = pamc.compare(pamc.Model.load(fitted), pamc.read_csv(records["physics"]))
    arrays = {k: got.pop(k) for k in ("t", "y_model", "residual")}
    assert got == want
    np.testing.assert_array_equal(arrays["residual"], pamc.read_csv(records["physics"]).y - arrays["y_model"])


def test_simulate_takes_strided_and_list_input_alike():
    model = pamc.Model()
    u = np.sin(np.linspace(0, 20, 4001)) * 3
    y = model.simulate(u)
    np.testing.assert_array_equal(model.simulate(np.repeat(u, 2)[::2]), y)
    np.testing.assert_array_equal(model.simulate(list(u)), y)
    assert model.simulate(np.array([])).shape == (0,)
    out = np.zeros_like(u)
    assert model.simulate(u, out=out) is out
    np.testing.assert_array_equal(out, y)
    with pytest.raises(ValueError, match="out"):
        model.simulate(u, out=np.zeros(3))


def test_parameters_dict_round_trip_and_save(tmp_path):
    model = pamc.Model(effects=["pressure_lag"])
    p = model.parameters
    assert list(p)[:6] == ["k", "rho", "b", "alpha", "beta", "gamma"]
    assert "pressure_lag.tau" in p
    model.parameters = {"k": 7.5, "pressure_lag.tau": 0.07}
    assert model.parameters["k"] == 7.5 and model.parameters["pressure_lag.tau"] == 0.07
    model.save(tmp_path / "m.json")
    again = pamc.Model.load(tmp_path / "m.json")
    assert again.parameters == model.parameters
    assert again.effects == ["pressure_lag"]
    assert pamc.Model.from_dict(model.to_dict()).parameters == model.parameters


def test_simulate_uses_the_load_column():
    model = pamc.Model(effects=["load"])
    u = np.full(100, 1.0)
    assert not np.array_equal(model.simulate(u, load=np.full(100, 50.0)), model.simulate(u))


def test_simulate_does_not_copy_a_contiguous_input():
    """numpy reports its allocations to tracemalloc: a float64 C-contiguous u is read where it lies, a strided
    one is copied first (the contrast shows the measurement would see a copy)."""
    import tracemalloc
    m = pamc.Model()
    u = np.sin(np.linspace(0.0, 100.0, 2_000_000))
    y = np.empty(u.size // 2)

    def peak_bytes(x):
        tracemalloc.start()
        m.simulate(x, out=y)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        return peak

    assert peak_bytes(u[: u.size // 2]) < 100_000
    assert peak_bytes(u[::2]) >= 8 * (u.size // 2)
