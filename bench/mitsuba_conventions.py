#!/usr/bin/python3
"""mitsuba_conventions.py: spectrack's scene conventions against Mitsuba 3, side by side.

What it checks: each case renders one small, lopsided scene (media off the image centre, lights
off the axis, so a mirrored, turned or rescaled image would not agree) in spectrack and, translated
field by field (the translations are written out next to each builder below), in Mitsuba 3
(`scalar_rgb`, `volpath`, max_depth -1, box pixel filter): perspective cameras on films wider and
taller than high (fov across the shorter side = fov_axis "smaller"), a thin lens, directional
(direction = -to_light), point and hard-edged spot lights (W/sr), a sphere light, a constant
environment, a smooth 256x128 environment map (spectrack rotate_deg R = Mitsuba to_world
rotate(+y, R - 180), both right-handed: R = 180 against Mitsuba unturned, and R = 270 against
Mitsuba's turn by 90 to catch a sign error 180
cannot), HG g = +-0.6, chromatic sigma_s / sigma_a, and the diffuse ground (a 1e5-wide Mitsuba
rectangle). The map is written for each renderer at its own texel centres (Mitsuba's rows lie at
v = i / (h - 1), pole to pole; see write_maps), and its cases allow a systematic 0.1% per block for
nearest (spectrack) against bilinear (Mitsuba) lookup of the directly seen map, where the noise is
~0.001%. A control case, the same map with rotate_deg 0, must differ from Mitsuba.

z scores: spectrack's variance comes from its variance layer (each pixel's variance of the mean),
Mitsuba's from K = 8 seeds (each pixel's sample variance over the seeds / K); pixels are
independent, so a region's mean has the sum of its pixels' variances / n^2 (pooled over pixels, so
the variance is well estimated even from 8 seeds). Per channel z = (ours - Mitsuba) / sqrt(var_ours
+ var_mitsuba + (floor x Mitsuba)^2), floor 1e-5 (1e-3 for the map cases), for the image mean and
for each of the 4x4 blocks; each line shows the image means (R G B), the image-mean z of the worst
channel and the largest block |z|. A case FAILS when |z| > 4 for the image mean or > 4.5 for any of
its 48 block scores (noise alone: about once in 2000 cases).

Run: cd /work/main && PYTHONPATH=build/python /usr/bin/python3 bench/mitsuba_conventions.py
(needs the built module, mitsuba 3.9 and numpy; fixed seeds, --seed to change them; scratch files
in a temporary folder; a few minutes on 2 CPU cores with PoCL). Exit status 0 when every case
passes and the control differs, 1 otherwise (a control that does not differ means the check has
lost its power). A failing case means the renderers disagree beyond noise: a spectrack convention
(or this script's translation) changed, or an estimator is biased. Check the translation against
docs/scene-format.md first; a pattern over the blocks points to geometry (a mirror, a turn), a
uniform ratio of the means to units; rerun with another --seed before calling a lone |z| just over
the limit real.
"""
import argparse
import os
import shutil
import sys
import tempfile
import time

import numpy as np

import mitsuba as mi
import spectrack

mi.set_variant("scalar_rgb")
mi.set_log_level(mi.LogLevel.Error)
T = mi.ScalarTransform4f

Z_MEAN, Z_BLOCK, NB = 4.0, 4.5, 4  # limits and blocks per side
FLOOR = 1e-5  # relative: float rounding; zero-variance regions (a constant sky seen directly) agree to it
POS, TGT, UP = [1.0, 1.5, -5.0], [0.1, 0.2, 0.0], [0.0, 1.0, 0.0]


def rgb(v):
    return {"type": "rgb", "value": list(v)}


# ---------------------------------------------------------------- the scenes, both ways

