#!/usr/bin/env bash
# bench/medium_interface_ab.sh: paths/s of two spectrack binaries on the cases the medium interface
# (point sampler, interval iterator, the trackers' policy: docs/architecture.md) runs hottest: a
# chromatic cloud with spectral tracking, a dense chromatic medium, and decomposition tracking
# (control and residual) on the dense subsurface scene; each at SEEDS, interleaved A B A B after
# both kernel caches are warmed (a 1-spp render of each case). OLD=... NEW=... [SPP=4] [ROUNDS=2]
# [SEEDS="1 2"] [OUTDIR=...]. Prints per render: case seed round binary paths_per_second
# seconds_render (wall, the render loop) wall_process cpu_seconds (user + sys of the process,
# /usr/bin/time), then per case the ratios NEW / OLD of the summed paths/s and CPU seconds.
set -u
cd "$(dirname "$0")/.."
OLD=${OLD:?OLD=old binary}; NEW=${NEW:?NEW=new binary}
out=${OUTDIR:-$(mktemp -d)}; mkdir -p "$out"
spp=${SPP:-4}; rounds=${ROUNDS:-2}; seeds=${SEEDS:-"1 2"}
cases=("cloud_spectral bench/scenes/cloud_chromatic.json --tracker spectral"
       "dense_chromatic bench/scenes/dense_chromatic.json"
       "subsurface_decomposition bench/scenes/dense_subsurface.json --tracker decomposition")
echo "# machine: $(hostname) $(nproc) cores, $(date -u +%FT%TZ); OLD=$OLD NEW=$NEW spp=$spp rounds=$rounds seeds=$seeds"
echo "# case seed round binary paths_per_second seconds_render wall_process cpu_seconds"
for c in "${cases[@]}"; do
  set -- $c; name=$1; shift
  for b in OLD NEW; do "${!b}" render "$@" -q --spp 1 --no-alpha -o "$out/warm.exr" >/dev/null 2>&1; done
  for seed in $seeds; do
    for round in $(seq "$rounds"); do
      for b in OLD NEW; do
        /usr/bin/time -f "%e %U %S" -o "$out/time.txt" "${!b}" render "$@" -q --spp "$spp" --seed "$seed" --no-alpha \
          -o "$out/$name.$b.exr" --stats-json "$out/$name.$seed.$round.$b.json" >/dev/null 2>&1
        python3 -c "
import json;j=json.load(open('$out/$name.$seed.$round.$b.json'));e,u,s=map(float,open('$out/time.txt').read().split()[-3:])
print('$name',$seed,$round,'$b',round(j['paths_per_second']),round(j['seconds_render'],3),e,round(u+s,2),flush=True)"
      done
    done
  done
done | tee "$out/runs.txt"
python3 - "$out/runs.txt" <<'PY'
import sys, collections
pps, cpu = collections.defaultdict(float), collections.defaultdict(float)
for line in open(sys.argv[1]):
    f = line.split()
    if len(f) != 8 or f[0].startswith('#'): continue
    pps[(f[0], f[3])] += float(f[4]); cpu[(f[0], f[3])] += float(f[7])
for name in dict.fromkeys(k[0] for k in pps):
    print(f"# {name}: paths/s NEW/OLD {pps[(name, 'NEW')] / pps[(name, 'OLD')]:.3f}, "
          f"cpu seconds NEW/OLD {cpu[(name, 'NEW')] / cpu[(name, 'OLD')]:.3f}")
PY
