#!/usr/bin/env bash
# Builds the libFuzzer targets of tests/fuzz (clang, ASan + UBSan) in build-fuzz/ and runs each one for
# SECONDS_PER_TARGET seconds from its seed corpus; prints target, executions and findings, and exits
# non-zero if any target found something. See docs/RELIABILITY.md, "Fuzzing".
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"

usage() {
  cat <<'EOF'
usage: tools/fuzz.sh [options] [SECONDS_PER_TARGET]

Builds every tests/fuzz/fuzz_*.cpp target with clang-14, -fsanitize=fuzzer,address,undefined in
build-fuzz/ and runs each one for SECONDS_PER_TARGET seconds (default 30), one after the other.

Each target starts from its seeds in tests/fuzz/corpus/<target>/ plus the inputs earlier runs found
(build-fuzz/fuzz-runs/<target>/corpus/; the seed directory itself is never written), with the
dictionary tests/fuzz/<target>.dict if there is one. A finding - a
crash, a sanitizer report, a broken property (FINDING), an uncaught exception, a timeout (10 s per
input) or more than 2 GB of memory - is saved to build-fuzz/fuzz-runs/<target>/artifacts/ (kept
across runs) and stops that target. The log of each run is build-fuzz/fuzz-runs/<target>/log.

options:
  -t, --target NAME   run only this target (repeatable), e.g. -t fuzz_eds
  -j, --jobs N        build with N jobs (default 2)
  --no-build          run the targets as they are in build-fuzz/
  --fresh             forget the inputs of earlier runs, start from the seeds only
  -h, --help          this text

Reproduce a finding:  build-fuzz/tests/fuzz/<target> <artifact file>
Exit status: 0 no findings, 1 findings, 2 usage or build error.
EOF
}

seconds=30
jobs=2
build=1
fresh=0
only=()
while (($#)); do
  case "$1" in
    -h|--help) usage; exit 0 ;;
    -t|--target) [ $# -ge 2 ] || { echo "fuzz.sh: $1 needs a target name" >&2; exit 2; }; only+=("$2"); shift ;;
    -j|--jobs) [ $# -ge 2 ] || { echo "fuzz.sh: $1 needs a number" >&2; exit 2; }; jobs="$2"; shift ;;
    --no-build) build=0 ;;
    --fresh) fresh=1 ;;
    -*) echo "fuzz.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
    *)
      [[ "$1" =~ ^[0-9]+$ ]] && [ "$1" -gt 0 ] || { echo "fuzz.sh: SECONDS_PER_TARGET must be a positive integer, got '$1'" >&2; exit 2; }
      seconds="$1" ;;
  esac
  shift
done

bdir="$root/build-fuzz"
targets=()
for src in "$root"/tests/fuzz/fuzz_*.cpp; do targets+=("$(basename "$src" .cpp)"); done
if ((${#only[@]})); then
  for t in "${only[@]}"; do
    [ -f "$root/tests/fuzz/$t.cpp" ] || { echo "fuzz.sh: no target $t (tests/fuzz/$t.cpp)" >&2; exit 2; }
  done
  targets=("${only[@]}")
fi

if ((build)); then
  cxx="$(command -v clang++-14 || command -v clang++ || true)"
  cc="$(command -v clang-14 || command -v clang || true)"
  if [ -z "$cxx" ] || [ -z "$cc" ]; then
    echo "fuzz.sh: clang is not installed (tools/deps.sh installs clang-14 and libclang-rt-14-dev)" >&2
    exit 2
  fi
  echo "fuzz.sh: building ${#targets[@]} targets in build-fuzz/ ($(basename "$cxx"), -j$jobs)"
  mkdir -p "$bdir"
  if ! CC="$cc" CXX="$cxx" cmake -S "$root" -B "$bdir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPAMC_FUZZ=ON \
         -DPAMC_BUILD_TESTS=OFF -DPAMC_BUILD_BENCH=OFF > "$bdir/fuzz-configure.log" 2>&1; then
    cat "$bdir/fuzz-configure.log" >&2
    echo "fuzz.sh: configuring build-fuzz/ failed" >&2
    exit 2
  fi
  nice cmake --build "$bdir" -j "$jobs" --target "${targets[@]}" > "$bdir/fuzz-build.log" 2>&1 || {
    tail -40 "$bdir/fuzz-build.log" >&2
    echo "fuzz.sh: build failed (full log: build-fuzz/fuzz-build.log)" >&2
    exit 2
  }
fi

export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1${UBSAN_OPTIONS:+:$UBSAN_OPTIONS}"
export ASAN_OPTIONS="abort_on_error=0${ASAN_OPTIONS:+:$ASAN_OPTIONS}"

stat_of() { sed -n "s/^stat::$1: *//p" "$2" | tail -1; }

total_findings=0
rows=()
for t in "${targets[@]}"; do
  bin="$bdir/tests/fuzz/$t"
  [ -x "$bin" ] || { echo "fuzz.sh: $bin is missing (build without --no-build)" >&2; exit 2; }
  seeds="$root/tests/fuzz/corpus/$t"
  work="$bdir/fuzz-runs/$t"
  ((fresh)) && rm -rf "$work/corpus"
  mkdir -p "$work/corpus" "$work/artifacts"
  touch "$work/started"  # artifacts newer than this are this run's findings; older ones stay for reference
  echo "fuzz.sh: $t for ${seconds} s"
  dict=()
  [ -f "$root/tests/fuzz/$t.dict" ] && dict=(-dict="$root/tests/fuzz/$t.dict")
  rc=0
  nice "$bin" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 "${dict[@]}" \
    -artifact_prefix="$work/artifacts/" "$work/corpus" "$seeds" > "$work/log" 2>&1 || rc=$?
  execs="$(stat_of number_of_executed_units "$work/log")"
  status_line="$(grep -E '^#[0-9]+' "$work/log" | tail -1 || true)"
  cov="$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$status_line")"
  corp="$(sed -n 's/.* corp: \([0-9]*\)\/.*/\1/p' <<<"$status_line")"
  mapfile -t artifacts < <(find "$work/artifacts" -type f -newer "$work/started" | sort)
  finding="-"
  if ((rc != 0)) || ((${#artifacts[@]})); then
    total_findings=$((total_findings + 1))
    what=""
    for pattern in '^FINDING:' 'runtime error:' 'Assertion .* failed' 'terminate called' '^==[0-9]+==ERROR: [A-Za-z]+Sanitizer' \
                   '^==[0-9]+== ?ERROR: libFuzzer' '^SUMMARY: '; do
      what="$(grep -m1 -E "$pattern" "$work/log" || true)"
      [ -z "$what" ] || break
    done
    [ -n "$what" ] || what="exit status $rc"
    rel=()
    for a in "${artifacts[@]}"; do rel+=("${a#"$root"/}"); done
    finding="${what#"$root"/} -> ${rel[*]:-no artifact} (log: ${work#"$root"/}/log)"
  fi
  rows+=("$(printf '%-18s %8s %12s %6s %7s  %s' "$t" "$seconds" "${execs:-?}" "${cov:-?}" "${corp:-?}" "$finding")")
done

echo
printf '%-18s %8s %12s %6s %7s  %s\n' target seconds executions cov corpus findings
for r in "${rows[@]}"; do echo "$r"; done
if ((total_findings)); then
  echo "fuzz.sh: $total_findings target(s) with findings"
  exit 1
fi
echo "fuzz.sh: no findings"
