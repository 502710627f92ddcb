#!/usr/bin/env python3
"""The loop of a user with a rig, on the in-process bus at a rig's period (docs/CONTROL.md, "A model that does
not come to rest"): on the calibrated physics plant (`pamc plant --calibrated`),
  1. the paper's u0 and u1 recorded through the bus, `pamc rig run --input sine:0.1:0.2:2.9` (u1: 1.4 V) at
     --period-us;
  2. `pamc diagnose u0.csv --validate u1.csv`, or the model given with --model instead;
  3. PI and MBC with that model over the bus at the same period, from the vented muscle: Table 2's triangle
     (tracking RMSE and largest error over the run, as the rig prints them) and the square wave 10-25 mm at
     0.1 Hz (each step's overshoot, from the controller's cycle records).
Prints a Markdown table. Exits 0 (a measurement, not a test), 1 when a command fails, 2 on a usage error.

  tools/rig_loop_table.py [--pamc BIN] [--out-dir DIR] [--period-us US] [--model MODEL.json]
                          [--plant-file PLANT.json]  (another plant than the calibrated one)
"""
import argparse
import csv
import os
import re
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
TRIANGLE = "triangle:0.05:0.2:30"
SQUARE = "square:0.1:10:25"
RECORDS = {"u0": "sine:0.1:0.2:2.9", "u1": "sine:0.1:0.2:1.4"}


def run(cmd, log):
    with open(log, "w") as f:
        r = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT)
    if r.returncode != 0:
        sys.exit(f"rig_loop_table: {' '.join(cmd)} exited {r.returncode} (its output: {log})")
    with open(log) as f:
        return f.read()


def rig(a, plant, args, out, log):
    return run([a.pamc, "rig", "run", "--od", os.path.join(ROOT, "od"), "--plant", plant, "--period-us",
                str(a.period_us), "--preroll", "1", "--duration", "40"] + args + [out[0], out[1]], log)


def overshoots(path):
    """Each setpoint step's overshoot [% of the step], by direction, from a cycle-record CSV (t,yd,y,...)."""
    with open(path) as f:
        rows = [(float(r["yd"]), float(r["y"])) for r in csv.DictReader(f)]
    jumps = [i for i in range(1, len(rows)) if rows[i][0] != rows[i - 1][0]] + [len(rows)]
    out = {"forward": [], "backward": []}
    for j, i in enumerate(jumps[:-1]):
        end = jumps[j + 1]
        a, b = rows[i - 1][0], rows[i][0]
        if end == len(rows):
            continue  # the last level, cut off by the run's end, is not a whole step response
        s = 1.0 if b > a else -1.0
        peak = max(s * (rows[k][1] - b) for k in range(i, end))
        out["forward" if s > 0 else "backward"].append(100.0 * max(peak, 0.0) / abs(b - a))
    return out


def row(name, a, plant, model, work):
    tri = rig(a, plant, ["--controller", name, "--model", model, "--trajectory", TRIANGLE],
              ["--csv", os.path.join(work, f"triangle_{name}.csv")], os.path.join(work, f"triangle_{name}.txt"))
    m = re.search(r"tracking error over \d+ cycles: RMSE ([0-9.]+) mm, max ([0-9.]+) mm", tri)
    sq_csv = os.path.join(work, f"square_{name}.csv")
    rig(a, plant, ["--controller", name, "--model", model, "--trajectory", SQUARE], ["--csv", sq_csv],
        os.path.join(work, f"square_{name}.txt"))
    o = overshoots(sq_csv)
    span = lambda v: f"{min(v):.1f}-{max(v):.1f}" if v else "-"
    note = "; ".join(l for l in tri.splitlines() if l.startswith("mbc: the model"))
    return f"| {name} | {m.group(1)} / {m.group(2)} | {span(o['forward'])} | {span(o['backward'])} | {note} |"


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--pamc", default=os.path.join(ROOT, "build", "src", "pamc"))
    p.add_argument("--out-dir", default=None, help="keep the records, runs and diagnosis here")
    p.add_argument("--period-us", type=int, default=20000, help="SYNC period [us] (default 20000: 50 Hz)")
    p.add_argument("--model", default=None, help="this model instead of the one diagnosed from u0")
    p.add_argument("--plant-file", default=None, help="this plant (`pamc plant` JSON) instead of the calibrated one")
    a = p.parse_args()
    if not os.access(a.pamc, os.X_OK):
        p.error(f"{a.pamc}: not an executable (build first: tools/build.sh)")
    work = a.out_dir or tempfile.mkdtemp(prefix="rig_loop_")
    os.makedirs(work, exist_ok=True)
    plant = a.plant_file or os.path.join(work, "calibrated.json")
    if not a.plant_file:
        with open(plant, "w") as f:
            subprocess.run([a.pamc, "plant", "--calibrated"], stdout=f, check=True)
    model = a.model
    if model is None:
        for name, spec in RECORDS.items():
            print(f"recording {name} ({spec}) at {a.period_us} us ...", file=sys.stderr)
            rig(a, plant, ["--input", spec], ["--out", os.path.join(work, f"{name}.csv")],
                os.path.join(work, f"record_{name}.txt"))
        print("diagnosing ...", file=sys.stderr)
        out = run([a.pamc, "diagnose", os.path.join(work, "u0.csv"), "--validate", os.path.join(work, "u1.csv"),
                   "--out-dir", os.path.join(work, "diagnosed")], os.path.join(work, "diagnose.txt"))
        model = os.path.join(work, "diagnosed", "model.json")
        last = [l for l in out.splitlines() if l.startswith("Added") or l.startswith("Nothing")]
        print(f"diagnosed: {last[-1][:160] if last else '?'}", file=sys.stderr)
    print(f"{a.plant_file or 'The calibrated physics plant'} at {a.period_us} us, model {model} (runs in {work}):\n")
    print("| controller | triangle RMSE / max [mm] | square overshoot forward [%] | backward [%] | the MBC's model |")
    print("|---|---|---|---|---|")
    for name in ("pi", "mbc"):
        print(row(name, a, plant, model, work))


if __name__ == "__main__":
    main()
