#!/usr/bin/env bash
# The test suite under AddressSanitizer and UndefinedBehaviorSanitizer (build in build-asan/).
# Allocation counting is skipped there (the sanitizer owns operator new). About 10 minutes on 2 cores.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
"$root/tools/deps.sh"
cmake -S "$root" -B "$root/${PAMC_ASAN_DIR:-build-asan}" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPAMC_SANITIZE=ON -DPAMC_BUILD_TESTS=ON -DPAMC_BUILD_BENCH=OFF > /dev/null
cmake --build "$root/${PAMC_ASAN_DIR:-build-asan}" -j "$(nproc)"
cd "$root/${PAMC_ASAN_DIR:-build-asan}"
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
ctest --output-on-failure -j "$(nproc)" -E e2e_vcan
