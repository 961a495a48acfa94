#!/usr/bin/env bash
# bench/cold_first_render.sh: seconds_render and seconds_kernel_build of first renders with cold
# caches, two binaries interleaved: (i) spectrack kernel cache warm, PoCL cache fresh
# (POCL_CACHE_DIR=$(mktemp -d)), (ii) both fresh; then one warm render each. A=... B=...
# [SCENE=...] [SPP=32]. Measures the kernel JIT outside seconds_render (bench/RESULTS.md).
set -u
cd "$(dirname "$0")/.."
A=${A:?A=binary before}; B=${B:?B=binary after}
scene=${SCENE:-bench/scenes/smoke_thin.json}; spp=${SPP:-32}
o=$(mktemp -d)
# the spectrack cache entry is written with a fresh PoCL cache too: a PoCL program binary carries the
# work-group functions compiled so far, so an entry written after launches would hide the JIT
for b in A B; do bin=${!b}; mkdir -p $o/stc_$b $o/pc0_$b; SPECTRACK_KERNEL_CACHE_DIR=$o/stc_$b POCL_CACHE_DIR=$o/pc0_$b $bin render $scene -q --spp 1 -o $o/w.exr; done
for round in 1 2; do
  modes="pocl_cold both_cold"; [ $round = 2 ] && modes=pocl_cold
  for mode in $modes; do
    for b in A B; do bin=${!b}
      pc=$(mktemp -d /tmp/pocl.XXXX)
      if [ $mode = both_cold ]; then sc=$(mktemp -d /tmp/stc.XXXX); else sc=$o/stc_$b; fi
      SPECTRACK_KERNEL_CACHE_DIR=$sc POCL_CACHE_DIR=$pc $bin render $scene -q --spp $spp -o $o/x.exr --stats-json $o/s.json
      python3 -c "import json;j=json.load(open('$o/s.json'));print('$round $mode $b render %.3f build %.3f total %.3f from_cache %s' % (j['seconds_render'],j['seconds_kernel_build'],j['seconds_total'],j['kernels_from_cache']),flush=True)"
      rm -rf $pc; [ $mode = both_cold ] && rm -rf $sc
    done
  done
done
# warm reference: the caches of the first render above (it compiled every kernel it launched)
for b in A B; do bin=${!b}; SPECTRACK_KERNEL_CACHE_DIR=$o/stc_$b POCL_CACHE_DIR=$o/pc0_$b $bin render $scene -q --spp $spp -o $o/x.exr --stats-json $o/s.json
python3 -c "import json;j=json.load(open('$o/s.json'));print('warm $b render %.3f build %.3f total %.3f' % (j['seconds_render'],j['seconds_kernel_build'],j['seconds_total']))"; done
