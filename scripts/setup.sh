#!/usr/bin/env bash
# setup.sh: installs the Debian bookworm packages spectrack needs (when missing) and builds it
# (Release) into build/. Idempotent; used by render-default.sh, test.sh and .ci/run.
# SETUP_PACKAGES_ONLY=1 installs the packages and builds nothing (sanitize.sh, fuzz.sh).
# clang + libclang-rt-14-dev (libFuzzer, only recommended by clang) are for scripts/fuzz.sh.
# pybind11-dev, python3-dev, python3-numpy, python3-pytest: the Python module and its tests (docs/python.md).
# SETUP_TARGETS="spectrack default_scene" builds only those targets (render-default.sh: the renderer
# and the default scene's volume, not the tests), and then installs only the packages they need.
set -euo pipefail
cd "$(dirname "$0")/.."
PKGS=(build-essential cmake pkg-config ocl-icd-opencl-dev opencl-clhpp-headers opencl-c-headers pocl-opencl-icd
      libopenvdb-dev libnanovdb-dev libopenimageio-dev openimageio-tools libcli11-dev nlohmann-json3-dev
      libfmt-dev libboost-iostreams-dev libtbb-dev libblosc-dev zlib1g-dev python3)
if [ -z "${SETUP_TARGETS:-}" ]; then
  PKGS+=(libgtest-dev libbenchmark-dev clinfo clang libclang-rt-14-dev libopenmpi-dev openmpi-bin
         pybind11-dev python3-dev python3-numpy python3-pytest)
fi
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PKGS[@]} Debian packages are installed (no apt-get)"
else
  echo "setup: installing ${#missing[@]} of ${#PKGS[@]} Debian packages (apt-get): ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
[ "${SETUP_PACKAGES_ONLY:-0}" = 1 ] && exit 0
BUILD_DIR=${BUILD_DIR:-build}
# the tests need GoogleTest: a renderer-only build without it configures them out (a full build
# turns them back on)
TESTING=ON
if [ -n "${SETUP_TARGETS:-}" ] && ! dpkg-query -W -f='${Status}' libgtest-dev 2>/dev/null | grep -q "install ok installed"; then
  TESTING=OFF
fi
echo "setup: configuring the build in $BUILD_DIR (Release)"
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=$TESTING ${CMAKE_ARGS:-} >/dev/null
if [ -n "${SETUP_TARGETS:-}" ]; then
  echo "setup: building ${SETUP_TARGETS} (not the tests: scripts/test.sh builds them)"
  # shellcheck disable=SC2086
  cmake --build "$BUILD_DIR" -j "${JOBS:-$(nproc)}" --target ${SETUP_TARGETS}
else
  echo "setup: building everything (the renderer, the tests, the benchmarks)"
  cmake --build "$BUILD_DIR" -j "${JOBS:-$(nproc)}"
fi
