#!/usr/bin/env python3
"""How much of the AMC's compensation is a one-step-ahead error gain: the correlation of u_c with
yd_{k+1} - y_k over a closed-loop run's CSV (a file `pamc experiments` writes, e.g.
results/triangle_0.05Hz_amc.csv). With the run's model.json and summary.json beside the CSV (the paper's
form of the AMC, u_c = kc (yd_{k+1} - Y_hat_{k+1})), also what the prediction Y_hat_{k+1} = yd_{k+1} - u_c / kc
misses y_{k+1} by, and how much of that is the offset -k rho u_c that eq. (17) as printed builds in (it
predicts from the nominal command u_n while the posterior was fitted with u = u_n + u_c); the rest is the
model's own one-step error. Usage: tools/amc_correlation.py RUN.csv"""
import csv
import json
import math
import os
import sys


def correlation(a, b):
    ma, mb = sum(a) / len(a), sum(b) / len(b)
    cov = sum((p - ma) * (q - mb) for p, q in zip(a, b))
    return cov / math.sqrt(sum((p - ma) ** 2 for p in a) * sum((q - mb) ** 2 for q in b))


def rms(a):
    return math.sqrt(sum(x * x for x in a) / len(a))


def main():
    if len(sys.argv) != 2:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        return 2
    try:
        rows = list(csv.DictReader(open(sys.argv[1])))
        uc, yd, y = ([float(r[c]) for r in rows] for c in ("u_c", "yd", "y"))
    except (OSError, KeyError, ValueError) as e:
        print(f"{sys.argv[1]}: {e}", file=sys.stderr)
        return 1
    ahead = [yd[k + 1] - y[k] for k in range(len(rows) - 1)]
    print(f"{sys.argv[1]}: u_c against yd[k+1] - y[k] over {len(ahead)} cycles: correlation {correlation(uc[:-1], ahead):.5f}")
    folder = os.path.dirname(sys.argv[1]) or "."
    try:
        core = json.load(open(os.path.join(folder, "model.json")))["core"]
        kc = json.load(open(os.path.join(folder, "summary.json")))["readings"]["kc"]
    except (OSError, KeyError, ValueError):
        return 0  # no model or gains beside the run: the correlation only
    if not kc > 0:
        return 0
    k_rho = core["k"] * core["rho"]
    n = len(rows) - 1
    miss = [yd[k + 1] - uc[k] / kc - y[k + 1] for k in range(n)]  # Y_hat_{k+1} - y_{k+1}
    offset = [-k_rho * uc[k] for k in range(n)]
    rest = [m - o for m, o in zip(miss, offset)]
    print(f"Y_hat[k+1] = yd[k+1] - u_c / kc (kc {kc:g} V/mm) misses y[k+1] by {rms(miss):.4f} mm rms; "
          f"the offset -k rho u_c (k rho {k_rho:.4f} mm/V) is {rms(offset):.4f} mm rms; "
          f"the rest: {rms(rest):.4f} mm rms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
