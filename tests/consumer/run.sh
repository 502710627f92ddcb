#!/usr/bin/env bash
# Installs pamc from the build tree into a temporary prefix, builds tests/consumer against it with
# find_package(pamc), runs it, and checks the Debian package cpack makes holds the same files.
# Arguments: BUILD_DIR SOURCE_DIR.
set -eu
BUILD=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
cmake --install "$BUILD" --prefix "$T/prefix" > "$T/install.txt"
for f in bin/pamc share/pamc/od/controller.eds share/pamc/od/rigs/default.ini include/pamc/control/controller.hpp \
         include/pamc/canopen/node.hpp lib/cmake/pamc/pamcConfig.cmake lib/systemd/system/pamc-controller@.service \
         share/bash-completion/completions/pamc; do
  [ -e "$T/prefix/$f" ] || { echo "FAIL: not installed: $f"; exit 1; }
done
# The installed completion completes: `pamc rig <TAB>` offers the four jobs, `--controller <TAB>` its kinds.
complete_words() {
  bash -c 'source "$1"; shift; COMP_WORDS=("$@"); COMP_CWORD=$(($# - 1)); _pamc; echo "${COMPREPLY[*]}"' \
    _ "$T/prefix/share/bash-completion/completions/pamc" "$@"
}
[ "$(complete_words pamc rig '')" = "run faults soak guards" ] || { echo "FAIL: completion of 'pamc rig '"; exit 1; }
[ "$(complete_words pamc rig run --controller '')" = "open pi pid eso amc mbc" ] || { echo "FAIL: completion of --controller"; exit 1; }
[ "$(complete_words pamc monitor --rep)" = "--replay" ] || { echo "FAIL: completion of monitor --rep"; exit 1; }
# The installed pamc finds its EDS files next to itself, from any working directory.
(cd "$T" && "$T/prefix/bin/pamc" rig run --duration 1 --preroll 0.2 > "$T/rig.txt") || { cat "$T/rig.txt"; echo "FAIL: installed pamc rig"; exit 1; }
cmake -S "$SRC/tests/consumer" -B "$T/consumer" -DCMAKE_PREFIX_PATH="$T/prefix" -DCMAKE_BUILD_TYPE=Release > "$T/configure.txt" \
  || { cat "$T/configure.txt"; exit 1; }
cmake --build "$T/consumer" -j2 > "$T/build.txt" 2>&1 || { cat "$T/build.txt"; exit 1; }
"$T/consumer/consumer"
if command -v cpack > /dev/null && command -v dpkg-deb > /dev/null; then
  (cd "$T" && cpack -G DEB --config "$BUILD/CPackConfig.cmake" > "$T/cpack.txt" 2>&1) || { cat "$T/cpack.txt"; exit 1; }
  deb=$(ls "$T"/*.deb | head -n 1)
  dpkg-deb -c "$deb" > "$T/deb.txt"
  for f in ./usr/bin/pamc ./usr/share/pamc/od/rigs/default.ini ./usr/lib/systemd/system/pamc-controller@.service \
           ./usr/share/bash-completion/completions/pamc; do
    grep -q " $f\$" "$T/deb.txt" || { echo "FAIL: $f not in $(basename "$deb")"; exit 1; }
  done
  echo "ok: $(basename "$deb") holds pamc, the rig files, the service unit and the bash completion"
fi
echo "ok: installed, found by find_package(pamc), consumer built and ran"
