#!/usr/bin/env bash
# bench/equiangular.sh [SPP] [SEEDS] [SCENES] (env SPECTRACK: the binary, default build/spectrack):
# equi-angular sampling towards local lights (--equiangular on) against the tracker's collisions
# alone (off), docs/equiangular.md. Scenes written here (not bench/scenes, which
# bench/bit_identity.sh renders with binaries that predate local lights):
#   searchlight: a spot through thin fog over a ground (the case the technique is for);
#   lamp_thin / lamp_medium / lamp_dense: a point light inside a homogeneous fog box of optical
#     depth ~0.1, ~1.3 and ~13 along its mean chord (inside a dense medium both estimators are
#     heavy-tailed: paths that scatter next to the light);
#   lamp_dense_outside: the dense box lit by the lamp from outside, above its front;
#   cloud_lamp_thin / cloud_lamp: data/volumes/cloud.vdb (heterogeneous) at density scale 1 and 12
#     with a point light beside it.
# For each scene, one run of bench/pbrt_grid.py (a warm-up render per configuration, then the
# configurations interleaved seed by seed; variance = per-pixel variance over the seeds, seconds =
# seconds_render) with the default tracker and with delta-per-channel. Prints the efficiency ratio
# 1 / (variance x seconds), on over off (> 1: equi-angular sampling pays), and what "auto" chose.
set -euo pipefail
cd "$(dirname "$0")/.."
SPP=${1:-32}; SEEDS=${2:-4}; BIN=${SPECTRACK:-$PWD/build/spectrack}
SCENES=${3:-"searchlight lamp_thin lamp_medium lamp_dense lamp_dense_outside cloud_lamp_thin cloud_lamp"}
out=$(mktemp -d)
/usr/bin/python3 - "$out" "$PWD" <<'PY'
import copy, json, os, sys
out, root = sys.argv[1], sys.argv[2]
cam = {"type": "perspective", "position": [0, 1.5, -6], "look_at": [0, 1.2, 0], "up": [0, 1, 0], "fov_deg": 50}
def fog(ss, sa):
    return {"type": "homogeneous", "bounds": [[-2, 0, -2], [2, 3, 2]], "sigma_s": [ss] * 3, "sigma_a": [sa] * 3,
            "phase": {"type": "hg", "g": 0.3}}
def scene(lights, media, ground=None):
    s = {"format": "spectrack-scene/1", "camera": cam, "film": {"width": 64, "height": 48, "spp": 16},
         "render": {"seed": 0}, "lights": lights, "media": media}
    if ground: s["ground"] = ground
    return s
spot = {"type": "spot", "position": [0, 2.8, 0], "look_at": [0.6, 0, 0.3], "intensity": [200, 190, 170],
        "cone_angle_deg": 20, "cone_delta_deg": 5}
lamp = {"type": "point", "position": [0.3, 1.4, 0.2], "intensity": [20, 18, 15]}
scenes = {
    "searchlight": scene([spot], [fog(0.05, 0.005)], {"height": 0, "albedo": [0.3, 0.3, 0.3]}),
    "lamp_thin": scene([lamp], [fog(0.05, 0.005)]),
    "lamp_medium": scene([lamp], [fog(0.5, 0.05)]),
    "lamp_dense": scene([lamp], [fog(5.0, 0.5)]),
    "lamp_dense_outside": scene([dict(lamp, position=[0.3, 4.0, -2.5])], [fog(5.0, 0.5)]),
}
cloud = json.load(open(os.path.join(root, "data/scenes/cloud.json")))
cloud["media"][0]["file"] = os.path.join(root, "data/volumes/cloud.vdb")
cloud["film"] = {"width": 64, "height": 44, "spp": 16}
cloud["lights"] = [{"type": "point", "position": [0.9, 0.3, -0.6], "intensity": [3, 2.8, 2.5]}]
for name, scale in (("cloud_lamp_thin", 1.0), ("cloud_lamp", 12.0)):
    c = copy.deepcopy(cloud)
    c["media"][0]["density_scale"] = scale
    scenes[name] = c
for name, s in scenes.items():
    json.dump(s, open(os.path.join(out, name + ".json"), "w"), indent=1)
PY
for s in $SCENES; do
  "$BIN" render "$out/$s.json" --spp 1 --equiangular auto --quiet -o "$out/$s.auto.exr" \
    --stats-json "$out/$s.auto.stats" >/dev/null
  /usr/bin/python3 -c "import json,sys;f=json.load(open(sys.argv[1]))['features'];print(sys.argv[2],'auto chooses', 'on' if f & (1 << 19) else 'off')" "$out/$s.auto.stats" "$s"
  /usr/bin/python3 bench/pbrt_grid.py --spectrack "$BIN" --scene "$out/$s.json" --spp "$SPP" --seeds "$SEEDS" \
    --config "default/off=--equiangular off" --config "default/on=--equiangular on" \
    --config "dpc/off=--tracker delta-per-channel --equiangular off" --config "dpc/on=--tracker delta-per-channel --equiangular on" \
    --json "$out/$s.result.json"
done
/usr/bin/python3 - "$out" <<'PY'
import glob, json, os, sys
print("\nsummary: --equiangular on over off, per scene and tracker, in one run (interleaved)")
print("variance: on / off; time: on seconds / off seconds; efficiency: 1/(variance x seconds), on over off")
print(f"{'scene':16s} {'tracker':24s} {'variance':>9s} {'time':>7s} {'efficiency':>10s}")
for f in sorted(glob.glob(os.path.join(sys.argv[1], "*.result.json"))):
    rows = {r["label"]: r for r in json.load(open(f))["rows"]}
    for t, name in (("default", "spectral-decomposition"), ("dpc", "delta-per-channel")):
        off, on = rows[t + "/off"], rows[t + "/on"]
        print(f"{os.path.basename(f)[:-12]:16s} {name:24s} {on['variance'] / off['variance']:8.3f}x "
              f"{on['seconds'] / off['seconds']:6.2f}x {off['var_x_s'] / on['var_x_s']:9.2f}x")
PY
rm -rf "$out"
