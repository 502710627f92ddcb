#!/usr/bin/env bash
# Runs with vcan0 up (on the host or inside the throw-away VM): emulator and controller as separate
# processes, candump recording the bus. Arguments: PAMC OD_DIR WORK_DIR.
set -u
PAMC="$1"; OD="$2"; W="$3"
candump -L vcan0 > "$W/bus.log" &
CD=$!
# 200 Hz: the VM runs under software emulation and the point here is the plumbing, not timing.
"$PAMC" emulator --iface vcan0 --od "$OD" --period-us 5000 > "$W/emulator.txt" 2>&1 &
EM=$!
sleep 0.5
"$PAMC" controller --iface vcan0 --od "$OD" --period-us 5000 --controller pi --ki 1.5 \
  --trajectory sine:0.5:15:5 --preroll 1 --duration 3 --csv "$W/controller.csv" --log "$W/controller.log" \
  > "$W/controller.txt" 2>&1
RC=$?
kill "$EM" 2>/dev/null; wait "$EM" 2>/dev/null
sleep 0.3
kill "$CD" 2>/dev/null; wait "$CD" 2>/dev/null
# The nodes' own log replays with can-utils' canplayer: every frame comes back on the bus.
candump -L vcan0 > "$W/replayed.log" &
CD=$!
sleep 0.3
canplayer -I "$W/controller.log"
sleep 0.5
kill "$CD" 2>/dev/null; wait "$CD" 2>/dev/null
# The monitor runs live on the interface (a short look while the player runs again).
canplayer -I "$W/controller.log" &
PL=$!
timeout 10 "$PAMC" monitor --iface vcan0 --od "$OD" --duration 2 > "$W/monitor.txt" 2>&1
kill "$PL" 2>/dev/null; wait "$PL" 2>/dev/null
exit $RC
