#!/usr/bin/env bash
# render-default.sh: set up (packages + build) and render the default scene to out/cloud.exr
# and out/cloud.png. Extra arguments go to `spectrack render` (e.g. --spp 16).
set -euo pipefail
cd "$(dirname "$0")/.."
echo "render-default: packages and a build of the renderer (scripts/setup.sh)"
SETUP_TARGETS="spectrack default_cloud" bash scripts/setup.sh
mkdir -p out
echo "render-default: rendering data/scenes/cloud.json (the first run compiles the kernels for this scene, then caches them)"
./build/spectrack render data/scenes/cloud.json -o out/cloud.exr --preview out/cloud.png --stats-json out/cloud.stats.json "$@"
