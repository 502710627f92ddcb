#!/usr/bin/env python3
"""Diagnose on a whole stroke written by other laws: the pre-decided cases of tests/oracle/wide_range.json.

For each case the oracle makes the training and validation records, `pamc diagnose` is run on them, and
the answer is judged against thresholds fixed with the case, before diagnose was first run on it:

  - every expected effect is among the effects found (muscle_balance: the oracle's exponential map,
    Maxwell-slip friction and end stops must be taken for the catalogue's muscle_balance);
  - the validated RMSE is at most 3x the record's noise (its std with quantisation).

Prints the ladder (effects, validated RMSE, x noise) of each case; exits 1 if a case fails, 2 on a usage error.
  tools/wide_range_judge.py [--cases FILE] [--out-dir DIR] [--pamc BIN] [--oracle BIN]
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
QUANTUM = 0.001
AT_NOISE = 3.0  # the validated error's bound, in noise std: fixed before the first run, not to be loosened


def run(cmd):
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        sys.exit("wide_range_judge: %s failed (%d): %s" % (" ".join(cmd), r.returncode, r.stderr.strip()[-500:]))
    return r.stdout


def diagnose(args, case, work):
    paths = {}
    for which in ("train", "validate"):
        paths[which] = os.path.join(work, "%s_%s.csv" % (case["name"], which))
        run([args.oracle, "--cases", args.cases, "--case", case["name"], "--record", which, "--out", paths[which]])
    report = os.path.join(work, case["name"] + ".diagnose.json")
    run([args.pamc, "diagnose", paths["train"], "--validate", paths["validate"], "--json", report,
         "--out-dir", os.path.join(work, case["name"])])
    with open(report) as f:
        return json.load(f)


def judge(case, report):
    noise = math.sqrt(case["noise"] ** 2 + QUANTUM ** 2 / 12.0)
    for r in report["ladder"]:
        print("  %-60s %.5f mm  %.2fx noise%s" % (" + ".join(r["effects"]) or "(core)", r["rmse_val"],
                                                  r["rmse_val"] / noise, "  (probe)" if r.get("probe") else ""))
    final = [r for r in report["ladder"] if not r.get("probe")][-1]
    missing = [e for e in case["expected"] if e not in final["effects"]]
    ratio = final["rmse_val"] / noise
    print("  found: %s; validated RMSE %.5f mm = %.2fx noise (bound %.1fx)" %
          (" + ".join(final["effects"]) or "(none)", final["rmse_val"], ratio, AT_NOISE))
    why = (["not named: " + ", ".join(missing)] if missing else []) + (["above the bound"] if ratio > AT_NOISE else [])
    return not why, why


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default=os.path.join(ROOT, "tests", "oracle", "wide_range.json"))
    ap.add_argument("--out-dir", dest="work", default="", help="folder for the records and reports (default: a temporary one)")
    ap.add_argument("--pamc", default=os.path.join(ROOT, "build", "src", "pamc"))
    ap.add_argument("--oracle", default=os.path.join(ROOT, "build", "tests", "oracle", "pamc_oracle_sim"))
    args = ap.parse_args()
    for exe in (args.pamc, args.oracle):
        if not os.access(exe, os.X_OK):
            sys.stderr.write("wide_range_judge: %s: not an executable (build first)\n" % exe)
            return 2
    with open(args.cases) as f:
        cases = json.load(f)["cases"]
    work = args.work or tempfile.mkdtemp(prefix="pamc_wide_")
    os.makedirs(work, exist_ok=True)
    failed = 0
    for case in cases:
        t0 = time.time()
        print("%s (expected %s):" % (case["name"], " + ".join(case["expected"])), flush=True)
        ok, why = judge(case, diagnose(args, case, work))
        print("  %s (%.0f s)" % ("as expected" if ok else "FAILED: " + "; ".join(why), time.time() - t0), flush=True)
        failed += 0 if ok else 1
    sys.stderr.write("records and reports in %s\n" % work)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