def camera(w, h, aperture=0.0, focus=None):
    """A perspective camera (a thin lens with aperture > 0): spectrack's and Mitsuba's, and the film."""
    st = {"type": "perspective", "position": POS, "look_at": TGT, "up": UP, "fov_deg": 40}
    mit = {"type": "perspective", "fov": 40, "fov_axis": "smaller", "to_world": T.look_at(origin=POS, target=TGT, up=UP)}
    if aperture > 0:
        st.update(aperture_radius=aperture, focus_distance=focus)
        mit.update(type="thinlens", aperture_radius=aperture, focus_distance=focus)
    return st, mit, w, h


def medium(lo, hi, sigma_s, sigma_a, g=None):
    """A homogeneous box: spectrack's medium, and Mitsuba's null-BSDF cube with the medium inside."""
    phase = {"type": "hg", "g": g} if g is not None else {"type": "isotropic"}  # the same dict in both; g > 0 forward
    st = {"type": "homogeneous", "bounds": [lo, hi], "sigma_s": sigma_s, "sigma_a": sigma_a, "phase": phase}
    sigma_t = [s + a for s, a in zip(sigma_s, sigma_a)]
    m = max(sigma_t)
    centre = [(a + b) / 2 for a, b in zip(lo, hi)]
    half = [(b - a) / 2 for a, b in zip(lo, hi)]
    mit = {"type": "cube", "to_world": T.translate(centre) @ T.scale(half), "bsdf": {"type": "null"},
           "interior": {"type": "homogeneous", "albedo": rgb([s / t if t > 0 else 0.0 for s, t in zip(sigma_s, sigma_t)]),
                        "sigma_t": rgb([t / m for t in sigma_t]), "scale": m, "phase": dict(phase)}}
    return st, mit


def ground(height, albedo):
    """spectrack's ground plane; Mitsuba's: a huge rectangle facing +y with a Lambertian BSDF."""
    st = {"height": height, "albedo": albedo, "mode": "diffuse"}
    mit = {"type": "rectangle", "to_world": T.translate([0, height, 0]) @ T.rotate([1, 0, 0], -90) @ T.scale(1e5),
           "bsdf": {"type": "diffuse", "reflectance": rgb(albedo)}}
    return st, mit


