#!/usr/bin/env python3
"""Diagnose on data that no model code made: the pre-decided cases of tests/oracle/cases.json.

For every case, a training and a validation record are made by an independent generator, `pamc diagnose`
is asked which effects are missing, and the answer is judged against the case's expected effects:

  - the effects found are exactly the expected ones (the order is reported: the right effect first);
  - the validated error is within 1.5x the generator's noise (its configured std with quantisation);
  - on plain data (no hidden effect): nothing added and no "something systematic is left";
  - no probe fits better than the catalogue's effects (no probe rung: each case is the catalogue's physics).

Generators:
  oracle   tests/oracle's continuous-time simulator (its own integrator, shares no code with the plants)
  physics  the physics plant (src/physics) in its reference mode with the case's core and effects,
           driven by the oracle record's command (`pamc emulate --input-from`)

Prints a Markdown table; exits 1 if any case fails, 2 on a usage error.
  tools/truth_table.py [--generator oracle|physics] [--only a,b] [--skip c] [--out-dir DIR] [--pamc BIN] [--oracle BIN]
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
AT_NOISE = 1.5  # the validated error's bound, in noise std


def run(cmd):
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        sys.exit("truth_table: %s failed (%d): %s" % (" ".join(cmd), r.returncode, r.stderr.strip()[-500:]))
    return r.stdout


def oracle_record(args, case, which, out):
    run([args.oracle, "--cases", args.cases, "--case", case["name"], "--record", which, "--out", out])


def physics_plant_file(case, path, seed):
    effects = {name: dict(params, enabled=True) for name, params in case.get("effects", {}).items()}
    plant = {
        "kind": "physics",
        "mode": "reference",
        "reference": case["core"],
        "effects": effects,
        "sensor": {"noise_std_mm": case["noise"], "quantum_mm": QUANTUM},
        "stroke": {"min_mm": -1000.0, "max_mm": 1000.0},
        "seed": seed,
    }
    with open(path, "w") as f:
        json.dump(plant, f)


def records(args, case, work):
    """The case's training and validation records from the chosen generator."""
    paths = {}
    for which in ("train", "validate"):
        base = os.path.join(work, "%s_%s" % (case["name"], which))
        oracle_record(args, case, which, base + ".oracle.csv")
        if args.generator == "oracle":
            paths[which] = base + ".oracle.csv"
            continue
        plant = base + ".plant.json"
        physics_plant_file(case, plant, case[which]["seed"])
        run([args.pamc, "emulate", "--plant", plant, "--input-from", base + ".oracle.csv", "--out", base + ".physics.csv"])
        paths[which] = base + ".physics.csv"
    return paths


def judge(case, report, seconds):
    noise = math.sqrt(case["noise"] ** 2 + QUANTUM ** 2 / 12.0)
    ladder = report["ladder"]
    final = [r for r in ladder if not r.get("probe")][-1]
    found = final["effects"]
    expected = case["expected"]
    first = ladder[1]["effects"][0] if len(ladder) > 1 and ladder[1]["effects"] else "-"
    ratio = final["rmse_val"] / noise
    ok_effects = sorted(found) == sorted(expected)
    ok_first = not expected or first in expected
    ok_noise = ratio <= AT_NOISE
    ok_verdict = bool(expected) or "something systematic is left" not in report["verdict"]
    # Every case is the catalogue's own physics: no probe may fit better than its effect (a probe rung).
    ok_probe = not any(r.get("probe") for r in ladder)
    ok = ok_effects and ok_first and ok_noise and ok_verdict and ok_probe
    why = []
    if not ok_effects:
        why.append("effects")
    if not ok_first:
        why.append("first")
    if not ok_noise:
        why.append("> %.1fx noise" % AT_NOISE)
    if not ok_verdict:
        why.append("verdict")
    if not ok_probe:
        why.append("a probe fits better")
    row = "| %s | %s | %s | %s | %.4g -> %.4g | %.2f | %.0f s | %s |" % (
        case["name"], " + ".join(expected) or "(none)", first, " + ".join(found) or "(none)",
        ladder[0]["rmse_val"], final["rmse_val"], ratio, seconds, "yes" if ok else "**no** (" + ", ".join(why) + ")")
    return ok, row


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--generator", choices=["oracle", "physics"], default="oracle")
    ap.add_argument("--only", default="", help="comma list of case names")
    ap.add_argument("--skip", default="", help="comma list of case names left out (say why where you do)")
    ap.add_argument("--out-dir", dest="work", default="", help="folder for the records and reports (default: a temporary one)")
    ap.add_argument("--pamc", default=os.path.join(ROOT, "build", "src", "pamc"))
    ap.add_argument("--oracle", default=os.path.join(ROOT, "build", "tests", "oracle", "pamc_oracle_sim"))
    ap.add_argument("--cases", default=os.path.join(ROOT, "tests", "oracle", "cases.json"))
    args = ap.parse_args()
    for exe in (args.pamc, args.oracle):
        if not os.access(exe, os.X_OK):
            sys.stderr.write("truth_table: %s: not an executable (build first)\n" % exe)
            return 2
    with open(args.cases) as f:
        cases = json.load(f)["cases"]
    only = [x for x in args.only.split(",") if x]
    skip = [x for x in args.skip.split(",") if x]
    unknown = [x for x in only + skip if x not in {c["name"] for c in cases}]
    if unknown:
        sys.stderr.write("truth_table: unknown case(s): %s\n" % ", ".join(unknown))
        return 2
    work = args.work or tempfile.mkdtemp(prefix="pamc_truth_")
    os.makedirs(work, exist_ok=True)
    print("| case | hidden | named first | found | validated RMSE before -> after [mm] | x noise | time | as expected |")
    print("|---|---|---|---|---|---|---|---|")
    failed = 0
    for case in cases:
        if (only and case["name"] not in only) or case["name"] in skip:
            continue
        sys.stderr.write("%s: %s ...\n" % (args.generator, case["name"]))
        paths = records(args, case, work)
        report_path = os.path.join(work, case["name"] + ".diagnose.json")
        t0 = time.time()
        run([args.pamc, "diagnose", paths["train"], "--validate", paths["validate"], "--json", report_path])
        with open(report_path) as f:
            report = json.load(f)
        ok, row = judge(case, report, time.time() - t0)
        print(row, flush=True)
        failed += 0 if ok else 1
    sys.stderr.write("records and reports in %s\n" % work)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
