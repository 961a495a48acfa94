#!/usr/bin/env bash
# bench/motion_blur_reach.sh OLD NEW [SPEEDS] [ROUNDS]: the load of a medium that moves far over the
# shutter (docs/scene-format.md, "Motion blur": past 1e9 voxel reads each majorant cell is bounded
# by the 8^3 leaves its grown extent meets). Blender's smoke frame (../shared/data/vdb/usd/
# smoke_000002.vdb, voxel 0.13) with tools/add_velocity.cpp's swirl at each speed of SPEEDS
# (default "300 800"; largest speed 1.6x that), shutter -0.01:0.01 s, a 32x32 film at 1 spp, so the
# wall time is the load, mostly the majorant bounds. OLD and NEW alternate (A B, B A) for ROUNDS
# rounds (default 2), each run limited to 300 s (a timeout prints as > 300). Prints each run's wall
# seconds and per speed the ratio of the medians OLD / NEW.
set -euo pipefail
cd "$(dirname "$0")/.."
OLD=$1; NEW=$2; SPEEDS=${3:-"300 800"}; ROUNDS=${4:-2}
SMOKE=../shared/data/vdb/usd/smoke_000002.vdb
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
echo "bench/motion_blur_reach.sh $OLD $NEW \"$SPEEDS\" $ROUNDS on $(hostname), $(date -u +%FT%TZ), $(nproc) cores," \
     "load $(cut -d' ' -f1-3 /proc/loadavg), $(git rev-parse --short HEAD)"
for speed in $SPEEDS; do
  build/add_velocity "$SMOKE" "$out/v.vdb" --speed "$speed"
  cat > "$out/scene.json" <<JSON
{"format": "spectrack-scene/1",
 "camera": {"type": "perspective", "position": [0, -14, 4], "look_at": [0, 0, 4], "up": [0, 0, 1], "fov_deg": 45, "shutter": [-0.01, 0.01]},
 "film": {"width": 32, "height": 32, "spp": 1},
 "lights": [{"type": "environment", "radiance": [0.3, 0.35, 0.4]}],
 "media": [{"type": "vdb", "file": "$out/v.vdb", "sigma_s": [8, 8, 8], "sigma_a": [0.5, 0.5, 0.5], "velocity": {"grid": "vel"}}]}
JSON
  declare -A t=([old]="" [new]="")
  for r in $(seq "$ROUNDS"); do
    order="old new"; [ $((r % 2)) -eq 0 ] && order="new old"
    for side in $order; do
      bin=$OLD; [ "$side" = new ] && bin=$NEW
      s=$(date +%s.%N)
      if timeout 300 "$bin" render "$out/scene.json" -q -o "$out/o.exr" >/dev/null 2>&1; then
        w=$(/usr/bin/python3 -c "print(f'{$(date +%s.%N) - $s:.2f}')")
      else
        w=300
      fi
      echo "speed $speed round $r $side ${w} s$([ "$w" = 300 ] && echo ' (timed out: > 300)')"
      t[$side]+="$w "
    done
  done
  /usr/bin/python3 -c "
import statistics as st, sys
o = [float(x) for x in '${t[old]}'.split()]; n = [float(x) for x in '${t[new]}'.split()]
print(f'speed $speed: old median {st.median(o):.2f} s, new median {st.median(n):.2f} s, old / new {st.median(o) / st.median(n):.1f}x'
      + (' (old timed out: a lower bound)' if max(o) >= 300 else ''))"
done
