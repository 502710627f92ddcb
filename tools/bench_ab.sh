#!/usr/bin/env bash
# Compares benchmark binaries on a shared machine: runs them alternately, ROUNDS rounds of each, every
# benchmark for 0.5 s, and prints the fastest time of each benchmark per binary (the least disturbed by
# the neighbours' load; medians of one binary move by 5-10 % within an hour on a 2-core VM).
#   tools/bench_ab.sh FILTER BINARY... [ROUNDS=8 in the environment]
# Example (docs/PERFORMANCE.md): the version before and this one, built side by side:
#   tools/bench_ab.sh 'BM_UkfStep$|BM_AmcCycle' old/tests/bench/pamc_bench build/tests/bench/pamc_bench
set -euo pipefail
usage() { sed -n '2,7p' "$0" | sed 's/^# \{0,1\}//'; }
if [ "${1:-}" = -h ] || [ "${1:-}" = --help ]; then usage; exit 0; fi
if [ $# -lt 2 ]; then usage >&2; exit 2; fi
filter="$1"; shift
for b in "$@"; do [ -x "$b" ] || { echo "bench_ab.sh: $b: not an executable" >&2; exit 2; }; done
rounds="${ROUNDS:-8}"
for ((i = 1; i <= rounds; i++)); do
  for b in "$@"; do
    "$b" --benchmark_filter="$filter" --benchmark_min_time=0.5 2> /dev/null | awk -v b="$b" '/^BM/ { print b, $1, $2, $3 }'
  done
done | awk '{ k = $1 " " $2; if (!(k in m) || $3 < m[k]) { m[k] = $3; u[k] = $4 } } END { for (k in m) print k, m[k], u[k] }' | sort -k2,2 -k1,1
