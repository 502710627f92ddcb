#!/usr/bin/env bash
# docs/MODELING.md, "From the probe to the effect": a rig whose rubber warms up after the start, a
# physical effect the catalogue once lacked. diagnose without it (--candidates=-warm_up) ends far above
# the noise and its drift probe says the output drifts with time; with warm_up written into the
# catalogue, diagnose adds it and the error falls to the noise; `pamc fit` with it reaches the noise too.
# Usage: tools/walkthrough_warm_up.sh [WORKDIR]   (about five minutes on 2 cores)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
P="$root/build/src/pamc"
W="${1:-$(mktemp -d)}"; mkdir -p "$W"; cd "$W"
cat > warm.json <<'JSON'
{"kind": "model", "effects": {"pressure_lag": {"enabled": true, "tau": 0.05, "slew": 1000}, "load": {"enabled": false},
             "saturation": {"enabled": false}, "friction_hysteresis": {"enabled": false}, "mass_spring": {"enabled": false},
             "warm_up": {"enabled": true, "tau": 20, "gain": 0.1, "shift": 0.5}},
 "stroke": {"enabled": false}}
JSON
"$P" emulate --plant warm.json --input random:3:-3:3 --duration 90 --out warm.csv
echo "== 1. diagnose with the catalogue as it was (without warm_up)"
"$P" diagnose warm.csv --candidates=-warm_up --json before.json --out-dir before 2>/dev/null | sed -n '/^Ladder/,$p'
echo "== 2. diagnose with warm_up in the catalogue"
"$P" diagnose warm.csv --json after.json --out-dir after 2>/dev/null | sed -n '/^Ladder/,$p'
echo "== 3. pamc fit with the structure diagnose found, on the whole record"
"$P" fit warm.csv --effects pressure_lag,warm_up --out warm_model.json 2>/dev/null | tail -3
echo "results in $W"
