"""Shared fixtures: the pamc command of the same build, and records made by it."""
import json
import os
import subprocess

import pytest

import pamc

# A plant of known structure: the model plant with a Bouc-Wen core inside the fit's search box and nothing
# else - no sensor noise, quantisation or stroke limits: data a fit of the plain model can match exactly.
TRUTH = {"k": 6.0, "rho": 0.7, "b": 15.0, "alpha": 1.0, "beta": 0.4, "gamma": 0.2}


@pytest.fixture(scope="session")
def pamc_exe():
    exe = os.environ.get("PAMC_EXE")
    if not exe:
        pytest.fail("PAMC_EXE is not set (ctest sets it to the pamc of the build)")
    return exe


def run_pamc(exe, *args, check=True):
    """Runs pamc; returns the completed process (stdout and stderr as text)."""
    return subprocess.run([exe, *map(str, args)], capture_output=True, text=True, check=check)


def truth_plant():
    """The model plant's configuration with TRUTH as its core and nothing else."""
    cfg = pamc.Plant({"kind": "model"}).config
    cfg["core"] = dict(TRUTH)
    for e in cfg["effects"].values():
        e["enabled"] = False
    cfg["stroke"]["enabled"] = False
    cfg["sensor"]["noise"] = False
    cfg["sensor"]["quantization"] = False
    return cfg


@pytest.fixture(scope="session")
def records(tmp_path_factory, pamc_exe):
    """Records made by `pamc emulate`: 'truth' on the plant of TRUTH, 'physics' on the default physics plant."""
    d = tmp_path_factory.mktemp("records")
    plant = d / "truth_plant.json"
    plant.write_text(json.dumps(truth_plant()))
    out = {"dir": d, "truth_plant": plant}
    for name, args in {"truth": ["--plant", plant, "--input", "sine:0.2:0.2:2.9", "--duration", 12],
                       "physics": ["--input", "sine:0.2:0.2:2.9", "--duration", 12]}.items():
        out[name] = d / f"{name}.csv"
        run_pamc(pamc_exe, "emulate", *args, "--out", out[name])
    return out


@pytest.fixture(scope="session")
def fitted(records, pamc_exe):
    """A model fitted by `pamc fit` on the physics record (the model file)."""
    path = records["dir"] / "physics_model.json"
    run_pamc(pamc_exe, "fit", records["physics"], "--method", "lm", "--quiet", "--out", path)
    return path
