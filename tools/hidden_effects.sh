#!/usr/bin/env bash
# The hidden-effect tables of docs/MODELING.md: the emulator with the plain Bouc-Wen core plus one or two
# catalogue effects, trained on random ramps and holds, validated on a different excitation, and
# `pamc diagnose` asked which effects are missing.
#   tools/hidden_effects.sh [WORKDIR]              the catalogue's cases (core k 6, seeds 1 / 2)
#   SET=unseen tools/hidden_effects.sh [WORKDIR]   other parameters, pairs, another core and other
#                                                  excitations than the tests and the table above use
# ONLY="name ..." limits either set. The last column is the validated RMSE over the emulator's sensor
# noise (0.004 mm rms and its 0.001 mm quantisation: 0.00401 mm).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
P="$root/build/src/pamc"
W="${1:-$(mktemp -d)}"; mkdir -p "$W"; cd "$W"
off='"pressure_lag":{"enabled":false},"load":{"enabled":false},"saturation":{"enabled":false},"friction_hysteresis":{"enabled":false},"mass_spring":{"enabled":false}'
if [ "${SET:-catalogue}" = unseen ]; then
  core='{"k":7.5,"rho":1.1,"b":15,"beta":0.45,"gamma":0.2}'
  train=random:21:-3:2; val=random:22:-2:3; order="none pressure_lag mass_spring delay dead_band saturation creep friction_hysteresis asymmetry lag+saturation delay+creep spring+dead_band asymmetry+lag"
  declare -A E=(
    [none]=''
    [pressure_lag]='"pressure_lag":{"enabled":true,"tau":0.15,"slew":1000}'
    [mass_spring]='"mass_spring":{"enabled":true,"fn":5,"zeta":0.2}'
    [delay]='"delay":{"enabled":true,"d":0.05}'
    [dead_band]='"dead_band":{"enabled":true,"threshold":0.6}'
    [saturation]='"saturation":{"enabled":true,"knee":20,"width":10}'
    [creep]='"creep":{"enabled":true,"fraction":0.15,"tau":1.5}'
    [friction_hysteresis]='"friction_hysteresis":{"enabled":true,"zmax":0.6,"delta":1.0}'
    [asymmetry]='"asymmetry":{"enabled":true,"gain":1.5,"w_up":0.8,"w_down":0.4}'
    [lag+saturation]='"pressure_lag":{"enabled":true,"tau":0.12,"slew":1000},"saturation":{"enabled":true,"knee":22,"width":8}'
    [delay+creep]='"delay":{"enabled":true,"d":0.04},"creep":{"enabled":true,"fraction":0.1,"tau":2}'
    [spring+dead_band]='"mass_spring":{"enabled":true,"fn":4,"zeta":0.25},"dead_band":{"enabled":true,"threshold":0.5}'
    [asymmetry+lag]='"asymmetry":{"enabled":true,"gain":1.5,"w_up":1.2,"w_down":0.4},"pressure_lag":{"enabled":true,"tau":0.1,"slew":1000}'
  )
else
  core='{"k":6}'
  train=random:1:-2.5:2.5; val=random:2:-2.5:2.5; order="none pressure_lag asymmetry creep mass_spring force_loop friction_hysteresis delay dead_band load saturation warm_up"
  declare -A E=(
    [none]=''
    [pressure_lag]='"pressure_lag":{"enabled":true,"tau":0.08,"slew":1000}'
    [asymmetry]='"asymmetry":{"enabled":true,"gain":2,"w_up":1.5,"w_down":0.3}'
    [creep]='"creep":{"enabled":true,"fraction":0.1,"tau":3}'
    [mass_spring]='"mass_spring":{"enabled":true,"fn":3,"zeta":0.3}'
    [friction_hysteresis]='"friction_hysteresis":{"enabled":true,"zmax":1.0,"delta":0.5}'
    [force_loop]='"force_loop":{"enabled":true,"fn":3,"zeta":0.3,"zmax":1.0,"delta":0.5}'
    [delay]='"delay":{"enabled":true,"d":0.03}'
    [dead_band]='"dead_band":{"enabled":true,"threshold":-1.0}'
    [load]='"load":{"enabled":true,"compliance":0.08}'
    [saturation]='"saturation":{"enabled":true,"knee":26,"width":6}'
    [warm_up]='"warm_up":{"enabled":true,"tau":15,"gain":0.1,"shift":0.5}'
  )
fi
echo "| hidden effect | named first | effects added | validated RMSE before -> after | fall | time | x noise |"
echo "|---|---|---|---|---|---|---|"
for e in ${ONLY:-$order}; do
  j="$off"; [ -n "${E[$e]}" ] && j="$off,${E[$e]}"
  echo "{\"kind\":\"model\",\"core\":$core,\"effects\":{$j},\"stroke\":{\"enabled\":false}}" > "h_$e.json"
  L1=(); L2=(); [ "$e" = load ] && L1=(--load random:7:0:40) && L2=(--load random:8:0:40)
  "$P" emulate --plant "h_$e.json" --input $train --duration 40 --out "tr_$e.csv" "${L1[@]}" > /dev/null
  "$P" emulate --plant "h_$e.json" --input $val --duration 30 --out "va_$e.csv" "${L2[@]}" > /dev/null
  "$P" diagnose "tr_$e.csv" --validate "va_$e.csv" --json "d_$e.json" > /dev/null 2>&1
  python3 - "$e" "d_$e.json" <<'PY'
import json, sys
e, f = sys.argv[1], sys.argv[2]
j = json.load(open(f))
l = [r for r in j["ladder"] if not r.get("probe")]  # a probe's rung is not part of the model
first = j["candidates"][0]["effect"] if len(l) > 1 else "-"
added = " + ".join(l[-1]["effects"]) or "(nothing)"
b, a = l[0]["rmse_val"], l[-1]["rmse_val"]
fall = "%.0fx" % (b / a) if len(l) > 1 else "-"
print("| %s | %s | %s | %.3g -> %.3g | %s | %.0f s | %.2f |" % (e, first, added, b, a, fall, j["seconds"], a / 0.00401))
PY
done
