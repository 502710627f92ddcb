#!/usr/bin/env bash
# Real-time pacing of the rig on this machine: `pamc rig run --realtime` (in-process bus, 1 ms of bus time per ms
# of wall time) with normal scheduling and with SCHED_FIFO + mlockall, on an idle machine and next to
# a CPU hog (one busy loop per core). Prints a markdown table of the wake-up lateness (docs/PERFORMANCE.md).
# Usage: tools/rt_jitter.sh [PAMC] [SECONDS]   (SCHED_FIFO needs root or CAP_SYS_NICE)
set -eu
PAMC=${1:-build/src/pamc}
SEC=${2:-20}
[ -x "$PAMC" ] || { echo "rt_jitter.sh: $PAMC: not an executable (build first)" >&2; exit 2; }
OD=$(cd "$(dirname "$0")/.." && pwd)/od
hogs=()
stop_hogs() { for p in "${hogs[@]:-}"; do [ -n "$p" ] && kill "$p" 2>/dev/null; done; hogs=(); }
trap stop_hogs EXIT
echo "| load | scheduling | median [us] | p99 [us] | max [us] | wake-ups >= 1 period late |"
echo "|---|---|---|---|---|---|"
for load in idle hog; do
  if [ "$load" = hog ]; then
    for _ in $(seq "$(nproc)"); do (while :; do :; done) & hogs+=($!); done
  fi
  for prio in 0 80; do
    out=$("$PAMC" rig run --od "$OD" --realtime --priority "$prio" --duration "$SEC" --preroll 0.5 2>/dev/null | grep '^wake-up lateness')
    sched=$([ "$prio" = 0 ] && echo "normal" || echo "SCHED_FIFO $prio, mlockall")
    echo "$out" | sed -E "s/.*median ([0-9.]+) us, p99 ([0-9.]+) us, max ([0-9.]+) us; ([0-9]+) of ([0-9]+).*/| $load | $sched | \1 | \2 | \3 | \4 of \5 |/"
  done
  stop_hogs
done
