#!/usr/bin/env python3
"""How much of the AMC's compensation is a one-step-ahead error gain: the correlation of u_c with
yd_{k+1} - y_k over a closed-loop run's CSV (a file `pamc experiments` writes, e.g.
results/triangle_0.05Hz_amc.csv). Usage: tools/amc_correlation.py RUN.csv"""
import csv
import math
import sys


def correlation(a, b):
    ma, mb = sum(a) / len(a), sum(b) / len(b)
    cov = sum((p - ma) * (q - mb) for p, q in zip(a, b))
    return cov / math.sqrt(sum((p - ma) ** 2 for p in a) * sum((q - mb) ** 2 for q in b))


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
    return 0


if __name__ == "__main__":
    sys.exit(main())
