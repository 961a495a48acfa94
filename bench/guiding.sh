#!/bin/bash
# bench/guiding.sh BIN [SPP] [SEEDS]: efficiency of volume path guiding against the unguided render
# on bench/scenes/dense_subsurface.json and cloud_chromatic.json: for each seed, an unguided and a
# guided render (interleaved, the same binary and settings), each with the variance layer; prints
# per run the mean over pixels and channels of the variance of the pixel means, seconds_render
# (training included), and the efficiency 1 / (variance x seconds_render). Raw lines, one per run.
BIN=${1:?usage: bench/guiding.sh BIN [SPP] [SEEDS]}; SPP=${2:-8}; SEEDS=${3:-3}
cd "$(dirname "$0")/.."; out=$(mktemp -d)
echo "# $(date -u '+%Y-%m-%d %H:%M UTC') $(uname -n) $(nproc) cores; $BIN; spp $SPP; seeds 1..$SEEDS"
echo "# scene seed guiding mean_variance seconds_render seconds_training efficiency regions_guided records"
for scene in dense_subsurface cloud_chromatic; do
  for seed in $(seq 1 $SEEDS); do
    for g in off on; do
      $BIN render bench/scenes/$scene.json --spp $SPP --seed $seed --guiding $g --aov variance --no-alpha \
        -o $out/r.exr --quiet --stats-json $out/r.json || { echo "FAIL $scene $seed $g"; continue; }
      v=$(oiiotool $out/r.exr --ch variance.R,variance.G,variance.B --printstats 2>/dev/null | awk '/Stats Avg/ {print ($3+$4+$5)/3}')
      python3 - "$out/r.json" "$scene" "$seed" "$g" "$v" <<'PY'
import json, sys
j = json.load(open(sys.argv[1])); v = float(sys.argv[5]); t = j["seconds_render"]
print(sys.argv[2], sys.argv[3], sys.argv[4], f"{v:.6g}", f"{t:.3f}", f"{j.get('seconds_guide_training', 0):.3f}",
      f"{1.0 / (v * t):.6g}", j.get("guide_regions_guided", 0), j.get("guide_training_records", 0))
PY
    done
  done
done
rm -rf $out
