#!/usr/bin/env bash
# bench/majorant_hierarchy.sh OLD_BINARY [SPP] [SEEDS] [TRACKERS]: the adaptive majorant hierarchy
# (docs/majorant-hierarchy.md) against the binary before it (OLD_BINARY: a spectrack
# built from a commit before the hierarchy: one 8-voxel cell grid with 4^3-cell empty blocks), on
# pbrt-v4's comparison grid (../shared/bench/pbrt-grid/) and every bench scene, in one run per
# scene, for each tracker of TRACKERS (default: spectral-decomposition, decomposition, spectral,
# delta-per-channel), interleaved seed by seed after a warm-up render each (bench/pbrt_grid.py:
# variance = per-pixel variance over the seeds, seconds = seconds_render). Prints per scene and
# tracker: density lookups, DDA steps and time, new over old, and the efficiency ratio
# 1 / (variance x seconds), new over old (> 1: the hierarchy wins); then decomposition's lookups
# over delta-per-channel's and spectral-decomposition's over spectral's, both new (the issue's
# targets: <= 1/2 on dense, mildly heterogeneous media), and the hierarchy's size per scene.
set -euo pipefail
cd "$(dirname "$0")/.."
OLD=${1:?usage: bench/majorant_hierarchy.sh OLD_BINARY [SPP] [SEEDS] [TRACKERS]}
SPP=${2:-8}; SEEDS=${3:-4}; TRACKERS=${4:-"spectral-decomposition decomposition spectral delta-per-channel"}
out=$(mktemp -d)
configs=()
for t in $TRACKERS; do configs+=(--config "$t=--tracker $t"); done
if [ -d ../shared/bench/pbrt-grid ] && /usr/bin/python3 -c "import pyopenvdb" 2>/dev/null; then
  /usr/bin/python3 bench/pbrt_grid.py --spp $((SPP * 2)) --seeds "$SEEDS" --old "$OLD" "${configs[@]}" --json "$out/pbrt-grid.json"
else
  echo "bench/majorant_hierarchy.sh: the pbrt-v4 grid (../shared/bench/pbrt-grid and python3-openvdb) is missing: skipped"
fi
for s in bench/scenes/*.json; do
  b=$(basename "$s" .json)
  /usr/bin/python3 bench/pbrt_grid.py --scene "$s" --spp "$SPP" --seeds "$SEEDS" --old "$OLD" "${configs[@]}" --json "$out/$b.json"
  ./build/spectrack render "$s" --spp 1 --quiet -o "$out/$b.exr" --stats-json "$out/$b.stats" >/dev/null
done
/usr/bin/python3 - "$out" <<'PY'
import glob, json, os, sys
d = sys.argv[1]
print("\nsummary: the majorant hierarchy (new) over the old grid, per scene and tracker, in one run (interleaved)")
print(f"{'scene':18s} {'tracker':24s} {'lookups':>8s} {'steps':>7s} {'time':>7s} {'variance':>8s} {'efficiency':>10s}")
lookups = {}
for f in sorted(glob.glob(os.path.join(d, "*.json"))):
    scene = os.path.basename(f)[:-5]
    rows = {r["label"]: r for r in json.load(open(f))["rows"]}
    for label, new in rows.items():
        if label.endswith(" [old]") or label + " [old]" not in rows:
            continue
        old = rows[label + " [old]"]
        lookups[(scene, label)] = new.get("density_lookups", 0)
        r = lambda k: new.get(k, 0) / max(old.get(k, 0), 1)
        print(f"{scene:18s} {label:24s} {r('density_lookups'):7.2f}x {r('dda_steps'):6.2f}x "
              f"{new['seconds'] / old['seconds']:6.2f}x {new['variance'] / old['variance']:7.2f}x "
              f"{old['var_x_s'] / new['var_x_s']:9.2f}x")
print("\nnew density lookups: decomposition / delta-per-channel, spectral-decomposition / spectral")
for scene in sorted({s for s, _ in lookups}):
    q = lambda a, b: (f"{lookups[(scene, a)] / lookups[(scene, b)]:.2f}"
                      if (scene, a) in lookups and lookups.get((scene, b)) else "-")
    print(f"{scene:18s} {q('decomposition', 'delta-per-channel'):>6s} {q('spectral-decomposition', 'spectral'):>6s}")
print("\nthe hierarchy of each bench scene's first VDB medium (the scene's own tracker)")
for f in sorted(glob.glob(os.path.join(d, "*.stats"))):
    for m in json.load(open(f)).get("majorant_grids", [])[:1]:
        print(f"{os.path.basename(f)[:-6]:18s} cell {m['cell']} block {m['block']} levels {m['levels']} "
              f"blocks per level {m['blocks_per_level']} {m['bytes'] / 1024:.0f} KiB, built in {m['seconds_build'] * 1e3:.1f} ms")
PY
rm -rf "$out"
