#!/usr/bin/env bash
# Command-line behaviour: help, one-line errors naming file/line/column, non-zero exit and no
# half-written output on bad input, and the happy path of fit and emulate.
set -u
PAMC="$1"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fails=0
passes=0
check() {  # name, condition...
  local name="$1"; shift
  if "$@"; then passes=$((passes + 1)); else echo "FAIL: $name"; fails=$((fails + 1)); fi
}

"$PAMC" --help > "$work/help.txt"; check "help exits 0" test $? -eq 0
check "help lists subcommands" grep -q "experiments" "$work/help.txt"
"$PAMC" fit --help > /dev/null; check "fit --help exits 0" test $? -eq 0

printf 't,u,y\n0,1,2\n0.001,abc,2\n0.002,1,2\n' > "$work/bad.csv"
"$PAMC" fit "$work/bad.csv" --out "$work/m.json" 2> "$work/err.txt" > /dev/null
rc=$?
check "bad csv exits non-zero" test $rc -ne 0
check "bad csv error is one line" test "$(wc -l < "$work/err.txt")" -eq 1
check "bad csv error names file, line and column" grep -q "bad.csv:3: column 'u': not a number: 'abc'" "$work/err.txt"
check "bad csv leaves no model file" test ! -e "$work/m.json"
check "no temporary files left" test -z "$(ls "$work" | grep tmp || true)"

printf 't,u,y\n0,1,2\n0.001,1,2\n0.003,1,2\n' > "$work/uneven.csv"
"$PAMC" fit "$work/uneven.csv" 2> "$work/err2.txt" > /dev/null
check "uneven step exits non-zero" test $? -ne 0
check "uneven step named" grep -q "uneven.csv:4: column 't': uneven sampling step" "$work/err2.txt"

# Finite but huge values: the ranges the identification scales by would overflow. Refused on reading.
printf 't,u,y\n0,1e308,2\n0.001,-1e308,2\n0.002,1,2\n0.003,-1,2\n' > "$work/huge.csv"
"$PAMC" fit "$work/huge.csv" --out "$work/huge.json" 2> "$work/err_huge.txt" > /dev/null
check "huge values: fit exits non-zero" test $? -ne 0
check "huge values: one line on stderr" test "$(wc -l < "$work/err_huge.txt")" -eq 1
check "huge values: error names file, line, column and limit" \
  grep -q "huge.csv:2: column 'u': value 1e308 is too large to identify a model from (|u| must be at most 1e+09)" "$work/err_huge.txt"
check "huge values: no model file" test ! -e "$work/huge.json"
"$PAMC" diagnose "$work/huge.csv" --json "$work/huge_dg.json" 2> "$work/err_huge2.txt" > /dev/null
check "huge values: diagnose exits non-zero" test $? -ne 0
check "huge values: diagnose error is one line" test "$(wc -l < "$work/err_huge2.txt")" -eq 1
check "huge values: no diagnose output" test ! -e "$work/huge_dg.json"

"$PAMC" fit "$work/nope.csv" 2> "$work/err3.txt" > /dev/null
check "missing file exits non-zero" test $? -ne 0
check "missing file named" grep -q "nope.csv: cannot open file" "$work/err3.txt"

"$PAMC" emulate --duration 4 --out "$work/d.csv" > /dev/null
check "emulate writes data" test -s "$work/d.csv"
"$PAMC" fit "$work/d.csv" --effects warp 2> "$work/err4.txt" > /dev/null
check "unknown effect exits non-zero" test $? -ne 0
check "unknown effect lists known ones" grep -q "known: pressure_lag" "$work/err4.txt"

