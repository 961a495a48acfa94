#!/usr/bin/env bash
# bench/film_layers.sh [SPP] [ROUNDS]: the cost of the film layers (docs/aov.md) per
# scene, in one run: the same binary with --no-alpha (the beauty alone), --no-alpha --aov variance
# (no per-path work: one more film layer), the EXR default (alpha: a transmittance estimate along
# every camera ray, and the environment layer), the denoiser's albedo and depth buffers alone
# (--no-alpha --aov albedo,depth: one delta-tracking flight per camera ray) and every layer (alpha,
# environment, variance, the emission, direct and indirect passes, albedo and depth), interleaved round by round after a
# warm-up render of each (both kernel builds cached), the order rotated every round. Prints per scene seconds_render of each and
# its ratio to the beauty alone, and the camera-ray layers' density lookups per camera path (every
# layer: the alpha estimate's and the albedo/depth flight's) beside the tracking's lookups per path.
set -euo pipefail
cd "$(dirname "$0")/.."
SPP=${1:-4}; ROUNDS=${2:-3}
BIN=${BIN:-./build/spectrack}
out=$(mktemp -d)
declare -A cfg=([beauty]="--no-alpha" [variance]="--no-alpha --aov variance" [alpha]="--alpha"
                [aux]="--no-alpha --aov albedo,depth"
                [all]="--alpha --aov variance,emission,direct,indirect,albedo,depth")
order="beauty variance alpha aux all"
echo "film layers: $BIN, $SPP spp, $ROUNDS interleaved rounds, $(date -u +%F) on $(nproc) cores"
for s in bench/scenes/*.json data/scenes/cloud.json; do
  n=$(basename "$s" .json)
  for c in $order; do $BIN render "$s" -q --spp 1 ${cfg[$c]} -o "$out/w.exr" >/dev/null; done
  for r in $(seq "$ROUNDS"); do
    # the order rotates every round, so no configuration always runs first
    set -- $order; k=$(( (r - 1) % $# )); rot="${*:k+1} ${*:1:k}"
    for c in $rot; do
      $BIN render "$s" -q --spp "$SPP" ${cfg[$c]} -o "$out/$n.$c.exr" --stats-json "$out/$n.$c.$r.json" >/dev/null
    done
  done
  /usr/bin/python3 - "$out" "$n" "$ROUNDS" $order <<'PY'
import json, sys
out, n, rounds, order = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4:]
sec = {c: sum(json.load(open(f"{out}/{n}.{c}.{r}.json"))["seconds_render"] for r in range(1, rounds + 1)) / rounds for c in order}
st = json.load(open(f"{out}/{n}.all.1.json"))
paths = max(st["paths"], 1)
print(f"{n:18s} " + " ".join(f"{c} {sec[c]:6.3f}s ({sec[c] / sec['beauty']:.3f}x)" for c in order) +
      f"  lookups/path: tracking {st['density_lookups_tracking'] / paths:.2f} alpha {st['density_lookups_alpha'] / paths:.2f}")
PY
done
rm -rf "$out"
