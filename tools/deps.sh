#!/usr/bin/env bash
# Installs the Debian 12 packages pamc builds and runs with (only those missing).
set -euo pipefail
PKGS=(build-essential cmake pkg-config libeigen3-dev libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev
      nlohmann-json3-dev libinih-dev libboost-dev gnuplot-nox can-utils time clang-14 libclang-rt-14-dev python3
      pybind11-dev python3-numpy python3-pytest python3-matplotlib python3-distributed)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "installing: ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" > /dev/null
fi
