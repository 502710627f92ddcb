#!/usr/bin/env bash
# The model in step with the physics, judged on data no model code made: the plain case of the oracle
# (tests/oracle, its own continuous-time simulator) compared with the model holding the case's TRUE
# parameters. Aligned: within 1.2x the record's noise and no sample off by more than 0.1 mm (input steps
# included). Eq. (6) as printed, the same parameters: well above the noise (what the aligned form mends).
#   aligned_truth.sh PAMC ORACLE CASES_JSON
set -euo pipefail
P="$1"; O="$2"; CASES="$3"
W="$(mktemp -d)"; trap 'rm -rf "$W"' EXIT
"$O" --cases "$CASES" --case plain --record train --out "$W/plain.csv" > /dev/null
python3 - "$CASES" "$W" <<'PY'
import json, sys
cases = {c["name"]: c for c in json.load(open(sys.argv[1]))["cases"]}
core = cases["plain"]["core"]
for form in ("aligned", "printed"):
    json.dump({"format": "pamc-model/1", "core": core, "output_form": form, "effects": []},
              open("%s/true_%s.json" % (sys.argv[2], form), "w"))
PY
"$P" compare "$W/true_aligned.json" "$W/plain.csv" --json "$W/aligned.json" > /dev/null
"$P" compare "$W/true_printed.json" "$W/plain.csv" --json "$W/printed.json" > /dev/null
python3 - "$CASES" "$W" <<'PY'
import json, math, sys
case = {c["name"]: c for c in json.load(open(sys.argv[1]))["cases"]}["plain"]
noise = math.sqrt(case["noise"] ** 2 + 0.001 ** 2 / 12)
a = json.load(open(sys.argv[2] + "/aligned.json"))
p = json.load(open(sys.argv[2] + "/printed.json"))
print("noise %.5f mm; aligned RMSE %.5f (%.2fx), max %.4f mm; printed RMSE %.5f (%.2fx), max %.4f mm"
      % (noise, a["rmse"], a["rmse"] / noise, a["max_abs"], p["rmse"], p["rmse"] / noise, p["max_abs"]))
ok = a["rmse"] <= 1.2 * noise and a["max_abs"] < 0.1 and p["rmse"] > 2 * noise
sys.exit(0 if ok else 1)
PY
