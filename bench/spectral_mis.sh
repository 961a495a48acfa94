#!/usr/bin/env bash
# bench/spectral_mis.sh [SPP] [SEEDS]: which estimator wins in which regime (docs/estimators.md, 'Spectral MIS').
# On pbrt-v4's comparison grid (../shared/bench/pbrt-grid/, strongly chromatic) and every bench
# scene, in one run per scene: the default tracker (spectral-decomposition, history-average,
# absorption weight), spectral-mis with absorption as a weight and as an event (pbrt-v4's volpath
# is the event variant), and delta-per-channel (the analog baseline), interleaved seed by seed
# after a warm-up render each (bench/pbrt_grid.py: variance = per-pixel variance over the seeds,
# times seconds_render; lookups per render from --stats-json). Prints one table per scene and a
# summary of efficiency and lookups-to-unit-variance relative to delta-per-channel.
set -euo pipefail
cd "$(dirname "$0")/.."
SPP=${1:-8}; SEEDS=${2:-4}
out=$(mktemp -d)
configs=(--config "default=" --config "spectral-mis=--tracker spectral-mis"
         --config "spectral-mis-event=--tracker spectral-mis --absorption event"
         --config "delta-per-channel=--tracker delta-per-channel")
if [ -d ../shared/bench/pbrt-grid ] && /usr/bin/python3 -c "import pyopenvdb" 2>/dev/null; then
  /usr/bin/python3 bench/pbrt_grid.py --spp $((SPP * 2)) --seeds "$SEEDS" "${configs[@]}" --json "$out/grid.json"
else
  echo "bench/spectral_mis.sh: the pbrt-v4 grid (../shared/bench/pbrt-grid and python3-openvdb) is missing: skipped"
fi
for s in bench/scenes/*.json; do
  b=$(basename "$s" .json)
  /usr/bin/python3 bench/pbrt_grid.py --scene "$s" --spp "$SPP" --seeds "$SEEDS" "${configs[@]}" --json "$out/$b.json"
done
/usr/bin/python3 - "$out" <<'PY'
import glob, json, os, sys
print("\nsummary: efficiency 1/(variance x seconds) and lookups-to-unit-variance (variance x density lookups),")
print("both relative to delta-per-channel in the same run (> 1: better than the baseline)")
print(f"{'scene':18s} {'configuration':20s} {'efficiency':>10s} {'lookups x var':>13s}")
for f in sorted(glob.glob(os.path.join(sys.argv[1], "*.json"))):
    rows = {r["label"]: r for r in json.load(open(f))["rows"]}
    base = rows["delta-per-channel"]
    for label, r in rows.items():
        if label == "delta-per-channel":
            continue
        eff = base["var_x_s"] / r["var_x_s"]
        lv = (base["variance"] * base.get("density_lookups", 0)) / max(r["variance"] * r.get("density_lookups", 0), 1e-30)
        print(f"{os.path.basename(f)[:-5]:18s} {label:20s} {eff:9.2f}x {lv:12.2f}x")
PY
rm -rf "$out"
