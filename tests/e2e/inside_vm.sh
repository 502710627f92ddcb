#!/usr/bin/env bash
# Runs with vcan0 up (on the host or inside the throw-away VM): emulator and controller as separate
# processes, candump recording the bus; then the same again with kernel-level faults injected.
# Arguments: PAMC OD_DIR WORK_DIR.
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

# Kernel-level faults (the in-process rig covers the rest, `pamc rig --faults`): a full transmit
# queue - the interface rate-limited by a tbf qdisc and flooded by higher-priority frames, so writes
# fail with ENOBUFS - and error frames (bus off, then restarted) as a CAN driver sends them.
# Timeline at 200 Hz: control from ~1.5 s, flood 1 s from 3.5 s, bus off at 8.5 s for 0.3 s, end ~16 s
# (a fault clears 500 cycles = 2.5 s after its cause).
candump -L vcan0,0:0,#FFFFFFFF > "$W/fault_bus.log" &
CD=$!
"$PAMC" emulator --iface vcan0 --od "$OD" --period-us 5000 > "$W/fault_emulator.txt" 2>&1 &
EM=$!
sleep 0.5
"$PAMC" controller --iface vcan0 --od "$OD" --period-us 5000 --controller pi --ki 1.5 \
  --trajectory const:15 --preroll 1 --duration 14 --csv "$W/fault_controller.csv" \
  > "$W/fault_controller.txt" 2>&1 &
CT=$!
sleep 3
tc qdisc replace dev vcan0 root tbf rate 100kbit burst 1600 limit 2000 > "$W/fault_tc.txt" 2>&1
date +%s.%N > "$W/fault_t_flood.txt"
cangen vcan0 -g 0 -I 001 -L 8 -i > "$W/fault_cangen.txt" 2>&1 &
CG=$!
sleep 1
kill "$CG" 2>/dev/null; wait "$CG" 2>/dev/null
tc -s qdisc show dev vcan0 >> "$W/fault_tc.txt" 2>&1
tc qdisc del dev vcan0 root >> "$W/fault_tc.txt" 2>&1
sleep 4
date +%s.%N > "$W/fault_t_busoff.txt"
cansend vcan0 20000040#0000000000000000   # CAN_ERR_BUSOFF
sleep 0.3
cansend vcan0 20000100#0000000000000000   # CAN_ERR_RESTARTED
wait "$CT"
echo $? > "$W/fault_rc.txt"
kill "$EM" 2>/dev/null; wait "$EM" 2>/dev/null
sleep 0.3
kill "$CD" 2>/dev/null; wait "$CD" 2>/dev/null
exit $RC
