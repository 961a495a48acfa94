#!/bin/bash
# bench/bit_identity.sh OLD NEW: renders cloud.json and every bench scene with each tracker (and
# schemes, generic kernels, a shard) with both binaries and compares EXR pixels and counters bit for
# bit; a control pair (another seed) must differ. OLD and NEW are absolute paths of spectrack binaries.
# Spectral mode is compared with the new binary's `--wavelength-sampling independent` (NEW_EXTRA):
# stratified wavelengths are a new default.
# A scene the old binary refuses as having an unknown field while the new one renders it (a scene
# field newer than the old binary, e.g. a ground) is listed as skipped, not compared; every other
# failure fails. Scenes lit by an environment map are the one intended difference: light sampling's
# pdf of a map takes sin(theta) of the direction drawn since 2026-12-07 (it had the texel's own in
# both the CDF and the pdf, a bias of up to 3.3% on maps a texel high, ~0.04% on 64x32: docs/scene-format.md,
# kernels/light.h env_map_pdf); their pixels must differ only by that reweighting, so each patch's
# mean must agree within 0.5% (EXPECTED_CHANGE), and the twin renders with a uniform environment
# stay bit-identical.
OLD=$1; NEW=$2; cd "$(dirname "$0")/.."; out=$(mktemp -d); fail=0; skipped=0
# --no-alpha where a binary has film layers (docs/aov.md: EXRs get alpha by default): the beauty alone
noalpha() { "$1" render --help 2>/dev/null | grep -q -- --no-alpha && echo --no-alpha; }
NA_OLD=$(noalpha $OLD); NA_NEW=$(noalpha $NEW)
run() { # name scene args...
  local name=$1; shift
  local old_ok=1
  $OLD render "$@" $NA_OLD -o $out/$name.old.exr --quiet --stats-json $out/$name.old.json >$out/$name.old.log 2>&1 || old_ok=0
  $NEW render "$@" ${NEW_EXTRA:-} $NA_NEW -o $out/$name.new.exr --quiet --stats-json $out/$name.new.json >/dev/null 2>&1 || { echo "NEW FAIL $name"; fail=1; return; }
  if [ $old_ok = 0 ]; then
    if grep -q "^error: .*\.json: /.*: unknown field" $out/$name.old.log; then  # a scene field the old binary does not know
      echo "skip $name: the old binary refuses the scene ($(grep -m1 '^error' $out/$name.old.log | cut -c1-160))"
      skipped=$((skipped + 1)); return
    fi
    echo "OLD FAIL $name"; fail=1; return
  fi
  # `--guiding auto` (the default) turns guiding on where a lamp lights a medium (docs/guiding.md):
  # a new feature on, so a binary that guided such a scene renders it again with guiding off
  for side in old new; do
    if python3 -c "import json,sys; sys.exit(0 if json.load(open('$out/$name.$side.json')).get('guiding_used') else 1)" 2>/dev/null; then
      echo "# $name: auto guides it ($side); compared with --guiding off"
      bin=$NEW; na="${NEW_EXTRA:-} $NA_NEW"; [ $side = old ] && bin=$OLD && na=$NA_OLD
      $bin render "$@" $na --guiding off -o $out/$name.$side.exr --quiet --stats-json $out/$name.$side.json >/dev/null 2>&1 || { echo "${side^^} FAIL $name"; }
    fi
  done
  if [ -n "${EXPECTED_CHANGE:-}" ]; then  # compared by the patch's mean (see the top of the file)
    avg() { oiiotool --stats "$1" | grep -m1 'Stats Avg' | sed 's/.*Avg: //; s/ (float)//'; }
    if python3 -c "import sys; a=list(map(float,sys.argv[1].split())); b=list(map(float,sys.argv[2].split()));
r=max(abs(x-y)/max(abs(x),1e-12) for x,y in zip(a,b)); print(f'mean relative difference {r:.2e}'); sys.exit(0 if r<0.005 else 1)" \
        "$(avg $out/$name.old.exr)" "$(avg $out/$name.new.exr)"
    then echo "changed $name (expected: $EXPECTED_CHANGE)"; else echo "CHANGED TOO MUCH $name"; fail=1; fi
    return
  fi
  if cmp -s <(oiiotool --dumpdata $out/$name.old.exr 2>/dev/null | tail -n +2) <(oiiotool --dumpdata $out/$name.new.exr 2>/dev/null | tail -n +2); then
    a=$(python3 -c "import json;j=json.load(open('$out/$name.old.json'));print(j['density_lookups'],j['real_collisions'],j['dda_steps'])")
    b=$(python3 -c "import json;j=json.load(open('$out/$name.new.json'));print(j['density_lookups'],j['real_collisions'],j['dda_steps'])")
    [ "$a" = "$b" ] && echo "same $name" || { echo "COUNTERS DIFFER $name: $a vs $b"; fail=1; }
  else echo "PIXELS DIFFER $name"; fail=1; fi
}
for t in delta-per-channel spectral decomposition spectral-decomposition; do
  run cloud_$t data/scenes/cloud.json --tracker $t --spp 2 --pixel-bounds 176,208,112,144
  run cloud_g_$t data/scenes/cloud.json --tracker $t --spp 2 --pixel-bounds 176,208,112,144 --generic-kernels
  for s in bench/scenes/*.json; do b=$(basename $s .json); pb=$(python3 -c "import json;f=json.load(open('$s'))['film'];w,h=f['width']//2,f['height']//2;print(f'{w-12},{w+12},{h-12},{h+12}')"); run ${b}_$t $s --tracker $t --spp 1 --pixel-bounds $pb; done
done
for sch in max average history-max; do run cloud_s_$sch data/scenes/cloud.json --tracker spectral --scheme $sch --spp 2 --pixel-bounds 176,208,112,144; done
run smoke_delta bench/scenes/smoke_thin.json --tracker delta --spp 1 --pixel-bounds 36,60,52,76
run cloud_shard data/scenes/cloud.json --spp-range 3:5 --pixel-bounds 180,200,120,140
# shadow rays: the other estimators, one light per scatter, and a tiny budget (shadow rays of
# several bounces of a path in flight at once)
run cloud_mis data/scenes/cloud.json --tracker spectral-mis --spp 2 --pixel-bounds 176,208,112,144
run cloud_rm data/scenes/cloud.json --transmittance ray-marching --spp 2 --pixel-bounds 176,208,112,144
run dense_uniform bench/scenes/dense_chromatic.json --light-sampling uniform --spp 1 --pixel-bounds 20,44,20,44
run cloud_budget3 data/scenes/cloud.json --budget 3 --spp 2 --pixel-bounds 176,208,112,144
# blackbody emission: a temperature grid through the colour table, specialised and generic kernels
run fire data/scenes/fire.json --spp 2 --pixel-bounds 116,140,150,174
run fire_g data/scenes/fire.json --tracker delta-per-channel --spp 2 --pixel-bounds 116,140,150,174 --generic-kernels
# a colour grid (albedo), and an environment map (a gradient written here) lighting the cloud
for t in delta-per-channel spectral-mis; do run smoke_cd_$t docs/examples/colored_smoke.json --tracker $t --spp 2 --pixel-bounds 148,172,108,132; done
oiiotool --pattern fill:top=0.2,0.4,0.9:bottom=1.6,0.8,0.3 64x32 3 -d float -o $out/sky.exr >/dev/null 2>&1
/usr/bin/python3 - "$out" <<'PY'
import json, os, sys
s = json.load(open("data/scenes/cloud.json"))
s["lights"] = [{"type": "environment", "map": os.path.join(sys.argv[1], "sky.exr"), "scale": 1.5}]
s["media"][0]["file"] = os.path.abspath("data/volumes/cloud.vdb")
s["film"].pop("output", None)
json.dump(s, open(os.path.join(sys.argv[1], "env.json"), "w"))
PY
for t in spectral-decomposition delta-per-channel; do
  EXPECTED_CHANGE="the environment map's pdf" run env_$t $out/env.json --tracker $t --spp 2 --pixel-bounds 176,208,112,144
done
# spectral mode: the new binary's default wavelengths are stratified (docs/spectral.md, a new
# feature); with --wavelength-sampling independent (NEW_EXTRA, the new binary only) it draws the
# old ones
for t in spectral-decomposition delta-per-channel spectral-mis; do
  NEW_EXTRA="--wavelength-sampling independent" run cloud_spectral_$t data/scenes/cloud.json --spectral --tracker $t --spp 2 --pixel-bounds 176,208,112,144
done
NEW_EXTRA="--wavelength-sampling independent" run fire_spectral data/scenes/fire.json --spectral --spp 2 --pixel-bounds 116,140,150,174
# control: a different seed must differ
$NEW render data/scenes/cloud.json --spp 1 --pixel-bounds 180,200,120,140 -o $out/c1.exr --quiet; $NEW render data/scenes/cloud.json --spp 1 --seed 9 --pixel-bounds 180,200,120,140 -o $out/c2.exr --quiet
cmp -s <(oiiotool --dumpdata $out/c1.exr | tail -n +2) <(oiiotool --dumpdata $out/c2.exr | tail -n +2) && { echo "CONTROL FAILED: comparison is blind"; fail=1; } || echo "control ok: seeds differ"
echo "skipped=$skipped fail=$fail"; rm -rf $out
