#!/usr/bin/python3
"""Efficiency on pbrt-v4's comparison grid (../shared/bench/pbrt-grid/), side by side with the
figures pbrt-v4 measured on this machine kind (its README) and, when given --pbrt, a pbrt-v4
binary run in the same session.

Design: the figure of merit is pbrt's own, "variance x seconds" = mean per-pixel variance of the
image (over pixels and RGB channels) times render seconds; lower is better, and it does not depend
on the sample count (variance ~ 1/spp, seconds ~ spp). pbrt's README measured variance as RMSE^2
against an 8192-spp reference; here it is the unbiased per-pixel sample variance over --seeds
independent renders of --spp samples each, which has the same expectation for an unbiased
estimator and needs no reference (pbrt's spectral image differs from our RGB one by up to 6%, so
its reference would not do anyway). Seconds are `seconds_render` of --stats-json (the stage loop,
after kernel build and warm-up). Each configuration is rendered once first to warm the kernel
caches, then the configurations are interleaved seed by seed (A B A B), so that one run's ratios
hold on a shared, noisy machine.

Usage (from the repository root, after a build; needs python3-numpy, python3-openvdb and
python3-openimageio from Debian):
  /usr/bin/python3 bench/pbrt_grid.py [--spectrack build/spectrack] [--g 0.6] [--spp 16] [--seeds 4]
      [--config 'LABEL=FLAGS' ...] [--old OTHER_BINARY] [--pbrt PBRT_BINARY] [--json OUT.json]
--scene: measure another spectrack scene the same way (bench/scenes/*.json).
  /usr/bin/python3 bench/pbrt_grid.py --score DIR: bench/gpu.sh step 10's pbrt-v4 GPU side by side
--config: extra spectrack flags per configuration (default: the scene's own settings, i.e. the
default tracker, and delta-per-channel as the analog baseline). --old: the same configurations with
a second binary, interleaved (before/after comparisons).
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np
import OpenImageIO as oiio

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED_GRID = os.path.join(os.path.dirname(ROOT), "shared", "bench", "pbrt-grid")
# pbrt-v4 (5f7a606, independent sampler, --nthreads 2) on this machine kind: shared/bench/pbrt-grid/README.md
PBRT_README_VxS = {"0.0": 0.0127, "0.6": 0.0172}


def cache_dir():
    return os.environ.get("SPECTRACK_BENCH_CACHE", os.path.expanduser("~/.cache/spectrack/bench"))


def prepare_grid():
    """The grid and the scenes, generated once into the bench cache by the shared recipe."""
    out = os.path.join(cache_dir(), "pbrt-grid")
    if os.path.exists(os.path.join(out, "st_chromatic_g0.6.json")):
        return out
    if not os.path.isdir(SHARED_GRID):
        sys.exit(f"pbrt_grid.py: {SHARED_GRID} not found (the shared comparison medium)")
    os.makedirs(out, exist_ok=True)
    shutil.copy(os.path.join(SHARED_GRID, "gen_chromatic_grid.py"), out)
    subprocess.run(["/usr/bin/python3", os.path.join(out, "gen_chromatic_grid.py")], check=True, cwd=out)
    subprocess.run(["/usr/bin/python3", os.path.join(SHARED_GRID, "make_peer_scenes.py"), out], check=True)
    return out


def read_rgb(path):
    buf = oiio.ImageBuf(path)
    px = buf.get_pixels(oiio.FLOAT)
    if px is None or px.size == 0:
        sys.exit(f"pbrt_grid.py: could not read {path}: {buf.geterror()}")
    return np.asarray(px, dtype=np.float64)[:, :, :3]


_no_alpha = {}


def no_alpha(binary):
    """--no-alpha where the binary has film layers (docs/aov.md: EXRs get a transparent film and an
    alpha estimate by default): the benchmarks compare whole images and the cost of the beauty,
    as pbrt-v4 and Mitsuba render it; bench/film_layers.sh measures the layers' cost"""
    if binary not in _no_alpha:
        h = subprocess.run([binary, "render", "--help"], capture_output=True, text=True).stdout
        _no_alpha[binary] = ["--no-alpha"] if "--no-alpha" in h else []
    return _no_alpha[binary]


def render_spectrack(binary, scene, flags, spp, seed, work, tag):
    """image, seconds_render, wall-clock seconds of the whole command, stats"""
    out = os.path.join(work, f"{tag}_{seed}.exr")
    stats = out + ".json"
    cmd = [binary, "render", scene, "-o", out, "--spp", str(spp), "--seed", str(seed), "--quiet",
           "--stats-json", stats] + no_alpha(binary) + flags
    t0 = time.monotonic()
    subprocess.run(cmd, check=True)
    wall = time.monotonic() - t0
    with open(stats) as f:
        st = json.load(f)
    return read_rgb(out), float(st["seconds_render"]), wall, st


