#!/bin/bash
# bench/guiding.sh BIN [SPP] [SEEDS] [SCENES] [CONFIGS]: efficiency of volume path guiding against
# the unguided render of the same binary. For each scene and seed, one render per configuration,
# interleaved (off, guided, guided with roulette and splitting, off, ...: A B C A B C), each with the
# variance layer; prints per run the mean over pixels and channels of the variance of the pixel
# means, seconds_render (training included), the efficiency 1 / (variance x seconds_render), and
# the counts that do not depend on the machine's load: scatter events and split paths per camera
# sample (training passes included), and the process's CPU seconds over seconds_render (all threads:
# PoCL's too) with the efficiency on them, which a loaded machine disturbs less than the wall
# seconds. Then per scene the ratios against `off` (variance and efficiency, per seed).
# With REF=DIR in the environment and DIR/<scene>.exr a long render of the scene with the variance
# layer (bench/guiding_reference.sh), each run's relative MSE against it (the mean over pixels and
# channels of (x - ref)^2 / (ref^2 + 0.01), less the reference's own share, its variance layer over
# the same) is printed too, and the efficiencies are 1 / (relMSE x seconds_render).
# SCENES: names under bench/scenes (default dense_subsurface dense_chromatic cloud_chromatic smoke1
# smoke_thin emissive_heat); CONFIGS: off, guided (--guiding on --guide-splitting off), split
# (--guiding on), auto (--guiding auto); guided:D or split:D guide the scatter events of depth below D
# (SPECTRACK_GUIDE_DEPTH; D = all: every scatter event); letters after guided or split: p samples
# the guide's product with the phase function (SPECTRACK_GUIDE_PRODUCT=1), 0 the first-event
# product fit (SPECTRACK_GUIDE_PRODUCT=0), f weighs the fit's records by the whole rest of their
# paths (SPECTRACK_GUIDE_FULL_PATH=1), r by the ring (=0). SPECTRACK_GUIDE_TRAINING and
# SPECTRACK_GUIDE_TRAINING_KEEP in the environment set the training schedule (docs/guiding.md).
BIN=${1:?usage: bench/guiding.sh BIN [SPP] [SEEDS] [SCENES] [CONFIGS]}; SPP=${2:-8}; SEEDS=${3:-3}
SCENES=${4:-dense_subsurface dense_chromatic cloud_chromatic smoke1 smoke_thin emissive_heat}
CONFIGS=${5:-off guided split}
cd "$(dirname "$0")/.."; out=$(mktemp -d); raw=$out/raw.txt
flags() {
  case ${1%%:*} in
    guided?*) echo "--guiding on --guide-splitting off" ;;
    split?*) echo "--guiding on --guide-splitting on" ;;
    off) echo "--guiding off" ;;
    guided) echo "--guiding on --guide-splitting off" ;;
    split) echo "--guiding on --guide-splitting on" ;;
    auto) echo "--guiding auto" ;;
  esac
}
echo "# $(date -u '+%Y-%m-%d %H:%M UTC') $(uname -n) $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg); $BIN; spp $SPP; seeds 1..$SEEDS"
echo "# scene seed config mean_variance seconds_render seconds_training efficiency scatter_per_sample split_per_sample regions_guided records regions relmse cpu_seconds_render efficiency_cpu iterations"
# the mean over pixels and channels of $1 (a layer expression's image) over ref^2 + 0.01
rel() { oiiotool "$@" "$ref" --ch R,G,B --dup --mul --addc 0.01 --div --printstats 2>/dev/null | awk '/Stats Avg/ {print ($3+$4+$5)/3}'; }
for scene in $SCENES; do
  ref=${REF:+$REF/$scene.exr}; ref_noise=0
  [ -n "$ref" ] && [ -f "$ref" ] && ref_noise=$(rel "$ref" --ch variance.R,variance.G,variance.B) || ref=
  [ -n "$ref" ] && echo "# $scene: reference $ref, its relative variance $ref_noise"
  for seed in $(seq 1 $SEEDS); do
    for c in $CONFIGS; do
      depth=; [[ $c == *:* ]] && depth=${c#*:} && [ "$depth" = all ] && depth=0
      mode=${c%%:*}; mode=${mode#guided}; mode=${mode#split}; product=; full=
      [[ $mode == *p* ]] && product=1; [[ $mode == *0* ]] && product=0
      [[ $mode == *f* ]] && full=1; [[ $mode == *r* ]] && full=0
      env ${depth:+SPECTRACK_GUIDE_DEPTH=$depth} ${product:+SPECTRACK_GUIDE_PRODUCT=$product} \
        ${full:+SPECTRACK_GUIDE_FULL_PATH=$full} $BIN render bench/scenes/$scene.json --spp $SPP --seed $seed $(flags $c) --aov variance --no-alpha \
        -o $out/r.exr --quiet --stats-json $out/r.json || { echo "FAIL $scene $seed $c"; continue; }
      v=$(oiiotool $out/r.exr --ch variance.R,variance.G,variance.B --printstats 2>/dev/null | awk '/Stats Avg/ {print ($3+$4+$5)/3}')
      r=-1; [ -n "$ref" ] && r=$(rel $out/r.exr --ch R,G,B "$ref" --ch R,G,B --sub --dup --mul) && r=$(python3 -c "print($r - $ref_noise)")
      python3 - "$out/r.json" "$scene" "$seed" "$c" "$v" "$r" <<'PY' | tee -a $raw
import json, sys
j = json.load(open(sys.argv[1])); v = float(sys.argv[5]); t = j["seconds_render"]; r = float(sys.argv[6])
n = j["width"] * j["height"] * j["spp"] if "width" in j else None
samples = n or 1
print(sys.argv[2], sys.argv[3], sys.argv[4], f"{v:.6g}", f"{t:.3f}", f"{j.get('seconds_guide_training', 0):.3f}",
      f"{1.0 / ((r if r > 0 else v) * t):.6g}", f"{j.get('scatter_events', 0) / samples:.4g}",
      f"{j.get('guide_split_paths', 0) / samples:.4g}", j.get("guide_regions_guided", 0), j.get("guide_training_records", 0),
      j.get("guide_regions", 0), f"{r:.6g}", f"{j.get('cpu_seconds_render', 0):.3f}",
      f"{1.0 / ((r if r > 0 else v) * max(j.get('cpu_seconds_render', 0), 1e-9)):.6g}", j.get("iterations", 0))
PY
    done
  done
done
python3 - $raw <<'PY'
import collections, sys
rows = [l.split() for l in open(sys.argv[1]) if l.strip()]
by = collections.defaultdict(dict)
for r in rows: by[(r[0], r[1])][r[2]] = (float(r[3]) if float(r[12]) <= 0 else float(r[12]), float(r[6]), float(r[7]), float(r[14]), float(r[3]), float(r[15]) if len(r) > 15 else 0.0)
print("# Summary: per scene, per config, per seed: off/config variance, or relMSE with REF (above 1: less error) | config/off")
print("# efficiency per second | efficiency per CPU second | config/off efficiency per scatter event (1 / (error x scatter events per sample))")
print("# | config/off scatter events per sample | off/config mean variance (with REF; without, the error column)")
print("# | config/off stage-loop iterations (training included)")
for scene in dict.fromkeys(r[0] for r in rows):
    seeds = [k for k in by if k[0] == scene]
    for c in dict.fromkeys(r[2] for r in rows if r[2] != "off"):
        vr = [by[k]["off"][0] / by[k][c][0] for k in seeds if c in by[k] and "off" in by[k]]
        er = [by[k][c][1] / by[k]["off"][1] for k in seeds if c in by[k] and "off" in by[k]]
        cr = [by[k][c][3] / by[k]["off"][3] for k in seeds if c in by[k] and "off" in by[k]]
        wr = [by[k]["off"][0] * by[k]["off"][2] / (by[k][c][0] * by[k][c][2]) for k in seeds if c in by[k] and "off" in by[k]]
        sr = [by[k][c][2] / by[k]["off"][2] for k in seeds if c in by[k] and "off" in by[k]]
        mv = [by[k]["off"][4] / by[k][c][4] for k in seeds if c in by[k] and "off" in by[k]]
        it = [by[k][c][5] / max(by[k]["off"][5], 1.0) for k in seeds if c in by[k] and "off" in by[k]]
        print(f"# {scene} {c}: error {' '.join(f'{x:.3f}' for x in vr)} | efficiency {' '.join(f'{x:.3f}' for x in er)}"
              f" | cpu {' '.join(f'{x:.3f}' for x in cr)} | per scatter event {' '.join(f'{x:.3f}' for x in wr)}"
              f" | scatter {' '.join(f'{x:.3f}' for x in sr)} | variance {' '.join(f'{x:.3f}' for x in mv)}"
              f" | iterations {' '.join(f'{x:.3f}' for x in it)}")
PY
rm -rf $out
