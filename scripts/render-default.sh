#!/usr/bin/env bash
# render-default.sh: set up (packages + build) and render the default scene to out/cloud.exr
# and out/cloud.png. Extra arguments go to `spectrack render` (e.g. --spp 16).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
mkdir -p out
./build/spectrack render data/scenes/cloud.json -o out/cloud.exr --preview out/cloud.png --stats-json out/cloud.stats.json "$@"
