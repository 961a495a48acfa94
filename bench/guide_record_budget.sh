#!/bin/bash
# bench/guide_record_budget.sh OLD NEW [SPP] [SEEDS] [SCENES...]: a guide training pass that records
# from every camera sample (OLD: a binary without the budget, or NEW with
# SPECTRACK_GUIDE_RECORD_SAMPLES=0) against one that records from at most kGuideRecordSamples of
# them (NEW), on films large enough for the budget to act. Per scene and seed, interleaved
# (off, old, new, off, ...): the mean pixel variance (variance layer), seconds_render, the training's
# seconds, its host fit's seconds, its records, the regions, and the process's peak resident memory
# (GNU time). Then per scene: old/new of records, peak memory and fit seconds, and the variance of
# `off` over each guided render's (above 1: guiding lowers the variance). SCENES are scene files
# (make larger films with bench/scaled_scene.py); default: guide_oracle at 512x512 and
# dense_subsurface at 512x384, both written to a temporary folder. Guided renders are `--guiding on
# --guide-splitting off` (what `auto` turns on where it guides).
OLD=${1:?usage: bench/guide_record_budget.sh OLD NEW [SPP] [SEEDS] [SCENES...]}; NEW=${2:?NEW binary}
SPP=${3:-16}; SEEDS=${4:-2}; shift 4 2>/dev/null || shift $#
cd "$(dirname "$0")/.."; out=$(mktemp -d)
SCENES=("$@")
if [ ${#SCENES[@]} -eq 0 ]; then
  python3 bench/scaled_scene.py bench/scenes/guide_oracle.json "$out/guide_oracle_512x512.json" 8
  python3 bench/scaled_scene.py bench/scenes/dense_subsurface.json "$out/dense_subsurface_512x384.json" 4
  SCENES=("$out/guide_oracle_512x512.json" "$out/dense_subsurface_512x384.json")
fi
echo "# $(date -u '+%Y-%m-%d %H:%M UTC') $(uname -n) $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg); old $OLD; new $NEW; spp $SPP; seeds 1..$SEEDS"
echo "# scene seed config mean_variance seconds_render seconds_training seconds_fit records regions peak_rss_mb"
raw=$out/raw.txt
for scene in "${SCENES[@]}"; do
  name=$(basename "$scene" .json)
  for seed in $(seq 1 "$SEEDS"); do
    for c in off old new; do
      bin=$NEW; flags="--guiding on --guide-splitting off"
      [ $c = old ] && bin=$OLD
      [ $c = off ] && flags="--guiding off"
      /usr/bin/time -f "%M" -o "$out/rss" "$bin" render "$scene" --spp "$SPP" --seed "$seed" $flags --aov variance --no-alpha \
        -o "$out/r.exr" --quiet --stats-json "$out/r.json" || { echo "FAIL $name $seed $c"; continue; }
      v=$(oiiotool "$out/r.exr" --ch variance.R,variance.G,variance.B --printstats 2>/dev/null | awk '/Stats Avg/ {print ($3+$4+$5)/3}')
      python3 - "$out/r.json" "$name" "$seed" "$c" "$v" "$(tail -1 "$out/rss")" <<'PY' | tee -a "$raw"
import json, sys
j = json.load(open(sys.argv[1]))
print(sys.argv[2], sys.argv[3], sys.argv[4], sys.argv[5], round(j["seconds_render"], 3), round(j.get("seconds_guide_training", 0), 3),
      round(j.get("seconds_guide_fit", 0), 3), j.get("guide_training_records", 0), j.get("guide_regions", 0),
      round(int(sys.argv[6]) / 1024))
PY
    done
  done
done
python3 - "$raw" <<'PY'
import collections, sys
rows = collections.defaultdict(dict)
for line in open(sys.argv[1]):
    f = line.split()
    rows[(f[0], f[1])][f[2]] = [float(x) for x in f[3:]]
print("# Summary per scene, per seed: old/new records | old/new peak memory | old/new fit seconds | off/old, off/new variance")
by = collections.defaultdict(list)
for (scene, seed), r in sorted(rows.items()):
    if {"off", "old", "new"} <= r.keys():
        by[scene].append(r)
for scene, rs in by.items():
    rec = " ".join(f"{r['old'][5] / max(r['new'][5], 1):.2f}" for r in rs)
    mem = " ".join(f"{r['old'][6] / r['new'][6]:.2f}" for r in rs)
    fit = " ".join(f"{r['old'][3] / max(r['new'][3], 1e-9):.2f}" for r in rs)
    vo = " ".join(f"{r['off'][0] / r['old'][0]:.3f}" for r in rs)
    vn = " ".join(f"{r['off'][0] / r['new'][0]:.3f}" for r in rs)
    print(f"# {scene}: records {rec} | peak memory {mem} | fit {fit} | variance off/old {vo}, off/new {vn}")
PY
rm -rf "$out"
