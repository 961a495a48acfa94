#!/usr/bin/env python3
"""bench/scaled_scene.py SRC DST SCALE: a copy of scene SRC with its film scaled by SCALE (at least
8x8) and its volume paths made absolute, so the copy works from any folder (bench/adaptive.sh,
bench/denoise.sh)."""
import json
import os
import sys

src, dst, scale = sys.argv[1], sys.argv[2], float(sys.argv[3])
j = json.load(open(src))
for m in j["media"]:
    if "file" in m:  # a VDB medium (homogeneous ones have none)
        m["file"] = os.path.abspath(os.path.join(os.path.dirname(src), m["file"]))
j["film"]["width"] = max(8, round(j["film"]["width"] * scale))
j["film"]["height"] = max(8, round(j["film"]["height"] * scale))
j["film"]["output"] = "out.exr"
json.dump(j, open(dst, "w"))
