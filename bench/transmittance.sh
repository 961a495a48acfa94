#!/usr/bin/env bash
# bench/transmittance.sh [SPECTRACK_BUILD_DIR]: ratio tracking against ray-marching transmittance
# (docs/transmittance.md) on every bench scene and on pbrt-v4's comparison grid (when
# bench/pbrt_grid.py has generated it in the cache). Two figures per scene, each a ratio measured
# in one run: (1) shadow rays alone: kernel_throughput's section (5), 32 rays from points in the
# medium towards the light, 1024 estimates each, variance x lookups and variance x seconds; (2)
# the whole image: bench/pbrt_grid.py --scene, variance x render seconds over 4 seeds, the two
# estimators interleaved (A B A B) after a warm-up render of each.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build}
CACHE=${SPECTRACK_BENCH_CACHE:-$HOME/.cache/spectrack/bench}
scenes=(bench/scenes/*.json)
grid=$CACHE/pbrt-grid/st_chromatic_g0.6.json
[ -f "$grid" ] && scenes+=("$grid")
echo "transmittance estimators, $(date -u +%F), $(nproc) cores, $(uname -m)"
for s in "${scenes[@]}"; do
  echo "== $s"
  "$BUILD/kernel_throughput" "$s" --points 65536 --paths 4096 | grep "shadow rays"
  /usr/bin/python3 bench/pbrt_grid.py --spectrack "$BUILD/spectrack" --scene "$s" --spp 8 --seeds 4 \
    --config "ratio=--transmittance ratio" --config "ray-marching=--transmittance ray-marching" |
    grep -v "^efficiency\|^'vs\|^'var"
done
