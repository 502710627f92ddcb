#!/usr/bin/env bash
# Does a better model make PI + AMC track better? Emulator with a strong pressure lag (tau 120 ms);
# the plain Bouc-Wen model (pamc fit) against the diagnosed one (pamc diagnose adds pressure_lag),
# both used by the AMC's UKF and prediction on the paper's Table 2 trajectories, in the paper's form
# (eq. 17/18) and in the predictive form (--amc-inverse), with the automatic horizon and fixed ones.
# Usage: tools/amc_model_comparison.sh [WORKDIR]   (prints a markdown table; about two minutes)
set -euo pipefail
if [ "${1:-}" = "-h" ] || [ "${1:-}" = "--help" ]; then sed -n 2,6p "$0" | cut -c3-; exit 0; fi
root="$(cd "$(dirname "$0")/.." && pwd)"
P="$root/build/src/pamc"
[ -x "$P" ] || { echo "amc_model_comparison: $P not built (run tools/build.sh)" >&2; exit 1; }
W="${1:-$(mktemp -d)}"; mkdir -p "$W"; cd "$W"
cat > plant.json <<'JSON'
{"effects":{"pressure_lag":{"enabled":true,"tau":0.12,"slew":1000},"load":{"enabled":false},"saturation":{"enabled":false},
 "friction_hysteresis":{"enabled":false},"mass_spring":{"enabled":false}},"stroke":{"enabled":false}}
JSON
"$P" emulate --plant plant.json --input random:1:-3:3 --duration 60 --out train.csv > /dev/null
"$P" emulate --plant plant.json --input random:2:-3:3 --duration 40 --out val.csv > /dev/null
"$P" fit train.csv --out plain.json --quiet > /dev/null
"$P" diagnose train.csv --validate val.csv --report diag > diagnose.txt 2> /dev/null
echo "diagnosed: $(grep -E '^(Added|No effect)' diagnose.txt | cut -d: -f1)"
echo
echo "| AMC form | horizon [samples] | model | triangle 0.05 Hz max/RMSE | sine 0.05 Hz max/RMSE | sine 0.1 Hz max/RMSE | command noise rms(du) [V] |"
echo "|---|---|---|---|---|---|---|"
for mode in "1 0" "0 1" "10 1" "30 1"; do
  set -- $mode
  label="paper, eq. (17)/(18)"
  [ "$2" != 0 ] && label="predictive, x = $2"
  for m in plain.json diag/model.json; do
    out=$("$P" experiments --plant plant.json --model "$m" --only table2 --no-figures \
          --amc-horizon "$1" --amc-inverse "$2" --out out 2> /dev/null)
    row=$(echo "$out" | grep -E "Hz " | awk '{print $NF}' | cut -d[ -f1 | tr '\n' '|')
    h=$(echo "$out" | sed -n 's/.*AMC horizon \([0-9]*\).*/\1/p' | head -1)
    du=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == "u") c = i; next }
                  NR > 2 { d = $c - p; s += d * d; n++ } { p = $c } END { printf "%.4f", sqrt(s / n) }' out/sine_0.1Hz_amc.csv)
    name=$([ "$m" = plain.json ] && echo "plain Bouc-Wen" || echo "diagnosed")
    echo "| $label | ${h:-$1} | $name | ${row%|} | $du |"
  done
done
