#!/usr/bin/env bash
# The public Bouc-Wen benchmark (Noel & Schoukens 2016) as a standing test (docs/MODELING.md, "The public
# Bouc-Wen benchmark"): `pamc diagnose` on the benchmark's training record, the model it ends with scored
# by `pamc compare` on the multisine test record, beside the published results. Exits non-zero unless
# the test RMSE is below the best published one (PNLSS, 0.012 mm).
#   tools/benchmark_bw.sh [PAMC_BINARY]     (default: build/src/pamc)
# BW_DATA    the benchmark's folder (train.csv, test_multisine.csv; default ../shared/data/bouc-wen-benchmark beside the repository)
# BW_WORK    where the records, reports and the model go (default: a new temporary folder, kept)
# BW_THREADS worker threads (default 0: all cores)
# BW_SEEDS   the seeds diagnose runs with (default "1 2"); the model kept is the one with the lowest
#            validated RMSE on the held-out end of the training record (the test record plays no part)
# BW_TARGET  the test RMSE to beat in mm (default 0.012)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
P="${1:-$root/build/src/pamc}"
data="${BW_DATA:-$root/../shared/data/bouc-wen-benchmark}"
W="${BW_WORK:-$(mktemp -d)}"
threads="${BW_THREADS:-0}"
seeds="${BW_SEEDS:-1 2}"
target="${BW_TARGET:-0.012}"
[ -x "$P" ] || { echo "benchmark_bw: no pamc binary at $P (build it, or give its path)" >&2; exit 2; }
for f in train.csv test_multisine.csv; do
  [ -r "$data/$f" ] || { echo "benchmark_bw: $data/$f is missing (BW_DATA names the benchmark's folder)" >&2; exit 2; }
done
mkdir -p "$W"
cd "$W"
start=$(date +%s)

# The training record starts from rest: the benchmark's system is at rest under no force before its first
# sample (y is 0 within the noise there). A model starts at rest under its record's first input, so one
# sample at rest (u = 0, y = 0) goes before the record; t is rewritten on the same 750 Hz grid.
awk -F, 'NR == 1 { print; next }
         NR == 2 { dt = 0 } { t[NR] = $1; u[NR] = $2; y[NR] = $3 }
         END { Ts = (t[3] - t[2]); print sprintf("%.7f", 0) ",0,0";
               for (i = 2; i <= NR; i++) printf "%.7f,%s,%s\n", (i - 1) * Ts, u[i], y[i] }' \
  "$data/train.csv" > train_from_rest.csv

# The test record is one period (8192 samples) of a periodic multisine in steady state - the system was
# not at rest at its first sample (y = 0.19 mm there; the benchmark's own equation simulated from rest
# misses it by 0.046 mm rms). It is scored as the benchmark's results are, in steady state: the period
# twice, the model run through the first and scored on the second.
awk -F, 'NR == 1 { h = $0; next } { t[NR-1] = $1; u[NR-1] = $2; y[NR-1] = $3; n = NR - 1 }
         END { Ts = t[2] - t[1]; print h;
               for (r = 0; r < 2; r++) for (i = 1; i <= n; i++) printf "%.7f,%s,%s\n", (r * n + i - 1) * Ts, u[i], y[i] }' \
  "$data/test_multisine.csv" > test_two_periods.csv
n_test=$(($(wc -l < "$data/test_multisine.csv") - 1))

echo "== pamc diagnose on the training record ($(($(wc -l < "$data/train.csv") - 1)) samples at 750 Hz), seeds $seeds"
best_val=""
for seed in $seeds; do
  d="diagnose_seed$seed"
  "$P" diagnose train_from_rest.csv --threads "$threads" --seed "$seed" --no-probes --out-dir "$d" \
    --json "$d.json" > "$d.txt" 2> "$d.log" || { cat "$d.txt" "$d.log" >&2; exit 1; }
  [ -r "$d/model.json" ] || { echo "benchmark_bw: diagnose wrote no model ($W/$d/)" >&2; exit 1; }
  # The last rung of the ladder: its validated RMSE is the last field.
  val=$(awk '/^Ladder/ { on = 1; next } on && /^  / { for (i = 1; i < NF; i++) if ($i == "validation") v = $(i + 1) }
             on && /^$/ { on = 0 } END { print v }' "$d.txt")
  echo "-- seed $seed: $(awk '/^Ladder/ { on = 1; next } on && /^  / { l = $0 } on && /^$/ { on = 0 } END { sub(/^ +/, "", l); print l }' "$d.txt")"
  if [ -z "$best_val" ] || awk -v a="$val" -v b="$best_val" 'BEGIN { exit !(a < b) }'; then
    best_val=$val
    best=$d
  fi
done
echo "kept: $best (validated RMSE $best_val mm)"
sed -n '/^Ladder/,$p' "$best.txt"
model="$W/$best/model.json"

"$P" compare "$model" train_from_rest.csv --out-dir compare_train > compare_train.txt
"$P" compare "$model" test_two_periods.csv --out-dir compare_test > compare_test.txt
rmse_train=$(awk '/^RMSE/ { sub(",", "", $2); print $2; exit }' compare_train.txt)
# Steady state: the second period's residuals; from rest: the first period's (the record as it is).
read -r rmse_test rmse_rest < <(awk -F, -v n="$n_test" 'NR > 1 { i = NR - 1; if (i > n) { s += $5 * $5; k++ } else { r += $5 * $5; m++ } }
  END { printf "%.6g %.6g\n", sqrt(s / k), sqrt(r / m) }' compare_test/compare.csv)
seconds=$(($(date +%s) - start))

echo
echo "== the Bouc-Wen benchmark, multisine test record ($n_test samples): RMSE of the simulated output [mm]"
printf '| %-42s | %-12s |\n' "model" "test RMSE" "$(printf -- '-%.0s' {1..42})" "------------"
printf '| %-42s | %-12s |\n' "pamc: $(awk -F': ' '/^model /{print $0; exit}' compare_test.txt | sed 's/.*(\(.*\)).*/\1/')" "$rmse_test"
printf '| %-42s | %-12s |\n' "PNLSS (best of the benchmark paper)" "0.012" "dynoNet" "0.045"
echo
echo "training record (from rest, noisy y; its noise ~0.0074 mm rms): RMSE $rmse_train mm"
echo "test record run from rest instead of in steady state: RMSE $rmse_rest mm (the start state's transient)"
echo "model: $model; reports in $W/ ($seconds s)"
if awk -v a="$rmse_test" -v b="$target" 'BEGIN { exit !(a < b) }'; then
  echo "PASS: test RMSE $rmse_test mm < $target mm"
else
  echo "FAIL: test RMSE $rmse_test mm is not below $target mm" >&2
  exit 1
fi
