#!/usr/bin/env bash
# Nothing lost on a crash (docs/RELIABILITY.md, "Nothing lost on a crash"): running pamc processes are
# killed with SIGKILL in mid-run and what they left on disk is checked. Hardware-free.
#  1. The rig paced in real time (`pamc rig run --realtime`), logging like the nodes on SocketCAN (frames and
#     cycle records through the logger thread's rings): after the kill every complete line of the
#     candump log and of the CSV parses, only the last line may be cut off, `pamc decode` and the CSV
#     reader (`pamc fit`) accept the files, and the records on disk reach to within a few cycles of what
#     the rig had computed (its --progress marker, written as each cycle is computed).
#  2. `pamc fit --out m.json` killed at random times around the end of its run, with and without an old
#     m.json: m.json is absent, the old file or the new one, always complete; no temporary files.
#  3. `pamc experiments` killed in mid-run: every file in its output directory is complete, no temporaries.
# Arguments: PAMC SOURCE_DIR [KILLS]. PAMC_KILL_KEEP=1 keeps the work directory.
set -u
PAMC="$(readlink -f "$1")"; SRC="$(readlink -f "$2")"; KILLS="${3:-5}"
W="$(mktemp -d /tmp/pamc-kill.XXXXXX)"
if [ "${PAMC_KILL_KEEP:-0}" = 1 ]; then trap 'echo "work directory kept: $W"' EXIT; else trap 'rm -rf "$W"' EXIT; fi
fails=0
passes=0
check() {  # name, condition...
  local name="$1"; shift
  if "$@"; then passes=$((passes + 1)); else echo "FAIL: $name"; fails=$((fails + 1)); fi
}
ends_with_newline() { [ ! -s "$1" ] || [ "$(tail -c 1 "$1" | od -An -c | tr -d ' ')" = '\n' ]; }
no_temporaries() { [ -z "$(find "$1" -name '*.tmp*' -print -quit)" ]; }
# Sleeps a random time between $1 and $2 seconds (decimals).
sleep_between() { sleep "$(awk -v a="$1" -v b="$2" -v r="$RANDOM" 'BEGIN { printf "%.3f", a + (b - a) * r / 32767 }')"; }

