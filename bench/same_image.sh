#!/usr/bin/env bash
# bench/same_image.sh: whether two spectrack binaries render bit-identical images (EXR pixel data
# by `oiiotool --dumpdata`) on a few scenes, trackers and queue settings, plus a control pair that
# must differ (another --seed). A=... B=... [OUTDIR=...] [CASES=FILE: one case (scene and flags) per
# line instead of the built-in ones]. A and B are split into words, so B="env SPECTRACK_LOOP=chunked
# build/spectrack" runs a binary with a setting. A render that fails is FAILED, never IDENTICAL.
# Used for the raygen change (bench/RESULTS.md).
set -u
cd "$(dirname "$0")/.."
A=${A:?A=binary before}; B=${B:?B=binary after}
out=${OUTDIR:-$(mktemp -d)}; mkdir -p $out
cases=(
 "bench/scenes/smoke_thin.json --spp 2"
 "bench/scenes/dense_subsurface.json --spp 2 --tracker decomposition"
 "bench/scenes/cloud_chromatic.json --spp 2 --tracker delta-per-channel"
 "bench/scenes/emissive_heat.json --spp 3 --tracker spectral-decomposition --path-slots 1000"
 "bench/scenes/smoke1.json --spp 2 --batches-in-flight 1 --path-slots 5000"
)
[ -n "${CASES:-}" ] && mapfile -t cases < <(grep -v '^\s*\(#\|$\)' "$CASES")
i=0
for c in "${cases[@]}"; do
  i=$((i+1))
  $A render $c -q -o $out/$i.A.exr >/dev/null 2>$out/$i.A.err || { echo "case $i ($c): FAILED (A: $(tail -n 1 $out/$i.A.err))"; continue; }
  $B render $c -q -o $out/$i.B.exr >/dev/null 2>$out/$i.B.err || { echo "case $i ($c): FAILED (B: $(tail -n 1 $out/$i.B.err))"; continue; }
  if cmp -s <(oiiotool --dumpdata $out/$i.A.exr | tail -n +2) <(oiiotool --dumpdata $out/$i.B.exr | tail -n +2); then r=IDENTICAL; else r=DIFFERENT; fi
  echo "case $i ($c): $r"
done
# control: the first case with another seed (its flags have none) must differ
$B render ${cases[0]} --seed 9 -q -o $out/ctl.exr >/dev/null 2>&1
if cmp -s <(oiiotool --dumpdata $out/1.B.exr | tail -n +2) <(oiiotool --dumpdata $out/ctl.exr | tail -n +2); then r=IDENTICAL; else r=DIFFERENT; fi
echo "control (case 1 with --seed 9): $r"