def scenes(cam, media, lights, gnd=None):
    """The spectrack scene dict and the Mitsuba scene dict of one case."""
    cam_st, cam_mi, w, h = cam
    st = {"format": "spectrack-scene/1", "camera": cam_st, "film": {"width": w, "height": h},
          "render": {"max_depth": -1}, "lights": [l[0] for l in lights], "media": [m[0] for m in media]}
    cam_mi = dict(cam_mi, film={"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "pixel_format": "rgb"})
    mit = {"type": "scene", "integrator": {"type": "volpath", "max_depth": -1}, "sensor": cam_mi}
    for i, m in enumerate(media):
        mit[f"medium{i}"] = m[1]
    for i, l in enumerate(lights):
        mit[f"light{i}"] = l[1]
    if gnd:
        st["ground"] = gnd[0]
        mit["ground"] = gnd[1]
    return st, mit


# Lights: (spectrack, Mitsuba) pairs.
def sun(to_light, e):  # Mitsuba's direction is the way the light travels: -to_light
    return ({"type": "directional", "to_light": to_light, "irradiance": e},
            {"type": "directional", "direction": [-x for x in to_light], "irradiance": rgb(e)})


def point(p, i):  # both W/sr
    return {"type": "point", "position": p, "intensity": i}, {"type": "point", "position": p, "intensity": rgb(i)}


def hard_spot(p, at, i, angle):  # a hard edge: cone_delta_deg 0 = Mitsuba's beam_width equal to cutoff_angle
    return ({"type": "spot", "position": p, "look_at": at, "intensity": i, "cone_angle_deg": angle, "cone_delta_deg": 0},
            {"type": "spot", "to_world": T.look_at(origin=p, target=at, up=[0, 1, 0]), "intensity": rgb(i),
             "cutoff_angle": angle, "beam_width": angle})


def sphere(c, r, le):
    return ({"type": "sphere", "position": c, "radius": r, "radiance": le},
            {"type": "sphere", "center": c, "radius": r, "bsdf": {"type": "diffuse", "reflectance": rgb([0, 0, 0])},
             "emitter": {"type": "area", "radiance": rgb(le)}})


def env_const(le):
    return {"type": "environment", "radiance": le}, {"type": "constant", "radiance": rgb(le)}


def env_map(maps, rotate_deg, mi_turn_deg, scale=1.5):
    """One environment both sides: spectrack turned by rotate_deg, Mitsuba's to_world a turn about +y."""
    st_path, mi_path = maps
    return ({"type": "environment", "map": st_path, "scale": scale, "rotate_deg": rotate_deg},
            {"type": "envmap", "filename": mi_path, "scale": scale, "to_world": T.rotate([0, 1, 0], mi_turn_deg)})


def smooth_sky(u, v):
    """A smooth radiance in Mitsuba's lat-long convention (u = atan2(x, -z) / 2 pi, v = acos(y) / pi):
    a bright lobe up, right and towards +z, and gentle colour gradients along x, y and z."""
    th, ph = v * np.pi, u * 2 * np.pi
    d = np.stack([np.sin(th) * np.sin(ph), np.cos(th), -np.sin(th) * np.cos(ph)], -1)
    d0 = np.array([0.5, 0.5, 0.7]) / np.linalg.norm([0.5, 0.5, 0.7])
    lobe = np.exp(8 * (d @ d0 - 1))
    return np.stack([0.3 + 3 * lobe + 0.2 * d[..., 0], 0.3 + 2 * lobe + 0.2 * d[..., 1], 0.3 + lobe + 0.2 * d[..., 2]], -1)


def write_maps(folder, w=256, h=128):
    """smooth_sky as a w x h map for each renderer, sampled where that renderer puts its texels: spectrack
    at cell centres, v = (i + 0.5) / h (docs/scene-format.md); Mitsuba's envmap (src/emitters/envmap.cpp,
    eval_spectrum) puts row i at v = i / (h - 1), the first and last rows on the poles. Columns are at
    u = (j + 0.5) / w in both. Given one file, Mitsuba's map is stretched from the equator towards the
    poles by up to half a texel: about 0.1% on this scene's directly seen blocks, far above the noise."""
    paths = []
    for name, rows in [("spectrack", (np.arange(h) + 0.5) / h), ("mitsuba", np.arange(h) / (h - 1))]:
        u, v = np.meshgrid((np.arange(w) + 0.5) / w, rows)
        paths.append(os.path.join(folder, f"smooth_{name}_{w}x{h}.exr"))
        mi.Bitmap(smooth_sky(u, v).astype(np.float32)).write(paths[-1])
    return tuple(paths)


def cases(maps, spp):
    """name -> (spectrack dict, Mitsuba dict, spectrack spp, Mitsuba spp per seed, relative floor, is_control)."""
    lo, hi = [-0.2, -0.6, -0.6], [1.0, 0.6, 0.6]  # the scattering box, right of the image centre
    # 1-2: three absorbers (tinting red, blue, green), none centred, under a white sky.
    absorbers = [medium([0.3, 0.2, -0.5], [1.2, 1.0, 0.5], [0, 0, 0], [0.6, 4.0, 4.0]),
                 medium([-1.2, -0.8, -0.3], [-0.6, -0.2, 0.3], [0, 0, 0], [4.0, 4.0, 0.6]),
                 medium([-0.2, 0.5, 1.0], [0.2, 1.5, 1.4], [0, 0, 0], [4.0, 0.6, 4.0])]
    white = [env_const([1, 1, 1])]
    # 3-6: the scattering box lit by one light setup at a time.
    box = [medium(lo, hi, [1.5] * 3, [0.3] * 3)]
    backlit = [sun([0.2, 0.3, 1.0], [3, 3, 3])]  # from behind the box: forward scattering shows
    sidelit = [sun([1, 2, -1], [2, 2, 2]), env_const([0.1, 0.1, 0.1])]
    wide = camera(48, 32)
    s, m = spp, spp // 4  # spectrack's samples; Mitsuba's per seed (x K seeds)
    map_floor = 1e-3  # a map seen directly: nearest (spectrack) vs bilinear (Mitsuba) lookup, measured <= 1.5e-4 a block
    c = {
        "camera 48x32 (fov across height)": (*scenes(wide, absorbers, white), s, m, FLOOR, False),
        "camera 32x48 (fov across width)": (*scenes(camera(32, 48), absorbers, white), s, m, FLOOR, False),
        "thin lens r 0.6 focus 2": (*scenes(camera(48, 32, 0.6, 2.0), absorbers, white), 2 * s, 2 * m, FLOOR, False),
        "directional": (*scenes(wide, box, [sun([1, 2, -1], [2, 2, 2])]), s, m, FLOOR, False),
        "point": (*scenes(wide, box, [point([-1.0, 1.0, -0.5], [3, 3, 3])]), s, m, FLOOR, False),
        "spot 20 deg hard edge": (*scenes(wide, box, [hard_spot([-1.5, 1.5, -1.0], [0.4, 0, 0], [8, 8, 8], 20)]),
                                  s, m, FLOOR, False),
        "sphere light": (*scenes(wide, box, [sphere([-1.2, 0.8, 0.0], 0.3, [4, 4, 4])]), s, m, FLOOR, False),
        "environment constant": (*scenes(wide, box, [env_const([0.5, 0.7, 1.0])]), s, m, FLOOR, False),
        "env map rotate_deg 180 / mi 0": (*scenes(wide, box, [env_map(maps, 180, 0)]), s, m, map_floor, False),
        "env map rotate_deg 270 / mi 90": (*scenes(wide, box, [env_map(maps, 270, 90)]), s, m, map_floor, False),
        "CONTROL env map rotate_deg 0 / mi 0": (*scenes(wide, box, [env_map(maps, 0, 0)]), s, m, map_floor, True),
        "HG g +0.6 backlit": (*scenes(wide, [medium(lo, hi, [1.5] * 3, [0.3] * 3, 0.6)], backlit), s, m, FLOOR, False),
        "HG g -0.6 backlit": (*scenes(wide, [medium(lo, hi, [1.5] * 3, [0.3] * 3, -0.6)], backlit), s, m, FLOOR, False),
        "chromatic sigma_s/sigma_a": (*scenes(wide, [medium(lo, hi, [2.0, 1.0, 0.3], [0.05, 0.5, 1.0])], sidelit),
                                      s, m, FLOOR, False),
        "ground, sun + sky": (*scenes(wide, box, [sun([1, 2, -1], [2, 2, 2]), env_const([0.2, 0.25, 0.3])],
                                      ground(-0.8, [0.6, 0.4, 0.2])), s, m, FLOOR, False),
    }
    return c


# ---------------------------------------------------------------- rendering and the statistics

def render_spectrack(scene, spp, seed):
    """The beauty (h, w, 3) and each pixel's variance of the mean, from the variance layer."""
    img = spectrack.load_dict(scene).render(spp=spp, seed=seed, aovs=["variance"], alpha=False)
    return np.asarray(img.rgb, np.float64)[..., :3], np.asarray(img.layers["variance"], np.float64)[..., :3]


def render_mitsuba(scene, spp, seeds):
    """The mean over the seeds' renders and each pixel's variance of that mean."""
    s = mi.load_dict(scene)
    imgs = np.stack([np.asarray(mi.render(s, spp=spp, seed=k), np.float64)[..., :3] for k in seeds])
    return imgs.mean(0), imgs.var(0, ddof=1) / len(seeds)


def region_means(img, var, nb):
    """Means of nb x nb blocks and their variances (independent pixels: sum of variances / n^2)."""
    h, w = img.shape[:2]
    m, v = np.zeros((nb, nb, 3)), np.zeros((nb, nb, 3))
    for i in range(nb):
        for j in range(nb):
            ys, xs = slice(i * h // nb, (i + 1) * h // nb), slice(j * w // nb, (j + 1) * w // nb)
            n = (ys.stop - ys.start) * (xs.stop - xs.start)
            m[i, j] = img[ys, xs].mean((0, 1))
            v[i, j] = var[ys, xs].sum((0, 1)) / n ** 2
    return m, v


def zscores(a, va, b, vb, floor):
    return (a - b) / np.sqrt(va + vb + (floor * np.abs(b)) ** 2 + 1e-30)


def compare(ours, theirs, floor):
    (a, va), (b, vb) = ours, theirs
    z_mean = zscores(*region_means(a, va, 1), *region_means(b, vb, 1), floor).ravel()
    z_block = zscores(*region_means(a, va, NB), *region_means(b, vb, NB), floor)
    worst = z_mean[np.argmax(np.abs(z_mean))]
    return a.mean((0, 1)), b.mean((0, 1)), float(worst), float(np.abs(z_block).max())


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=1, help="spectrack's seed; Mitsuba's seeds are 100*seed + 0..K-1")
    ap.add_argument("--mitsuba-seeds", type=int, default=8, help="K, Mitsuba renders per case")
    ap.add_argument("--spp", type=int, default=4096, help="spectrack's samples per pixel (Mitsuba: spp / 4 per seed)")
    args = ap.parse_args()
    t_start = time.time()
    work = tempfile.mkdtemp(prefix="spectrack-mitsuba-conventions.")
    try:
        maps = write_maps(work)
        print(f"spectrack {getattr(spectrack, '__version__', '?')} vs Mitsuba {mi.__version__} ({mi.variant()}, volpath); "
              f"spectrack seed {args.seed}, Mitsuba seeds {100 * args.seed}..{100 * args.seed + args.mitsuba_seeds - 1}")
        print(f"FAIL: |z image mean| > {Z_MEAN} or max |z| over {NB}x{NB} blocks x 3 channels > {Z_BLOCK}")
        print(f"{'case':38s} {'spectrack mean (R G B)':>26s} {'Mitsuba mean (R G B)':>26s} {'z mean':>7s} {'z block':>7s}  "
              f"{'result':6s} {'spp st/mi':>12s} {'s':>5s}")
        ok = True
        for name, (st_scene, mi_scene, spp_st, spp_mi, floor, control) in cases(maps, args.spp).items():
            t0 = time.time()
            ours = render_spectrack(st_scene, spp_st, args.seed)
            theirs = render_mitsuba(mi_scene, spp_mi, range(100 * args.seed, 100 * args.seed + args.mitsuba_seeds))
            ma, mb, zm, zb = compare(ours, theirs, floor)
            failed = abs(zm) > Z_MEAN or zb > Z_BLOCK
            if control:
                result = "differs (expected)" if failed else "SAME: control did not differ, FAIL"
                ok &= failed
            else:
                result = "FAIL" if failed else "PASS"
                ok &= not failed
            fmt = lambda m: " ".join(f"{x:8.5f}" for x in m)
            print(f"{name:38s} {fmt(ma):>26s} {fmt(mb):>26s} {zm:7.2f} {zb:7.2f}  {result:6s} "
                  f"{f'{spp_st}/{args.mitsuba_seeds}x{spp_mi}':>12s} {time.time() - t0:5.1f}", flush=True)
        print(f"{'ALL PASS, control differs' if ok else 'FAILED'}; {time.time() - t_start:.0f} s in all")
        return 0 if ok else 1
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
