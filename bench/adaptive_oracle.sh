#!/usr/bin/env bash
# bench/adaptive_oracle.sh [TARGET] [SCALE] [REF_SPP_SMOKE] [REF_SPP_CLOUD]: the bound on adaptive
# sampling's gain under the noise target's statistic (bench/adaptive_oracle.py), on the films of
# bench/adaptive.sh (smoke1 and the Disney cloud, the cloud's film scaled by SCALE / 2). Per scene:
# a long uniform render with the variance layer (seed 99), an adaptive render to TARGET (seed 1)
# with its per-pixel trace (SPECTRACK_ADAPTIVE_PIXELS: samples and work per pixel; BASE=binary adds
# that binary's adaptive render, its trace the row "measured: base"), the cost model
# of a sample, c_p = A + B w_p (w_p the pixel's density lookups and majorant steps per sample),
# fitted by least squares to the CPU seconds of uniform renders of four horizontal bands of the
# film (--pixel-bounds, 512 spp: samples and work, tracking, shadow and alpha, from their statistics), and the fixed CPU seconds
# of a render (a 1-sample render, whole process). Then adaptive_oracle.py prints the costs.
set -euo pipefail
cd "$(dirname "$0")/.."
TARGET=${1:-0.05}; SCALE=${2:-0.25}; REF_SMOKE=${3:-8192}; REF_CLOUD=${4:-8192}
BIN=${BIN:-./build/spectrack}
CAP=${CAP:-1024}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
echo "adaptive oracle: $BIN, noise target $TARGET, spp cap $CAP, film scale $SCALE," \
     "$(date -u '+%F %H:%M') UTC on $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg), commit $(git rev-parse --short HEAD)"
for entry in bench/scenes/smoke1.json:1:$REF_SMOKE data/scenes/disney_cloud.json:0.5:$REF_CLOUD; do
  IFS=: read -r s f ref_spp <<<"$entry"
  n=$(basename "$s" .json)
  /usr/bin/python3 bench/scaled_scene.py "$s" "$out/$n.json" "$(/usr/bin/python3 -c "print($SCALE * $f)")"
  read -r W H < <(/usr/bin/python3 -c "import json; f = json.load(open('$out/$n.json'))['film']; print(f['width'], f['height'])")
  $BIN render "$out/$n.json" -q --spp 16 -o "$out/w.exr" >/dev/null  # kernels cached
  /usr/bin/time -f "%U %S" -o "$out/$n.fixed.cpu" $BIN render "$out/$n.json" -q --spp 1 -o "$out/w.exr" >/dev/null
  $BIN render "$out/$n.json" -q --seed 99 --spp "$ref_spp" --aov variance -o "$out/$n.ref.exr" >/dev/null
  traces=""
  for mode in adaptive${BASE:+ base}; do
    bin=$BIN; [ "$mode" = base ] && bin=$BASE
    SPECTRACK_ADAPTIVE_PIXELS="$out/$n.$mode.txt" $bin render "$out/$n.json" -q --seed 1 --spp "$CAP" \
      --noise-target "$TARGET" --adaptive -o "$out/$n.adaptive.exr" >/dev/null
    traces="$traces${traces:+,}$mode=$out/$n.$mode.txt"
  done
  for band in 0 1 2 3; do
    y0=$((H * band / 4)); y1=$((H * (band + 1) / 4))
    $BIN render "$out/$n.json" -q --seed 7 --spp 512 --pixel-bounds "0,$W,$y0,$y1" -o "$out/b.exr" \
      --stats-json "$out/$n.band$band.json" >/dev/null
  done
  read -r A B FIXED < <(/usr/bin/python3 - "$out" "$n" <<'PY'
import json, sys
import numpy as np
out, n = sys.argv[1], sys.argv[2]
rows, t = [], []
for band in range(4):
    j = json.load(open(f"{out}/{n}.band{band}.json"))
    st = j.get("stats", j)
    work = sum(float(st.get(k, 0)) for k in ("density_lookups_tracking", "density_lookups_shadow", "density_lookups_alpha", "dda_steps"))
    samples = float(j["spp"]) * float(j["width"]) * float(j["height"])
    rows.append([samples, work])
    t.append(float(j["cpu_seconds_render"]))
(a, b), *_ = np.linalg.lstsq(np.array(rows), np.array(t), rcond=None)
fixed = sum(map(float, open(f"{out}/{n}.fixed.cpu").read().split()[-2:]))
print(a, b, fixed)
PY
)
  /usr/bin/python3 bench/adaptive_oracle.py "$out/$n.ref.exr" "$traces" "$TARGET" "$A" "$B" "$FIXED" "$n ${W}x$H"
done
