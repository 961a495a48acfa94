#!/usr/bin/python3
"""Point and spot lights side by side with pbrt-v4: the same scene (a homogeneous gray medium in a
box, lit by a point light just above it and a spot light beside it, no other light) rendered by
spectrack and by a pbrt-v4 binary; their images must agree within 4 standard errors.

Design: both renderers see one scene: the box [-1, 1]^3 of sigma_s 0.8, sigma_a 0.2 (constant
spectra in pbrt, so its spectral image is the RGB one), HG g = 0.3, unlimited depth; a point light
of intensity 2 W/sr at (0.4, 1.3, -0.2) and a spot of intensity 6 at (-1.6, 1.4, -0.6) aimed at
the origin, cone 25 degrees, falloff 8 (pbrt's coneangle and conedeltaangle); a 64 x 64 perspective
camera at (0, 0, -4) with a 40 degree field of view; box pixel filter of radius 0.5, independent
sampler. Both lights lie outside the medium: scatter events next to a point light inside it have
I / r^2 contributions of unbounded variance (docs/scene-format.md), which standard errors cannot
hold. pbrt's "rgb I" of a light is an illuminant spectrum normalised so that a gray value images
as itself on its default sensor, which is spectrack's convention. pbrt's LookAt is left-handed:
its image is spectrack's mirrored left-right, flipped before the comparison. Each pixel of each
image is an independent estimate, so the per-pixel differences of the two images are independent
with zero mean when both renderers are unbiased: the script reports, per channel and over the
whole image and its four quadrants, the mean difference over its standard error (|z| < 4 passes),
and the same with pbrt's image scaled by 1.03 (a 3% error, which must be seen: |z| > 4).

Usage (from the repository root, after a build; Debian's python3 with python3-numpy and
python3-openimageio):
  /usr/bin/python3 bench/pbrt_local_lights.py --pbrt /path/to/pbrt [--spectrack build/spectrack]
      [--spp 1024] [--out DIR] [--json OUT.json]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pbrt_grid import read_rgb  # noqa: E402

W = H = 64
SIGMA_S, SIGMA_A, G = 0.8, 0.2, 0.3
POINT = {"position": [0.4, 1.3, -0.2], "intensity": 2.0}
SPOT = {"position": [-1.6, 1.4, -0.6], "look_at": [0, 0, 0], "intensity": 6.0, "cone": 25.0, "delta": 8.0}
EYE, TARGET, UP, FOV = [0, 0, -4], [0, 0, 0], [0, 1, 0], 40


def spectrack_scene(spp, out):
    return {
        "format": "spectrack-scene/1",
        "camera": {"type": "perspective", "position": EYE, "look_at": TARGET, "up": UP, "fov_deg": FOV},
        "film": {"width": W, "height": H, "spp": spp, "output": out, "alpha": False},
        "render": {"max_depth": -1, "seed": 1},
        "lights": [{"type": "point", "position": POINT["position"], "intensity": [POINT["intensity"]] * 3},
                   {"type": "spot", "position": SPOT["position"], "look_at": SPOT["look_at"],
                    "intensity": [SPOT["intensity"]] * 3, "cone_angle_deg": SPOT["cone"],
                    "cone_delta_deg": SPOT["delta"]}],
        "media": [{"name": "fog", "type": "homogeneous", "bounds": [[-1, -1, -1], [1, 1, 1]],
                   "sigma_s": [SIGMA_S] * 3, "sigma_a": [SIGMA_A] * 3, "phase": {"type": "hg", "g": G}}]}


def cube_mesh():
    P, idx = [], []
    for axis in range(3):
        for side in (-1, 1):
            b = len(P)
            u, v = (axis + 1) % 3, (axis + 2) % 3
            for a, c in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = [0, 0, 0]
                p[axis], p[u], p[v] = side, a, c
                P.append(p)
            # counter-clockwise seen from outside (pbrt's geometric normal points out, so that
            # MediumInterface's "inside" is the box)
            idx += [b, b + 1, b + 2, b, b + 2, b + 3] if side > 0 else [b, b + 2, b + 1, b, b + 3, b + 2]
    return ' '.join('%g' % c for p in P for c in p), ' '.join(map(str, idx))


def pbrt_scene(spp, out, seed):
    P, idx = cube_mesh()
    v = lambda x: ' '.join('%g' % c for c in x)
    return f'''LookAt {v(EYE)}  {v(TARGET)}  {v(UP)}
Camera "perspective" "float fov" {FOV}
Film "rgb" "integer xresolution" {W} "integer yresolution" {H} "string filename" "{out}" "bool savefp16" false
PixelFilter "box" "float xradius" 0.5 "float yradius" 0.5
Sampler "independent" "integer pixelsamples" {spp} "integer seed" {seed}
Integrator "volpath" "integer maxdepth" 100000
WorldBegin
MakeNamedMedium "fog" "string type" "homogeneous"
    "spectrum sigma_a" [ 300 {SIGMA_A} 900 {SIGMA_A} ] "spectrum sigma_s" [ 300 {SIGMA_S} 900 {SIGMA_S} ]
    "float scale" 1 "float g" {G}
LightSource "point" "point3 from" [ {v(POINT["position"])} ] "rgb I" [ {v([POINT["intensity"]] * 3)} ]
LightSource "spot" "point3 from" [ {v(SPOT["position"])} ] "point3 to" [ {v(SPOT["look_at"])} ]
    "rgb I" [ {v([SPOT["intensity"]] * 3)} ] "float coneangle" {SPOT["cone"]} "float conedeltaangle" {SPOT["delta"]}
AttributeBegin
    MediumInterface "fog" ""
    Material "interface"
    Shape "trianglemesh" "point3 P" [ {P} ] "integer indices" [ {idx} ]
AttributeEnd
'''


def z_scores(a, b):
    """|mean(a - b)| / SE over the whole image and its quadrants, per channel."""
    out = []
    for region in range(-1, 4):
        for c in range(3):
            d = a[:, :, c] - b[:, :, c]
            if region >= 0:
                y0, x0 = (region // 2) * (H // 2), (region % 2) * (W // 2)
                d = d[y0:y0 + H // 2, x0:x0 + W // 2]
            d = d.ravel()
            out.append(abs(d.mean()) / max(d.std(ddof=1) / np.sqrt(d.size), 1e-12))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--pbrt", required=True)
    ap.add_argument("--spectrack", default="build/spectrack")
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--out", default=None)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    out = a.out or tempfile.mkdtemp(prefix="pbrt_local_lights_")
    os.makedirs(out, exist_ok=True)
    st_json, st_exr = os.path.join(out, "st_local_lights.json"), os.path.join(out, "st_local_lights.exr")
    pb_file, pb_exr = os.path.join(out, "pbrt_local_lights.pbrt"), os.path.join(out, "pbrt_local_lights.exr")
    json.dump(spectrack_scene(a.spp, st_exr), open(st_json, "w"), indent=1)
    open(pb_file, "w").write(pbrt_scene(a.spp, pb_exr, 7))
    t0 = time.time()
    subprocess.run([a.spectrack, "render", st_json, "--quiet"], check=True)
    t_st = time.time() - t0
    t0 = time.time()
    subprocess.run([a.pbrt, "--nthreads", "2", "--quiet", pb_file], check=True)
    t_pb = time.time() - t0
    st = read_rgb(st_exr)
    pb = read_rgb(pb_exr)[:, ::-1, :]  # pbrt's LookAt is left-handed: mirror it back
    z = z_scores(st, pb)
    z_twin = z_scores(st, 1.03 * pb)
    means_st, means_pb = st.reshape(-1, 3).mean(0), pb.reshape(-1, 3).mean(0)
    res = {"spp": a.spp, "spectrack_mean_rgb": means_st.tolist(), "pbrt_mean_rgb": means_pb.tolist(),
           "max_z": float(max(z)), "max_z_pbrt_times_1.03": float(max(z_twin)),
           "agree_within_4_se": bool(max(z) < 4), "twin_detects_3_percent": bool(max(z_twin) > 4), "spectrack_wall_s": t_st, "pbrt_wall_s": t_pb,
           "images": [st_exr, pb_exr]}
    print(json.dumps(res, indent=1))
    if a.json:
        json.dump(res, open(a.json, "w"), indent=1)
    return 0 if res["agree_within_4_se"] and res["twin_detects_3_percent"] else 1


if __name__ == "__main__":
    sys.exit(main())
