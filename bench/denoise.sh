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
/usr/bin/python3 - data/scenes/disney_cloud.json "$out/cloud.json" "$SCALE" <<'PY'
import json, os, sys
src, dst, scale = sys.argv[1], sys.argv[2], float(sys.argv[3])
j = json.load(open(src))
for m in j["media"]:
    m["file"] = os.path.abspath(os.path.join(os.path.dirname(src), m["file"]))
j["film"]["width"] = max(8, round(j["film"]["width"] * scale))
j["film"]["height"] = max(8, round(j["film"]["height"] * scale))
j["film"]["output"] = "out.exr"
json.dump(j, open(dst, "w"))
PY
r() { $BIN render "$out/cloud.json" -q --no-alpha "$@"; }
r --spp "$REF" --seed 99 -o "$out/ref.exr" --stats-json "$out/ref.json"
r --spp 16 --seed 1 --denoise -o "$out/d16.exr" --stats-json "$out/d16.json"
r --spp 256 --seed 1 -o "$out/u256.exr" --stats-json "$out/u256.json"
# PFM (little-endian floats) through oiiotool, read without numpy
oiiotool "$out/ref.exr" --ch R,G,B -o "$out/ref.pfm"
oiiotool "$out/d16.exr" --ch R,G,B -o "$out/n16.pfm"
oiiotool "$out/d16.exr" --ch denoised.R,denoised.G,denoised.B -o "$out/d16.pfm"
oiiotool "$out/u256.exr" --ch R,G,B -o "$out/u256.pfm"
/usr/bin/python3 - "$out" <<'PY'
import json, struct, sys
out = sys.argv[1]
def pfm(path):
    with open(path, "rb") as f:
        assert f.readline().strip() == b"PF"
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        n = w * h * 3
        return struct.unpack(("<" if scale < 0 else ">") + f"{n}f", f.read(4 * n))
ref = pfm(f"{out}/ref.pfm")
den = sum(r * r for r in ref)
def rel(name): return sum((a - r) ** 2 for a, r in zip(pfm(f"{out}/{name}.pfm"), ref)) / den
sec = {k: json.load(open(f"{out}/{k}.json"))["seconds_render"] for k in ("d16", "u256", "ref")}
e = {"16 spp": rel("n16"), "16 spp denoised": rel("d16"), "256 spp": rel("u256")}
for k, v in e.items(): print(f"{k:16s} relative MSE {v:.3e}")
print(f"render seconds: 16 spp {sec['d16']:.1f} + denoiser {json.load(open(f'{out}/d16.json')).get('denoise_seconds', float('nan')):.2f}, 256 spp {sec['u256']:.1f}, reference {sec['ref']:.1f}")
print(f"denoised 16 spp / plain 256 spp relative MSE: {e['16 spp denoised'] / e['256 spp']:.3f}"
      f" ({'closer' if e['16 spp denoised'] < e['256 spp'] else 'farther'} to the reference)")
PY