"$PAMC" fit "$work/d.csv" --generations 15 --out "$work/m.json" --quiet > "$work/fit.txt"
check "fit exits 0" test $? -eq 0
check "fit prints RMSE" grep -q "^RMSE" "$work/fit.txt"
check "fit writes the model" grep -q '"pamc-model/1"' "$work/m.json"
check "fit records the output form" grep -q '"output_form": "aligned"' "$work/m.json"
"$PAMC" fit "$work/d.csv" --generations 15 --out "$work/mp.json" --quiet --output-form printed > /dev/null
check "fit --output-form printed is recorded" grep -q '"output_form": "printed"' "$work/mp.json"
"$PAMC" fit "$work/d.csv" --output-form sideways 2> "$work/err_form.txt" > /dev/null
check "a bad output form exits non-zero" test $? -ne 0
# A fit started from a model file: its effects and the ones added, searched from its parameters.
"$PAMC" fit "$work/d.csv" --start "$work/m.json" --effects creep --out "$work/ms.json" --quiet > "$work/fit_start.txt"
check "fit --start exits 0" test $? -eq 0
check "fit --start adds the effects to the start's" grep -q "^model: bouc_wen + creep" "$work/fit_start.txt"
check "fit --start ends no worse than its start" \
  awk 'FNR == 1 { f++ } /^RMSE/ { r[f] = $2 } END { exit !(r[2] <= r[1] * 1.0001) }' "$work/fit.txt" "$work/fit_start.txt"
"$PAMC" fit "$work/d.csv" --start "$work/nope.json" 2> "$work/err_start.txt" > /dev/null
check "fit --start with a missing file exits non-zero" test $? -ne 0
check "fit --start: the error is one line" test "$(wc -l < "$work/err_start.txt")" -eq 1

# A recorded command replayed through the plant; the record's sample time must be the plant's.
"$PAMC" emulate --input-from "$work/d.csv" --out "$work/replay.csv" > /dev/null
check "emulate --input-from replays every sample" test "$(wc -l < "$work/replay.csv")" -eq "$(wc -l < "$work/d.csv")"
printf 't,u,y\n0,1,2\n0.002,1,2\n0.004,1,2\n' > "$work/slow.csv"
"$PAMC" emulate --input-from "$work/slow.csv" --out "$work/replay2.csv" 2> "$work/err_replay.txt" > /dev/null
check "emulate --input-from: another sample time exits non-zero" test $? -ne 0
check "emulate --input-from: the error names the file and both sample times" \
  grep -q "slow.csv: sample time 0.002 s, the plant's is 0.001 s" "$work/err_replay.txt"
check "emulate --input-from: no output on error" test ! -e "$work/replay2.csv"
# A plant file of the model kind without its kind: told what it takes.
echo '{"core":{"k":6}}' > "$work/oldplant.json"
"$PAMC" emulate --plant "$work/oldplant.json" --duration 1 --out "$work/op.csv" 2> "$work/err_plant.txt" > /dev/null
check "a model plant file without its kind exits non-zero" test $? -ne 0
check "... and is told to say its kind" grep -q '"kind": "model"' "$work/err_plant.txt"

"$PAMC" experiments --only nonsense --out-dir "$work/x" 2> "$work/err5.txt" > /dev/null
check "unknown experiment exits non-zero" test $? -ne 0

