#!/usr/bin/env bash
# Fresh Debian 12 to a test verdict: installs what is missing, builds, runs every test.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
"$root/tools/deps.sh"
"$root/tools/build.sh"
cd "$root/build"
ctest --output-on-failure -j "$(nproc)" --timeout 600
# Short fuzzing run of every parser and decoder (clang + libFuzzer, ASan/UBSan, build-fuzz/): 10 s per target.
"$root/tools/fuzz.sh" 10
