#!/usr/bin/env bash
# Recording on the rig (`--input SPEC --out FILE` of `pamc rig run` and `pamc controller`): an open-loop
# record on the in-process bus that fit and diagnose read, the refusals (--input with --trajectory, a bad
# spec) with one line, a non-zero exit and no file, and the new input forms through `pamc emulate`.
set -u
PAMC="$1"
SRC="$(cd "$(dirname "$0")/../.." && pwd)"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fails=0
passes=0
check() {  # name, condition...
  local name="$1"; shift
  if "$@"; then passes=$((passes + 1)); else echo "FAIL: $name"; fails=$((fails + 1)); fi
}

# A 5 s record in virtual time: t from 0 at 1 ms, u within the valve's range, y and the valve's pressure.
"$PAMC" rig run --od "$SRC/od" --input random:1:-3:3 --duration 5 --preroll 1 --out "$work/rec.csv" \
  > "$work/rec.txt" 2> "$work/rec_err.txt"
check "rig run --input --out exits 0" test $? -eq 0
check "the record has the measurement's header" test "$(head -1 "$work/rec.csv")" = "t,u,y,p"
check "the record has 5 s of 1 ms samples ($(($(wc -l < "$work/rec.csv") - 1)))" test "$(wc -l < "$work/rec.csv")" -ge 4990
check "t starts at 0 with a 1 ms step" awk -F, 'NR == 2 && $1 + 0 != 0 { exit 1 } NR == 3 && ($1 - 0.001)^2 > 1e-18 { exit 1 }' "$work/rec.csv"
check "u stays within [-3, 3]" awk -F, 'NR > 1 && ($2 < -3 || $2 > 3) { exit 1 }' "$work/rec.csv"
check "the run says what it wrote" grep -q "wrote $work/rec.csv: [0-9]* samples" "$work/rec.txt"
check "no tracking error is claimed for an open-loop input" test -z "$(grep "tracking error" "$work/rec.txt")"
"$PAMC" diagnose "$work/rec.csv" --candidates pressure_lag --max-effects 1 --no-probes --json "$work/rec_dg.json" \
  > "$work/dg.txt" 2> "$work/dg_err.txt"
check "diagnose reads the record (rc $?)" test -s "$work/rec_dg.json"
"$PAMC" fit "$work/rec.csv" --generations 10 --quiet --out "$work/rec_model.json" > /dev/null 2>&1
check "fit reads the record" grep -q '"pamc-model/1"' "$work/rec_model.json"

# The record is the plant's, not the bus's: replayed through the same plant (`emulate --input-from`), the
# position's steps line up with the record's at no lag - not at the bus's 3 cycles.
"$PAMC" emulate --input-from "$work/rec.csv" --out "$work/rec_replay.csv" > /dev/null 2>&1
lag=$(python3 - "$work/rec.csv" "$work/rec_replay.csv" <<'PY'
import csv, sys
def col(path):
    with open(path) as f:
        y = [float(r["y"]) for r in csv.DictReader(f)]
    return [b - a for a, b in zip(y, y[1:])]
a, b = col(sys.argv[1]), col(sys.argv[2])
def corr(lag):
    pairs = [(a[i], b[i - lag]) for i in range(max(0, lag), min(len(a), len(b) + lag))]
    return sum(x * y for x, y in pairs) / len(pairs)
print(max(range(-5, 6), key=corr))
PY
)
check "the record's y follows its u at the plant's timing (best lag $lag, 0 expected)" test "$lag" = 0

# The same through the logger thread that `pamc controller` uses (rig run --realtime: paced, 1 s).
"$PAMC" rig run --od "$SRC/od" --realtime --priority 0 --input aprbs:2:0.05:0.3:-2:2 --duration 1 --preroll 0.2 \
  --out "$work/rt.csv" > "$work/rt.txt" 2>&1
check "rig run --realtime --input --out exits 0" test $? -eq 0
check "the paced record has 1 s of samples ($(($(wc -l < "$work/rt.csv") - 1)))" test "$(wc -l < "$work/rt.csv")" -ge 990
check "the paced record is an evenly sampled measurement" \
  "$PAMC" emulate --input-from "$work/rt.csv" --out "$work/rt_replay.csv" > /dev/null 2>&1

