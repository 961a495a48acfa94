#!/usr/bin/env bash
# bench/gpu_step_cost.sh [OUT_DIR]: the majorant hierarchy's step cost on a GPU
# (docs/majorant-hierarchy.md), sized for about 4 minutes on the `device` tool's H200.
#
# The hierarchy's cost model weighs a DDA step into a non-empty group against a density lookup
# (--majorant-step-cost, in lookups; automatic: 0.6, 2 for spectral-decomposition, measured on
# PoCL). A GPU's lookups are dear against its steps (build/kernel_throughput on the H200: 9.3e7
# lookups/s against 1.2e9 DDA steps/s), so finer levels may pay there. For each scene and tracker
# this renders, after a warm-up, SPP samples for SEEDS seeds with each step cost of COSTS
# ("auto": none given) interleaved seed by seed, plus the bundle's spectrack_old (gpu_bundle.py
# --old) with its defaults, and writes one TSV row per render: seconds_render, paths/s, density
# lookups, DDA steps. The variance of each configuration is the same on any device (the same
# estimator): take it from a CPU run (bench/pbrt_grid.py --config) and combine.
#
# Setup as bench/gpu.sh (STEPS=0 there unpacks a bundle; GPU_DEVICE picks the device).
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/gpu-step-cost-$(date -u +%Y%m%dT%H%M%S)}
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
SPP=${SPP:-64}
SEEDS=${SEEDS:-"1 2"}
COSTS=${COSTS:-"auto 0.6 0.2 0.05"}
TRACKERS=${TRACKERS:-"spectral-decomposition decomposition"}
SCENES=${SCENES:-"bench/scenes/cloud_chromatic.json bench/scenes/dense_subsurface.json bench/scenes/dense_chromatic.json data/scenes/disney_cloud.json bench/scenes/smoke_thin.json"}
STEPS=0 bash bench/gpu.sh "$OUT/setup" > "$OUT/setup.log" 2>&1 || true
tail -n 5 "$OUT/setup.log"
build/spectrack devices | tee "$OUT/devices.txt"
DEV=${GPU_DEVICE:-$(awk '$0 ~ / GPU / {print $1; exit}' "$OUT/devices.txt")}
[ -n "$DEV" ] || { echo "gpu_step_cost.sh: no GPU device listed"; exit 2; }
export SPECTRACK_DEVICE=$DEV
command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
printf 'scene\ttracker\tconfig\tseed\tspp\tseconds_render\tpaths_per_second\tdensity_lookups\tdda_steps\n' > "$OUT/step_cost.tsv"
row() {  # scene tracker config seed stats.json
  python3 -c "
import json, sys; j = json.load(open(sys.argv[5]))
print('\t'.join(sys.argv[1:5] + [str(x) for x in ['$SPP', j['seconds_render'], round(j['paths_per_second']), j['density_lookups'], j['dda_steps']]]))" "$@" >> "$OUT/step_cost.tsv"
}
for s in $SCENES; do
  b=$(basename "$s" .json)
  for t in $TRACKERS; do
    build/spectrack render "$s" --tracker "$t" --spp 4 -q --no-alpha -o "$OUT/warm.exr" >/dev/null 2>&1 || echo "warm-up failed: $b $t"
    [ -x build/spectrack_old ] && build/spectrack_old render "$s" --tracker "$t" --spp 4 -q --no-alpha -o "$OUT/warm.exr" >/dev/null 2>&1
    for seed in $SEEDS; do
      for c in $COSTS old; do
        bin=build/spectrack; flags=()
        [ "$c" = old ] && { [ -x build/spectrack_old ] || continue; bin=build/spectrack_old; }
        [ "$c" != old ] && [ "$c" != auto ] && flags=(--majorant-step-cost "$c")
        $bin render "$s" --tracker "$t" "${flags[@]}" --spp "$SPP" --seed "$seed" -q --no-alpha -o "$OUT/r.exr" \
          --stats-json "$OUT/r.json" >/dev/null 2>&1 || { echo "render failed: $b $t $c $seed"; continue; }
        row "$b" "$t" "$c" "$seed" "$OUT/r.json"
      done
    done
  done
done
rm -f "$OUT/warm.exr" "$OUT/r.exr" "$OUT/r.json"
python3 - "$OUT/step_cost.tsv" <<'PY'
import csv, sys, collections
rows = list(csv.DictReader(open(sys.argv[1]), delimiter="\t"))
acc = collections.defaultdict(lambda: [0.0, 0.0, 0.0, 0])
for r in rows:
    a = acc[(r["scene"], r["tracker"], r["config"])]
    a[0] += float(r["seconds_render"]); a[1] += float(r["density_lookups"]); a[2] += float(r["dda_steps"]); a[3] += 1
print(f"{'scene':18s} {'tracker':24s} {'config':>6s} {'seconds':>8s} {'lookups':>10s} {'steps':>10s}")
for (s, t, c), (sec, lk, st, n) in acc.items():
    print(f"{s:18s} {t:24s} {c:>6s} {sec / n:8.4f} {lk / n:10.0f} {st / n:10.0f}")
PY
