#!/usr/bin/python3
"""Spectral mode's wavelength sampling: stratified (the default) against independent, in one run.

Design: one binary, two configurations that differ only in `--wavelength-sampling`, rendered in
spectral mode on the bench scenes (and pbrt-v4's comparison grid when its scene is in the bench
cache, bench/pbrt_grid.py). Each scene is rendered once per configuration first to warm the kernel
cache, then seed by seed with the configurations interleaved (A B, B A alternately), so the ratios
hold on a shared, noisy machine. Variance is the unbiased per-pixel variance over the seeds (each
seed an independent render, so the within-pixel correlation of stratified samples is counted),
averaged over pixels and R, G, B; seconds are `seconds_render` of --stats-json (the stage loop).
Efficiency = 1 / (variance x seconds); the table prints independent/stratified ratios of variance
and of efficiency, the median over pixels of the per-pixel variance ratio (a scene whose variance is
a few fireflies, emissive_heat, moves its mean ratio from run to run; the median shows the typical
pixel), and the image means (the two samplings estimate one image).

Usage (from the repository root, after a build; needs python3-numpy and python3-openimageio):
  /usr/bin/python3 bench/wavelength_sampling.py [--spectrack build/spectrack] [--spp 8] [--seeds 4]
      [--scenes smoke1,dense_chromatic,...] [--tracker T]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
import OpenImageIO as oiio

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_SCENES = "cloud_chromatic,dense_chromatic,dense_subsurface,smoke1,smoke_thin,emissive_heat,pbrt_grid"
CONFIGS = (("stratified", ["--wavelength-sampling", "stratified"]),
           ("independent", ["--wavelength-sampling", "independent"]))


def scene_path(name):
    if name == "pbrt_grid":  # prepared by bench/pbrt_grid.py into the bench cache
        cache = os.environ.get("SPECTRACK_BENCH_CACHE", os.path.expanduser("~/.cache/spectrack/bench"))
        p = os.path.join(cache, "pbrt-grid", "st_chromatic_g0.6.json")
        return p if os.path.exists(p) else None
    p = os.path.join(ROOT, "bench", "scenes", name + ".json")
    if not os.path.exists(p):
        sys.exit(f"wavelength_sampling.py: no scene {p}")
    return p


def read_rgb(path):
    """R, G, B of an EXR, read with ImageInput (an ImageBuf of a path goes through OIIO's image cache,
    which may return the pixels of an earlier file of the same name)."""
    inp = oiio.ImageInput.open(path)
    if inp is None:
        sys.exit(f"wavelength_sampling.py: cannot read {path}: {oiio.geterror()}")
    img = inp.read_image(0, 0, 0, 3, "float")
    inp.close()
    return img.astype(np.float64)


def render(binary, scene, args, seed, spp, out):
    tag = f"{args[-1]}_{seed}_{spp}"  # a file per render
    exr, stats = os.path.join(out, f"img_{tag}.exr"), os.path.join(out, f"stats_{tag}.json")
    cmd = [binary, "render", scene, "--spectral", "--spp", str(spp), "--seed", str(seed), "--no-alpha", "--quiet",
           "-o", exr, "--stats-json", stats] + args
    subprocess.run(cmd, check=True)
    img = read_rgb(exr)
    os.remove(exr)
    return img, json.load(open(stats))["seconds_render"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--spectrack", default=os.path.join(ROOT, "build", "spectrack"))
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--scenes", default=DEFAULT_SCENES)
    ap.add_argument("--tracker", default=None, help="a tracker for every render (default: each scene's)")
    a = ap.parse_args()
    if a.seeds < 2:
        sys.exit("wavelength_sampling.py: --seeds must be at least 2 (the variance is over seeds)")
    binary = os.path.abspath(a.spectrack)
    extra = ["--tracker", a.tracker] if a.tracker else []
    print(f"spectral mode, {a.spp} spp x {a.seeds} seeds, {binary}{' --tracker ' + a.tracker if a.tracker else ''}")
    print(f"{'scene':18} {'variance strat':>14} {'indep':>11} {'s strat':>8} {'indep':>7} "
          f"{'var ratio':>9} {'eff ratio':>9} {'median px':>9} {'mean strat':>10} {'indep':>8}")
    with tempfile.TemporaryDirectory() as out:
        for name in a.scenes.split(","):
            scene = scene_path(name)
            if scene is None:
                print(f"{name:18} skipped: run bench/pbrt_grid.py once to prepare its scene")
                continue
            for _, args in CONFIGS:  # warm the kernel cache
                render(binary, scene, args + extra, 1, 1, out)
            imgs = {c: [] for c, _ in CONFIGS}
            secs = {c: 0.0 for c, _ in CONFIGS}
            for s in range(a.seeds):
                order = CONFIGS if s % 2 == 0 else CONFIGS[::-1]
                for c, args in order:
                    img, t = render(binary, scene, args + extra, 1000 + s, a.spp, out)
                    imgs[c].append(img)
                    secs[c] += t
            per_pixel = {c: np.var(np.array(imgs[c]), axis=0, ddof=1) for c in imgs}
            var = {c: per_pixel[c].mean() for c in imgs}
            both = (per_pixel["stratified"] > 0) & (per_pixel["independent"] > 0)
            median = float(np.median(per_pixel["independent"][both] / per_pixel["stratified"][both])) if both.any() else 0.0
            mean = {c: np.array(imgs[c]).mean() for c in imgs}
            vr = var["independent"] / var["stratified"]
            er = vr * secs["independent"] / secs["stratified"]
            print(f"{name:18} {var['stratified']:14.4e} {var['independent']:11.4e} {secs['stratified']:8.2f} "
                  f"{secs['independent']:7.2f} {vr:8.2f}x {er:8.2f}x {median:8.2f}x {mean['stratified']:10.5f} "
                  f"{mean['independent']:8.5f}", flush=True)
    print("var ratio = independent's variance / stratified's; eff ratio = stratified's efficiency / independent's "
          "(1 / (variance x seconds_render)); median px = the median pixel's variance ratio; > 1: stratified wins")


if __name__ == "__main__":
    main()
