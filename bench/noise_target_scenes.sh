#!/usr/bin/env bash
# bench/noise_target_scenes.sh [TARGET] [EDGE] [REF_MULT]: every bench scene rendered to a noise
# target (default 0.02), uniform (--noise-target) and adaptive (--noise-target --adaptive), each
# checked against a long uniform render of another seed.
#
# The scenes are the ones bench/ renders: bench/scenes/*.json and data/scenes/{cloud,disney_cloud,
# fire,fire_usd}.json, each film scaled so that its long edge is EDGE pixels (default 24; the noise
# of a pixel does not depend on the film size). Per scene and mode the script records the samples
# reached (the mean over pixels for adaptive), the stage-loop seconds, the error reached and the
# stop reason. The reference is a uniform render of REF_MULT (default 4) times the samples the
# uniform render reached, seed 99 (the others use seeds 1 and 2). CAP (default 262144) is the --spp
# of both modes: fire at 2% needs about 72000 samples per pixel uniform (and its hardest pixels
# more), so a cap of 65536 measured the cap, not the noise target (both modes stopped at it).
#
# Agreement, a block statistic: the film is cut into 4x4-pixel blocks; per block and channel the
# difference of the block means of the whole beauty (R, G, B plus the environment layer of a
# transparent film: the variance layer is of the whole beauty) is divided by its standard error,
# sqrt(sum of both films' per-pixel variances / 16^2): the reference's variance layer, and the
# rendered film's variance layer or, where larger, the reference's per-sample variance over the
# pixel's sample count (a pixel whose few samples all missed a rare path, a background pixel next
# to thin smoke, estimates its own variance as 0; the variance of an adaptive pixel's weighted
# estimate is at least that of the mean of its samples). A mode passes when
# every block's |z| and the whole image's |z| (the same over all pixels) are below 4. The twin
# multiplies the rendered image by 1.03 and must fail (a block or the image beyond 4 SE), which
# shows the test can see a 3% error. The fraction of single pixels beyond 4 SE is printed too
# (per-pixel variance estimates are noisy, so it is a diagnostic, not the test).
set -euo pipefail
cd "$(dirname "$0")/.."
TARGET=${1:-0.02}; EDGE=${2:-24}; REF_MULT=${3:-4}
BIN=${BIN:-./build/spectrack}
CAP=${CAP:-262144}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
echo "noise target on every bench scene: $BIN, target $TARGET, long edge $EDGE px, spp cap $CAP, reference" \
     "$REF_MULT x the uniform spp (seed 99), $(date -u '+%F %H:%M') UTC on $(nproc) cores," \
     "load $(cut -d' ' -f1-3 /proc/loadavg), commit $(git rev-parse --short HEAD)"
SCENES=${SCENES:-"bench/scenes/*.json data/scenes/cloud.json data/scenes/disney_cloud.json data/scenes/fire.json
                  data/scenes/fire_usd.json"}
for s in $SCENES; do
  n=$(basename "$s" .json)
  scale=$(/usr/bin/python3 -c "import json; f = json.load(open('$s'))['film']; print($EDGE / max(f['width'], f['height']))")
  /usr/bin/python3 bench/scaled_scene.py "$s" "$out/$n.json" "$scale"
  r() { $BIN render "$out/$n.json" -q "$@" >/dev/null; }
  r --spp "$CAP" --seed 1 --noise-target "$TARGET" -o "$out/$n.uniform.exr" --stats-json "$out/$n.uniform.json"
  r --spp "$CAP" --seed 2 --noise-target "$TARGET" --adaptive -o "$out/$n.adaptive.exr" --stats-json "$out/$n.adaptive.json"
  ref_spp=$(/usr/bin/python3 -c "import json; print($REF_MULT * json.load(open('$out/$n.uniform.json'))['spp'])")
  r --spp "$ref_spp" --seed 99 --aov variance -o "$out/$n.ref.exr" --stats-json "$out/$n.ref.json"
  /usr/bin/python3 - "$out" "$n" "$TARGET" "$ref_spp" <<'PY'
import json, sys
import numpy as np
import OpenImageIO as oiio
out, n, target, ref_spp = sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4])

def load(path):
    b = oiio.ImageBuf(path)
    spec = b.spec()
    px = b.get_pixels(oiio.FLOAT).reshape(spec.height, spec.width, spec.nchannels).astype(np.float64)
    ch = {c: px[:, :, i] for i, c in enumerate(spec.channelnames)}
    beauty = np.stack([ch[c] for c in "RGB"], -1)
    if "A" in ch and "environment.R" in ch:  # a transparent film: the whole beauty adds the environment
        beauty = beauty + np.stack([ch["environment." + c] for c in "RGB"], -1)
    var = np.stack([ch["variance." + c] for c in "RGB"], -1)
    return beauty, var, ch.get("samples")

def z_blocks(x, vx, ref, vref, b=4):
    h, w = (x.shape[0] // b) * b, (x.shape[1] // b) * b
    d = (x - ref)[:h, :w].reshape(h // b, b, w // b, b, 3).sum((1, 3))
    v = (vx + vref)[:h, :w].reshape(h // b, b, w // b, b, 3).sum((1, 3))
    zb = np.where(v > 0, np.abs(d) / np.sqrt(np.maximum(v, 1e-300)), np.where(d != 0, np.inf, 0.0))
    zi = np.abs((x - ref).sum((0, 1))) / np.sqrt((vx + vref).sum((0, 1)))
    return zb.max(), zi.max()

ref, vref, _ = load(f"{out}/{n}.ref.exr")
for mode in ("uniform", "adaptive"):
    j = json.load(open(f"{out}/{n}.{mode}.json"))
    x, vx, samples = load(f"{out}/{n}.{mode}.exr")
    # a pixel whose samples all missed a rare path estimates its variance as 0: its variance is at
    # least the reference's per-sample variance over its own sample count
    samples = np.full(x.shape[:2], float(j["spp"])) if samples is None else samples
    vx = np.maximum(vx, vref * ref_spp / np.maximum(samples, 1.0)[:, :, None])
    zb, zi = z_blocks(x, vx, ref, vref)
    tb, ti = z_blocks(1.03 * x, 1.03**2 * vx, ref, vref)
    v = vx + vref
    zp = np.abs(x - ref) / np.sqrt(np.where(v > 0, v, np.inf))
    spp = j["spp"] if mode == "uniform" else j.get("adaptive_mean_spp", float("nan"))
    ok = j.get("noise_error", 1.0) <= target and j.get("stop_reason") == "noise-target"
    agree = zb < 4 and zi < 4
    twin = tb >= 4 or ti >= 4
    print(f"{n:16s} {mode:8s} spp {spp:8.1f} {j['seconds_render']:7.2f} s error {j.get('noise_error', float('nan')):.4f}"
          f" stop {j.get('stop_reason') or 'spp cap'}: target {'reached' if ok else 'MISSED'};"
          f" max block |z| {zb:5.2f}, image |z| {zi:5.2f}: {'agree' if agree else 'DISAGREE'};"
          f" twin (x1.03) {'fails' if twin else 'PASSES'} ({max(tb, ti):.1f});"
          f" pixels beyond 4 SE {100 * (zp >= 4).mean():.2f}%")
PY
done
