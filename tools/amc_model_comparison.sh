#!/usr/bin/env bash
# Does a better model make PI + AMC track better? For each emulator below (the Bouc-Wen core plus
# effects), the plain Bouc-Wen model (`pamc fit`) and the model `pamc diagnose` returns are both
# given to the controller, in the paper's AMC form (eq. 17/18, horizon 1) and in the predictive
# form (--amc-inverse 1, automatic horizon), on the paper's Table 2 trajectories.
# Usage: tools/amc_model_comparison.sh [WORKDIR]   (prints a markdown table; about two minutes)
set -euo pipefail
if [ "${1:-}" = "-h" ] || [ "${1:-}" = "--help" ]; then sed -n 2,6p "$0" | cut -c3-; exit 0; fi
root="$(cd "$(dirname "$0")/.." && pwd)"
P="$root/build/src/pamc"
[ -x "$P" ] || { echo "amc_model_comparison: $P not built (run tools/build.sh)" >&2; exit 1; }
W="${1:-$(mktemp -d)}"; mkdir -p "$W"; cd "$W"
off='"load":{"enabled":false},"saturation":{"enabled":false},"friction_hysteresis":{"enabled":false},"mass_spring":{"enabled":false}'
declare -A PLANT=(
  [lag120]='"pressure_lag":{"enabled":true,"tau":0.12,"slew":1000}'
  [lag40_delay30]='"pressure_lag":{"enabled":true,"tau":0.04,"slew":1000},"delay":{"enabled":true,"d":0.03}'
  [lag40_creep]='"pressure_lag":{"enabled":true,"tau":0.04,"slew":1000},"creep":{"enabled":true,"fraction":0.1,"tau":3}'
)
declare -A LABEL=(
  [lag120]='pressure lag 120 ms'
  [lag40_delay30]='pressure lag 40 ms + delay 30 ms'
  [lag40_creep]='pressure lag 40 ms + creep 10 %, 3 s'
)
echo "| emulator | diagnosed effects | AMC form | model | horizon | triangle 0.05 Hz max/RMSE | sine 0.05 Hz max/RMSE | sine 0.1 Hz max/RMSE | rms(du) [V] |"
echo "|---|---|---|---|---|---|---|---|---|"
for p in lag120 lag40_delay30 lag40_creep; do
  echo "{\"kind\":\"model\",\"effects\":{$off,${PLANT[$p]}},\"stroke\":{\"enabled\":false}}" > "$p.json"
  "$P" emulate --plant "$p.json" --input random:1:-3:3 --duration 60 --out "$p.train.csv" > /dev/null
  "$P" emulate --plant "$p.json" --input random:2:-3:3 --duration 40 --out "$p.val.csv" > /dev/null
  "$P" fit "$p.train.csv" --out "$p.plain.json" --quiet > /dev/null
  "$P" diagnose "$p.train.csv" --validate "$p.val.csv" --json "$p.diag.json" --out-dir "$p.diag" > /dev/null 2>&1
  effects=$(python3 -c 'import json,sys; print(" + ".join(json.load(open(sys.argv[1]))["ladder"][-1]["effects"]) or "(none)")' "$p.diag.json")
  for x in 0 1; do
    form="paper, eq. (17)/(18)"; H=1
    [ "$x" = 1 ] && form="predictive, x = 1" && H=0
    for m in plain diag; do
      mf="$p.plain.json"; name="plain Bouc-Wen"
      [ "$m" = diag ] && mf="$p.diag/model.json" && name="diagnosed"
      # ki 1.3: the gains this table was first measured with (the default ki is 3).
      out=$("$P" experiments --plant "$p.json" --model "$mf" --only table2 --no-figures --ki 1.3 \
            --amc-horizon "$H" --amc-inverse "$x" --out "out_$p" 2> /dev/null)
      # The PID+AMC column (5th field) of Table 2's three rows (the first three: later tables repeat them).
      row=$(echo "$out" | grep -E "^(triangle|sine)_" | head -3 | awk '{print $5}' | cut -d[ -f1 | paste -sd'|' | sed 's/|/ | /g')
      h=$(echo "$out" | sed -n 's/.*AMC horizon \([0-9]*\).*/\1/p' | head -1)
      du=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == "u") c = i; next }
                    NR > 2 { d = $c - q; s += d * d; n++ } { q = $c } END { printf "%.4f", sqrt(s / n) }' "out_$p/sine_0.1Hz_amc.csv")
      echo "| ${LABEL[$p]} | $effects | $form | $name | $h | $row | $du |"
    done
  done
done
