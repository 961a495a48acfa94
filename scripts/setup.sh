#!/usr/bin/env bash
# setup.sh: installs the Debian bookworm packages spectrack needs (when missing) and builds it
# (Release) into build/. Idempotent; used by render-default.sh, test.sh and .ci/run.
# SETUP_PACKAGES_ONLY=1 installs the packages and builds nothing (sanitize.sh, fuzz.sh).
# clang + libclang-rt-14-dev (libFuzzer, only recommended by clang) are for scripts/fuzz.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
PKGS=(build-essential cmake pkg-config ocl-icd-opencl-dev opencl-clhpp-headers opencl-c-headers pocl-opencl-icd
      libopenvdb-dev libnanovdb-dev libopenimageio-dev openimageio-tools libcli11-dev nlohmann-json3-dev
      libfmt-dev libboost-iostreams-dev libgtest-dev libbenchmark-dev libtbb-dev libblosc-dev zlib1g-dev clinfo
      clang libclang-rt-14-dev libopenmpi-dev openmpi-bin python3)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
[ "${SETUP_PACKAGES_ONLY:-0}" = 1 ] && exit 0
BUILD_DIR=${BUILD_DIR:-build}
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release ${CMAKE_ARGS:-} >/dev/null
cmake --build "$BUILD_DIR" -j "${JOBS:-$(nproc)}"