# ---- 1. the live rig -----------------------------------------------------------------------------------
max_lost_csv=0; max_lost_log=0; partial_logs=0; partial_csvs=0; losses=""
for k in $(seq 1 "$KILLS"); do
  d="$W/rig$k"; mkdir -p "$d"
  "$PAMC" rig run --od "$SRC/od" --realtime --duration 60 --preroll 0.5 --controller pi \
    --log "$d/run.log" --csv "$d/run.csv" --progress "$d/progress.txt" > "$d/out.txt" 2> "$d/err.txt" &
  pid=$!
  sleep_between 1.5 3.0
  kill -9 "$pid"
  wait "$pid" 2> /dev/null
  echo "--- rig kill $k: $(wc -l < "$d/run.log") log lines, $(wc -l < "$d/run.csv") CSV lines, last marker: $(tail -n 1 "$d/progress.txt")"
  check "rig $k: the run had started" test -s "$d/progress.txt" -a -s "$d/run.log" -a -s "$d/run.csv"
  # candump log: every complete line is a frame; only the last line may be cut off.
  n=$(wc -l < "$d/run.log")
  bad=$(head -n "$n" "$d/run.log" | grep -cvE '^\([0-9]+\.[0-9]{6}\) vcan0 [0-9A-F]{3}#([0-9A-F]{2}){0,8}$')
  check "rig $k: every complete log line is a frame ($bad are not)" test "$bad" -eq 0
  ends_with_newline "$d/run.log" || partial_logs=$((partial_logs + 1))
  "$PAMC" decode "$d/run.log" --od "$SRC/od" --out "$d/decoded.csv" > "$d/decode.txt" 2> "$d/decode_err.txt"
  check "rig $k: pamc decode accepts the log" test $? -eq 0 -a -s "$d/decoded.csv"
  if ! ends_with_newline "$d/run.log"; then
    check "rig $k: decode warns of the cut-off last line" grep -q "truncated last line ignored" "$d/decode_err.txt"
  fi
  # CSV: the header, then complete lines of 9 numbers; the reader accepts it.
  check "rig $k: CSV header" test "$(head -n 1 "$d/run.csv")" = "t,yd,y,u,u_n,u_c,y_hat,fault,latency_us"
  n=$(wc -l < "$d/run.csv")
  bad=$(head -n "$n" "$d/run.csv" | awk -F, 'NR > 1 { for (i = 1; i <= NF; i++) if ($i !~ /^-?[0-9]+(\.[0-9]+)?$/) { b++; break } if (NF != 9) b++ } END { print b + 0 }')
  check "rig $k: every complete CSV line has 9 numbers ($bad do not)" test "$bad" -eq 0
  ends_with_newline "$d/run.csv" || partial_csvs=$((partial_csvs + 1))
  "$PAMC" fit "$d/run.csv" --generations 1 --population 4 --threads 1 --quiet > "$d/fit.txt" 2> "$d/fit_err.txt"
  check "rig $k: the CSV reader accepts the CSV (pamc fit)" test $? -eq 0
  if ! ends_with_newline "$d/run.csv"; then
    check "rig $k: the reader warns of the cut-off last line" grep -q "truncated last line ignored" "$d/fit_err.txt"
  fi
  # What was lost: the rig's last marker (computed) against the last complete record on disk.
  marker=$(grep -E '^cycle [0-9]+ t [0-9.]+ bus_us [0-9]+$' "$d/progress.txt" | tail -n 1)
  t_computed=$(echo "$marker" | awk '{ print $4 }'); bus_computed=$(echo "$marker" | awk '{ print $6 }')
  t_written=$(head -n "$n" "$d/run.csv" | tail -n 1 | cut -d, -f1)
  lost_csv=$(awk -v a="$t_computed" -v b="$t_written" 'BEGIN { printf "%d", (a - b) * 1000 + 0.5 }')
  # The log's time stamps: the first frame (boot-up) is bus time 0.
  first=$(head -n 1 "$d/run.log" | sed -E 's/^\(([0-9]+)\.([0-9]{6})\).*/\1\2/')
  last=$(head -n "$(wc -l < "$d/run.log")" "$d/run.log" | tail -n 1 | sed -E 's/^\(([0-9]+)\.([0-9]{6})\).*/\1\2/')
  lost_log=$(awk -v c="$bus_computed" -v f="$first" -v l="$last" 'BEGIN { printf "%d", (c - (l - f)) / 1000 }')
  echo "    computed up to t = $t_computed s (bus $bus_computed us); on disk: CSV to t = $t_written s ($lost_csv cycles behind), log to bus $((last - first)) us ($lost_log ms behind)"
  # The logger thread writes once per period; when it does not get the CPU (a loaded machine) the ring
  # holds more. Every kill: at most 20 cycles; the median over the kills: at most 2 (below).
  check "rig $k: CSV at most 20 cycles behind what was computed ($lost_csv)" test "$lost_csv" -le 20
  check "rig $k: log at most 20 ms behind what was computed ($lost_log)" test "$lost_log" -le 20
  losses="$losses $lost_csv/$lost_log"
  [ "$lost_csv" -gt "$max_lost_csv" ] && max_lost_csv=$lost_csv
  [ "$lost_log" -gt "$max_lost_log" ] && max_lost_log=$lost_log
  check "rig $k: no temporary files" no_temporaries "$d"