def pbrt_scene(grid, name):
    """A copy of pbrt's scene with the independent sampler (the pbrt-build recipe: zsobol is 1.6x
    slower per sample and no more efficient here, and the mirrors lack pmj02bn's tables)."""
    src = os.path.join(grid, name)
    dst = os.path.join(grid, name.replace(".pbrt", "_independent.pbrt"))
    with open(src) as f:
        lines = f.read().splitlines()
    out = ['Sampler "independent"' if l.strip().startswith("Sampler") else l for l in lines]
    if out == lines:
        sys.exit(f"pbrt_grid.py: no Sampler line in {src}")
    with open(dst, "w") as f:
        f.write("\n".join(out) + "\n")
    return dst


def render_pbrt(binary, scene, spp, seed, work, tag):
    """pbrt-v4 has no render-only timer in its output: wall-clock of the command (scene loading
    included, ~0.2 s here), as its README's figures were taken"""
    out = os.path.join(work, f"{tag}_{seed}.exr")
    t0 = time.monotonic()
    subprocess.run([binary, "--nthreads", "2", "--spp", str(spp), "--seed", str(seed), "--quiet",
                    "--outfile", out, scene], check=True, cwd=os.path.dirname(scene))
    wall = time.monotonic() - t0
    return read_rgb(out), wall, wall, {}