# --input takes the place of --trajectory (and of the controller): both together refused in one line.
"$PAMC" rig run --od "$SRC/od" --input random:1:-3:3 --trajectory triangle:0.05:0.2:30 --duration 1 \
  --out "$work/both.csv" > /dev/null 2> "$work/both_err.txt"
check "--input with --trajectory exits non-zero" test $? -ne 0
check "--input with --trajectory: one line" test "$(wc -l < "$work/both_err.txt")" -eq 1
check "--input with --trajectory: named" grep -qE -- "--(input|trajectory) excludes --(trajectory|input)" "$work/both_err.txt"
check "--input with --trajectory: no file" test ! -e "$work/both.csv"
"$PAMC" controller --od "$SRC/od" --input random:1:-3:3 --controller amc --out "$work/c.csv" > /dev/null 2> "$work/ctrl_err.txt"
check "controller --input with --controller exits non-zero" test $? -ne 0
check "controller --input with --controller: one line" test "$(wc -l < "$work/ctrl_err.txt")" -eq 1

# A bad spec: one line naming the option and the spec, no file - neither --out nor --csv.
for cmd in "rig run" "controller --iface pamc_no_such_if"; do
  # shellcheck disable=SC2086
  "$PAMC" $cmd --od "$SRC/od" --input multisine:1:2:1:-3:3 --duration 1 --out "$work/bad.csv" --csv "$work/bad_cyc.csv" \
    > /dev/null 2> "$work/bad_err.txt"
  check "$cmd: a bad spec exits non-zero" test $? -ne 0
  check "$cmd: a bad spec is one line" test "$(wc -l < "$work/bad_err.txt")" -eq 1
  check "$cmd: the error names the option and the spec" grep -q -- "--input: trajectory 'multisine:1:2:1:-3:3': " "$work/bad_err.txt"
  check "$cmd: no measurement written" test ! -e "$work/bad.csv"
  check "$cmd: no cycle records written" test ! -e "$work/bad_cyc.csv"
done
check "no temporary files left" test -z "$(ls "$work" | grep tmp || true)"

# controller --help lists the options (it needs a CAN interface to run: the in-process runs above share its code).
"$PAMC" controller --help > "$work/ctrl_help.txt"
check "controller --help lists --input" grep -q -- "--input" "$work/ctrl_help.txt"
check "controller --help lists --out" grep -q -- "--out" "$work/ctrl_help.txt"
check "controller --help names the new forms" grep -q "multisine:SEED:F0:F1:LO:HI" "$work/ctrl_help.txt"

# The new forms in `pamc emulate` too.
"$PAMC" emulate --input multisine:1:0.1:5:-3:3 --duration 10 --out "$work/ms.csv" > /dev/null
check "emulate --input multisine writes data" test "$(wc -l < "$work/ms.csv")" -eq 10001
check "emulate --input multisine spans exactly [-3, 3]" \
  test "$(awk -F, 'NR > 1 { if (lo == "" || $2 < lo) lo = $2; if (hi == "" || $2 > hi) hi = $2 } END { print lo + 0, hi + 0 }' "$work/ms.csv")" = "-3 3"
"$PAMC" emulate --input aprbs:1:0.1:2:-3:3 --duration 5 --out "$work/ap.csv" > /dev/null
check "emulate --input aprbs writes data" test "$(wc -l < "$work/ap.csv")" -eq 5001
"$PAMC" emulate --input aprbs:1:2:0.1:-3:3 --duration 5 --out "$work/ap_bad.csv" > /dev/null 2> "$work/ap_err.txt"
check "emulate: a bad aprbs exits non-zero, one line, no file" \
  test $? -ne 0 -a "$(wc -l < "$work/ap_err.txt")" -eq 1 -a ! -e "$work/ap_bad.csv"

echo "$passes passed, $fails failed"
test $fails -eq 0
