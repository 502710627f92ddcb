#!/usr/bin/env bash
# Installs pamc from the build tree into a temporary prefix, builds tests/consumer against it with
# find_package(pamc), runs it, and checks the Debian package cpack makes holds the same files.
# With the Python module (PAMC_BUILD_PYTHON and PAMC_PYTHON in the build's cache), checks it is installed with its stubs and that the
# installed copy imports and runs. Arguments: BUILD_DIR SOURCE_DIR.
set -eu
BUILD=$1; SRC=$2
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
cmake --install "$BUILD" --prefix "$T/prefix" > "$T/install.txt"
for f in bin/pamc share/pamc/od/controller.eds share/pamc/od/rigs/default.ini include/pamc/control/controller.hpp \
         include/pamc/canopen/node.hpp lib/cmake/pamc/pamcConfig.cmake lib/systemd/system/pamc-controller@.service \
         share/bash-completion/completions/pamc; do
  [ -e "$T/prefix/$f" ] || { echo "FAIL: not installed: $f"; exit 1; }
done
# The installed Python module: its files, and the copy in the prefix imports and simulates.
PY=$(sed -n 's/^PAMC_PYTHON:FILEPATH=//p' "$BUILD/CMakeCache.txt")
grep -q '^PAMC_BUILD_PYTHON:BOOL=ON$' "$BUILD/CMakeCache.txt" || PY=""
if [ -n "$PY" ]; then
  site="$T/prefix/lib/python3/dist-packages"
  for f in pamc/__init__.py pamc/__init__.pyi pamc/py.typed; do
    [ -e "$site/$f" ] || { echo "FAIL: not installed: lib/python3/dist-packages/$f"; exit 1; }
  done
  ls "$site"/pamc/_pamc*.so > /dev/null || { echo "FAIL: the module's extension is not installed"; exit 1; }
  (cd "$T" && PYTHONPATH="$site" "$PY" -c "import pamc, sys
assert pamc.__file__.startswith(sys.argv[1]), pamc.__file__
assert len(pamc.Model().simulate([0.0, 1.0, 2.0])) == 3" "$site") || { echo "FAIL: the installed module"; exit 1; }
fi
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
  if [ -n "$PY" ]; then
    for f in ./usr/lib/python3/dist-packages/pamc/__init__.py ./usr/lib/python3/dist-packages/pamc/__init__.pyi; do
      grep -q " $f\$" "$T/deb.txt" || { echo "FAIL: $f not in $(basename "$deb")"; exit 1; }
    done
    grep -q " ./usr/lib/python3/dist-packages/pamc/_pamc.*\.so\$" "$T/deb.txt" || { echo "FAIL: the module's extension not in $(basename "$deb")"; exit 1; }
    dpkg-deb -f "$deb" Depends | grep -q python3-numpy || { echo "FAIL: $(basename "$deb") does not depend on python3-numpy"; exit 1; }
  fi
  echo "ok: $(basename "$deb") holds pamc, the rig files, the service unit, the bash completion${PY:+ and the Python module}"
fi
echo "ok: installed, found by find_package(pamc), consumer built and ran"
