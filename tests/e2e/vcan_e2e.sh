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

# Kernel-level faults (inside_vm.sh): ENOBUFS under a flood, error frames bus off / restarted.
echo "--- controller under faults"; cat "$W/fault_controller.txt"
echo "--- tc"; cat "$W/fault_tc.txt"
# Reaction: the first safe setpoint (0x203#0000: 0 V) on the bus after the flood started / after the
# bus-off error frame, in 5 ms periods (informational: the VM runs under software emulation).
for ev in flood busoff; do
  t0=$(cat "$W/fault_t_$ev.txt" 2>/dev/null)
  [ -n "$t0" ] && awk -v t0="$t0" -v ev="$ev" '{ t = substr($1, 2, length($1) - 2) + 0 }
    t > t0 && $3 ~ /^203#0000$/ { printf "%s: first safe setpoint on the bus %.1f ms = %.1f periods after the fault\n", ev, (t - t0) * 1e3, (t - t0) * 200; found = 1; exit }
    END { if (!found) print ev ": no safe setpoint on the bus" }' "$W/fault_bus.log"
done
check "the controller ran through the faults (exit 0)" test "$(cat "$W/fault_rc.txt" 2>/dev/null)" = 0
cycles=$(sed -n 's/^cycles \([0-9]*\),.*/\1/p' "$W/fault_controller.txt")
echo "cycles under faults: ${cycles:-none} (15 s at 200 Hz: 3000)"
check "the loop did not block while writes failed (>= 2900 cycles)" test "${cycles:-0}" -ge 2900
queued=$(sed -n 's/.*tx queued \([0-9]*\),.*/\1/p' "$W/fault_controller.txt")
expired=$(sed -n 's/.*tx expired \([0-9]*\),.*/\1/p' "$W/fault_controller.txt")
echo "frames queued behind ENOBUFS/EAGAIN: ${queued:-?}, dropped at their deadline: ${expired:-?}"
check "the kernel refused frames (ENOBUFS/EAGAIN) and the transport queued them" test "${queued:-0}" -gt 0
check "EMCY 0x8110 (CAN overrun) on the bus" grep -qE ' 081#1081' "$W/fault_bus.log"
check "error frames reached the controller: EMCY 0x8140 (recovered from bus off)" grep -qE ' 081#4081' "$W/fault_bus.log"
check "EMCY error reset after each fault" test "$(grep -cE ' 081#0000' "$W/fault_bus.log")" -ge 2
check "the controller reported both faults cleared" test "$(grep -c 'fault cleared' "$W/fault_controller.txt")" -ge 2
last_fault=$(tail -n 1 "$W/fault_controller.csv" | awk -F, '{print $8}')
check "in control at the end (fault column 0)" test "${last_fault:-x}" = 0
echo "$((18 - fails)) passed, $fails failed"
[ $fails -eq 0 ]
