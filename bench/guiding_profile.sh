#!/bin/bash
# bench/guiding_profile.sh BIN [SPP] [SEED] [SCENES]: where a guided render's time goes against the
# unguided render of the same scene. Per scene, one render per configuration (off, guided =
# --guiding on --guide-splitting off, split = --guiding on), each line: the process's CPU seconds
# (user + sys, every thread: PoCL's too) and wall seconds, the stats JSON's cpu_seconds_render and
# seconds_render, the training's share (its stage loops, the record drains' host time and count,
# the host's refinement and fit), stage-loop iterations (training and all), scatter events of the
# whole render (training included), then the per-kernel profile of the training passes and of the
# render loop (seconds / launches).
BIN=${1:?usage: bench/guiding_profile.sh BIN [SPP] [SEED] [SCENES]}; SPP=${2:-8}; SEED=${3:-1}
SCENES=${4:-dense_subsurface cloud_chromatic}
cd "$(dirname "$0")/.."; out=$(mktemp -d)
echo "# $(date -u '+%Y-%m-%d %H:%M UTC') $(uname -n) $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg); $BIN; spp $SPP; seed $SEED"
for scene in $SCENES; do
  for c in off guided split; do
    case $c in
      off) f="--guiding off" ;;
      guided) f="--guiding on --guide-splitting off" ;;
      split) f="--guiding on --guide-splitting on" ;;
    esac
    /usr/bin/time -f "%U %S %e" -o $out/time.txt $BIN render bench/scenes/$scene.json --spp $SPP --seed $SEED $f --quiet \
      -o $out/r.exr --stats-json $out/r.json || { echo "FAIL $scene $c"; continue; }
    python3 - $out/r.json $out/time.txt $scene $c <<'PY'
import json, sys
j = json.load(open(sys.argv[1])); u, s, e = map(float, open(sys.argv[2]).read().split())
g = lambda k: j.get(k, 0)
tk = g("guide_training_kernels") or {}
ks = lambda d: sum(v["seconds"] for v in d.values())
print(f"{sys.argv[3]} {sys.argv[4]}: process cpu {u + s:.2f} wall {e:.2f} | cpu_seconds_render {g('cpu_seconds_render'):.2f}"
      f" seconds_render {g('seconds_render'):.2f} | training {g('seconds_guide_training'):.2f} (cpu {g('cpu_seconds_guide_training'):.2f},"
      f" stage loops {g('seconds_guide_training_loops'):.2f}, drains {g('seconds_guide_drain'):.2f} x{g('guide_drains')},"
      f" refine+fit {g('seconds_guide_fit'):.2f}, iterations {g('guide_training_iterations')}, kernels {ks(tk):.2f})"
      f" | iterations {g('iterations')} kernels {ks(g('kernels')):.2f} | scatter events {g('scatter_events')} paths {g('paths')}")
render = {k: dict(v) for k, v in g("kernels").items()}
for k, v in tk.items():  # the render's kernels include the training's: the render loop's is the rest
    render[k]["seconds"] -= v["seconds"]; render[k]["launches"] -= v["launches"]
for k in sorted(render):
    a = tk.get(k, {"seconds": 0, "launches": 0}); b = render[k]
    print(f"    {k:14s} training {a['seconds']:.3f} s / {a['launches']:5d}   render loop {b['seconds']:.3f} s / {b['launches']:5d}")
PY
  done
done
rm -rf $out
