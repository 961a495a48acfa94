#!/usr/bin/env bash
# tracker_costs.sh SCENE [SPP]: renders SCENE once per tracker at equal spp in one run and prints a
# markdown table of render seconds, density lookups per sample (tracking and shadow rays),
# collisions per sample and paths per second, with the ratio of each tracker's seconds and
# lookups to delta-per-channel's. Uses ./build/spectrack; needs python3 for the table.
set -euo pipefail
cd "$(dirname "$0")/.."
scene=$1
spp=${2:-16}
out=$(mktemp -d)
trackers=(delta-per-channel spectral decomposition spectral-decomposition)
for t in "${trackers[@]}"; do
  ./build/spectrack render "$scene" --spp "$spp" --tracker "$t" --no-alpha -o "$out/$t.exr" --stats-json "$out/$t.json" --quiet
done
python3 - "$out" "$scene" "$spp" "${trackers[@]}" <<'PY'
import json, sys
out, scene, spp, trackers = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4:]
rows = {t: json.load(open(f"{out}/{t}.json")) for t in trackers}
ref = rows["delta-per-channel"]
w, h = ref["width"], ref["height"]
samples = w * h * spp
print(f"scene {scene}, {w}x{h}, {spp} spp, device {ref['device']}")
print()
print("| tracker | render s | s / delta-pc | lookups/sample (track + shadow) | lookups / delta-pc | real/sample | null/sample | control/sample | paths/s |")
print("|---|---|---|---|---|---|---|---|---|")
for t, j in rows.items():
    lk = j["density_lookups_tracking"] + j["density_lookups_shadow"]
    lk_ref = ref["density_lookups_tracking"] + ref["density_lookups_shadow"]
    print(f"| {t} | {j['seconds_render']:.2f} | {j['seconds_render']/ref['seconds_render']:.2f} | "
          f"{lk/samples:.1f} ({j['density_lookups_tracking']/samples:.1f} + {j['density_lookups_shadow']/samples:.1f}) | "
          f"{lk/lk_ref:.2f} | {j['real_collisions']/samples:.2f} | {j['null_collisions']/samples:.2f} | "
          f"{j['control_collisions']/samples:.2f} | {j['paths_per_second']:.0f} |")
PY
rm -rf "$out"
