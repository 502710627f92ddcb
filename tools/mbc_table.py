#!/usr/bin/env python3
"""A controller that gets better as its model does: the MBC along the diagnose ladder (docs/CONTROL.md).

On the calibrated physics plant `pamc experiments` runs on (`pamc plant --calibrated`):
  1. a record over the whole stroke, `pamc emulate --input random:1:-3.5:4 --duration 60`, validated on
     `random:2:-3.5:4 --duration 30`;
  2. `pamc diagnose` on the pair; every rung's model (diagnosis.json's ladder) - the reference model fitted
     on the record first, the final model last;
  3. each rung's model given to `pamc experiments --model` (Table 2's triangle): PI and MBC tracking RMSE;
  4. the reference model and the final model through Table 2, the square and sawtooth waves and the payload
     step: every row of the MBC beside the PI, with the bounds of issue 36 step 2 said met or not.
With --records paper the ladder is diagnosed on the paper's identification records instead: u0 (2.9 sin(0.2 pi t)
+ 0.2 V) validated on u1 (its amplitude 1.4 V), as `pamc experiments` writes them on the same plant - the
recipe of the paper, whose model sees only part of the stroke the trajectories drive (issue 36's bounds are
for the whole stroke's model; they are printed here as the same yardstick).
With --oracle-plant CASES.json the same table on a second plant that shares no code with the physics plant
or src/model: the test oracle's simulator (tests/oracle), its records written by pamc_oracle_sim from the
case's train and validate specs, the experiments run by pamc_oracle_experiments with the oracle as the plant.
Prints Markdown tables. Exits 0 (the tables are a measurement, not a test), 2 on a usage error.

  tools/mbc_table.py [--pamc BIN] [--out-dir DIR] [--plant-file PLANT.json | --oracle-plant CASES.json]
                     [--records whole|paper]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SINES = ["sine_0.05Hz", "sine_0.1Hz"]
TRIANGLE = "triangle_0.05Hz"


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def run(cmd, out=None):
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        sys.exit("mbc_table: %s failed (%d): %s" % (" ".join(cmd), r.returncode, r.stderr.strip()[-500:]))
    if out:
        with open(out, "w") as f:
            f.write(r.stdout)
    return r.stdout


def records(pamc, d, plant):
    train, val = os.path.join(d, "wide_train.csv"), os.path.join(d, "wide_val.csv")
    run([pamc, "emulate", "--plant", plant, "--input", "random:1:-3.5:4", "--duration", "60", "--out", train])
    run([pamc, "emulate", "--plant", plant, "--input", "random:2:-3.5:4", "--duration", "30", "--out", val])
    return train, val


def oracle_records(oracle_bin, d, cases):
    paths = []
    for which in ("train", "validate"):
        path = os.path.join(d, "oracle_%s.csv" % which)
        run([oracle_bin, "--cases", cases, "--record", which, "--case", only_case(cases), "--out", path])
        paths.append(path)
    return paths


def paper_records(runner, d):
    """The paper's u0 and u1, written by the experiments' Table 1 on the plant they run on."""
    out = os.path.join(d, "paper")
    run(runner + ["--only", "table1", "--no-figures", "--out-dir", out])
    return os.path.join(out, "ident_u0.csv"), os.path.join(out, "ident_u1.csv")


def only_case(cases):
    with open(cases) as f:
        names = [c["name"] for c in json.load(f)["cases"]]
    if len(names) != 1:
        sys.exit("mbc_table: %s holds %d cases, the plant must be the only one" % (cases, len(names)))
    return names[0]


def rung_models(pamc, d, train, val):
    js = os.path.join(d, "diagnosis.json")
    t0 = time.time()
    run([pamc, "diagnose", train, "--validate", val, "--json", js, "--out-dir", os.path.join(d, "diagnose")])
    log("diagnose: %.0f s" % (time.time() - t0))
    with open(js) as f:
        ladder = json.load(f)["ladder"]
    rungs = []
    for i, rung in enumerate(r for r in ladder if not r.get("probe")):
        path = os.path.join(d, "rung%d.json" % i)
        with open(path, "w") as f:
            json.dump(rung["model"], f, indent=2)
        label = "reference model" if i == 0 else " + ".join(rung["effects"])
        rungs.append({"label": label, "path": path, "rmse_val": rung["rmse_val"]})
    return rungs


def experiments(runner, d, model, only, name):
    """runner: the command before the options, [pamc, "experiments"] or [pamc_oracle_experiments, --cases, F]."""
    out = os.path.join(d, name)
    t0 = time.time()
    run(runner + ["--model", model, "--only", only, "--no-figures", "--out-dir", out])
    log("experiments %s (%s): %.0f s" % (name, only, time.time() - t0))
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


def ladder_table(rungs):
    print("| rung | validated RMSE of the model [mm] | PI triangle RMSE [mm] | MBC triangle RMSE [mm] | MBC / PI |")
    print("|---|---|---|---|---|")
    for r in rungs:
        t = r["summary"]["table2"][TRIANGLE]
        pi, mbc = t["pi"]["rmse"], t["mbc"]["rmse"]
        print("| %s | %.4f | %.4f | %.4f | %.2f |" % (r["label"], r["rmse_val"], pi, mbc, mbc / pi))
    tri = [r["summary"]["table2"][TRIANGLE]["mbc"]["rmse"] for r in rungs]
    rises = [i for i in range(1, len(tri)) if tri[i] > tri[i - 1]]
    print("\nAlong the ladder the MBC's triangle RMSE %s." %
          ("never rises" if not rises else "rises at rung(s) %s" % ", ".join(str(i) for i in rises)))


def rows(summary):
    """(row name, PI value, MBC value, kind) for every judged row; kind says how the bound reads."""
    out = []
    t2 = summary["table2"]
    for tag in [TRIANGLE] + SINES:
        out.append((tag + " RMSE [mm]", t2[tag]["pi"]["rmse"], t2[tag]["mbc"]["rmse"], "rmse"))
        out.append((tag + " max [mm]", t2[tag]["pi"]["max"], t2[tag]["mbc"]["max"], "max"))
    for wave, dirs in summary["discontinuous"].items():
        for dirn in ("forward", "backward"):
            if dirn not in dirs:
                continue
            e = dirs[dirn]
            out.append(("%s %s overshoot [%%]" % (wave, dirn), e["pi"]["overshoot_pct"], e["mbc"]["overshoot_pct"],
                        "overshoot" if wave == "square" else "other"))
            out.append(("%s %s settling [s]" % (wave, dirn), e["pi"]["settling_s"], e["mbc"]["settling_s"],
                        "settling" if wave == "square" else "other"))
    p = summary["payload"]
    out.append(("payload recovery [s]", p["pi"]["recovery_s"], p["mbc"]["recovery_s"], "recovery"))
    return out


def bound_final(kind, pi, mbc):
    """Issue 36 step 2 for the model diagnosed over the whole stroke."""
    if kind == "rmse":
        return mbc <= 0.5 * pi, "<= 0.5x PI"
    if kind == "overshoot":
        return mbc <= 2.0, "<= 2 %"
    if kind in ("max", "settling", "recovery"):
        return mbc <= pi, "<= PI"
    return None, "-"


def bound_plain(kind, pi, mbc):
    """Issue 36 step 2 for the plain reference model: never worse than 1.05x PI on a Table 2 row."""
    if kind in ("rmse", "max"):
        return mbc <= 1.05 * pi, "<= 1.05x PI"
    return None, "-"


def criteria_table(name, summary, bound):
    print("\n%s:\n" % name)
    print("| row | PI | MBC | MBC / PI | bound | met |")
    print("|---|---|---|---|---|---|")
    met = missed = 0
    for row, pi, mbc, kind in rows(summary):
        ok, text = bound(kind, pi, mbc)
        ratio = mbc / pi if pi else float("nan")
        verdict = "-" if ok is None else ("yes" if ok else "**no**")
        met += ok is True
        missed += ok is False
        print("| %s | %.4g | %.4g | %.2f | %s | %s |" % (row, pi, mbc, ratio, text, verdict))
    print("\n%d bounds met, %d missed." % (met, missed))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pamc", default=os.path.join(ROOT, "build", "src", "pamc"))
    ap.add_argument("--out-dir", help="keep the records, models and runs here (default: a temporary folder)")
    ap.add_argument("--plant-file", help="plant to emulate the records on (default: `pamc plant --calibrated`)")
    ap.add_argument("--oracle-plant", metavar="CASES.json",
                    help="the second plant: the test oracle's only case in this file (tests/oracle/closed_loop_plant.json)")
    ap.add_argument("--records", choices=("whole", "paper"), default="whole",
                    help="the records diagnosed: whole (random:1:-3.5:4 for 60 s, validated on random:2 for 30 s) or "
                         "paper (the experiments' u0, validated on u1)")
    a = ap.parse_args()
    if not os.access(a.pamc, os.X_OK):
        ap.error("no pamc binary at %s (build first: tools/build.sh)" % a.pamc)
    if a.plant_file and a.oracle_plant:
        ap.error("--plant-file and --oracle-plant are two plants: give one")
    d = a.out_dir or tempfile.mkdtemp(prefix="pamc_mbc_")
    os.makedirs(d, exist_ok=True)
    if a.oracle_plant:
        oracle_dir = os.path.join(os.path.dirname(os.path.dirname(a.pamc)), "tests", "oracle")
        sim_bin, exp_bin = (os.path.join(oracle_dir, b) for b in ("pamc_oracle_sim", "pamc_oracle_experiments"))
        for b in (sim_bin, exp_bin):
            if not os.access(b, os.X_OK):
                ap.error("no %s (build first: tools/build.sh)" % b)
        # The oracle's experiments link the controllers' library of the build: linked before it, they run other code.
        lib = os.path.join(os.path.dirname(a.pamc), "libpamc_control.a")
        if os.path.exists(lib) and os.path.getmtime(exp_bin) < os.path.getmtime(lib):
            ap.error("%s is older than %s: it runs other controllers (build it: tools/build.sh)" % (exp_bin, lib))
        log("records on the oracle's plant %s, in %s" % (a.oracle_plant, d))
        runner = [exp_bin, "--cases", a.oracle_plant]
        train, val = paper_records(runner, d) if a.records == "paper" else oracle_records(sim_bin, d, a.oracle_plant)
    else:
        plant = a.plant_file or os.path.join(d, "plant.json")
        if not a.plant_file:
            run([a.pamc, "plant", "--calibrated"], out=plant)
        log("records on %s, in %s" % (plant, d))
        # The experiments on the same plant as the records (without --plant-file: the calibrated one they run on).
        runner = [a.pamc, "experiments"] + (["--plant", a.plant_file] if a.plant_file else [])
        train, val = paper_records(runner, d) if a.records == "paper" else records(a.pamc, d, plant)
    tables(runner, a.pamc, d, train, val)


def tables(runner, pamc, d, train, val):
    rungs = rung_models(pamc, d, train, val)
    for i, r in enumerate(rungs):
        r["summary"] = experiments(runner, d, r["path"], "triangle", "rung%d" % i)
    print("MBC along the diagnose ladder (%s -> %s), Table 2's triangle:\n" % (os.path.basename(train), os.path.basename(val)))
    ladder_table(rungs)
    full = "table2,discontinuous,payload"
    criteria_table("The reference model fitted on the record (" + rungs[0]["label"] + ")",
                   experiments(runner, d, rungs[0]["path"], full, "plain"), bound_plain)
    criteria_table("The final model (" + rungs[-1]["label"] + ")", experiments(runner, d, rungs[-1]["path"], full, "final"),
                   bound_final)


if __name__ == "__main__":
    main()
