#!/usr/bin/env bash
# End-to-end on a real SocketCAN vcan0 (inside a throw-away VM when this kernel has no CAN):
# controller and emulator as separate processes, can-utils' candump recording the bus, and the
# decoded log must reproduce what the controller saw. Arguments: PAMC SOURCE_DIR. Exit 77 = skipped.
set -u
PAMC="$(readlink -f "$1")"; SRC="$(readlink -f "$2")"
W="$(mktemp -d /tmp/pamc-e2e.XXXXXX)"
trap 'rm -rf "$W"' EXIT
if ! command -v candump > /dev/null; then
  if [ "$(id -u)" -eq 0 ]; then DEBIAN_FRONTEND=noninteractive apt-get install -y -qq can-utils > /dev/null 2>&1; fi
  command -v candump > /dev/null || { echo "SKIP: can-utils (candump) not installed"; exit 77; }
fi
"$SRC/vcan_setup.sh" auto vcan0 -- bash "$SRC/tests/e2e/inside_vm.sh" "$PAMC" "$SRC/od" "$W"
rc=$?
if [ $rc -eq 124 ] || [ $rc -eq 125 ]; then
  echo "SKIP: could not bring up vcan0 or the VM (vcan_setup.sh exit $rc)"; exit 77
fi
echo "--- controller"; cat "$W/controller.txt"
echo "--- emulator"; cat "$W/emulator.txt"
[ $rc -eq 0 ] || { echo "FAIL: controller exited $rc"; exit 1; }
fails=0
check() { local n="$1"; shift; if "$@"; then echo "ok: $n"; else echo "FAIL: $n"; fails=$((fails+1)); fi; }
check "candump recorded the bus" test "$(wc -l < "$W/bus.log")" -gt 1000
check "the controller logged the bus too" test "$(wc -l < "$W/controller.log")" -gt 1000
check "boot-up of all three nodes in the log" test "$(grep -cE ' 70[123]#00$' "$W/bus.log")" -ge 3
"$PAMC" decode "$W/bus.log" --od "$SRC/od" --out "$W/decoded.csv"
check "decode succeeded" test -s "$W/decoded.csv"
# The controller's y at cycle k is the position the sensor sent in cycle k-1: the decoded position
# series must contain the controller's series, value for value.
awk -F, 'NR>1 {printf "%.3f\n", $3}' "$W/controller.csv" > "$W/ctrl_y.txt"
awk -F, 'NR>1 && $3 != "" {printf "%.3f\n", $3}' "$W/decoded.csv" > "$W/dec_y.txt"
n_ctrl=$(wc -l < "$W/ctrl_y.txt")
match=$(awk 'NR==FNR {d[NR]=$1; n=NR; next} {c[FNR]=$1; m=FNR}
  END { best=0
        for (off = 0; off + 50 <= n; off++) { ok = 1
          for (i = 1; i <= 50 && ok; i++) if (d[off+i] != c[i]) ok = 0
          if (ok) { cnt = 0; for (i = 1; i <= m && off+i <= n; i++) if (d[off+i] == c[i]) cnt++
                    if (cnt > best) best = cnt } }
        print best }' "$W/dec_y.txt" "$W/ctrl_y.txt")
echo "controller cycles: $n_ctrl, matched in the decoded log: $match"
check "decoded log reproduces the controller's positions (>= 99 %)" test $((match * 100)) -ge $((n_ctrl * 99))
check "the run is 3 s at 200 Hz" test "$n_ctrl" -ge 590
"$PAMC" fit "$W/decoded.csv" --generations 5 --quiet > /dev/null
check "the decoded log is a measurement the modelling tools read" test $? -eq 0
n_log=$(wc -l < "$W/controller.log"); n_rep=$(wc -l < "$W/replayed.log")
echo "controller log: $n_log frames, replayed by canplayer: $n_rep"
check "canplayer replays the node's log frame for frame" test "$n_rep" -eq "$n_log"
check "the live monitor decoded the bus" grep -q "sensor.position_value" "$W/monitor.txt"
echo "$((9 - fails)) passed, $fails failed"
[ $fails -eq 0 ]
