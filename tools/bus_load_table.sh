#!/usr/bin/env bash
# The bus load of N muscles on one 1 Mbit/s bus, counted from the frames that went over the in-process
# bus (pamc rig run's "bus load:" line: every frame with its stuff bits at the rig's bit rate), for
# 1, 2, 4 and 8 muscles at 1 kHz and 500 Hz. Each rig: CiA 401 modules of four valve outputs (one RPDO
# of the four setpoints, one TPDO of the four pressures each) and a CiA 406 encoder per muscle (its
# position in a TPDO of its own), written as od/rigs/four_muscles.ini is. docs/PERFORMANCE.md.
#
#   tools/bus_load_table.sh [PAMC] [OUT_DIR]     # defaults: build/src/pamc, a temporary directory
set -euo pipefail
HERE=$(cd "$(dirname "$0")/.." && pwd)
PAMC=${1:-$HERE/build/src/pamc}
OUT=${2:-$(mktemp -d)}
mkdir -p "$OUT"

# rig N PERIOD_US: the rig file of N muscles.
rig() {
  local n=$1 period=$2 m c
  cat <<EOT
[bus]
bitrate = 1000000
period_us = $period
[controller]
node_id = 1
eds = $HERE/od/controller.eds
EOT
  for ((m = 0; m < (n + 3) / 4; m++)); do
    cat <<EOT
[slave.io$((m + 1))]
node_id = $((3 + m))
eds = $HERE/od/profile/analog401.eds
device_type = 0x000C0191
command_full_counts = 20000
feedback_full_counts = 20000
heartbeat_ms = 100
master_heartbeat_ms = 250
EOT
  done
  for ((c = 1; c <= n; c++)); do
    cat <<EOT
[slave.enc$c]
node_id = $((19 + c))
eds = $HERE/od/sensor.eds
device_type = 0x00080196
heartbeat_ms = 100
[channel.$c]
sensor = enc$c
position = 0x6004:00
valve = io$(((c - 1) / 4 + 1))
command = 0x6411:0$(((c - 1) % 4 + 1))
feedback = 0x6401:0$(((c - 1) % 4 + 1))
EOT
  done
}

echo "| muscles | rate | frames per cycle | bits per cycle | bus load (1 Mbit/s) |"
echo "|---|---|---|---|---|"
for period in 1000 2000; do
  for n in 1 2 4 8; do
    f="$OUT/muscles_${n}_${period}us.ini"
    rig "$n" "$period" > "$f"
    out=$("$PAMC" rig run --rig "$f" --period-us "$period" --duration 10 --preroll 1 2> "$OUT/muscles_${n}_${period}us.err") || {
      echo "muscles $n, $period us: pamc rig run failed ($OUT/muscles_${n}_${period}us.err)" >&2; exit 1; }
    line=$(grep '^bus load:' <<< "$out")
    # "bus load: 62.0 % of 1000 kbit/s (176984 frames, 15556136 bits with stuffing, over 25.102 s)"
    read -r load frames bits secs < <(sed -E 's/bus load: ([0-9.]+) % .*\(([0-9]+) frames, ([0-9]+) bits.* over ([0-9.]+) s\)/\1 \2 \3 \4/' <<< "$line")
    cycles=$(awk -v s="$secs" -v p="$period" 'BEGIN { printf "%.0f", s * 1e6 / p }')
    awk -v n="$n" -v p="$period" -v f="$frames" -v b="$bits" -v c="$cycles" -v l="$load" 'BEGIN {
      printf "| %d | %s | %.2f | %.0f | %s %% |\n", n, (p == 1000 ? "1 kHz" : "500 Hz"), f / c, b / c, l }'
  done
done
