#!/usr/bin/env bash
# The modelling loop and the model-based controllers over a real SocketCAN vcan0 (in the throw-away VM
# when this kernel has no CAN, vcan_setup.sh): the physics plant's emulator node at 50 Hz records the
# paper's u0 and u1 through the bus (`pamc controller --input`), diagnose learns a model from them on the
# host, and PI, AMC (eq. 17 as printed) and MBC track Table 2's triangle with it, each run over the bus.
# docs/CONTROL.md ("Over vcan").
#
#   tools/vcan_model_loop.sh [PAMC] [OUT_DIR]     # defaults: build/src/pamc, vcan_model_loop/
#
# Prints one line per controller: tracking RMSE and max error from the controller's own cycle records,
# and whether it ended in a fault. PERIOD_US (default 20000) sets the SYNC period.
set -euo pipefail
HERE=$(cd "$(dirname "$0")/.." && pwd)
if [ "${1:-}" = --inside ]; then  # in the VM (or on a host with vcan0): $2 = record|track, $3 = PAMC, $4 = dir
  what=$2; PAMC=$3; W=$4; P=${PERIOD_US:-20000}
  run_emulator() { "$PAMC" emulator --iface vcan0 --od "$HERE/od" --period-us "$P" > "$W/emulator_$1.txt" 2>&1 & EM=$!; sleep 1; }
  stop_emulator() { kill "$EM" 2>/dev/null; wait "$EM" 2>/dev/null || true; }
  if [ "$what" = record ]; then
    for rec in "u0 sine:0.1:0.2:2.9" "u1 sine:0.1:0.2:1.4"; do
      set -- $rec
      run_emulator "$1"
      "$PAMC" controller --iface vcan0 --od "$HERE/od" --period-us "$P" --input "$2" --preroll 1 --duration 40 \
        --out "$W/$1.csv" > "$W/record_$1.txt" 2>&1 || echo "record $1: controller exited $?" >> "$W/errors.txt"
      stop_emulator
    done
  else
    for kind in pi amc mbc; do
      run_emulator "$kind"
      "$PAMC" controller --iface vcan0 --od "$HERE/od" --period-us "$P" --controller "$kind" --model "$W/diagnosed/model.json" \
        --trajectory triangle:0.05:0.2:30 --preroll 1 --duration 40 --csv "$W/track_$kind.csv" \
        > "$W/track_$kind.txt" 2>&1 || echo "track $kind: controller exited $?" >> "$W/errors.txt"
      stop_emulator
    done
  fi
  exit 0
fi
PAMC=$(readlink -f "${1:-$HERE/build/src/pamc}"); OUT=${2:-vcan_model_loop}
mkdir -p "$OUT"; OUT=$(readlink -f "$OUT"); rm -f "$OUT/errors.txt"
cp "$PAMC" "$OUT/pamc"  # a rebuild during the run must not swap the binary
echo "recording u0 and u1 over vcan0 ..." >&2
"$HERE/vcan_setup.sh" auto vcan0 -- bash "$HERE/tools/vcan_model_loop.sh" --inside record "$OUT/pamc" "$OUT"
echo "diagnosing on the host ..." >&2
"$OUT/pamc" diagnose "$OUT/u0.csv" --validate "$OUT/u1.csv" --out-dir "$OUT/diagnosed" > "$OUT/diagnose.txt" 2>&1
tail -3 "$OUT/diagnose.txt" >&2
echo "tracking over vcan0 ..." >&2
"$HERE/vcan_setup.sh" auto vcan0 -- bash "$HERE/tools/vcan_model_loop.sh" --inside track "$OUT/pamc" "$OUT"
for kind in pi amc mbc; do
  # The controller's cycle records (--csv): t, yd, y, ... after the pre-roll.
  awk -F, -v k="$kind" 'NR == 1 { for (i = 1; i <= NF; i++) c[$i] = i; next }
    { e = $c["yd"] - $c["y"]; s += e * e; n++; if (e < 0) e = -e; if (e > m) m = e }
    END { printf "%-4s over vcan0: RMSE %.3f mm, max %.3f mm over %d cycles\n", k, sqrt(s / n), m, n }' "$OUT/track_$kind.csv"
  grep -h "fault" "$OUT/track_$kind.txt" | head -3 || true
done
[ ! -s "$OUT/errors.txt" ] || { cat "$OUT/errors.txt"; exit 1; }
