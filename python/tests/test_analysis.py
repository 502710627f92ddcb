"""pamc.diagnose and pamc.experiments: the dicts of `pamc diagnose --json` and summary.json."""
import json

import pytest

import pamc
from conftest import run_pamc


def without_timings(x):
    """x without the wall times (the keys holding seconds of computing), which differ from run to run."""
    if isinstance(x, dict):
        return {k: without_timings(v) for k, v in x.items() if k not in ("seconds", "wall_s", "elapsed_s")}
    if isinstance(x, list):
        return [without_timings(v) for v in x]
    return x


def test_diagnose_equals_the_cli(records, pamc_exe, tmp_path):
    settings = ["--max-effects", 1, "--candidates", "pressure_lag,creep", "--no-probes", "--threads", 2]
    run_pamc(pamc_exe, "diagnose", records["physics"], *settings, "--json", tmp_path / "d.json")
    want = json.loads((tmp_path / "d.json").read_text())
    data = pamc.read_csv(records["physics"])
    got = pamc.diagnose(data, max_effects=1, candidates=["pressure_lag", "creep"], probes=False, threads=2)
    model = got.pop("final_model")
    assert without_timings(got) == without_timings(want)
    assert sorted(model.effects) == sorted(want["ladder"][-1]["effects"])


def test_diagnose_with_a_validation_record(records):
    train, val = pamc.read_csv(records["physics"]), pamc.read_csv(records["truth"])
    got = pamc.diagnose(train, validate=(val.t, val.u, val.y), max_effects=0, probes=False)
    assert got["ladder"][0]["effects"] == [] and isinstance(got["final_model"], pamc.Model)
    assert got["validation"] != pamc.diagnose(train, max_effects=0, probes=False)["validation"]


def test_an_unknown_experiment_is_refused_with_the_clis_message(tmp_path):
    with pytest.raises(ValueError, match="--only: unknown experiment 'nonsense'"):
        pamc.experiments(out_dir=str(tmp_path / "x"), only=["nonsense"])
    assert not (tmp_path / "x").exists()


def test_experiments_equal_the_cli(fitted, pamc_exe, tmp_path):
    run_pamc(pamc_exe, "experiments", "--only", "triangle", "--model", fitted, "--no-figures",
             "--out-dir", tmp_path / "cli")
    want = json.loads((tmp_path / "cli" / "summary.json").read_text())
    got = pamc.experiments(out_dir=str(tmp_path / "py"), only=["triangle"], model=fitted)
    assert without_timings(got) == without_timings(want)
    assert got == json.loads((tmp_path / "py" / "summary.json").read_text())
