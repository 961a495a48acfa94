#!/usr/bin/env bash
# bench/motion_blur.sh [SPP] [SEEDS] [SPEEDS]: the cost of Eulerian motion blur per sample
# (docs/scene-format.md, "Motion blur"): Blender's smoke frame (../shared/data/vdb/usd/
# smoke_000002.vdb, density only) with a synthetic swirling velocity grid of each largest speed
# in SPEEDS (world units per second, default "5 20"; tools/add_velocity.cpp), rendered with the
# default tracker still (--shutter 0:0: the velocity grid is read but nothing moves, the still
# medium's kernels and image) and blurred (--shutter -0.01:0.01, a 180-degree shutter at 50 frames
# per second), interleaved A B A B seed by seed after one warm-up render of each (warm kernel
# caches). Prints per speed and seed the render seconds of both, and the ratio blurred / still per
# sample, their mean, the density lookups per sample of both (the velocity's lookups included),
# and the ratio of the kernels' own seconds (the stats' per-kernel profiled times, summed: the
# device's work without the host's share of the render).
set -euo pipefail
cd "$(dirname "$0")/.."
SPP=${1:-16}; SEEDS=${2:-4}; SPEEDS=${3:-"5 20"}
BUILD=${BUILD:-build}
SMOKE=../shared/data/vdb/usd/smoke_000002.vdb
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
echo "bench/motion_blur.sh $SPP $SEEDS \"$SPEEDS\" on $(hostname), $(date -u +%FT%TZ), $(nproc) cores, $(git rev-parse --short HEAD)"
for speed in $SPEEDS; do
  "$BUILD/add_velocity" "$SMOKE" "$out/smoke_vel.vdb" --speed "$speed"
  cat > "$out/scene.json" <<JSON
{"format": "spectrack-scene/1",
 "camera": {"type": "perspective", "position": [0, -14, 4], "look_at": [0, 0, 4], "up": [0, 0, 1], "fov_deg": 45},
 "film": {"width": 160, "height": 160, "spp": $SPP},
 "render": {"max_depth": 16},
 "lights": [{"type": "environment", "radiance": [0.3, 0.35, 0.4]},
            {"type": "directional", "to_light": [0.5, -0.4, 1], "irradiance": [3, 3, 3]}],
 "media": [{"type": "vdb", "file": "$out/smoke_vel.vdb", "sigma_s": [8, 8, 8], "sigma_a": [0.5, 0.5, 0.5],
            "velocity": {"grid": "vel"}}]}
JSON
  run() {  # label seed shutter
    "$BUILD/spectrack" render "$out/scene.json" -o "$out/$1.exr" --seed "$2" --shutter "$3" --quiet \
      --stats-json "$out/$1.json"
    /usr/bin/python3 -c "import json,sys; j=json.load(open(sys.argv[1])); print(j['seconds_render'], j['density_lookups'], sum(k['seconds'] for k in j['kernels'].values()))" "$out/$1.json"
  }
  run warm_still 99 0:0 >/dev/null
  run warm_blur 99 -0.01:0.01 >/dev/null
  for seed in $(seq 1 "$SEEDS"); do
    read -r s0 l0 k0 < <(run still "$seed" 0:0)
    read -r s1 l1 k1 < <(run blur "$seed" -0.01:0.01)
    echo "speed $speed seed $seed still ${s0}s blurred ${s1}s ratio $(/usr/bin/python3 -c "print(f'{$s1/$s0:.3f}')") lookups/sample still $(/usr/bin/python3 -c "print(f'{$l0/($SPP*160*160):.1f}')") blurred $(/usr/bin/python3 -c "print(f'{$l1/($SPP*160*160):.1f}')") kernel seconds still $(/usr/bin/python3 -c "print(f'{$k0:.3f}')") blurred $(/usr/bin/python3 -c "print(f'{$k1:.3f}')") ratio $(/usr/bin/python3 -c "print(f'{$k1/$k0:.3f}')")"
  done
done | tee "$out/log.txt"
/usr/bin/python3 - "$out/log.txt" <<'PY'
import collections, sys
r = collections.defaultdict(list)
k = collections.defaultdict(list)
for line in open(sys.argv[1]):
    w = line.split()
    if w and w[0] == "speed":
        r[w[1]].append(float(w[w.index("ratio") + 1]))
        k[w[1]].append(float(w[len(w) - 1]))
print("\nsummary: blurred over still render seconds per sample (same spp), mean and range over seeds;")
print("the kernels' own seconds likewise")
for speed, v in r.items():
    print(f"speed {speed:>4s} units/s: {sum(v) / len(v):.3f}x ({min(v):.3f} .. {max(v):.3f}, {len(v)} seeds); "
          f"kernels {sum(k[speed]) / len(k[speed]):.3f}x ({min(k[speed]):.3f} .. {max(k[speed]):.3f})")
PY
