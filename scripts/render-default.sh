#!/usr/bin/env bash
# render-default.sh: the first command. Installs the Debian packages the renderer needs (when
# missing), builds the renderer and the default scene's volume (not the tests: scripts/test.sh
# builds them), and renders the default scene, data/scenes/sunset_smoke.json, to its noise target
# with adaptive sampling: out/sunset_smoke.exr and out/sunset_smoke.png. When Intel Open Image
# Denoise is installed (PyPI's pyoidn, docs/cli.md "Denoising") it also writes the denoised
# picture, out/sunset_smoke_denoised.png; without it the render alone is the picture. Every step
# says what it does and how long it took. Extra arguments go to `spectrack render` (for example
# --noise-target 0.1 for a quicker, noisier image, or --spp 64 for a fixed count).
set -euo pipefail
cd "$(dirname "$0")/.."
scene=data/scenes/sunset_smoke.json
out=out/sunset_smoke
t0=$(date +%s)
step() { echo "render-default [$(($(date +%s) - t0)) s]: $*"; }

step "1/3 packages and a build of the renderer and the default scene's volume (scripts/setup.sh)"
SETUP_TARGETS="spectrack default_scene" bash scripts/setup.sh
step "    built build/spectrack and data/volumes/color_cloud.vdb"

denoise=()
if /usr/bin/python3 -c 'import importlib.util, sys; sys.exit(importlib.util.find_spec("pyoidn") is None)' 2>/dev/null; then
  denoise=(--denoise)
  step "2/3 rendering $scene to its noise target, then denoising it (pyoidn found: Intel Open Image Denoise)"
else
  step "2/3 rendering $scene to its noise target (the denoiser is optional and not installed:" \
       "/usr/bin/python3 -m pip install --user --break-system-packages pyoidn adds it)"
fi
echo "    the first render compiles the kernels for this scene (cached for the next ones)"
mkdir -p out
./build/spectrack render "$scene" -o "$out.exr" --preview "$out.png" --stats-json "$out.stats.json" "${denoise[@]}" "$@"

if [ ${#denoise[@]} -gt 0 ]; then
  step "3/3 writing the denoised layer as $out""_denoised.png"
  oiiotool "$out.exr" --ch denoised.R,denoised.G,denoised.B --chnames R,G,B --colorconvert linear sRGB \
    -d uint8 -o "${out}_denoised.png"
  step "done: $out""_denoised.png (denoised), $out.png (the unbiased render), $out.exr (every layer)"
else
  step "3/3 done: $out.png (the picture), $out.exr (linear, with the variance layer)"
fi
