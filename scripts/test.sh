#!/usr/bin/env bash
# test.sh: set up (packages + build) and run the whole test suite with ctest. Kernel tests run on
# PoCL (any OpenCL device: SPECTRACK_DEVICE picks one). Extra arguments go to ctest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cd build
ctest --output-on-failure -j "${TEST_JOBS:-2}" "$@"
