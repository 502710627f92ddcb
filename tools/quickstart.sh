#!/usr/bin/env bash
# Fresh Debian 12 to results: installs what is missing, builds, runs `pamc experiments`
# (the paper's experiments on the built-in plant emulator). Extra arguments go to pamc.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
"$root/tools/deps.sh"
"$root/tools/build.sh"
cd "$root"
exec "$root/build/src/pamc" experiments "$@"