# CANopen side: corrupt EDS, bad candump log, missing interface.
SRC="$(cd "$(dirname "$0")/../.." && pwd)"
mkdir -p "$work/od"; cp "$SRC"/od/*.eds "$work/od/"
sed -i '0,/DataType=0x0007/s//DataType=0xZZ07/' "$work/od/controller.eds"
"$PAMC" rig run --od "$work/od" --duration 1 > /dev/null 2> "$work/err6.txt"
check "corrupt EDS exits non-zero" test $? -ne 0
check "corrupt EDS error names file and line" grep -q "controller.eds:[0-9]*: \[1000\] DataType" "$work/err6.txt"
printf '(1700000000.000001) vcan0 080#\n(1700000000.001000) vcan0 18G#0102\n' > "$work/bad.log"
"$PAMC" decode "$work/bad.log" --od "$SRC/od" --out "$work/bad_decoded.csv" > /dev/null 2> "$work/err7.txt"
check "bad candump log exits non-zero" test $? -ne 0
check "bad candump log error names the line" grep -q "bad.log:2:" "$work/err7.txt"
check "bad candump log leaves no CSV" test ! -e "$work/bad_decoded.csv"
"$PAMC" controller --iface pamc_no_such_if --od "$SRC/od" --duration 1 > /dev/null 2> "$work/err8.txt"
check "missing interface exits non-zero" test $? -ne 0
check "missing interface is named" grep -q "pamc_no_such_if" "$work/err8.txt"
# A master DCF that is not one: one line naming the file, the line and the problem, before the bus is opened.
sed 's/^ParameterValue=0x00000190$/ParameterValue=0x190Z/' "$SRC/tests/dcf/moved_pdos.dcf" > "$work/bad.dcf"
"$PAMC" controller --iface pamc_no_such_if --od "$SRC/od" --dcf "$work/bad.dcf" --duration 1 > /dev/null 2> "$work/err9.txt"
check "bad DCF exits non-zero" test $? -ne 0
check "bad DCF error is one line" test "$(wc -l < "$work/err9.txt")" -eq 1
check "bad DCF error names file, line and problem" grep -q "bad.dcf:[0-9]*: \[1400sub1\] ParameterValue: '0x190Z' is not a valid UNSIGNED32" "$work/err9.txt"
"$PAMC" rig run --od "$SRC/od" --duration 2 --preroll 1 --log "$work/rig.log" --csv "$work/rig.csv" > /dev/null
check "rig runs on the in-process bus" test -s "$work/rig.csv"
"$PAMC" decode "$work/rig.log" --od "$SRC/od" --out "$work/rig_dec.csv" > /dev/null
check "decode of the rig's log" grep -q "^t,u,y,p,t_log" "$work/rig_dec.csv"
"$PAMC" monitor --replay "$work/rig.log" --od "$SRC/od" --once > "$work/mon.txt"
check "monitor shows the nodes operational" test "$(grep -c operational "$work/mon.txt")" -eq 3
# A run on devices pamc did not make decodes through the rig file (its COB-IDs and scaling); through the
# EDS files alone it has no position. Without the rig file the loop never starts: exit 1, the COB-ID named.
"$PAMC" rig run --od "$SRC/od" --rig "$SRC/od/rigs/profile.ini" --profile-defaults --duration 1 --preroll 0.5 \
  --log "$work/prof.log" > /dev/null 2>&1
"$PAMC" decode "$work/prof.log" --rig "$SRC/od/rigs/profile.ini" --out "$work/prof_dec.csv" > /dev/null
check "decode --rig of a run on the profile devices" grep -q "^t,u,y,p,t_log" "$work/prof_dec.csv"
"$PAMC" decode "$work/prof.log" --od "$SRC/od" --out "$work/prof_eds.csv" > /dev/null 2>&1
check "the same log through the EDS files has no cycles" test $? -ne 0
"$PAMC" rig run --od "$SRC/od" --profile-defaults --duration 1 --preroll 0.5 > /dev/null 2> "$work/noprof.txt"
check "rig on devices it cannot read exits non-zero" test $? -ne 0
check "rig on devices it cannot read names the COB-ID it waits on" \
  grep -q "no position within 1 s of Operational: waiting for the sensor's (node 2) PDO on COB-ID 0x182" "$work/noprof.txt"


# Every subcommand's help, and every option it lists accepted by the parser.
python3 "$SRC/tests/cli/help_options.py" "$PAMC" > "$work/help_options.txt"
check "every listed option is accepted ($(tail -1 "$work/help_options.txt"))" test $? -eq 0
grep FAIL "$work/help_options.txt"

# Live monitor runs until Ctrl-C unless --duration is given (it used to stop after 40 s).
"$PAMC" monitor --help | grep -qE -- "--duration FLOAT:NONNEGATIVE=0( |$)"
check "monitor's --duration defaults to 0 (until Ctrl-C)" test $? -eq 0
# rig run --duration 0 runs until stopped (it used to run zero cycles and exit at once).
start=$(date +%s%N)
timeout -s INT 3 "$PAMC" rig run --od "$SRC/od" --duration 0 --preroll 0.1 > "$work/forever.txt" 2>&1
rc=$?
elapsed_ms=$(( ($(date +%s%N) - start) / 1000000 ))
check "rig run --duration 0 runs until interrupted (rc $rc, ${elapsed_ms} ms)" test "$elapsed_ms" -gt 2500
cycles=$(sed -n 's/^cycles \([0-9]*\),.*/\1/p' "$work/forever.txt")
check "rig run --duration 0 ran cycles (${cycles:-none})" test "${cycles:-0}" -gt 5000
# rig faults --controller pi runs the fault table with PI (it used to run the AMC).
"$PAMC" rig faults --od "$SRC/od" --only sensor-silent-short --controller pi > "$work/faults.md" 2> "$work/faults_err.txt"
check "rig faults --controller pi runs PI" grep -q "in-process bus, pi," "$work/faults_err.txt"
"$PAMC" rig faults --od "$SRC/od" --only sensor-silent-short > /dev/null 2> "$work/faults_err2.txt"
check "rig faults without --controller runs the fault table's AMC" grep -q "in-process bus, amc," "$work/faults_err2.txt"

