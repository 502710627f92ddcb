#!/usr/bin/env python3
"""Timings of the Python module against the C++ calls it wraps (docs/PERFORMANCE.md, "Python").

    PYTHONPATH=build/python python3 python/bench_python.py [--samples 1000000] [--repeats 15]

- Model.simulate on SAMPLES samples from Python against the same Model::simulate called from C++
  (pamc._pamc._simulate_seconds, no Python in the timed loop), best of REPEATS each: returning a new array
  against C++ writing into a new vector, and into a reused array (out=) against C++ into a buffer allocated
  once; for the paper's Bouc-Wen model and for the model with pressure_lag + creep;
- Controller.update's round trip from Python (PI, and AMC on the Bouc-Wen model): the mean over 200000 calls,
  and the same loop calling a Python function that returns at once (the loop's own share)."""
import argparse
import os
import platform
import sys
import time

import numpy as np

# This script's folder holds the sources of pamc/ (without the built extension): import the built module
# from PYTHONPATH instead.
sys.path = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(os.path.abspath(__file__))]
import pamc  # noqa: E402


def best_of(repeats, fn):
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def bench_simulate(model, u, repeats):
    y = np.empty_like(u)
    new = best_of(repeats, lambda: model.simulate(u))
    into = best_of(repeats, lambda: model.simulate(u, out=y))
    cpp_new = pamc._pamc._simulate_seconds(model, u, 1e-3, repeats, True)
    cpp_into = pamc._pamc._simulate_seconds(model, u, 1e-3, repeats, False)
    print(f"simulate {model.describe()}, {len(u)} samples:\n"
          f"  a new array:  Python {new * 1e3:7.2f} ms, C++ {cpp_new * 1e3:7.2f} ms, ratio {new / cpp_new:.3f}\n"
          f"  into out=:    Python {into * 1e3:7.2f} ms, C++ {cpp_into * 1e3:7.2f} ms, ratio {into / cpp_into:.3f}")


def bench_update(ctrl, n=200_000):
    ctrl.activate(0.0, 0.0)
    update = ctrl.update
    t0 = time.perf_counter()
    for k in range(n):
        update(10.0, 10.0, 9.9)
    per_call = (time.perf_counter() - t0) / n

    def nothing(a, b, c):
        return 0.0

    t0 = time.perf_counter()
    for k in range(n):
        nothing(10.0, 10.0, 9.9)
    loop = (time.perf_counter() - t0) / n
    print(f"Controller('{ctrl.kind}').update round trip: {per_call * 1e6:.3f} us per call in a Python loop "
          f"(the loop calling a Python function that returns at once: {loop * 1e6:.3f} us)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1_000_000)
    ap.add_argument("--repeats", type=int, default=15)
    a = ap.parse_args()
    print(f"Python {platform.python_version()}, numpy {np.__version__}, {platform.machine()}")
    u = 2.9 * np.sin(2 * np.pi * 0.2 * np.arange(a.samples) * 1e-3) + 0.2
    bench_simulate(pamc.Model(), u, a.repeats)
    bench_simulate(pamc.Model(effects=["pressure_lag", "creep"]), u, a.repeats)
    bench_update(pamc.Controller("pi"))
    bench_update(pamc.Controller("amc", model=pamc.Model()))


if __name__ == "__main__":
    main()
