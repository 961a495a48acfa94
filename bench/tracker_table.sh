#!/usr/bin/env bash
# bench/tracker_table.sh [SPP] [SEEDS] [SCENES...]: every tracker x absorption mode x light
# selection on every bench scene (bench/RESULTS.md, 'Every tracker x absorption mode x light selection'), in one run per scene: bench/pbrt_grid.py with
# one configuration each, interleaved seed by seed after a warm-up render each. Prints a markdown
# table per scene: variance x seconds_render and the paper's lookups-to-unit-variance (density
# lookups x variance), both as ratios to delta-per-channel / event / all (> 1: better). `delta` is
# left out on chromatic scenes, which it refuses.
set -euo pipefail
cd "$(dirname "$0")/.."
SPP=${1:-4}; SEEDS=${2:-3}; shift 2 2>/dev/null || shift $#
scenes=("$@"); [ ${#scenes[@]} -gt 0 ] || scenes=(bench/scenes/*.json)
out=$(mktemp -d)
for s in "${scenes[@]}"; do
  b=$(basename "$s" .json)
  chromatic=$(/usr/bin/python3 -c "import json,sys;m=json.load(open('$s'))['media'];print(int(any(len(set(x.get(k,[0,0,0])))>1 for x in m for k in ('sigma_a','sigma_s'))))")
  cfg=()
  for t in delta-per-channel delta spectral decomposition spectral-decomposition spectral-mis; do
    [ "$t" = delta ] && [ "$chromatic" = 1 ] && continue
    for a in event weight; do for l in all uniform power; do
      cfg+=(--config "$t/$a/$l=--tracker $t --absorption $a --light-sampling $l")
    done; done
  done
  /usr/bin/python3 bench/pbrt_grid.py --scene "$s" --spp "$SPP" --seeds "$SEEDS" "${cfg[@]}" --json "$out/$b.json" >/dev/null
  /usr/bin/python3 - "$out/$b.json" "$b" <<'PY'
import json, sys
rows = json.load(open(sys.argv[1]))["rows"]
base = next(r for r in rows if r["label"] == "delta-per-channel/event/all")
print(f"\n{sys.argv[2]} ({len(rows)} configurations)\n")
print("| tracker / absorption / lights | variance | seconds | efficiency | lookups x var |")
print("|---|---|---|---|---|")
for r in sorted(rows, key=lambda r: r["var_x_s"]):
    lv = base["variance"] * base.get("density_lookups", 0) / max(r["variance"] * r.get("density_lookups", 0), 1e-30)
    print(f"| {r['label']} | {r['variance']:.3e} | {r['seconds']:.2f} | {base['var_x_s'] / r['var_x_s']:.2f}x | {lv:.2f}x |")
PY
done
rm -rf "$out"
