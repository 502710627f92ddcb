#!/usr/bin/env python3
"""Name what the catalogue lacks: `pamc diagnose` on the pre-committed records of tests/oracle/unseen.json,
each with one kind of physics outside pamc's effect catalogue, made by the test oracle (an independent
simulator).

For every case the training and validation records are made, `pamc diagnose` runs, and the answer is
judged against the case's kind with the table NAMED_BY below (which probe, or which kind of spectral
line, names which kind):
  - named: the top probe is one that names the kind, or (for a periodic disturbance) the residual's
    spectrum has a line within 5 % of the case's frequency that is not coherent with the input;
  - falls 5x: the validated RMSE with the named structure (the top probe on top of the final model) is
    at least 5x below the final model's (scored on the validation record, not the training one).
    Beside it, for reading only (not the criterion): the same fall of the error above the validation
    record's own noise, sqrt(RMSE^2 - noise^2) with the noise the case writes down - the part of the
    error a model can remove; where a record starts only a few times above its noise, the RMSE cannot
    fall 5x however right the structure.

Prints a Markdown table and the count; exits 0 whatever the count (the count is the result), 2 on a
usage error - with --require-named, 1 unless every case run is named.
  tools/unseen_table.py [--only a,b] [--out-dir DIR] [--pamc BIN] [--oracle BIN] [--cases FILE] [--require-named]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FALL = 5.0           # the validated error must fall this much once the named structure is fitted
LINE_TOLERANCE = 0.05

# kind (unseen.json) -> the probes that name it
NAMED_BY = {
    "dead-zone": {"dead_zone"},
    "backlash": {"backlash"},
    "piecewise-linear gain": {"piecewise_gain"},
    "saturation of the command": {"command_clip"},
    "periodic disturbance": {"periodic"},
    "hysteresis operator (play)": {"play_hysteresis"},
    "direction-dependent lag": {"direction_lag"},
    "valve flow characteristic": {"valve_flow"},
}


def run(cmd):
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        sys.exit("unseen_table: %s failed (%d): %s" % (" ".join(cmd), r.returncode, r.stderr.strip()[-500:]))
    return r.stdout


def spectrum_names(case, diag):
    """A periodic disturbance named by the spectrum: a line near its frequency, not driven by the input."""
    eff = case["effects"].get("periodic_disturbance")
    if not eff:
        return False
    for p in diag.get("spectrum", {}).get("peaks", []):
        if abs(p["hz"] - eff["freq"]) <= LINE_TOLERANCE * eff["freq"] and not p["coherent"]:
            return True
    return False


def judge(case, diag):
    probes = diag.get("probes", [])
    top = probes[0]["probe"] if probes else "-"
    by_probe = top in NAMED_BY[case["kind"]]
    by_spectrum = spectrum_names(case, diag)
    final = diag["ladder"][-2] if diag["ladder"][-1].get("probe") else diag["ladder"][-1]  # the catalogue's last rung
    final_val = final["rmse_val"]
    with_named = probes[0]["rmse_val"] if by_probe else None
    fall = final_val / with_named if with_named else None
    peaks = diag.get("spectrum", {}).get("peaks", [])
    line = "%.2f Hz %s" % (peaks[0]["hz"], "coherent" if peaks[0]["coherent"] else "not coherent") if peaks else "none"
    label = top + (" for " + probes[0]["replaces"] if probes and "replaces" in probes[0] else "")
    return {"top": label, "named": by_probe or by_spectrum, "by": "probe" if by_probe else ("spectrum" if by_spectrum else "-"),
            "final_val": final_val, "fall": fall, "line": line,
            "effects": "+".join(final["effects"]) or "-",
            "fall_above_noise": above_noise(final_val, with_named, case["noise"]) if with_named else None}


def above_noise(before, after, noise):
    """How much the error above the noise falls: sqrt(rmse^2 - noise^2) before over after."""
    b, a = (max(v * v - noise * noise, 0.0) ** 0.5 for v in (before, after))
    return b / a if a > 0 else float("inf")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", default="", help="comma list of case names")
    ap.add_argument("--out-dir", dest="work", default="", help="folder for the records and reports (default: a temporary one)")
    ap.add_argument("--pamc", default=os.path.join(ROOT, "build", "src", "pamc"))
    ap.add_argument("--oracle", default=os.path.join(ROOT, "build", "tests", "oracle", "pamc_oracle_sim"))
    ap.add_argument("--cases", default=os.path.join(ROOT, "tests", "oracle", "unseen.json"))
    ap.add_argument("--require-named", action="store_true",
                    help="exit 1 unless every case run is named (a regression test of the cases given with --only)")
    args = ap.parse_args()
    for b in (args.pamc, args.oracle):
        if not os.path.exists(b):
            print("unseen_table: %s not found (build first)" % b, file=sys.stderr)
            return 2
    cases = json.load(open(args.cases))["cases"]
    if args.only:
        wanted = set(args.only.split(","))
        cases = [c for c in cases if c["name"] in wanted]
    work = args.work or tempfile.mkdtemp(prefix="pamc_unseen_")
    os.makedirs(work, exist_ok=True)
    rows, named, fell = [], 0, 0
    for c in cases:
        t0 = time.time()
        tr, va = os.path.join(work, c["name"] + ".csv"), os.path.join(work, c["name"] + "_val.csv")
        for which, out in (("train", tr), ("validate", va)):
            run([args.oracle, "--cases", args.cases, "--case", c["name"], "--record", which, "--out", out])
        js = os.path.join(work, c["name"] + ".json")
        run([args.pamc, "diagnose", tr, "--validate", va, "--json", js, "--out-dir", os.path.join(work, c["name"] + "_report")])
        j = judge(c, json.load(open(js)))
        named += j["named"]
        fell += bool(j["fall"] and j["fall"] >= FALL)
        rows.append((c, j, time.time() - t0))
        print("%s: top probe %s, line %s -> %s" % (c["name"], j["top"], j["line"], "named" if j["named"] else "not named"),
              file=sys.stderr)
    print("| case | kind | effects added | top probe | strongest line | named (by) | validated RMSE final -> with it | falls | above the noise falls |")
    print("|---|---|---|---|---|---|---|---|---|")
    for c, j, secs in rows:
        fall = "%.1fx" % j["fall"] if j["fall"] else "-"
        above = "-" if not j["fall_above_noise"] else (
            "to the noise" if j["fall_above_noise"] == float("inf") else "%.0fx" % j["fall_above_noise"])
        after = "%.4g -> %.4g" % (j["final_val"], j["final_val"] / j["fall"]) if j["fall"] else "%.4g" % j["final_val"]
        print("| %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (c["name"], c["kind"], j["effects"], j["top"], j["line"],
              "yes (%s)" % j["by"] if j["named"] else "no", after, fall, above))
    print("\nnamed: %d of %d; the validated error falls %.0fx or more with the named probe: %d of %d" %
          (named, len(rows), FALL, fell, len(rows)))
    if args.require_named and named < len(rows):
        print("unseen_table: %d of %d cases not named" % (len(rows) - named, len(rows)), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
