#!/bin/bash
# bench/guiding_reference.sh BIN DIR [SPP] [SCENES]: the long unguided renders that bench/guiding.sh
# compares against (REF=DIR): DIR/<scene>.exr, seed 1000 (no run of bench/guiding.sh uses it), with
# the variance layer (bench/guiding.sh subtracts the reference's own share of the error).
BIN=${1:?usage: bench/guiding_reference.sh BIN DIR [SPP] [SCENES]}; DIR=${2:?DIR}; SPP=${3:-512}
SCENES=${4:-dense_subsurface cloud_chromatic cloud_sunlit_dense}
cd "$(dirname "$0")/.."; mkdir -p "$DIR"
for scene in $SCENES; do
  $BIN render bench/scenes/$scene.json --spp $SPP --seed 1000 --guiding off --aov variance --no-alpha \
    -o "$DIR/$scene.exr" --quiet --stats-json "$DIR/$scene.json" || { echo "FAIL $scene"; exit 1; }
  echo "$scene: $SPP spp, $(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['seconds_render'])" "$DIR/$scene.json") s"
done
