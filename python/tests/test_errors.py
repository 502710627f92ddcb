"""Errors: a missing file is FileNotFoundError, bad content ValueError, each with the command's one-line message."""
import json

import pytest

import pamc
from conftest import run_pamc


def cli_error(exe, *args):
    """The one-line message `pamc` prints for an error (without its 'pamc: error: ' prefix)."""
    r = run_pamc(exe, *args, check=False)
    assert r.returncode == 1, r.stderr
    line = r.stderr.strip().splitlines()[-1]
    assert line.startswith("pamc: error: ")
    return line[len("pamc: error: "):]


def test_missing_model_file(tmp_path, records, pamc_exe):
    missing = tmp_path / "no_model.json"
    with pytest.raises(FileNotFoundError) as e:
        pamc.Model.load(missing)
    assert str(e.value) == cli_error(pamc_exe, "compare", missing, records["physics"], "--out-dir", tmp_path / "o")


def test_missing_measurement(tmp_path, fitted, pamc_exe):
    missing = tmp_path / "no_data.csv"
    with pytest.raises(FileNotFoundError) as e:
        pamc.read_csv(missing)
    assert str(e.value) == cli_error(pamc_exe, "compare", fitted, missing, "--out-dir", tmp_path / "o")


def test_bad_measurement(tmp_path, fitted, pamc_exe):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,u,y\n0,0,0\n0.001,zero,0\n0.002,0,0\n")
    with pytest.raises(ValueError) as e:
        pamc.read_csv(bad)
    msg = cli_error(pamc_exe, "compare", fitted, bad, "--out-dir", tmp_path / "o")
    assert str(e.value) == msg and "bad.csv:3" in msg


def test_bad_model_file(tmp_path, records, pamc_exe):
    bad = tmp_path / "bad_model.json"
    bad.write_text(json.dumps({"format": "pamc-model/1", "core": {"k": "nine"}}))
    with pytest.raises(ValueError) as e:
        pamc.Model.load(bad)
    assert str(e.value) == cli_error(pamc_exe, "compare", bad, records["physics"], "--out-dir", tmp_path / "o")


def test_missing_and_bad_plant(tmp_path, pamc_exe):
    missing = tmp_path / "no_plant.json"
    with pytest.raises(FileNotFoundError) as e:
        pamc.Plant(missing)
    assert str(e.value) == cli_error(pamc_exe, "plant", "--plant", missing)
    with pytest.raises(ValueError, match="no_such_key"):
        pamc.Plant({"kind": "model", "no_such_key": 1})


def test_bad_arguments():
    with pytest.raises(ValueError, match="'nope' is not a parameter"):
        pamc.Model().parameters = {"nope": 1.0}
    with pytest.raises(ValueError, match="no_effect"):
        pamc.Model(effects=["no_effect"])
    with pytest.raises(ValueError, match="u has 2 samples, t has 3"):
        pamc.Measurement([0, 1, 2], [0, 1], [0, 1, 2])
    with pytest.raises(ValueError, match=r"^arrays:4: column 't': time does not increase"):
        pamc.Measurement([0, 1, 1], [0, 1, 2], [0, 1, 2])
    with pytest.raises(ValueError, match=r"^arrays:3: column 'y': value .* is too large"):
        pamc.Measurement([0, 1, 2], [0, 1, 2], [0, 1e300, 2])
    with pytest.raises(ValueError, match=r"^arrays:3: column 'u': value is not finite"):
        pamc.fit([0, 1, 2], [0, float("nan"), 2], [0, 1, 2])
    with pytest.raises(ValueError, match="trajectory"):
        pamc.Trajectory("zigzag:1")
    with pytest.raises(ValueError):
        pamc.Controller("fuzzy")
    with pytest.raises(TypeError, match="unknown controller setting 'kq'"):
        pamc.Controller("pi", kq=1.0)
    with pytest.raises(FileNotFoundError):
        pamc.Controller("amc", model="no_model_here.json")
