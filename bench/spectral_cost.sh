#!/usr/bin/env bash
# bench/spectral_cost.sh [SPP] [ROUNDS]: the cost of spectral mode per path (docs/spectral.md;
# its target: at most 1.3x rgb) on the bench scenes, in one run: each scene and tracker
# rendered in rgb and with --spectral (both --no-alpha, so both do the same per-path work),
# interleaved round by round after a warm-up render of each (kernel builds cached), the order
# swapped every round. Prints the mean seconds_render of each mode and, spectral over rgb, the
# ratios of seconds per path, of density lookups per path (spectral transport meets more
# extinction where the upsampled spectra exceed their RGB averages) and of seconds per lookup.
set -euo pipefail
cd "$(dirname "$0")/.."
SPP=${1:-8}; ROUNDS=${2:-3}
BIN=${BIN:-./build/spectrack}
SCENES=${SCENES:-"bench/scenes/cloud_chromatic.json bench/scenes/dense_subsurface.json bench/scenes/smoke_thin.json bench/scenes/emissive_heat.json"}
TRACKERS=${TRACKERS:-"delta-per-channel spectral-decomposition spectral-mis"}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
echo "spectral mode cost: $BIN, $SPP spp, $ROUNDS interleaved rounds, $(date -u +%F) on $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs))"
printf '%-18s %-24s %10s %10s %12s %14s %14s\n' scene tracker rgb_s spectral_s "s/path ratio" "lookups/path" "s/lookup"
for s in $SCENES; do
  n=$(basename "$s" .json)
  for t in $TRACKERS; do
    run() {  # mode round
      local flag=""; [ "$1" = spectral ] && flag="--spectral"
      $BIN render "$s" -q --no-alpha --tracker "$t" --spp "$SPP" $flag -o "$out/img.exr" --stats-json "$out/$n.$t.$1.$2.json" >/dev/null
    }
    $BIN render "$s" -q --no-alpha --tracker "$t" --spp 1 -o "$out/w.exr" >/dev/null
    $BIN render "$s" -q --no-alpha --tracker "$t" --spp 1 --spectral -o "$out/w.exr" >/dev/null
    for r in $(seq "$ROUNDS"); do
      if [ $((r % 2)) -eq 1 ]; then run rgb "$r"; run spectral "$r"; else run spectral "$r"; run rgb "$r"; fi
    done
    /usr/bin/python3 - "$out" "$n" "$t" "$ROUNDS" <<'PY'
import json, sys
out, n, t, rounds = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
def load(mode):
    st = [json.load(open(f"{out}/{n}.{t}.{mode}.{r}.json")) for r in range(1, rounds + 1)]
    return sum(x["seconds_render"] for x in st) / rounds, st[0]["paths"], st[0]["density_lookups"]
(a, pa, la), (b, pb, lb) = load("rgb"), load("spectral")
lk = (lb / pb) / (la / pa) if la > 0 and lb > 0 else float("nan")
print(f"{n:18s} {t:24s} {a:10.3f} {b:10.3f} {(b / pb) / (a / pa):12.3f} {lk:14.3f} {(b / pb) / (a / pa) / lk:14.3f}")
PY
  done
done
