#!/usr/bin/env bash
# SYNC-to-setpoint latency and jitter of the controller node on SocketCAN vcan0, without and with
# background traffic from cangen. Needs vcan0 up (sudo ./vcan_setup.sh), or run the whole script in
# the VM: ./vcan_setup.sh vm -- tools/bench_socketcan.sh   (timings from a software-emulated VM say
# nothing about a real host).  Usage: tools/bench_socketcan.sh [SECONDS] [PERIOD_US]
set -u
root="$(cd "$(dirname "$0")/.." && pwd)"
PAMC="$root/build/src/pamc"; OD="$root/od"
secs="${1:-10}"; period="${2:-1000}"
run() {
  local label="$1"; shift
  "$PAMC" emulator --iface vcan0 --od "$OD" --period-us "$period" --duration 600 > /dev/null 2>&1 &
  local em=$!
  local bg=""
  if [ "$label" = "with cangen" ]; then
    # Random frames with IDs below the PDOs' (higher priority), 0.1 ms gap: ~30 % extra bus load.
    cangen vcan0 -g 0.1 -I 50 -L 8 -D i > /dev/null 2>&1 &
    bg=$!
  fi
  sleep 0.3
  echo "== $label ($secs s at $period us)"
  "$PAMC" controller --iface vcan0 --od "$OD" --period-us "$period" --controller pi --preroll 1 \
    --duration "$secs" --trajectory sine:0.5:15:5 --realtime 2>&1 | grep -E "latency|jitter|cycles|warning"
  [ -n "$bg" ] && kill "$bg" 2>/dev/null
  kill "$em" 2>/dev/null; wait 2>/dev/null
}
run "quiet bus"
run "with cangen"
