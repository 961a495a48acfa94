#!/usr/bin/env bash
# bench/blackbody.sh [SPP] [ROUNDS]: the cost of blackbody emission (docs/scene-format.md
# "Blackbody emission") on the fire scenes, in one run: each scene as shipped (blackbody: a
# temperature-grid lookup and the colour table), its twin with emission "radiance" read from the
# same grid (the same lookup, no table: what the table adds), and its twin without emission,
# interleaved round by round after a warm-up render of each (kernel builds cached), the order
# rotated every round. Prints seconds_render of each, their ratios to the radiance twin, and the
# emission lookups per path.
set -euo pipefail
cd "$(dirname "$0")/.."
SPP=${1:-16}; ROUNDS=${2:-3}
BIN=${BIN:-./build/spectrack}
out=$(mktemp -d)
order="blackbody radiance none"
echo "blackbody emission: $BIN, $SPP spp, $ROUNDS interleaved rounds, $(date -u +%F) on $(nproc) cores"
for s in data/scenes/fire.json data/scenes/fire_usd.json; do
  n=$(basename "$s" .json)
  dir=$(cd "$(dirname "$s")" && pwd)
  # the twins, written beside the scene so that its relative paths hold
  /usr/bin/python3 - "$s" "$out/$n" <<'PY'
import json, sys
src, base = sys.argv[1], sys.argv[2]
j = json.load(open(src))
m = j["media"][0]
e = m["emission"]
grid = e.get("temperature_grid", "heat" if "usd" in src else "temperature")
json.dump(j, open(base + ".blackbody.json", "w"))
m["emission"] = {"radiance": [1.0, 0.5, 0.2], "grid": grid, "scale": 1e-3}
json.dump(j, open(base + ".radiance.json", "w"))
del m["emission"]
json.dump(j, open(base + ".none.json", "w"))
PY
  for c in $order; do cp "$out/$n.$c.json" "$dir/.bench_$n.$c.json"; done
  for c in $order; do $BIN render "$dir/.bench_$n.$c.json" -q --spp 1 -o "$out/w.exr" >/dev/null; done
  for r in $(seq "$ROUNDS"); do
    set -- $order; k=$(( (r - 1) % $# )); rot="${*:k+1} ${*:1:k}"
    for c in $rot; do
      $BIN render "$dir/.bench_$n.$c.json" -q --spp "$SPP" -o "$out/$n.$c.exr" --stats-json "$out/$n.$c.$r.json" >/dev/null
    done
  done
  for c in $order; do rm -f "$dir/.bench_$n.$c.json"; done
  /usr/bin/python3 - "$out" "$n" "$ROUNDS" $order <<'PY'
import json, sys
out, n, rounds, order = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4:]
sec = {c: sum(json.load(open(f"{out}/{n}.{c}.{r}.json"))["seconds_render"] for r in range(1, rounds + 1)) / rounds for c in order}
st = json.load(open(f"{out}/{n}.blackbody.1.json"))
paths = max(st["paths"], 1)
print(f"{n:10s} " + " ".join(f"{c} {sec[c]:6.3f}s ({sec[c] / sec['radiance']:.3f}x)" for c in order) +
      f"  emission lookups/path {st['emission_lookups'] / paths:.2f}, paths {paths}")
PY
done
rm -rf "$out"
