"""mitsuba_side.py: renders a spectrack benchmark scene with Mitsuba 3 (volpath) from exactly the
same grid, for the side-by-side in bench/error_vs_time.py. Run with a Python that has `mitsuba`
(bench/run makes a venv for it); the renderer itself never needs Python.

  python mitsuba_side.py SCENE.json GRID_PREFIX VARIANT OUT_DIR SPP:SEED [SPP:SEED ...]

Design: the scene JSON is translated field by field, and the heterogeneous medium is built from
grid_export's dense dump of the grid as spectrack loads it:
- values sit at voxel centres (integer index coordinates); the dump spans index_min - 1 ..
  index_max + 1, so Mitsuba's cell-centred gridvolume (N cells over [0,1]^3, trilinear, clamp) is
  mapped by to_world = scene transform * index_to_world * translate(origin - 0.5) * scale(dims);
  its box (the null-BSDF cube holding the medium) is the same box;
- sigma_t = density * density_scale * (sigma_s + sigma_a) per channel: a 3-channel grid of
  density * (sigma_s + sigma_a) with `scale` = density_scale; albedo = sigma_s / sigma_t (constant);
- HG g as is (both: g > 0 forward); the sun is a `directional` emitter with direction = -to_light
  and the same irradiance (benchmark scenes use angle_deg 0, a delta light); the sky is a
  `constant` emitter; the camera is `perspective` with fov across the smaller side
  (fov_axis 'smaller', our convention) and look_at; the pixel filter is a box (ours: uniform
  jitter in the pixel); max_depth -1 (Russian roulette only), as ours.
The integrator is `volpath`, or $MITSUBA_INTEGRATOR (`volpathmis`: spectral MIS, bench/mitsuba_mis.py).
Each SPP:SEED render writes OUT_DIR/mi_<spp>_<seed>.exr (RGB float32, Mitsuba's Bitmap) and the
render seconds (wall clock around mi.render and the read-back to the host) into
OUT_DIR/timings.json. It needs Mitsuba and Dr.Jit alone, not numpy (the GPU machine's Python has
no registry): the grid is read with `array` and multiplied out with Dr.Jit.
"""
import array
import json
import math
import os
import re
import subprocess
import sys
import time

import drjit as dr
import mitsuba as mi


def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def scene_transform(t):
    """scale, then rotations about x, y, z, then translate (docs/scene-format.md, `transform`), as a 4x4."""
    s = t.get("scale", 1.0)
    s = [s, s, s] if isinstance(s, (int, float)) else s
    m = [[s[0], 0, 0, 0], [0, s[1], 0, 0], [0, 0, s[2], 0], [0, 0, 0, 1]]
    for axis, deg in enumerate(t.get("rotate_deg", [0, 0, 0])):
        r = math.radians(deg)
        c, sn = math.cos(r), math.sin(r)
        i, j = (axis + 1) % 3, (axis + 2) % 3
        rot = [[1.0 if a == b else 0.0 for b in range(4)] for a in range(4)]
        rot[i][i], rot[i][j], rot[j][i], rot[j][j] = c, -sn, sn, c
        m = matmul(rot, m)
    tr = t.get("translate", [0, 0, 0])
    tm = [[1, 0, 0, tr[0]], [0, 1, 0, tr[1]], [0, 0, 1, tr[2]], [0, 0, 0, 1]]
    return matmul(tm, m)