done
median() { tr ' ' '\n' | grep -v '^$' | sort -n | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] + 0 }'; }
median_csv=$(echo "$losses" | tr ' ' '\n' | cut -d/ -f1 | tr '\n' ' ' | median)
median_log=$(echo "$losses" | tr ' ' '\n' | cut -d/ -f2 | tr '\n' ' ' | median)
echo "rig: $KILLS kills; records lost: median $median_csv cycles (CSV), $median_log ms (log), at most $max_lost_csv and $max_lost_log; per kill (CSV cycles/log ms):$losses; cut-off last line in $partial_logs logs, $partial_csvs CSVs"
check "rig: median loss at most 2 cycles (CSV: $median_csv, log: $median_log ms)" test "$median_csv" -le 2 -a "$median_log" -le 2

# ---- 2. pamc fit --out m.json ----------------------------------------------------------------------------
d="$W/fit"; mkdir -p "$d"
"$PAMC" emulate --duration 20 --out "$d/data.csv" > /dev/null
fit_args=(fit "$d/data.csv" --out "$d/m.json" --threads 1 --population 20 --generations 30 --quiet)
start=$(date +%s%N); "$PAMC" "${fit_args[@]}" > /dev/null 2>&1; check "fit runs to the end" test $? -eq 0; end=$(date +%s%N)
cp "$d/m.json" "$d/complete.json"
T=$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.3f", (b - a) / 1e9 }')
valid_model() { "$PAMC" rig run --od "$SRC/od" --model "$1" --controller amc --duration 0.01 --preroll 0.01 > /dev/null 2>&1; }
absent=0; old=0; new=0
for k in $(seq 1 $((2 * KILLS))); do
  # Even kills replace an old m.json (dated 2000), odd ones write a new one.
  if [ $((k % 2)) -eq 0 ]; then cp "$d/complete.json" "$d/m.json"; touch -d '2000-01-01' "$d/m.json"; else rm -f "$d/m.json"; fi
  "$PAMC" "${fit_args[@]}" > /dev/null 2>&1 &  # pamc itself in the background, so that the kill hits it
  pid=$!
  sleep_between "$(awk -v t="$T" 'BEGIN { print 0.5 * t }')" "$(awk -v t="$T" 'BEGIN { print 1.2 * t }')"
  kill -9 "$pid" 2> /dev/null
  wait "$pid" 2> /dev/null
  if [ ! -e "$d/m.json" ]; then absent=$((absent + 1))
  elif [ "$(stat -c %Y "$d/m.json")" -lt 1000000000 ]; then old=$((old + 1)); check "fit kill $k: the old m.json intact" cmp -s "$d/m.json" "$d/complete.json"
  else new=$((new + 1)); check "fit kill $k: the new m.json is complete" valid_model "$d/m.json"; fi
  check "fit kill $k: no temporary files" no_temporaries "$d"
done
check "every m.json left behind is a complete model" valid_model "$d/complete.json"
echo "fit: $((2 * KILLS)) kills in 0.5-1.2 x its run time ($T s): m.json absent $absent, old $old, new $new times; never partial"

# ---- 3. pamc experiments ------------------------------------------------------------------------------------
d="$W/experiments"; mkdir -p "$d"
"$PAMC" experiments --out-dir "$d/results" --only table1 --no-figures > "$d/out.txt" 2>&1 & pid=$!
sleep_between 2 4
kill -9 "$pid" 2> /dev/null
wait "$pid" 2> /dev/null
files=$(find "$d/results" -type f 2> /dev/null | wc -l)
echo "experiments: killed with $files files in its output directory: $(ls "$d/results" 2> /dev/null | tr '\n' ' ')"
check "experiments: no temporary files" no_temporaries "$d"
for f in $(find "$d/results" -type f 2> /dev/null); do
  check "experiments: $(basename "$f") ends with a newline" ends_with_newline "$f"
  case "$f" in
    *.json) case "$f" in */model.json) check "experiments: model.json is a complete model" valid_model "$f" ;; esac ;;
    *.csv) check "experiments: $(basename "$f") is complete" test "$(awk -F, 'NR == 1 { n = NF } NF != n { b++ } END { print b + 0 }' "$f")" -eq 0 ;;
  esac
done

echo "$passes passed, $fails failed"
test $fails -eq 0
