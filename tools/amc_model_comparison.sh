#!/usr/bin/env bash
# Does a better model make PI + AMC track better? Emulator with a strong pressure lag (tau 120 ms);
# the plain Bouc-Wen model (pamc fit) against the diagnosed one (pamc diagnose adds pressure_lag),
# both used by the AMC's UKF and prediction on the paper's Table 2 trajectories.
# Usage: tools/amc_model_comparison.sh [WORKDIR]   (prints a markdown table; about a minute)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
P="$root/build/src/pamc"
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
echo "| ki | AMC mode | model | triangle 0.05 Hz max/RMSE | sine 0.05 Hz max/RMSE | sine 0.1 Hz max/RMSE |"
echo "|---|---|---|---|---|---|"
for ki in 0.15 1.5; do
  for mode in "1 0" "60 0" "60 0.3"; do
    set -- $mode
    label="eq. (17), horizon 1"
    [ "$1" != 1 ] && label="horizon $1, kc e_hat"
    [ "$2" != 0 ] && label="horizon $1, model inverse x$2"
    for m in plain.json diag/model.json; do
      row=$("$P" experiments --plant plant.json --model "$m" --only table2 --no-figures --ki "$ki" \
            --amc-horizon "$1" --amc-inverse "$2" --out out 2> /dev/null | grep -E "Hz " | awk '{print $NF}' | cut -d[ -f1 | tr '\n' '|')
      name=$([ "$m" = plain.json ] && echo "plain Bouc-Wen" || echo "diagnosed")
      echo "| $ki | $label | $name | ${row%|} |"
    done
  done
done