def sigma_t_grid(path, dims, sigma_t):
    """The dense density dump times sigma_t per channel: a (nz, ny, nx, 3) tensor, channels last."""
    density = array.array("f")
    with open(path, "rb") as f:
        density.frombytes(f.read())
    n = dims[0] * dims[1] * dims[2]
    if len(density) != n:
        raise SystemExit(f"mitsuba_side: {path}: {len(density)} values, the dims say {n}")
    k = dr.arange(mi.UInt32, 3 * n)
    grid = dr.gather(mi.Float, mi.Float(density), k // 3) * dr.gather(mi.Float, mi.Float(sigma_t), k % 3)
    return mi.TensorXf(grid, shape=(*dims, 3))


def build_scene(scene, grid_prefix, spp):
    meta = json.load(open(grid_prefix + ".json"))
    nx, ny, nz = meta["dims"]
    med = scene["media"][0]
    sigma_t = [s + a for s, a in zip(med["sigma_s"], med["sigma_a"])]
    albedo = [s / t if t > 0 else 0.0 for s, t in zip(med["sigma_s"], sigma_t)]
    grid = sigma_t_grid(grid_prefix + ".f32", (nz, ny, nx), sigma_t)
    i2w = meta["index_to_world"] + [[0, 0, 0, 1]]
    o = meta["index_origin"]
    unit_to_index = [[nx, 0, 0, o[0] - 0.5], [0, ny, 0, o[1] - 0.5], [0, 0, nz, o[2] - 0.5], [0, 0, 0, 1]]
    to_world = matmul(scene_transform(med.get("transform", {})), matmul(i2w, unit_to_index))
    cube_from_unit = [[0.5, 0, 0, 0.5], [0, 0.5, 0, 0.5], [0, 0, 0.5, 0.5], [0, 0, 0, 1]]
    phase = med.get("phase", {"type": "isotropic"})
    mi_phase = {"type": "hg", "g": phase["g"]} if phase["type"] == "hg" else {"type": "isotropic"}
    cam = scene["camera"]
    film = scene["film"]
    d = {
        "type": "scene",
        "integrator": {"type": os.environ.get("MITSUBA_INTEGRATOR", "volpath"), "max_depth": -1},
        "sensor": {
            "type": "perspective",
            "fov": cam["fov_deg"],
            "fov_axis": "smaller",
            "to_world": mi.ScalarTransform4f().look_at(origin=cam["position"], target=cam["look_at"], up=cam["up"]),
            "film": {"type": "hdrfilm", "width": film["width"], "height": film["height"],
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "medium_box": {
            "type": "cube",
            "to_world": mi.ScalarTransform4f(matmul(to_world, cube_from_unit)),
            "bsdf": {"type": "null"},
            "interior": {
                "type": "heterogeneous",
                "albedo": {"type": "rgb", "value": albedo},
                "sigma_t": {"type": "gridvolume", "data": grid, "filter_type": "trilinear",
                            "wrap_mode": "clamp", "to_world": mi.ScalarTransform4f(to_world)},
                "scale": med.get("density_scale", 1.0),
                "phase": mi_phase,
            },
        },
    }
    for k, light in enumerate(scene["lights"]):
        if light["type"] == "environment":
            d[f"light{k}"] = {"type": "constant", "radiance": {"type": "rgb", "value": light["radiance"]}}
        elif light["type"] == "directional":
            if light.get("angle_deg", 0) != 0:
                raise SystemExit("mitsuba_side: directional lights must have angle_deg 0 in benchmark scenes")
            norm = math.sqrt(sum(c * c for c in light["to_light"]))
            d[f"light{k}"] = {"type": "directional", "direction": [-c / norm for c in light["to_light"]],
                              "irradiance": {"type": "rgb", "value": light["irradiance"]}}
    return mi.load_dict(d)


def resolve_framed_camera(scene, scene_path):
    """A camera framed by spectrack ("position": "auto", "look_at": "media") gets the position and
    look_at spectrack computes, from `spectrack info` ($SPECTRACK, else build/spectrack), which
    prints them to 6 significant digits."""
    cam = scene["camera"]
    if not isinstance(cam.get("position"), str) and not isinstance(cam.get("look_at"), str):
        return
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    binary = os.environ.get("SPECTRACK", os.path.join(root, "build", "spectrack"))
    out = subprocess.run([binary, "info", scene_path], capture_output=True, text=True, check=True).stdout
    m = re.search(r"camera \w+ \(framed\): position \(([^)]*)\), look_at \(([^)]*)\)", out)
    if not m:
        raise SystemExit(f"mitsuba_side: no framed camera in `spectrack info {scene_path}`")
    cam["position"] = [float(x) for x in m.group(1).split(",")]
    cam["look_at"] = [float(x) for x in m.group(2).split(",")]


def main():
    scene_path, grid_prefix, variant, out_dir = sys.argv[1:5]
    jobs = [tuple(int(x) for x in a.split(":")) for a in sys.argv[5:]]
    mi.set_variant(variant)
    scene = json.load(open(scene_path))
    resolve_framed_camera(scene, scene_path)
    os.makedirs(out_dir, exist_ok=True)
    tpath = os.path.join(out_dir, "timings.json")
    timings = json.load(open(tpath)) if os.path.exists(tpath) else {}
    loaded = {}
    for spp, seed in jobs:
        if spp not in loaded:
            loaded[spp] = build_scene(scene, grid_prefix, spp)
        t0 = time.perf_counter()
        img = mi.Bitmap(mi.render(loaded[spp], spp=spp, seed=seed))
        secs = time.perf_counter() - t0
        img.write(os.path.join(out_dir, f"mi_{spp}_{seed}.exr"))
        timings[f"{spp}:{seed}"] = secs
        json.dump(timings, open(tpath, "w"), indent=1)
        print(f"mitsuba {variant} {spp} spp seed {seed}: {secs:.2f} s", flush=True)


if __name__ == "__main__":
    main()
