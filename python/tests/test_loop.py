"""A closed loop written in Python against the library's own lockstep loop."""
import collections
import os

import numpy as np
import pytest

import pamc

TRIANGLE = "triangle:0.05:0.2:30"
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DURATION, PREROLL, U0 = 20.0, 1.0, 0.0


def python_loop(ctrl, plant, ref, delay):
    """sim::Lockstep in Python (docs/PYTHON.md): latch, control, send; the valve applies what was sent `delay` cycles ago."""
    plant.reset(U0); ctrl.activate(U0, plant.measure())
    pipe, e = collections.deque([U0] * (delay + 1), maxlen=delay + 1), []
    for k in range(-round(PREROLL / plant.Ts), round(DURATION / plant.Ts)):
        t = max(k, 0) * plant.Ts; y = plant.measure()
        yd, yd_next = ref.at(t), ref.at(t + ctrl.lookahead * plant.Ts if k >= 0 else 0.0)
        pipe.appendleft(ctrl.update(yd, yd_next, y)); plant.step(pipe[-1])
        if k >= 0: e.append(yd - y)
    return float(np.sqrt(np.mean(np.square(e))))


def test_python_loop_tracks_like_the_library_loop():
    ref = pamc.Trajectory(TRIANGLE)
    ctrl = pamc.Controller("pi")
    rmse = python_loop(ctrl, pamc.Plant(), ref, delay=2)
    lib = pamc.closed_loop(pamc.Controller("pi"), pamc.Plant(), ref, DURATION, u0=U0, preroll=PREROLL)
    assert rmse == pytest.approx(lib["rmse"], rel=1e-12)
    assert len(lib["t"]) == round(DURATION / 1e-3)
    assert rmse < 3.0  # mm, on a 30 mm triangle


def test_controller_settings_and_lookahead():
    ctrl = pamc.Controller("pi", kp=0.2, ki=1.0)
    assert ctrl.kind == "pi" and ctrl.lookahead == 1
    ctrl.activate(0.0, 0.0)
    u = ctrl.update(1.0, 1.0, 0.0)
    assert u == pytest.approx(ctrl.last["u"]) and u > 0
    amc = pamc.Controller("amc", model=pamc.Model(), amc_horizon=4, amc_inverse=0.5)
    assert amc.lookahead == 4


def test_trajectory_samples():
    ref = pamc.Trajectory(TRIANGLE)
    t = np.linspace(0, 20, 11)
    np.testing.assert_array_equal(ref(t), [ref.at(x) for x in t])
    assert ref.at(10.0) == pytest.approx(30.0)


def test_the_mbc_says_when_its_model_moves_otherwise_than_the_muscle():
    """A model with a tenth of the gain: the MBC's response monitor takes its feedforward off (docs/CONTROL.md)."""
    fitted = pamc.Model.load(os.path.join(ROOT, "tests", "data", "models", "calibrated_pneumatic_balance.json"))
    d = fitted.to_dict()
    d["core"]["k"] *= 0.1
    model = pamc.Model.from_dict(d)
    ctrl, plant, ref = pamc.Controller("mbc", model=model), pamc.Plant(), pamc.Trajectory(TRIANGLE)
    plant.reset(0.0); ctrl.activate(0.0, plant.measure())
    verdicts = []
    for k in range(8000):
        t = k * plant.Ts
        plant.step(ctrl.update(ref.at(t), ref.at(t + ctrl.lookahead * plant.Ts), plant.measure()))
        verdicts.append((ctrl.last["model_distrusted"], ctrl.last["model_ratio"], ctrl.last["u_c"]))
    assert not verdicts[0][0]
    off = [v for v in verdicts if v[0]]
    assert off and all(u_c == 0.0 for _, _, u_c in off)
    assert off[0][1] > 2.0