def score_gpu(out_dir):
    """bench/gpu.sh step 10's results (pbrt_grid.tsv, pbrt_images.tar): per renderer and sample
    count the variance over seeds; the marginal seconds per sample from the two counts' mean wall
    clocks (pbrt's CUDA and OptiX start-up, spectrack's kernel-cache load cancel out); efficiency
    1 / (variance at the larger count x its marginal seconds), and spectrack's against pbrt's"""
    import csv
    import tarfile
    rows = list(csv.DictReader(open(os.path.join(out_dir, "pbrt_grid.tsv")), delimiter="\t"))
    if not rows:
        sys.exit(f"pbrt_grid.py: {out_dir}/pbrt_grid.tsv has no renders")
    work = tempfile.mkdtemp(prefix="spectrack-pbrt-gpu.")
    try:
        with tarfile.open(os.path.join(out_dir, "pbrt_images.tar")) as t:
            t.extractall(work)
        fig = {}
        for r in rows:
            key = (r["renderer"], int(r["spp"]))
            f = fig.setdefault(key, {"images": [], "wall": [], "render": []})
            f["images"].append(read_rgb(os.path.join(work, f"{r['renderer']}_{r['spp']}_{r['seed']}.exr")))
            f["wall"].append(float(r["wall_s"]))
            if r["seconds_render"] not in ("", "-"):
                f["render"].append(float(r["seconds_render"]))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    eff = {}
    print(f"{'renderer':20s} {'spp':>5s} {'seeds':>5s} {'mean':>7s} {'variance':>10s} {'wall s':>7s} {'render s':>8s}")
    for (r, spp), f in sorted(fig.items()):
        if len(f["images"]) < 2:
            sys.exit(f"pbrt_grid.py: {r} at {spp} spp has {len(f['images'])} seed(s): the variance needs 2")
        ims = np.stack(f["images"])
        f["var"] = float(np.mean(np.var(ims, axis=0, ddof=1)))
        render = f"{np.mean(f['render']):8.3f}" if f["render"] else f"{'-':>8s}"
        print(f"{r:20s} {spp:5d} {len(ims):5d} {float(np.mean(ims)):7.4f} {f['var']:10.4e} {np.mean(f['wall']):7.3f} {render}")
    for r in sorted({k[0] for k in fig}):
        spps = sorted(spp for (q, spp) in fig if q == r)
        if len(spps) < 2:
            continue
        lo, hi = spps[0], spps[-1]
        per_sample = (np.mean(fig[r, hi]["wall"]) - np.mean(fig[r, lo]["wall"])) / (hi - lo)
        eff[r] = 1.0 / (fig[r, hi]["var"] * per_sample * hi)
        print(f"{r}: marginal {per_sample * 1e3:.3f} ms per sample, efficiency {eff[r]:.4g} at {hi} spp")
    if "pbrt" in eff:
        for r, e in eff.items():
            if r != "pbrt":
                print(f"side by side on the GPU: {r}: {e / eff['pbrt']:.2f}x pbrt-v4 --gpu's efficiency")


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--score":
        return score_gpu(sys.argv[2])
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spectrack", default=os.path.join(ROOT, "build", "spectrack"))
    ap.add_argument("--old", help="a second spectrack binary, run on the same configurations")
    ap.add_argument("--pbrt", help="a pbrt-v4 binary (shared/bench/pbrt-build/): side by side")
    ap.add_argument("--g", default="0.6", choices=["0.0", "0.6"])
    ap.add_argument("--gray", action="store_true", help="the gray (constant-spectrum) scenes")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--config", action="append", default=[], help="LABEL=FLAGS")
    ap.add_argument("--json", help="write the raw figures here")
    ap.add_argument("--scene", help="another spectrack scene, measured the same way (no pbrt figures)")
    a = ap.parse_args()
    if a.seeds < 2:
        sys.exit("pbrt_grid.py: --seeds must be >= 2 (the variance is taken over seeds)")
    kind = "gray" if a.gray else "chromatic"
    if a.scene:
        if a.pbrt:
            sys.exit("pbrt_grid.py: --pbrt needs the grid (no --scene)")
        scene, kind = os.path.abspath(a.scene), os.path.basename(a.scene)
    else:
        grid = prepare_grid()
        scene = os.path.join(grid, f"st_{kind}_g{a.g}.json")
    configs = [c.split("=", 1) for c in a.config] or [["default", ""], ["delta-per-channel", "--tracker delta-per-channel"]]
    runs = []  # (label, render function)
    for label, flags in configs:
        fl = flags.split()
        runs.append((label, lambda s, w, t, fl=fl: render_spectrack(a.spectrack, scene, fl, a.spp, s, w, t)))
        if a.old:
            runs.append((label + " [old]", lambda s, w, t, fl=fl: render_spectrack(a.old, scene, fl, a.spp, s, w, t)))
    if a.pbrt:
        pscene = pbrt_scene(grid, f"chromatic_grid{'_gray' if a.gray else ''}_g{a.g}.pbrt")
        runs.append(("pbrt-v4", lambda s, w, t: render_pbrt(a.pbrt, pscene, a.spp, s, w, t)))
    work = tempfile.mkdtemp(prefix="spectrack-pbrt-grid.")
    try:
        for i, (label, fn) in enumerate(runs):  # warm kernel caches (PoCL compiles at first launch)
            fn(1000 + i, work, f"warm{i}")
        images = {label: [] for label, _ in runs}
        seconds = {label: [] for label, _ in runs}
        walls = {label: [] for label, _ in runs}
        stats = {label: [] for label, _ in runs}
        for seed in range(a.seeds):
            for i, (label, fn) in enumerate(runs):  # interleaved: A B A B
                im, t, wall, st = fn(seed, work, f"r{i}")
                images[label].append(im)
                seconds[label].append(t)
                walls[label].append(wall)
                stats[label].append(st)
    finally:
        shutil.rmtree(work, ignore_errors=True)

    ref = PBRT_README_VxS[a.g] if not (a.gray or a.scene) else None
    print(f"{'scene ' + kind if a.scene else f'pbrt-v4 grid, {kind}, g = {a.g}, 256x256'}, {a.spp} spp x {a.seeds} seeds")
    print(f"{'configuration':30s} {'mean':>7s} {'variance':>10s} {'seconds':>8s} {'var x s':>10s} {'vs README':>9s} "
          f"{'wall s':>7s} {'var x wall':>10s}")
    rows = []
    for label, _ in runs:
        ims = np.stack(images[label])
        var = float(np.mean(np.var(ims, axis=0, ddof=1)))
        t = float(np.mean(seconds[label]))
        wall = float(np.mean(walls[label]))
        row = {"label": label, "mean": float(np.mean(ims)), "variance": var, "seconds": t, "var_x_s": var * t,
               "wall": wall, "var_x_wall": var * wall}
        if stats[label] and stats[label][0]:
            row["density_lookups"] = float(np.mean([s.get("density_lookups", 0) for s in stats[label]]))
            row["dda_steps"] = float(np.mean([s.get("dda_steps", 0) for s in stats[label]]))
        rows.append(row)
        cmp = f"{ref / (var * t):8.2f}x" if ref else ""
        print(f"{label:30s} {row['mean']:7.4f} {var:10.4e} {t:8.2f} {var * t:10.4e} {cmp:>9s} {wall:7.2f} {var * wall:10.4e}")
    print("efficiency = 1 / (variance x seconds). seconds: spectrack's seconds_render (the stage loop), pbrt's wall clock.")
    print("'vs README' = pbrt-v4's figure in shared/bench/pbrt-grid/README.md / ours (> 1: we are more efficient);")
    print("'var x wall' uses every command's wall clock (scene load, kernel build from the cache, image write).")
    if a.pbrt:
        p = next(r for r in rows if r["label"] == "pbrt-v4")
        for r in rows:
            if r is not p:
                print(f"side by side: {r['label']}: {p['var_x_wall'] / r['var_x_wall']:.2f}x pbrt-v4's efficiency (wall clock)")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"g": a.g, "kind": kind, "spp": a.spp, "seeds": a.seeds, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
