#!/usr/bin/env bash
# bench/old_vs_new.sh: paths/s of two spectrack binaries, interleaved (A B A B ...), both kernel
# caches warmed first (a 1-spp render each). OLD=... NEW=... [SCENES="a.json b.json"] [SPP=4]
# [ROUNDS=3] [OUTDIR=...]. Prints per render: scene round binary paths_per_second seconds_render
# cpu_seconds (user + sys of the process, /usr/bin/time) paths waiting_requeues (paths re-queued
# waiting for their shadow rays; '-' for a binary without the counter); the stats JSON of each render is
# kept in OUTDIR (per-kernel device times). Results: bench/RESULTS.md.
set -u
cd "$(dirname "$0")/.."
OLD=${OLD:?OLD=old binary}; NEW=${NEW:?NEW=new binary}
out=${OUTDIR:-$(mktemp -d)}; mkdir -p $out
scenes=${SCENES:-"bench/scenes/cloud_chromatic.json bench/scenes/dense_chromatic.json bench/scenes/dense_subsurface.json bench/scenes/emissive_heat.json bench/scenes/smoke1.json bench/scenes/smoke_thin.json data/scenes/cloud.json"}
spp=${SPP:-4}; rounds=${ROUNDS:-3}
# --no-alpha where a binary has film layers (docs/aov.md: EXRs get alpha by default): the beauty's cost alone
noalpha() { "$1" render --help 2>/dev/null | grep -q -- --no-alpha && echo --no-alpha; }
NA_OLD=$(noalpha $OLD); NA_NEW=$(noalpha $NEW)
for s in $scenes; do
  n=$(basename $s .json)
  for b in OLD NEW; do bin=${!b}; $bin render $s -q --spp 1 -o $out/warm.exr >/dev/null 2>&1; done
  for round in $(seq $rounds); do
    for b in OLD NEW; do bin=${!b}
      /usr/bin/time -f "%U %S" -o $out/time.txt $bin render $s -q --spp $spp $(eval echo \$NA_$b) -o $out/$n.$b.exr --stats-json $out/$n.$b.$round.json >/dev/null 2>&1
      python3 -c "
import json;j=json.load(open('$out/$n.$b.$round.json'));u,s=map(float,open('$out/time.txt').read().split()[-2:])
print('$n',$round,'$b',round(j['paths_per_second']),round(j['seconds_render'],3),round(u+s,2),j['paths'],j.get('waiting_requeues','-'),flush=True)"
    done
  done
done
