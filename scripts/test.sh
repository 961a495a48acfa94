#!/usr/bin/env bash
# test.sh: set up (packages + build) and run the whole test suite with ctest. Kernel tests run on
# PoCL (any OpenCL device: SPECTRACK_DEVICE picks one). Extra arguments go to ctest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# USD in (docs/usd.md) is an optional extra from PyPI (Debian has no USD): installed for Debian's
# python3 when the network allows; without it the USD tests skip and say why.
if ! /usr/bin/python3 -c 'import pxr' 2>/dev/null; then
  timeout 300 /usr/bin/python3 -m pip install --quiet --user --break-system-packages usd-core ||
    echo "test.sh: usd-core could not be installed: the USD tests will skip"
fi
# Denoising (--denoise, docs/cli.md) is an optional extra too: Intel Open Image Denoise from PyPI's
# pyoidn wheel (Debian has no OIDN); without it the denoise tests skip and say why.
if ! /usr/bin/python3 -c 'import importlib.util, sys; sys.exit(importlib.util.find_spec("pyoidn") is None)' 2>/dev/null; then
  timeout 300 /usr/bin/python3 -m pip install --quiet --user --break-system-packages pyoidn ||
    echo "test.sh: pyoidn could not be installed: the denoise tests will skip"
fi
cd build
ctest --output-on-failure -j "${TEST_JOBS:-2}" "$@"
