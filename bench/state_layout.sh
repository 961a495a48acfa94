#!/usr/bin/env bash
# bench/state_layout.sh [BINARY]: paths/s and CPU seconds of the two path state layouts
# (kernels/path_state.h) of one spectrack binary (default build/spectrack) on the default device:
# bench/host_waits.sh with OLD = the binary under SPECTRACK_STATE_LAYOUT=aos and NEW = the same
# binary under SPECTRACK_STATE_LAYOUT=soa, so its NEW/OLD ratios are soa/aos (interleaved A B, B A
# per round and seed, after a warm-up render of each layout: both kernel builds cached). Defaults:
# SPP=16, ROUNDS=2, SEEDS="0 1", SCENES = dense_subsurface, smoke1, cloud_chromatic (all override).
# Where `perf stat -e instructions:u` counts (a machine whose load does not disturb the count),
# each layout's user-space instructions of one render per scene follow.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=$(realpath "${1:-build/spectrack}")
w=$(mktemp -d)
for l in aos soa; do printf '#!/bin/sh\nSPECTRACK_STATE_LAYOUT=%s exec %s "$@"\n' "$l" "$BIN" > "$w/spectrack_$l"; chmod +x "$w/spectrack_$l"; done
export SPP=${SPP:-16} ROUNDS=${ROUNDS:-2} SEEDS=${SEEDS:-0 1}
export SCENES=${SCENES:-bench/scenes/dense_subsurface.json bench/scenes/smoke1.json bench/scenes/cloud_chromatic.json}
echo "state layouts of $BIN: OLD = aos, NEW = soa (ratios NEW/OLD = soa/aos)"
bash bench/host_waits.sh "$w/spectrack_aos" "$w/spectrack_soa"
if perf stat -x, -e instructions:u true 2>&1 | grep -q '^[0-9]'; then
  for s in $SCENES; do
    for l in aos soa; do
      n=$(perf stat -x, -e instructions:u "$w/spectrack_$l" render "$s" --spp "$SPP" --seed 0 -q --no-alpha -o "$w/i.exr" 2>&1 >/dev/null |
        awk -F, '/instructions/ {print $1}')
      echo "instructions:u $(basename "$s" .json) $l $n"
    done
  done
else
  echo "perf stat -e instructions:u: not supported on this machine (no hardware counters)"
fi
rm -rf "$w"