# A report folder used before keeps no probe table or chart the new diagnosis did not make.
"$PAMC" emulate --input random:1:-3:3 --duration 6 --out "$work/dg.csv" > /dev/null 2>&1
mkdir -p "$work/rep" && touch "$work/rep/probes.png" "$work/rep/probes.csv"
"$PAMC" diagnose "$work/dg.csv" --candidates pressure_lag --max-effects 1 --no-probes --out-dir "$work/rep" > /dev/null 2>&1
check "diagnose --out-dir writes its files" test -s "$work/rep/diagnosis.json"
check "diagnose --out-dir leaves no stale probe chart" test ! -e "$work/rep/probes.png"
check "diagnose --out-dir leaves no stale probe table" test ! -e "$work/rep/probes.csv"
check "diagnose removes the ladder kept while it ran" test ! -e "$work/rep/diagnosis.partial.json" -a ! -e "$work/rep/model.partial.json"

# The convention (docs/CLI.md) over every command's --help, and the old spellings with their notice.
python3 "$SRC/tests/cli/cli_convention.py" "$PAMC" > "$work/convention.txt"
check "the command-line convention holds ($(tail -1 "$work/convention.txt"))" test $? -eq 0
grep FAIL "$work/convention.txt"
# One place per fact: no literal of the valve range or the bus delay outside its definition.
python3 "$SRC/tests/cli/one_place.py" "$SRC" > "$work/one_place.txt"
check "each fact in one place ($(tail -1 "$work/one_place.txt"))" test $? -eq 0
grep FAIL "$work/one_place.txt"

# The default gains: every command that takes --ki shows one default, the controller's dictionary has it,
# and the experiments run with it (summary.json's readings).
ki_defaults=$(for c in experiments robustness controller "rig run" "rig faults" "rig soak" "rig guards"; do
  "$PAMC" $c --help | sed -n 's/^ *--ki FLOAT[^=]*=\([^ ]*\) .*/\1/p'; done | sort -u)
check "one --ki default in every --help (got: $(echo $ki_defaults))" test "$(echo "$ki_defaults" | wc -l)" -eq 1 -a -n "$ki_defaults"
eds_ki=$(awk '/^\[2000sub2\]/{s=1} s && /^DefaultValue=/{sub(/.*=/, ""); print; exit}' "$SRC/od/controller.eds" | tr -d '\r')
check "the EDS default of ki (0x2000:02 = $eds_ki) is the --ki default ($ki_defaults)" \
  python3 -c "import sys; sys.exit(float('$eds_ki') != float('$ki_defaults'))"
"$PAMC" experiments --only table1 --no-figures --out-dir "$work/ki" > /dev/null 2>&1
run_ki=$(python3 -c "import json; print(json.load(open('$work/ki/summary.json'))['readings']['ki'])" 2> /dev/null)
check "experiments run with the --ki default ($run_ki, --help $ki_defaults)" \
  python3 -c "import sys; sys.exit(float('$run_ki') != float('$ki_defaults'))"

echo "$passes passed, $fails failed"
test $fails -eq 0
