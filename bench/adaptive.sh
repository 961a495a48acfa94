#!/usr/bin/env bash
# bench/adaptive.sh [TARGET] [SEEDS] [SCALE]: time to the same noise target, adaptive sampling
# (--adaptive, docs/adaptive.md) against uniform sampling (a plain --noise-target render, which
# stops once the image's error is at or below the target), on the bench scenes with thin and dense
# regions: smoke1 and the Disney cloud (data/scenes/disney_cloud.json), their films scaled by SCALE
# (default 0.5; the Disney cloud's by SCALE / 2, its paths being longer: the per-pixel noise and the
# samples it takes do not depend on the film size). After a warm-up render of each mode (kernels
# cached), the runs are interleaved A B A B over the seeds, the order swapped every seed. Prints per run the stage-loop seconds, the process's CPU seconds
# (user + system: on a shared machine less sensitive to the other processes than the wall time),
# the error reached and the samples (the mean over pixels for adaptive), then per scene the ratios
# of the mean seconds and of the mean CPU seconds (uniform / adaptive) and the per-seed ratios.
# BASE=path/to/spectrack adds a third mode, that binary's adaptive render ("base"), interleaved with
# the others, and the ratios base / adaptive (an A/B of two versions of the adaptive rule).
# SCENES="FILE:FACTOR ..." replaces the two scenes (FACTOR multiplies SCALE for that scene), e.g.
# SCENES=bench/scenes/fire_lit.json:1 CAP=256 for a medium lit by its own fire (docs/adaptive.md,
# "Light that the pilot does not see").
set -euo pipefail
cd "$(dirname "$0")/.."
TARGET=${1:-0.05}; SEEDS=${2:-3}; SCALE=${3:-0.5}
BIN=${BIN:-./build/spectrack}
BASE=${BASE:-}
CAP=${CAP:-1024}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
echo "adaptive vs uniform: $BIN, noise target $TARGET, spp cap $CAP, $SEEDS seeds, film scale $SCALE," \
     "$(date -u '+%F %H:%M') UTC on $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg), commit $(git rev-parse --short HEAD)"
for entry in ${SCENES:-bench/scenes/smoke1.json:1 data/scenes/disney_cloud.json:0.5}; do
  s=${entry%%:*}; f=${entry##*:}
  n=$(basename "$s" .json)
  # a copy with the film scaled and the volume paths absolute (the copy lives in $out)
  /usr/bin/python3 bench/scaled_scene.py "$s" "$out/$n.json" "$(/usr/bin/python3 -c "print($SCALE * $f)")"
  $BIN render "$out/$n.json" -q --spp 16 -o "$out/w.exr" >/dev/null
  $BIN render "$out/$n.json" -q --spp 32 --noise-target 0.5 --adaptive -o "$out/w.exr" >/dev/null
  [ -n "$BASE" ] && $BASE render "$out/$n.json" -q --spp 32 --noise-target 0.5 --adaptive -o "$out/w.exr" >/dev/null
  for seed in $(seq "$SEEDS"); do
    order="uniform adaptive${BASE:+ base}"; [ $((seed % 2)) -eq 0 ] && order="${BASE:+base }adaptive uniform"
    for mode in $order; do
      flags=""; [ "$mode" != uniform ] && flags="--adaptive"
      bin=$BIN; [ "$mode" = base ] && bin=$BASE
      /usr/bin/time -f "%U %S" -o "$out/$n.$mode.$seed.cpu" \
        $bin render "$out/$n.json" -q --seed "$seed" --spp "$CAP" --noise-target "$TARGET" $flags \
        -o "$out/$n.$mode.$seed.exr" --stats-json "$out/$n.$mode.$seed.json" >/dev/null
    done
  done
  /usr/bin/python3 - "$out" "$n" "$SEEDS" <<'PY'
import json, sys
import statistics as st
import os
out, n, seeds = sys.argv[1], sys.argv[2], int(sys.argv[3])
modes = ["uniform", "adaptive"] + (["base"] if os.path.exists(f"{out}/{n}.base.1.json") else [])
sec = {m: [] for m in modes}
cpu = {m: [] for m in modes}
for seed in range(1, seeds + 1):
    for mode in modes:
        j = json.load(open(f"{out}/{n}.{mode}.{seed}.json"))
        sec[mode].append(j["seconds_render"])
        cpu[mode].append(sum(map(float, open(f"{out}/{n}.{mode}.{seed}.cpu").read().split()[-2:])))
        spp = j["spp"] if mode == "uniform" else j.get("adaptive_mean_spp", float("nan"))
        # a binary that records no stop reason for a target missed at the spp leaves it empty
        print(f"{n:14s} seed {seed} {mode:8s} {j['seconds_render']:8.2f} s  cpu {cpu[mode][-1]:7.2f} s"
              f"  error {j.get('noise_error', float('nan')):.4f}  spp {spp:7.1f}  stop {j.get('stop_reason') or 'spp cap'}")
for what, v in (("time", sec), ("cpu time", cpu)):
    for other in modes:
        if other == "adaptive":
            continue
        ratios = [u / a for u, a in zip(v[other], v["adaptive"])]
        print(f"{n:14s} {other}/adaptive {what}: {st.mean(v[other]) / st.mean(v['adaptive']):.2f}x"
              f" (per seed: {', '.join(f'{r:.2f}' for r in ratios)})")
PY
done
