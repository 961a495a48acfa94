#!/usr/bin/env bash
# bench/stochastic_lookup.sh [SPP] [SEEDS] [TRACKERS]: stochastic one-voxel lookups against
# trilinear ones (docs/stochastic-lookup.md). On pbrt-v4's comparison grid
# (../shared/bench/pbrt-grid/) and every bench scene, in one run per scene, for each tracker of
# TRACKERS (default: the default spectral-decomposition, delta-per-channel, spectral-mis): the
# tracker with --lookup trilinear and --lookup stochastic, interleaved seed by seed after a warm-up
# render each (bench/pbrt_grid.py: variance = per-pixel variance over the seeds, seconds =
# seconds_render). Prints per scene and tracker the variance the stochastic lookup adds, the time
# it saves and the efficiency ratio 1 / (variance x seconds), stochastic over trilinear (> 1: the
# stochastic lookup wins), with the density lookups per second of both.
set -euo pipefail
cd "$(dirname "$0")/.."
SPP=${1:-8}; SEEDS=${2:-4}; TRACKERS=${3:-"spectral-decomposition delta-per-channel spectral-mis"}
out=$(mktemp -d)
configs=()
for t in $TRACKERS; do
  configs+=(--config "$t/trilinear=--tracker $t --lookup trilinear" --config "$t/stochastic=--tracker $t --lookup stochastic")
done
if [ -d ../shared/bench/pbrt-grid ] && /usr/bin/python3 -c "import pyopenvdb" 2>/dev/null; then
  /usr/bin/python3 bench/pbrt_grid.py --spp $((SPP * 2)) --seeds "$SEEDS" "${configs[@]}" --json "$out/pbrt-grid.json"
else
  echo "bench/stochastic_lookup.sh: the pbrt-v4 grid (../shared/bench/pbrt-grid and python3-openvdb) is missing: skipped"
fi
for s in bench/scenes/*.json; do
  b=$(basename "$s" .json)
  /usr/bin/python3 bench/pbrt_grid.py --scene "$s" --spp "$SPP" --seeds "$SEEDS" "${configs[@]}" --json "$out/$b.json"
done
/usr/bin/python3 - "$out" <<'PY'
import glob, json, os, sys
print("\nsummary: stochastic over trilinear lookups, per scene and tracker, in one run (interleaved)")
print("variance: x added; time: trilinear seconds / stochastic seconds; efficiency: 1/(variance x seconds), ratio")
print(f"{'scene':18s} {'tracker':24s} {'variance':>9s} {'time saved':>10s} {'efficiency':>10s} {'Mlookups/s tri':>14s} {'sto':>6s}")
for f in sorted(glob.glob(os.path.join(sys.argv[1], "*.json"))):
    rows = {r["label"]: r for r in json.load(open(f))["rows"]}
    for label, tri in rows.items():
        if not label.endswith("/trilinear"):
            continue
        t = label[: -len("/trilinear")]
        sto = rows[t + "/stochastic"]
        lps = lambda r: r.get("density_lookups", 0) / max(r["seconds"], 1e-9) / 1e6
        print(f"{os.path.basename(f)[:-5]:18s} {t:24s} {sto['variance'] / tri['variance']:8.3f}x "
              f"{tri['seconds'] / sto['seconds']:9.3f}x {tri['var_x_s'] / sto['var_x_s']:9.3f}x "
              f"{lps(tri):14.2f} {lps(sto):6.2f}")
PY
rm -rf "$out"
