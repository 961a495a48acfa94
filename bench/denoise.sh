#!/usr/bin/env bash
# bench/denoise.sh [SCALE] [REF_SPP]: the denoised Disney cloud (--denoise: Intel Open Image
# Denoise with the albedo layer, docs/cli.md#denoising) at 16 spp against the plain render at 256
# spp, both measured against a long reference render of another seed (REF_SPP, default 4096): the
# relative mean squared error sum (x - ref)^2 / sum ref^2 over R, G, B, and the seconds of each
# (render, and the denoiser's). The film is scaled by SCALE (default 0.25: 96x64) to fit the time;
# the reference's own noise (REF_SPP samples) adds to every error, so the ratios are lower bounds.
set -euo pipefail
cd "$(dirname "$0")/.."
SCALE=${1:-0.25}; REF=${2:-4096}
BIN=${BIN:-./build/spectrack}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
echo "denoise: $BIN, Disney cloud, film scale $SCALE, reference $REF spp," \
     "$(date -u '+%F %H:%M') UTC on $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg), commit $(git rev-parse --short HEAD)"
/usr/bin/python3 bench/scaled_scene.py data/scenes/disney_cloud.json "$out/cloud.json" "$SCALE"
r() { $BIN render "$out/cloud.json" -q --no-alpha "$@"; }
r --spp "$REF" --seed 99 -o "$out/ref.exr" --stats-json "$out/ref.json"
r --spp 16 --seed 1 --denoise -o "$out/d16.exr" --stats-json "$out/d16.json"
r --spp 256 --seed 1 -o "$out/u256.exr" --stats-json "$out/u256.json"
# relative MSE through oiiotool's arithmetic: the mean over pixels of (x - ref)^2 and of ref^2 per
# channel (--printstats), summed over R, G, B
/usr/bin/python3 - "$out" <<'PY'
import json, re, subprocess, sys
out = sys.argv[1]
def sq_means(args):
    text = subprocess.run(["oiiotool", *args, "--dup", "--mul", "--printstats"], capture_output=True, text=True,
                          check=True).stdout
    return sum(float(v) for v in re.search(r"Stats Avg:\s*([-0-9.e+ ]+)", text).group(1).split()[:3])
ref = [f"{out}/ref.exr", "--ch", "R,G,B"]
den = sq_means(ref)
def rel(path, chans): return sq_means([path, "--ch", chans, *ref, "--sub"]) / den
e = {"16 spp": rel(f"{out}/d16.exr", "R,G,B"),
     "16 spp denoised": rel(f"{out}/d16.exr", "R=denoised.R,G=denoised.G,B=denoised.B"),
     "256 spp": rel(f"{out}/u256.exr", "R,G,B")}
for k, v in e.items(): print(f"{k:16s} relative MSE {v:.3e}")
sec = {k: json.load(open(f"{out}/{k}.json")) for k in ("d16", "u256", "ref")}
print(f"render seconds: 16 spp {sec['d16']['seconds_render']:.1f} + denoiser {sec['d16'].get('denoise_seconds', float('nan')):.2f},"
      f" 256 spp {sec['u256']['seconds_render']:.1f}, reference {sec['ref']['seconds_render']:.1f}")
print(f"denoised 16 spp / plain 256 spp relative MSE: {e['16 spp denoised'] / e['256 spp']:.3f}"
      f" ({'closer' if e['16 spp denoised'] < e['256 spp'] else 'farther'} to the reference)")
PY
