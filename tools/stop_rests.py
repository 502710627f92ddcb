#!/usr/bin/env python3
"""Whether a measurement record rests on an end stop or only turns at its extremes: for each record (the
CSV `fit`, `compare` and `diagnose` read: columns t, u, y) and each extreme of its output, the share of its
samples within 0.2 % of the output's range from that extreme, and how far the input moves over those samples
(as a share of the input's range). The search's box for an end stop (src/ident/identify.cpp,
restsAtExtremes) takes a record to rest on a stop where the first is at least 0.2 % and the second at least
3.5 %: a stop holds the output while the input moves on past it, a sine's turn holds it only while the
input turns too. Usage: tools/stop_rests.py RECORD.csv [RECORD.csv ...]"""
import csv
import sys

BAND = 0.002  # kRestBand
SHARE = 0.002  # kRestShare
INPUT = 0.035  # kRestInput


def extremes(path):
    rows = list(csv.DictReader(open(path)))
    u, y = [float(r["u"]) for r in rows], [float(r["y"]) for r in rows]
    if not y:
        raise ValueError("no samples")
    band, ru = BAND * (max(y) - min(y)), max(u) - min(u)
    for name, near in (("low", lambda v: v <= min(y) + band), ("high", lambda v: v >= max(y) - band)):
        us = [a for a, v in zip(u, y) if near(v)]
        share, moved = len(us) / len(y), (max(us) - min(us)) / ru if ru > 0 else 0.0
        yield name, share, moved, share >= SHARE and moved >= INPUT


def main():
    if len(sys.argv) < 2:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        return 2
    lines = []
    for path in sys.argv[1:]:
        try:
            for name, share, moved, stop in extremes(path):
                lines.append(f"| {path} | {name} | {100 * share:.2f} % | {100 * moved:.1f} % | {'yes' if stop else 'no'} |")
        except (OSError, KeyError, ValueError) as e:
            print(f"{path}: {e}", file=sys.stderr)
            return 1
    print("| record | extreme | samples there | input moved there | a stop |")
    print("|---|---|---|---|---|")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
